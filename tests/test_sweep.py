"""The stability sweep: grid and input checks, the capped runner, and the sweep on Dask (LocalCluster, a
scheduler and a worker started here as separate processes, a worker killed mid-sweep, --resume).

Everything that starts a cluster runs in a subprocess with a timeout, so that a hang fails the test.
"""

import contextlib
import json
import math
import shlex
import signal
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import bouncingball as bb
from bouncingball.cli import EXIT_BAD_INPUT
from bouncingball.solvers.cvode import DEFAULT_ATOL, DEFAULT_RTOL
from bouncingball.solvers.exact import ExactSolution
from bouncingball.sweep import Grid, parse_range
from bouncingball.sweep.child import run_batch
from bouncingball.sweep.store import COLUMNS as STORE_COLUMNS

SWEEP = ["--k", "1e2:1e8:4", "--zeta", "1e-3:1:3", "--solvers", "cvode,article", "--t-end", "1",
         "--batch-size", "2", "--time-cap", "30"]
TIMES = ["wall_time", "worker", "batch"]  # what may differ between two sweeps of the same grid
BIN = Path(sys.executable).parent


def _sweep(*args: str, timeout: float = 240.0) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "bouncingball"), "sweep", *args], capture_output=True, text=True,
                          timeout=timeout, check=False)


def _table(directory: Path) -> pd.DataFrame:
    return pd.read_parquet(directory / "stability_map.parquet")


# --- input, before any cluster ------------------------------------------------------------------------
@pytest.mark.parametrize(("args", "names"), [
    (["--k", "1e2:1e1:0"], ["--k", "'1e2:1e1:0'", "LO:HI:N"]),
    (["--zeta=-1:1:3"], ["--zeta", "'-1:1:3'", "0 < LO <= HI"]),
    (["--m", "1:1:3"], ["--m", "need LO < HI"]),
    (["--solvers", "cvode,rk4"], ["--solvers", "'rk4'", "scipy:DOP853", "article"]),
    (["--t-end", "0"], ["--t-end", "0.0", "> 0"]),
    (["--workers", "0"], ["--workers", ">= 1"]),
    (["--time-cap", "-2"], ["--time-cap", "-2.0", "> 0"]),
])
def test_bad_input_is_one_line_and_exit_2_before_any_cluster(args, names):
    script = (f"import sys\nfrom bouncingball.cli import main\nassert main(['sweep', *{args!r}]) == {EXIT_BAD_INPUT}\n"
              "print(sorted(m for m in ('distributed', 'dask') if m in sys.modules))")
    completed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60,
                               check=True)
    assert completed.stdout.strip() == "[]"  # no cluster was started: Dask was not even imported
    error = completed.stderr.strip().splitlines()
    assert len(error) == 1 and error[0].startswith("bouncingball: error: ")
    for name in names:
        assert name in error[0]


def test_grid_is_log_spaced_with_exact_ends_and_every_solver_spelling():
    assert parse_range("k", "1e2:1e14:13") == (1e2, 1e14, 13)
    grid = Grid(k=(1e2, 1e14, 13), zeta=(1e-4, 1e2, 7), solvers=("CVODE", "Article", "scipy:dop853"))
    assert grid.solvers == ("cvode", "article", "scipy:DOP853")
    assert grid.axis("k")[0] == 1e2 and grid.axis("k")[-1] == 1e14
    np.testing.assert_allclose(np.diff(np.log10(grid.axis("k"))), 1.0, rtol=1e-12)
    runs = grid.runs()
    assert len(runs) == 13 * 7 * 3 and len({run["key"] for run in runs}) == len(runs)
    cell = runs[-1]
    assert cell["b"] == pytest.approx(2.0 * cell["zeta"] * math.sqrt(cell["k"] * cell["m"]), rel=1e-15)
    with pytest.raises(ValueError, match="solver = 'rk4' is not allowed"):
        Grid(solvers=("rk4",))


def test_import_and_a_cvode_run_load_no_sweep_dependency():
    script = ("import sys\nimport bouncingball\nbouncingball.simulate(bouncingball.Ball(), 2.0, 0.0, 1.0)\n"
              "from bouncingball.cli import main\n"
              "print(sorted(m for m in sys.modules if m.split('.')[0] in "
              "('dask', 'distributed', 'pandas', 'pyarrow', 'matplotlib', 'tqdm')))")
    completed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=True)
    assert completed.stdout.strip() == "[]"


