import math
import os
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from bouncingball.cli import main
from bouncingball.output import read_solution_csv
from bouncingball.physics import Ball
from bouncingball.scenes import BUILTIN_SCENES
from bouncingball.solvers.exact import ExactSolution
from closed_forms import first_impact_time
from oracle_counts import oracle_counts


def test_run_article_prints_summary_and_writes_files(tmp_path, capsys):
    out, events, plot = tmp_path / "out.csv", tmp_path / "events.csv", tmp_path / "h.png"
    code = main(["run", "article", "--output", str(out), "--events", str(events), "--plot", str(plot)])
    text = capsys.readouterr().out
    assert code == 0
    truth = oracle_counts(Ball())
    assert (f"events      {truth.events} ({truth.impacts} impacts, {truth.departures} departures); "
            f"exact solution: {truth.events}") in text
    error = float(text.split("max |h - h_exact|")[1].split()[0])
    assert 0 < error <= 1e-6
    columns = read_solution_csv(out)
    lines = out.read_text().splitlines()
    assert lines[0] == _fmpy_header("time", "h", "v")
    assert lines[299].startswith("0.298,")  # the shortest form that reads back, as FMPy writes it
    assert all(float(text) == value for line, t, h, v in zip(lines[1:], columns["time"], columns["h"], columns["v"],
                                                             strict=True)
               for text, value in zip(line.split(","), (t, h, v), strict=True))
    assert len(columns["time"]) == 8001
    h_exact, _ = ExactSolution(Ball(), 2.0, 0.0, 0.0, 8.0).state(columns["time"])
    assert np.max(np.abs(columns["h"] - h_exact)) <= 1e-6
    lines = events.read_text().splitlines()
    assert lines[0] == "time,kind,v" and len(lines) == 1 + truth.events and lines[1].split(",")[1] == "impact"
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    printed = " ".join(text.split())
    missing = [line for line in readme_run_article() if line not in printed]
    assert missing == [], f"README.md's `bouncingball run article` shows lines this run does not print: {missing}"


def test_run_a_hunt_crossley_ball_says_its_law_and_its_own_error_estimate(capsys):
    """No exact solution to measure it against: the summary gives the run's own error estimate, and the events."""
    assert main(["run", "article", "--contact", "hunt-crossley", "--n", "1.2", "--alpha", "0.05", "--t-end", "1"]) == 0
    text = capsys.readouterr().out
    assert "Hunt-Crossley contact, k = 10000 N/m^1.2, n = 1.2, alpha = 0.05 s/m" in text
    assert "exact" not in text.replace("without the exact solution", "")
    estimate = float(text.split("error estimate")[1].split()[0])
    assert 0 < estimate <= 1e-6
    # the first impact ends a free fall from 2 m onto R: at sqrt(2 (2 - R) / g), at sqrt(2 g (2 - R))
    impact = text.split("#1")[1].split("\n")[0].split()
    assert impact[4] == "impact" and abs(float(impact[2]) - math.sqrt(2 * 1.94 / 9.81)) < 1e-9
    assert abs(float(impact[7]) + math.sqrt(2 * 9.81 * 1.94)) < 1e-5


def readme_run_article() -> list[str]:
    """The lines of README.md's `bouncingball run article` that do not depend on the machine or the process
    (wall time, the engine's first use and the choice it makes in a process that ran others are left out)."""
    readme = Path(__file__).resolve().parents[1] / "README.md"
    if not readme.is_file():
        return []
    block = readme.read_text(encoding="utf-8").split("$ bouncingball run article\n")[1].split("```")[0]
    lines = [" ".join(line.split()) for line in block.splitlines()]
    kept = [line for line in lines if line and line != "..." and not line.startswith(("first use", "engine"))]
    # the wall time's line: only its step and right-hand-side counts
    return [line.split(" ", 2)[2].split(" ", 2)[2] if line.startswith("wall time") else line for line in kept]


def test_run_options_reach_the_solver(capsys):
    assert main(["run", "in-contact", "--solver", "scipy", "--method", "DOP853", "--rtol", "1e-9",
                 "--atol", "1e-12", "--t-end", "2", "--output-interval", "0.01"]) == 0
    text = capsys.readouterr().out
    assert "scipy (method DOP853, rtol 1e-09, atol 1e-12" in text
    assert "0 to 2 s, output every 0.01 s" in text


def test_exact_solver_has_no_error_lines(capsys):
    assert main(["run", "overdamped", "--solver", "exact"]) == 0
    text = capsys.readouterr().out
    rest = float(text.split("at rest from t = ")[1].split()[0])  # the overdamped ball stops at its first impact
    assert rest == pytest.approx(first_impact_time(2.0, 0.06, 9.81), rel=1e-12)
    assert "h_exact" not in text


def test_scenes_table_lists_every_scene(capsys):
    assert main(["scenes"]) == 0
    text = capsys.readouterr().out
    for name in BUILTIN_SCENES:
        assert f"\n{name} " in text


def _fmpy_header(*names):
    """The header row FMPy's own write_csv writes for a result with these columns."""
    from fmpy.util import write_csv

    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "fmpy.csv")
        write_csv(path, np.zeros(1, dtype=[(name, float) for name in names]))
        with open(path) as file:
            return file.readline().rstrip("\n")


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "bouncingball.cli", *args], capture_output=True, text=True,
                          env=None if env is None else {**os.environ, **env})


def _one_line(completed, code=2):
    assert completed.returncode == code, completed.stderr
    [line] = completed.stderr.strip().splitlines()
    assert line.startswith("bouncingball: ") and "Traceback" not in completed.stderr
    return line


def test_bad_input_is_one_line_and_exit_code_2():
    for args, fragment in [
        (["run", "moon"], "scene = 'moon' is not allowed"),
        (["run", "--rtol", "-1"], "rtol = -1.0 is not allowed: it must be in [1e-15, 1]"),
        (["run", "--rtol", "1e-17"], "rtol = 1e-17 is not allowed: it must be in [1e-15, 1] (CVODE cannot honour"),
        (["run", "--atol", "1e-320"], "atol = 1e-320 m is not allowed: it must be 0 (none) or finite and >= "),
        (["run", "--max-step", "1e-320"], "max_step = 1e-320 s is not allowed: it must be 0 (none) or finite and >= "
                                          "8e-07 s"),
        (["run", "--solver", "euler"], "solver = 'euler' is not allowed"),
        (["run", "--method", "RK4"], "method = 'RK4' is not allowed"),
        (["run", "--engine", "fast"], "engine = 'fast' is not allowed"),
        (["run", "--t-end", "0"], "t_end = 0.0 s is not allowed"),
        (["run", "--output-interval", "100"], "output_interval = 100.0 s is not allowed"),
        (["run", "--contact", "hunt-crossley", "--n", "3"], "n = 3.0 is not allowed: it must be in [1, 2.5]"),
        (["run", "--contact", "hunt-crossley", "--alpha", "-1"], "alpha = -1.0 s/m is not allowed"),
        (["run", "--contact", "hunt-crossley", "--alpha", "1e20"], "alpha = 1e+20 s/m is not allowed for this scene "
                                                                   "(h0 = 2.0 m, v0 = 0.0 m/s"),
    ]:
        completed = _cli(*args)
        assert completed.returncode == 2, args
        lines = completed.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("bouncingball: error: ")
        assert fragment in completed.stderr
        assert "Traceback" not in completed.stderr