# --- one run under its cap --------------------------------------------------------------------------------
@pytest.mark.slow
def test_a_timed_out_or_failed_run_is_a_row_and_the_runner_goes_on():
    base = {"key": "", "m": 1.0, "h0": 2.0, "t_end": 8.0, "output_interval": 1e-3, "b": 0.0}
    # Explicit RK45 at rest on an over-damped k = 1e8 N/m spring: millions of steps. A contact of 1e-11 s
    # cannot be resolved in double precision up to 8 s: CVODE refuses it.
    stiff, unresolvable, after = run_batch([{**base, "k": 1e8, "zeta": 100.0, "solver": "article"},
                                            {**base, "k": 1e14, "m": 1e-9, "zeta": 0.1, "solver": "cvode"},
                                            {**base, "k": 1e4, "zeta": 0.05, "t_end": 2.0, "solver": "cvode"}], 0.5)
    assert (stiff["status"], stiff["reason"]) == ("timed out", "killed after 0.5 s")
    assert math.isnan(stiff["max_height_error"]) and stiff["events_found"] == -1
    assert unresolvable["status"] == "failed"
    assert "k = 100000000000000.0 N/m with m = 1e-09 kg is not allowed" in unresolvable["reason"]
    exact = ExactSolution(bb.Ball(k=1e4, b=2.0 * 0.05 * 100.0), 2.0, 0.0, 0.0, 2.0)
    assert after["status"] == "finished" and after["events_found"] == after["events_exact"] == len(exact.events)


# --- the sweep on Dask ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory) -> Path:
    """The small sweep (4 x 3 cells, 2 solvers) on a LocalCluster of 2 workers, through the CLI."""
    directory = tmp_path_factory.mktemp("local")
    with contextlib.ExitStack() as stack:
        try:  # Dask's default HTTP port taken, as by another cluster on the machine (unless it already is)
            stack.enter_context(socket.create_server(("", 8787)))
        except OSError:
            pass
        completed = _sweep(*SWEEP, "--workers", "2", "--output-dir", str(directory))
    assert completed.returncode == 0, completed.stderr
    assert "24 runs (24 run now): 24 finished" in completed.stderr
    assert "already in use" not in completed.stderr
    assert "\r" not in completed.stderr and "run/s" not in completed.stderr  # no progress bar into a pipe
    return directory


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(process: subprocess.Popen) -> None:
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout=20)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


@pytest.mark.slow
def test_every_cell_agrees_with_the_exact_solution_recomputed_here(local_sweep):
    table = _table(local_sweep)
    assert len(table) == 24 and set(table["status"]) == {"finished"}
    for row in table.itertuples():
        ball = bb.Ball(m=row.m, k=row.k, b=2.0 * row.zeta * math.sqrt(row.k * row.m))
        options = ({"rtol": DEFAULT_RTOL, "atol": DEFAULT_ATOL}, "cvode") if row.solver == "cvode" else ({}, "scipy")
        result = bb.simulate(ball, row.h0, 0.0, row.t_end, row.output_interval, options[1], **options[0])
        exact = ExactSolution(ball, row.h0, 0.0, 0.0, row.t_end)
        h_exact, _ = exact.state(result.t)
        assert row.events_exact == len(exact.events)
        assert row.events_found == len(result.events)
        assert row.max_height_error == pytest.approx(float(np.max(np.abs(result.h - h_exact))), rel=1e-9, abs=1e-15)
        paired = [abs(a.time - b.time) for a, b in zip(result.events, exact.events, strict=False)]
        assert row.max_event_time_error == pytest.approx(max(paired, default=0.0), rel=1e-9, abs=1e-15)
        if row.solver == "cvode":
            assert row.events_found == row.events_exact and row.event_mismatches == 0
            assert row.max_height_error < 1e-6
    markdown = (local_sweep / "stability_map.md").read_text()
    assert "per task" in markdown and "batch size 2 runs per task" in markdown
    assert "None: in every cell CVODE finished" in markdown
    assert all((local_sweep / f"stability_map_{name}.png").stat().st_size > 1000 for name in ("cvode", "article"))


@pytest.mark.slow
def test_the_same_sweep_on_a_scheduler_and_worker_started_here_gives_the_same_results(local_sweep, tmp_path):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = str(BIN / "dask")
    scheduler = subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                  "--no-dashboard"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    worker = None
    try:
        worker = subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--nworkers", "2",
                                   "--no-dashboard"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        completed = _sweep(*SWEEP, "--scheduler", address, "--output-dir", str(tmp_path))
    finally:
        for process in (worker, scheduler):
            if process is not None:
                _stop(process)
    assert completed.returncode == 0, completed.stderr
    assert f"the scheduler at {address}" in (tmp_path / "stability_map.md").read_text()
    pd.testing.assert_frame_equal(_table(tmp_path).drop(columns=TIMES), _table(local_sweep).drop(columns=TIMES))