def test_output_paths_are_checked_before_the_run_and_nothing_partial_is_left(tmp_path):
    folder = tmp_path / "a-folder"
    folder.mkdir()
    for option in ("--output", "--events", "--plot"):
        for path, reason in [(tmp_path / "missing" / "out.csv", "does not exist"), (folder, "it is a folder")]:
            completed = _cli("run", "undamped", option, str(path))  # 1000 s: a run would take seconds
            assert completed.returncode == 2, completed.stderr
            [line] = completed.stderr.strip().splitlines()
            assert line.startswith(f"bouncingball: error: {option} = {str(path)!r} is not allowed") and reason in line
            assert completed.stdout == ""  # refused before the run printed anything
    assert list(tmp_path.iterdir()) == [folder] and list(folder.iterdir()) == []


@pytest.mark.parametrize(("args", "said"), [
    (["run", "--rtl", "1e-6"], "bouncingball run: error: unrecognized arguments: --rtl (did you mean --rtol?)"),
    (["run", "article", "--output-intervl=0.1"],
     "bouncingball run: error: unrecognized arguments: --output-intervl=0.1 (did you mean --output-interval?)"),
    (["check", "out.csv", "--tolerence", "1"],
     "bouncingball check: error: unrecognized arguments: --tolerence 1 (did you mean --tolerance?)"),
    (["run", "--zzz"], "bouncingball run: error: unrecognized arguments: --zzz"),
])
def test_a_mistyped_option_is_refused_by_its_command_with_the_option_it_may_mean(args, said, capsys):
    with pytest.raises(SystemExit) as info:
        main(args)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: bouncingball {args[0]} ")  # the command's usage, not the top level's
    assert err.splitlines()[-1] == said


def test_build_fmu_refuses_a_folder_that_does_not_exist_as_run_does(tmp_path, capsys):
    for command in (["build-fmu"], ["build-fmu", "--fmi-version", "3"]):
        target = tmp_path / "missing" / "x.fmu"
        assert main([*command, "-o", str(target)]) == 2
        [line] = capsys.readouterr().err.splitlines()
        assert line == f"bouncingball: error: output = {str(target)!r} is not allowed: its folder " \
                       f"{str(target.parent)!r} does not exist"
        assert list(tmp_path.iterdir()) == []  # the folder was not made