KILL_SCRIPT = """
import json, os, signal, sys
from distributed import Client, LocalCluster
from bouncingball.sweep import Grid, run_sweep

if __name__ == "__main__":
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None)
    client = Client(cluster)
    killed = []

    def kill_one(rows):
        if not killed:
            pid = next(iter(client.run(os.getpid).values()))
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    grid = Grid(k=(1e2, 1e8, 4), zeta=(1e-3, 1.0, 3), solvers=("cvode", "article"), t_end=1.0)
    frame = run_sweep(grid, client, output_dir=sys.argv[1], batch_size=1, time_cap=30.0, progress=False,
                      on_batch=kill_one)
    print(json.dumps({"killed": killed, "workers": sorted(frame["worker"].unique())}))
    client.close()
    cluster.close()
"""


@pytest.mark.slow
def test_a_worker_killed_mid_sweep_only_costs_its_batches(local_sweep, tmp_path):
    script = tmp_path / "kill.py"
    script.write_text(textwrap.dedent(KILL_SCRIPT), encoding="utf-8")
    completed = subprocess.run([sys.executable, str(script), str(tmp_path / "out")], capture_output=True, text=True,
                               timeout=240, check=False)
    assert completed.returncode == 0, completed.stderr
    report = json.loads(completed.stdout.strip().splitlines()[-1])
    assert len(report["killed"]) == 1
    from bouncingball.sweep.store import read_parts

    table = read_parts(tmp_path / "out").sort_values("key").reset_index(drop=True)
    expected = _table(local_sweep).sort_values(["solver", "k", "zeta"]).reset_index(drop=True)
    assert len(table) == 24 and table["key"].is_unique and set(table["status"]) == {"finished"}
    columns = [c for c in expected.columns if c not in TIMES]
    got = table.sort_values(["solver", "k", "zeta"]).reset_index(drop=True)[columns]
    pd.testing.assert_frame_equal(got, expected[columns])


@pytest.mark.slow
def test_resume_runs_only_what_is_missing_and_nothing_twice(local_sweep, tmp_path):
    from bouncingball.sweep.store import write_part

    # An interrupted sweep: the batches it finished are on disk as parts, five runs are missing.
    rows = _table(local_sweep).to_dict("records")
    removed = pd.DataFrame(rows[:5])
    for start in range(5, len(rows), 8):
        write_part(tmp_path, rows[start:start + 8])
    before = _table(local_sweep).set_index("key")
    completed = _sweep(*SWEEP, "--workers", "1", "--output-dir", str(tmp_path), "--resume")
    assert completed.returncode == 0, completed.stderr
    assert f"24 runs ({len(removed)} run now)" in completed.stderr
    after = _table(tmp_path).set_index("key")
    assert after.index.is_unique and set(after.index) == set(before.index)
    kept = before.index.difference(removed["key"])
    # The kept runs were not run again: the same measured wall times, to the last bit.
    assert after.loc[kept, "wall_time"].tolist() == before.loc[kept, "wall_time"].tolist()
    again = _sweep(*SWEEP, "--workers", "1", "--output-dir", str(tmp_path), "--resume")
    assert "24 runs (0 run now)" in again.stderr


# --- leftovers of an interrupted part-write ------------------------------------------------------------------
LEFTOVER = ".0123456789abcdef0123456789abcdef.parquet.0a1b2c3d"  # what write_part leaves if killed before its rename


def test_clearing_removes_the_sweeps_own_leftover_temporaries_and_nothing_else(tmp_path):
    from bouncingball.sweep import store

    parts = tmp_path / store.PARTS
    parts.mkdir()
    (parts / LEFTOVER).write_bytes(b"half a part")
    (parts / ".fedcba9876543210fedcba9876543210.parquet.0a1b2c3d").write_bytes(b"half a part, other spelling")
    (parts / "0123456789abcdef0123456789abcdef.parquet").write_bytes(b"a part")
    (tmp_path / f".{store.TABLE}.tmp").write_bytes(b"half a table")
    (tmp_path / f".{store.TABLE}.0a1b2c3d").write_bytes(b"half a table, other spelling")
    store.clear(tmp_path)  # was: OSError: Directory not empty
    assert list(tmp_path.iterdir()) == []
    parts.mkdir()
    (parts / LEFTOVER).write_bytes(b"half a part")
    (parts / "notes.txt").write_text("mine")  # not the sweep's: kept, and with it the folder
    (parts / ".notes.tmp").write_text("mine too")
    store.clear(tmp_path)
    assert sorted(path.name for path in parts.iterdir()) == [".notes.tmp", "notes.txt"]


@pytest.mark.slow
def test_a_leftover_temporary_part_neither_fails_a_sweep_nor_stops_its_report(tmp_path):
    tiny = ["--k", "1e2:1e3:2", "--zeta", "0.1", "--solvers", "cvode", "--t-end", "0.5", "--batch-size", "1",
            "--time-cap", "30", "--workers", "1", "--output-dir", str(tmp_path)]
    parts = tmp_path / "sweep_parts"
    parts.mkdir()
    (parts / LEFTOVER).write_bytes(b"half a part")
    fresh = _sweep(*tiny)  # was: OSError: Directory not empty, before any run
    assert fresh.returncode == 0, fresh.stderr
    assert "2 runs (2 run now): 2 finished" in fresh.stderr
    parts.mkdir()
    (parts / LEFTOVER).write_bytes(b"half a part")
    for name in ("stability_map.md", "stability_map_cvode.png"):
        (tmp_path / name).unlink()
    resumed = _sweep(*tiny, "--resume")  # was: the table written, then the same OSError and no report
    assert resumed.returncode == 0, resumed.stderr
    assert "2 runs (0 run now)" in resumed.stderr and "Traceback" not in resumed.stderr
    assert (tmp_path / "stability_map.md").is_file() and (tmp_path / "stability_map_cvode.png").is_file()
    assert not parts.exists() and len(_table(tmp_path)) == 2