@pytest.mark.slow
def test_unwritable_and_odd_output_paths_and_formats_are_one_line_before_the_run(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("")
    cases = [(["--output", "/proc/nope.csv"], "a file cannot be created in '/proc'"),
             (["--events", "/sys/x.csv"], "a file cannot be created in '/sys'"),
             (["--output", str(afile / "x.csv")], f"{str(afile)!r} is a file, not a folder"),
             (["--plot", str(afile / "deeper" / "x.png")], f"{str(afile)!r} is a file, not a folder"),
             (["--output", str(tmp_path / "a.csv"), "--plot", str(tmp_path / "out.txt")], "its format 'txt'"),
             (["--events", "-"], "only --output writes to stdout")]
    for options, reason in cases:
        line = _one_line(_cli("run", "undamped", *options))  # 1000 s: a run would take seconds
        assert line.startswith(f"bouncingball: error: {options[-2]} = {options[-1]!r} is not allowed") and \
            reason in line, line
    assert sorted(tmp_path.iterdir()) == [afile] and afile.read_text() == ""  # nothing written, not even a.csv
    completed = _cli("build-fmu", "-o", str(afile / "x.fmu"))
    assert f"{str(afile)!r} is a file, not a folder" in _one_line(completed)
    for command in (["bench", "--quick"], ["sweep", "--quick"]):
        for folder, reason in [("/proc/x", "a file cannot be created in '/proc'"), (afile, "it is a file")]:
            line = _one_line(_cli(*command, "--output-dir", str(folder)))
            assert line.startswith(f"bouncingball: error: --output-dir = {str(folder)!r} is not allowed") and \
                reason in line, line


def test_output_dash_writes_the_csv_to_stdout_and_the_summary_to_stderr(tmp_path):
    completed = _cli("run", "article", "--engine", "sksundae", "--output", "-")
    assert completed.returncode == 0, completed.stderr
    assert completed.stderr.startswith("scene article:") and "max |h - h_exact|" in completed.stderr
    lines = completed.stdout.splitlines()
    assert lines[0] == _fmpy_header("time", "h", "v") and len(lines) == 8002
    h_exact, _ = ExactSolution(Ball(), 2.0, 0.0, 0.0, 8.0).state(np.array([float(line.split(",")[0])
                                                                             for line in lines[1:]]))
    assert np.max(np.abs(np.array([float(line.split(",")[1]) for line in lines[1:]]) - h_exact)) <= 1e-6
    assert not (tmp_path / "-").exists() and not os.path.exists("-")


@pytest.mark.slow
def test_a_closed_pipe_ends_the_run_quietly():
    process = subprocess.Popen([sys.executable, "-m", "bouncingball.cli", "run", "undamped", "--engine", "sksundae",
                                "--output", "-"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert process.stdout.readline() == b'"time","h","v"\n'
    process.stdout.close()  # as `| head -1` does
    err = process.stderr.read().decode()
    process.wait(timeout=120)
    assert process.returncode == 141 and "Traceback" not in err and "BrokenPipe" not in err, err


def test_version_is_the_installed_distributions():
    from importlib.metadata import version

    completed = _cli("--version")
    assert completed.returncode == 0 and completed.stdout.strip() == f"bouncingball {version('bouncingball')}"


def test_a_scene_file_that_is_not_utf8_is_named(tmp_path):
    scene = tmp_path / "latin1.toml"
    scene.write_bytes("description = 'h\xf6he'\n".encode("latin-1"))
    line = _one_line(_cli("run", str(scene)))
    assert f"scene file {str(scene)!r} is not UTF-8" in line


def test_a_refused_bound_is_printed_exactly(tmp_path):
    """Rounded to 6 digits, (0, 1.23457] would seem to hold the refused 1.2345679."""
    completed = _cli("run", "article", "--t-end", "1.23456789", "--output-interval", "1.2345679")
    assert "output_interval = 1.2345679 s is not allowed: it must be in (0, 1.23456789]" in _one_line(completed)


def test_build_fmu_without_a_working_compiler_names_it_and_cc(tmp_path):
    line = _one_line(_cli("build-fmu", "-o", str(tmp_path / "x.fmu"), env={"CC": "nonexistent-cc"}), code=1)
    assert "the C compiler 'nonexistent-cc' from $CC cannot be run" in line and "set CC to" in line
    assert list(tmp_path.iterdir()) == []


def test_validate_names_a_bad_fmu_before_any_stage(tmp_path):
    for content, reason in [(b"not a zip", "not a zip archive"), (None, "no modelDescription.xml")]:
        fmu = tmp_path / "bad.fmu"
        if content is None:
            with zipfile.ZipFile(fmu, "w") as archive:
                archive.writestr("readme.txt", "no model here")
        else:
            fmu.write_bytes(content)
        line = _one_line(_cli("validate", "--fmu", str(fmu)))  # one line: no "validate: <stage>" before it
        assert line == f"bouncingball: error: --fmu = {str(fmu)!r} is not allowed: it is not an FMU ({reason})"


@pytest.mark.slow
def test_validate_skips_stages_and_caps_scipy():
    started = time.perf_counter()
    completed = _cli("validate", "tiny-mass", "--skip", "fmu", "--skip", "cvode", "--time-cap", "1")
    assert completed.returncode == 0, completed.stderr
    assert time.perf_counter() - started < 30  # not the 60 s SciPy took to be stopped before
    rows = completed.stdout.splitlines()[3:]
    assert [row.split()[0] for row in rows] == ["article", "exact"] and "killed after 1 s" in rows[0]
    assert "FMU skipped" in completed.stdout and "CVODE" not in completed.stdout
    assert "--skip = 'fem' is not allowed" in _one_line(_cli("validate", "--skip", "fem"))
    assert "--time-cap = 0.0 s is not allowed" in _one_line(_cli("validate", "--time-cap", "0"))


@pytest.mark.slow
def test_an_unreachable_scheduler_is_one_line_within_the_connect_timeout(tmp_path):
    pytest.importorskip("distributed")
    started = time.perf_counter()
    completed = _cli("sweep", "--quick", "--scheduler", "tcp://127.0.0.1:1", "--connect-timeout", "2",
                     "--output-dir", str(tmp_path / "sweep"))
    assert time.perf_counter() - started < 15
    line = _one_line(completed)
    assert "--scheduler = 'tcp://127.0.0.1:1' is not allowed" in line and "2 s" in line
    assert not (tmp_path / "sweep").exists()


def test_a_grid_too_large_for_memory_is_refused_with_the_interval_that_fits():
    completed = _cli("run", "article", "--t-end", "1e6")
    assert completed.returncode == 2
    [line] = completed.stderr.strip().splitlines()
    assert "1e+09 output points, more than 5e+07" in line and "output_interval >= 0.02 s" in line


def test_a_boolean_or_text_in_a_scene_file_is_not_a_number(tmp_path):
    for value, shown in [("true", "True"), ('"1e4"', "'1e4'")]:
        scene = tmp_path / "scene.toml"
        scene.write_text(f"m = {value}\n")
        completed = _cli("run", str(scene))
        assert completed.returncode == 2, completed.stdout
        assert f"m = {shown} is not allowed: it must be a number" in completed.stderr


def test_a_missing_extra_names_the_pip_install_that_adds_it(tmp_path):
    """fmpy hidden from the process (as if [fmu] were not installed): validate says what to install."""
    code = ("import sys; sys.modules['fmpy'] = None\n"
            "from bouncingball.cli import main\n"
            f"sys.exit(main(['validate', 'article', '--fmu', {str(tmp_path / 'x.fmu')!r}]))\n")
    (tmp_path / "x.fmu").write_bytes(b"")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert completed.returncode == 2, completed.stderr
    [line] = completed.stderr.strip().splitlines()  # before any work: no progress line either
    from bouncingball.extras import install_command

    assert "fmpy" in line and line.endswith(f"({install_command('fmu')})"), line


def _read_until(stream, text: str, timeout: float) -> str:
    """What a child process wrote to stream (a pipe) up to and including text; fails after timeout seconds."""
    import selectors

    seen = b""
    with selectors.DefaultSelector() as selector:
        selector.register(stream, selectors.EVENT_READ)
        deadline = time.monotonic() + timeout
        while text.encode() not in seen:
            left = deadline - time.monotonic()
            assert left > 0 and selector.select(left), f"no {text!r} within {timeout} s; seen {seen!r}"
            data = os.read(stream.fileno(), 65536)
            assert data, f"the stream closed before {text!r}; seen {seen!r}"
            seen += data
    return seen.decode()


@pytest.mark.slow
def test_ctrl_c_is_one_line_and_exit_code_130():
    import signal

    # As a terminal's shell starts a command: SIGINT at its default. A test runner started in the background
    # of a non-interactive shell ignores SIGINT, its children inherit that, and Python then never raises
    # KeyboardInterrupt: the run would end normally with 0 (it did, on CI).
    process = subprocess.Popen([sys.executable, "-m", "bouncingball.cli", "run", "undamped", "--solver", "scipy"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        # said on stderr as the run starts; the article's algorithm then takes seconds on 1000 s of bouncing
        started = _read_until(process.stderr, "Ctrl-C stops it)\n", timeout=120)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        process.kill()
    err = started + err
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == "bouncingball: interrupted" and "Traceback" not in err


def test_bench_writes_to_a_folder_of_its_own_unless_told():
    from bouncingball.cli import _build_parser

    assert _build_parser().parse_args(["bench", "--quick"]).output_dir == "bench-results"


def test_sundials_own_error_text_stays_off_the_terminal(monkeypatch, capfd, tmp_path):
    """scikit-sundae prints "[CVode, Error: -2] At t = 0, too much accuracy requested." to stdout on a failure.

    Such an rtol is refused before any work; the floor is lowered here to reach CVODE's own failure.
    """
    from bouncingball.solvers.phase_machine import settings

    monkeypatch.setattr(settings, "MIN_RTOL", 0.0)
    code = main(["run", "article", "--rtol", "1e-300", "--engine", "sksundae", "--output", str(tmp_path / "r.csv")])
    out, err = capfd.readouterr()
    [line] = err.strip().splitlines()
    assert code == 1 and line.startswith("bouncingball: solver failed: CVODE failed at t = 0.0 s")
    assert "accuracy" in line
    assert out == "" and "Error: -2" not in err


def test_atol_zero_is_none_on_the_command_line(capsys, tmp_path):
    """The FMU documents atol = 0 as none; --atol 0 was refused "must be > 0"."""
    assert main(["run", "article", "--atol", "0", "--t-end", "0.1", "--output", str(tmp_path / "r.csv")]) == 0
    assert "atol None" in capsys.readouterr().out


def test_text_printed_during_a_solver_call_other_than_sundials_errors_is_passed_on(capsys):
    from bouncingball.solvers.engines.sundials_log import ErrorsOffStdout

    with ErrorsOffStdout():
        print("before")
        print("\n[CVode, Error: -2] At t = 0, too much accuracy requested.\n")
        print("after")
    assert capsys.readouterr().out == "before\nafter\n"


@pytest.mark.slow
def test_a_long_run_shows_its_progress_on_a_terminal_only():
    """A run past PROGRESS_AFTER seconds draws a tqdm bar of the simulated time on a terminal's stderr."""
    import fcntl
    import pty
    import struct
    import termios

    pytest.importorskip("tqdm")
    args = [sys.executable, "-m", "bouncingball.cli", "run", "undamped", "--engine", "sksundae", "--t-end", "4000",
            "--output-interval", "1"]  # ~4 s of CVODE
    terminal, secondary = pty.openpty()
    fcntl.ioctl(secondary, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a terminal 100 columns wide
    process = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=secondary, stdin=subprocess.DEVNULL)
    os.close(secondary)
    seen = b""
    while True:
        try:
            data = os.read(terminal, 65536)
        except OSError:  # the terminal closed with the process
            break
        if not data:
            break
        seen += data
    os.close(terminal)
    out = process.stdout.read().decode()
    assert process.wait(timeout=60) == 0
    assert b"simulated time: " in seen and b"/4000 s" in seen and "simulated time" not in out
    assert "simulated time" not in _cli(*args[3:]).stderr  # not a terminal: no bar


def test_scipy_progress_is_told_the_time_reached_phase_by_phase():
    import bouncingball

    reached = []
    result = bouncingball.simulate(Ball(), 2.0, 0.0, 8.0, solver="scipy", progress=reached.append)
    impacts = [event.time for event in result.events if event.kind == "impact"]
    assert reached[0] == 0.0 and all(a < b for a, b in zip(reached, reached[1:], strict=False))
    assert len(reached) >= len(result.events) and reached[-1] >= impacts[-1]  # told at each phase's start


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_cvode_progress_is_told_the_time_reached_every_so_many_steps(engine):
    """The phase machine returns to Python every PROGRESS_STEPS steps (progress, Ctrl-C), at a phase's start."""
    import bouncingball
    from bouncingball.solvers.integrator import PROGRESS_STEPS

    reached = []
    result = bouncingball.simulate(Ball(b=0.0), 2.0, 0.0, 600.0, engine=engine, progress=reached.append)
    starts = {0.0} | {event.time for event in result.events}
    assert reached[0] == 0.0 and all(a < b for a, b in zip(reached, reached[1:], strict=False))
    assert len(reached) >= result.stats.steps // PROGRESS_STEPS >= 2 and set(reached) <= starts