@pytest.mark.slow
def test_ctrl_c_on_a_sweep_is_one_line_without_worker_tracebacks(tmp_path):
    """Ctrl-C signals the terminal's whole process group; each Dask worker printed its KeyboardInterrupt."""
    import os
    import time

    # Ctrl-C live in the sweep, as at a terminal: a test run started in the background of a shell (cmd &) has SIGINT
    # ignored, which its children inherit, and the sweep then ran to its end (exit 0, or minutes on a larger grid).
    live_ctrl_c = ("import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
                   "sys.argv[0] = 'bouncingball'; runpy.run_module('bouncingball.cli', run_name='__main__')")
    process = subprocess.Popen([sys.executable, "-c", live_ctrl_c, "sweep", "--quick", "--workers", "2",
                                "--output-dir", str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not list((tmp_path / "sweep_parts").glob("*.parquet")):  # a batch done: the sweep is under way
            assert time.monotonic() < deadline and process.poll() is None, "no batch written in 120 s"
            time.sleep(0.2)  # the polling interval, not a wait for something to happen
        os.killpg(process.pid, signal.SIGINT)
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode == 130, err
    last = err.strip().splitlines()[-1]
    assert "Traceback" not in err and "KeyboardInterrupt" not in err and " ERROR " not in err, err
    # One line: what is kept, where, and the exact command that goes on from it (run here as printed).
    kept = sorted((tmp_path / "sweep_parts").glob("*.parquet"))
    command = (f"bouncingball sweep --quick --workers 2 --output-dir {tmp_path} --resume")
    assert last == f"bouncingball: interrupted: {len(kept)} finished batch(es) kept in {tmp_path}; to run only the " \
                   f"rest: {command}", last
    kept_keys = set(pd.concat([pd.read_parquet(path) for path in kept])["key"])
    resumed = subprocess.run([str(BIN / "bouncingball"), *shlex.split(command)[1:]], capture_output=True, text=True,
                             timeout=900)  # the rest of the quick grid: minutes on a busy machine
    assert resumed.returncode == 0, resumed.stderr
    table = _table(tmp_path)
    assert f"{len(table)} runs ({len(table) - len(kept_keys)} run now)" in resumed.stderr
    assert kept_keys < set(table["key"]) and table["key"].is_unique


def test_a_sweep_where_results_are_refuses_to_start_without_resume_or_overwrite(tmp_path):
    """Never delete a result unasked: the store named, both options offered, every file left as it was."""
    from bouncingball.sweep.store import write_part

    rows = [{column: None for column in STORE_COLUMNS} | {"key": f"k{i}", "status": "finished"} for i in range(3)]
    part = write_part(tmp_path, rows)
    (tmp_path / "stability_map.parquet").write_bytes(b"a table")
    before = {path: path.read_bytes() for path in tmp_path.rglob("*") if path.is_file()}
    completed = _sweep("--quick", "--output-dir", str(tmp_path))
    assert completed.returncode == EXIT_BAD_INPUT, completed.stderr
    [line] = completed.stderr.strip().splitlines()
    assert line == (f"bouncingball: error: --output-dir = {str(tmp_path)!r} holds an earlier sweep's results (the "
                    f"table {tmp_path / 'stability_map.parquet'} and 1 finished batch(es) in {part.parent}), which a "
                    "sweep does not delete unasked: add --resume to keep them and run only the missing runs, or "
                    "--overwrite to delete them and start over (or choose another --output-dir)")
    both = _sweep("--quick", "--output-dir", str(tmp_path), "--resume", "--overwrite")
    assert both.returncode == EXIT_BAD_INPUT and "--resume and --overwrite are not allowed together" in both.stderr
    assert {path: path.read_bytes() for path in tmp_path.rglob("*") if path.is_file()} == before
    from bouncingball.sweep import Grid, run_sweep

    with pytest.raises(ValueError, match="add resume=True to keep them .* or overwrite=True to delete them"):
        run_sweep(Grid(k=(1e3, 1e4, 2), zeta=(0.1, 0.1, 1)), output_dir=tmp_path)
    assert {path: path.read_bytes() for path in tmp_path.rglob("*") if path.is_file()} == before


@pytest.mark.slow
def test_overwrite_deletes_the_earlier_results_and_runs_everything(tmp_path):
    from bouncingball.sweep.store import write_part

    write_part(tmp_path, [{column: None for column in STORE_COLUMNS} | {"key": "stale", "status": "finished"}])
    tiny = ["--k", "1e2:1e3:2", "--zeta", "0.1", "--solvers", "cvode", "--t-end", "0.5", "--time-cap", "30",
            "--workers", "1", "--output-dir", str(tmp_path)]
    completed = _sweep(*tiny, "--overwrite")
    assert completed.returncode == 0, completed.stderr
    assert "2 runs (2 run now): 2 finished" in completed.stderr and "stale" not in set(_table(tmp_path)["key"])


def test_the_map_page_formats_every_constant_from_the_code(tmp_path, monkeypatch):
    """R, g, the tolerances, the solvers' settings and the acceptance rule follow the code's constants."""
    from bouncingball.sweep import report, store

    monkeypatch.setattr(report, "ARTICLE_BALL", bb.Ball(R=0.07, g=1.62))
    monkeypatch.setattr(report, "DEFAULT_RTOL", 3e-10)
    monkeypatch.setattr(report, "HEIGHT_LIMIT", 2e-4)
    monkeypatch.setattr(report, "MERGED_HOP_MARGIN", 7.0)
    monkeypatch.setattr(report, "HOP_RESOLUTION", 11.0)
    monkeypatch.setattr(report, "HEIGHT_TOLERANCE", 4e-7)
    monkeypatch.setattr(report, "ARTICLE_LABEL", "article (RK23, max_step 0.5)")
    row = dict.fromkeys(store.COLUMNS, 0)
    row.update(key="a", k=1e11, zeta=0.1, m=1.0, h0=2.0, solver="cvode", status="finished", reason="",
               events_found=71, events_exact=73, event_mismatches=0, first_mismatch="", max_height_error=7e-10,
               wall_time=0.01, rhs_calls=100)
    frame = pd.DataFrame([row], columns=list(store.COLUMNS))
    frame.attrs.update(workers=1, threads=1, wall_time=1.0, runs_done=1, overhead=0.005, batch_size=1)
    grid = Grid(k=(1e11, 1e11, 1), zeta=(0.1, 0.1, 1), solvers=("cvode",))
    info = {"command": "bouncingball sweep", "time_cap": 2.0, "cluster": "test", "scaling": None}
    text = report.write_markdown(frame, grid, info, tmp_path, []).read_text()
    for fragment in ("R = 0.07 m, g = 1.62 m/s2", "default rtol 3e-10", "article: article (RK23, max_step 0.5)",
                     "max error <= 0.0002 m", "7 x 11 rtol times the static deflection", "(rtol 3e-10)",
                     "move 4e-07 m", "stayed within 0.0002 m"):
        assert fragment in text, fragment
    for typed in ("0.06 m", "9.81", "1e-10 m + 1e-9 R", "max_step 0.01", "1e-5 m", "1e-6 m"):
        assert typed not in text, typed


@pytest.mark.slow
def test_the_csv_holds_the_tables_doubles_in_their_shortest_form(local_sweep):
    csv = pd.read_csv(local_sweep / "stability_map.csv", keep_default_na=False, na_values=[""])
    table = _table(local_sweep)
    for column in ("k", "zeta", "b", "max_height_error", "max_event_time_error", "wall_time"):
        assert csv[column].tolist() == table[column].tolist(), column  # read back, the same doubles
    text = (local_sweep / "stability_map.csv").read_text()
    assert not any(len(cell) > len(repr(float(cell))) for line in text.splitlines()[1:]
                   for cell in line.split(",") if cell.replace(".", "", 1).isdigit())


DASK_SYNC_CTRL_C = """
import asyncio, logging, os, signal, sys, threading, time
from distributed.utils import LoopRunner, sync
from bouncingball.sweep import run

signal.signal(signal.SIGINT, signal.default_int_handler)  # CI may start this process with SIGINT ignored
logging.basicConfig()
if sys.argv[1] == "hidden":
    run.hide_dask_sync_cancel_bug()
runner = LoopRunner(asynchronous=False)
runner.start()
runner.loop.add_callback(time.sleep, 2.0)  # the loop busy: sync()'s coroutine has not started at Ctrl-C
threading.Timer(0.1, os.kill, (os.getpid(), signal.SIGINT)).start()
try:
    sync(runner.loop, asyncio.sleep, 0)
except KeyboardInterrupt:
    print("interrupted")
time.sleep(2.5)  # the loop runs sync()'s cancel
runner.stop()
"""


@pytest.mark.slow
def test_ctrl_c_inside_dask_sync_logs_no_name_error_with_the_filter():
    """distributed's sync() logs a NameError when Ctrl-C comes before its coroutine starts; the filter drops it."""
    def run(mode):
        return subprocess.run([sys.executable, "-c", DASK_SYNC_CTRL_C, mode], capture_output=True, text=True,
                              timeout=120)

    shown, hidden = run("shown"), run("hidden")
    assert shown.stdout.strip() == hidden.stdout.strip() == "interrupted", (shown.stderr, hidden.stderr)
    assert "NameError" in shown.stderr and "in cancel" in shown.stderr, \
        f"distributed's sync() no longer shows the bug: remove HideDaskSyncCancelBug\n{shown.stderr}"
    assert hidden.stderr == "", hidden.stderr


def test_the_grid_takes_a_contact_law_its_axes_describe_and_cvode_alone_for_the_no_pull_law():
    from bouncingball.sweep.command import build_grid
    from bouncingball.sweep.grid import Grid

    grid = build_grid(k="1e4", zeta="0.05", contact="linear-no-pull")
    assert grid.solvers == ("cvode",) and grid.cells()[0].scene(1.0, 1e-3).ball.contact == "linear-no-pull"
    [run] = grid.runs()
    assert run["contact"] == "linear-no-pull" and run["key"].endswith("|linear-no-pull")
    linear = build_grid(k="1e4", zeta="0.05", solvers="cvode").runs()[0]
    assert linear["key"] == "cvode|10000.0|0.05|1.0|2.0|8.0|0.001"  # as before the laws: --resume still reads them
    with pytest.raises(ValueError, match="contact = 'rigid' is not allowed: it must be one of linear, linear-no-pull"):
        Grid(contact="rigid")
    with pytest.raises(ValueError, match="solver = 'article' is not allowed with contact = 'linear-no-pull'"):
        build_grid(solvers="cvode,article", contact="linear-no-pull")


def test_a_no_pull_cell_is_measured_with_the_no_pull_truths_events():
    """The worker's measure on a no-pull cell: every impact, release and departure of the mpmath truth."""
    from bouncingball.sweep.child import measure
    from nopull_truth import NoPullTruth

    row = measure({"k": 1e4, "zeta": 0.05, "m": 1.0, "h0": 2.0, "t_end": 3.0, "output_interval": 1e-3,
                   "solver": "cvode", "contact": "linear-no-pull"})
    truth = NoPullTruth(1.0, 1e4, 10.0, 0.06, 9.81, 2.0, 0.0, 3.0)
    assert row["status"] == "finished" and row["event_mismatches"] == 0
    assert row["events_found"] == row["events_exact"] == len(truth.events) == 9
    assert row["max_height_error"] <= 1e-9


# --- the Hunt-Crossley law: k [N/m^1.5] by alpha [s/m], against a reference run per cell ------------------------
def test_the_hunt_crossley_grid_maps_k_and_alpha_with_their_own_checks():
    from bouncingball.sweep.command import build_grid
    from bouncingball.sweep.grid import Cell, Grid, parse_alpha

    grid = build_grid(contact="hunt-crossley")
    assert grid.damping == "alpha" and grid.zeta is None and grid.solvers == ("cvode", "article", "scipy:DOP853")
    np.testing.assert_allclose(grid.axis("k"), 10.0 ** np.arange(3.0, 9.01, 0.5), rtol=1e-12)
    assert grid.axis("alpha")[0] == 0.0 and grid.axis("alpha")[1] == 1e-4 and grid.axis("alpha")[-1] == 1.0
    np.testing.assert_allclose(np.diff(np.log10(grid.axis("alpha")[1:])), 0.5, rtol=1e-12)
    runs = grid.runs()
    assert len(runs) == 13 * 10 * 3 and len({run["key"] for run in runs}) == len(runs)
    run = runs[3 * 13 * 5]  # k = 1e3 N/m^1.5, alpha = 1e-2 s/m, cvode
    assert (run["k"], run["alpha"], run["n"], run["solver"]) == (1e3, 1e-2, 1.5, "cvode")
    assert math.isnan(run["zeta"]) and math.isnan(run["b"])
    assert run["key"] == "cvode|1000.0|alpha=0.01|1.0|2.0|8.0|0.001|hunt-crossley"
    ball = Cell(1e3, None, 1.0, 2.0, "hunt-crossley", 1e-2).scene(1.0, 1e-3).ball
    assert (ball.contact, ball.k, ball.n, ball.alpha, ball.m, ball.R, ball.g) == \
        ("hunt-crossley", 1e3, 1.5, 1e-2, 1.0, 0.06, 9.81)
    # the linear laws' runs carry NaN for alpha and n, their keys as before
    linear = build_grid(k="1e4", zeta="0.05", solvers="cvode").runs()[0]
    assert linear["key"] == "cvode|10000.0|0.05|1.0|2.0|8.0|0.001" and math.isnan(linear["alpha"])
    assert parse_alpha("0,1e-2:1:3") == (0.0, 0.01, 0.1, 1.0) and parse_alpha("0.5,0") == (0.0, 0.5)
    for text, words in (("-1", "-1 s/m is not finite and >= 0"), ("1:1e-2:3", "'1:1e-2:3' is not LO:HI:N"),
                        ("0:1:3", "'0:1:3' is not LO:HI:N"), ("inf", "inf s/m is not finite"), ("a", "values >= 0")):
        with pytest.raises(ValueError, match=f"^--alpha = {text!r} is not allowed: .*" + words.replace("(", r"\(")):
            parse_alpha(text)
    with pytest.raises(ValueError, match=r"^zeta = \(0.1, 0.1, 1\) is not allowed with contact = 'hunt-crossley'"):
        Grid(zeta=(0.1, 0.1, 1), contact="hunt-crossley")
    with pytest.raises(ValueError, match=r"^alpha = \(0.1,\) is not allowed with contact = 'linear'"):
        Grid(alpha=(0.1,))
    with pytest.raises(ValueError, match=r"^alpha = -0.5 s/m is not allowed: it must be finite and >= 0"):
        Cell(1e6, None, 1.0, 2.0, "hunt-crossley", -0.5)
    with pytest.raises(ValueError, match=r"^alpha = 0.1 s/m is not allowed with contact = 'linear-no-pull'"):
        Cell(1e6, 0.1, 1.0, 2.0, "linear-no-pull", 0.1)
    with pytest.raises(ValueError, match="^contact = 'rigid' is not allowed: it must be one of linear, linear-no-pull, "
                                         r"hunt-crossley \(the rigid law has no k or damping to map\)"):
        Grid(contact="rigid")
    with pytest.raises(ValueError, match="^--zeta = '0.1' is not allowed with --contact hunt-crossley: .* use --alpha"):
        build_grid(zeta="0.1", contact="hunt-crossley")
    with pytest.raises(ValueError, match="^--alpha = '0.1' is not allowed with --contact linear: .* use --zeta"):
        build_grid(alpha="0.1")


@pytest.mark.parametrize(("args", "names"), [
    (["--contact", "hunt-crossley", "--zeta", "0.1"], ["--zeta", "'0.1'", "--alpha"]),
    (["--contact", "hunt-crossley", "--alpha=-1"], ["--alpha", "'-1'", ">= 0"]),
    (["--alpha", "0.1"], ["--alpha", "'0.1'", "--contact linear"]),
    (["--contact", "rigid"], ["--contact", "'rigid'", "hunt-crossley", "no k or damping"]),
])
def test_bad_hunt_crossley_input_is_one_line_before_any_cluster(args, names):
    test_bad_input_is_one_line_and_exit_2_before_any_cluster(args, names)


HC_CELL = {"k": 1e6, "zeta": math.nan, "alpha": 0.2, "n": 1.5, "m": 1.0, "h0": 0.5, "t_end": 1.0,
           "output_interval": 1e-2, "contact": "hunt-crossley"}


@pytest.mark.slow  # the mpmath truth: seconds
def test_a_hunt_crossley_cell_is_measured_against_a_reference_that_follows_the_mpmath_truth():
    """Its reference within REFERENCE_HELD_WITHIN of the truth with every event to 1e-9 s; each row's error within
    that of the solver's own distance from the truth (triangle inequality), and under 1e-6 m."""
    from bouncingball.bench.hunt_crossley_study import REFERENCE_HELD_WITHIN
    from bouncingball.sweep.child import measure, reference_run
    from bouncingball.sweep.grid import cell_of
    from hunt_crossley_truth import HuntCrossleyTruth

    truth = HuntCrossleyTruth(1.0, 1e6, 1.5, 0.2, 0.06, 9.81, 0.5, 0.0, 1.0)
    assert [kind for _, kind, _ in truth.events] == ["impact", "departure"] * 3
    reference = reference_run(cell_of(HC_CELL), 1.0, 1e-2)
    h_true = np.array([float(truth.state(t)[0]) for t in reference.t])
    reference_error = float(np.max(np.abs(reference.h - h_true)))
    assert reference_error < REFERENCE_HELD_WITHIN
    assert [str(e.kind) for e in reference.events] == [kind for _, kind, _ in truth.events]
    assert max(abs(e.time - float(t)) for e, (t, _, _) in zip(reference.events, truth.events, strict=True)) < 1e-9
    ball = bb.Ball(m=1.0, k=1e6, contact="hunt-crossley", n=1.5, alpha=0.2)
    for solver, options in (("cvode", {"rtol": DEFAULT_RTOL, "atol": DEFAULT_ATOL}),
                            ("scipy:DOP853", {"solver": "scipy", "method": "DOP853", "rtol": DEFAULT_RTOL,
                                              "atol": DEFAULT_RTOL * 0.5, "max_step": 0.0})):
        row = measure({**HC_CELL, "solver": solver})
        result = bb.simulate(ball, 0.5, 0.0, 1.0, 1e-2, **options)
        solver_error = float(np.max(np.abs(result.h - h_true)))
        assert row["status"] == "finished" and row["event_mismatches"] == 0, row
        assert row["events_found"] == row["events_exact"] == len(truth.events) == 6
        assert abs(row["max_height_error"] - solver_error) <= reference_error, (solver, row, solver_error)
        assert row["max_height_error"] < 1e-6
        paired = max(abs(e.time - float(t)) for e, (t, _, _) in zip(result.events, truth.events, strict=True))
        assert row["max_event_time_error"] <= paired + 1e-9


def test_the_sweep_says_what_its_timeouts_are():
    from bouncingball.sweep.command import timeouts_line

    frame = pd.DataFrame({"solver": ["cvode", "scipy:DOP853", "scipy:DOP853", "article", "cvode"],
                          "k": [1e12, 1e10, 1e12, 1e14, 1e4], "status": ["finished", "timed out", "timed out",
                                                                          "timed out", "finished"]})
    assert timeouts_line(frame, 2.0) == ("timed out (past --time-cap = 2 s): scipy:DOP853 2 (k 1e+10 to 1e+12), "
                                         "article 1 (k 1e+14): the SciPy peers on stiff cells, whose explicit "
                                         "steps shrink with the contact (expected)")
    frame.loc[0, "status"] = "timed out"
    assert timeouts_line(frame, 2.0).endswith("1 of them CVODE's, which is not expected: see the timed-out cells in "
                                              "stability_map.md")
    assert timeouts_line(frame[frame["status"] == "finished"], 2.0) == ""
