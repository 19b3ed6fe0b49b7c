import subprocess
import sys

import numpy as np
import pytest

from bouncingball.cli import main
from bouncingball.output import read_solution_csv
from bouncingball.physics import Ball
from bouncingball.scenes import BUILTIN_SCENES
from bouncingball.solvers.exact import ExactSolution
from closed_forms import first_impact_time


def test_run_article_prints_summary_and_writes_files(tmp_path, capsys):
    out, events, plot = tmp_path / "out.csv", tmp_path / "events.csv", tmp_path / "h.png"
    code = main(["run", "article", "--output", str(out), "--events", str(events), "--plot", str(plot)])
    text = capsys.readouterr().out
    assert code == 0
    assert "events      41 (21 impacts, 20 departures); exact solution: 41" in text
    error = float(text.split("max |h - h_exact|")[1].split()[0])
    assert 0 < error <= 1e-6
    columns = read_solution_csv(out)
    assert out.read_text().splitlines()[0] == "time,h,v"
    assert len(columns["time"]) == 8001
    h_exact, _ = ExactSolution(Ball(), 2.0, 0.0, 0.0, 8.0).state(columns["time"])
    assert np.max(np.abs(columns["h"] - h_exact)) <= 1e-6
    lines = events.read_text().splitlines()
    assert lines[0] == "time,kind,v" and len(lines) == 42 and lines[1].split(",")[1] == "impact"
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


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


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "bouncingball.cli", *args], capture_output=True, text=True)


def test_bad_input_is_one_line_and_exit_code_2():
    for args, fragment in [
        (["run", "moon"], "scene = 'moon' is not allowed"),
        (["run", "--rtol", "-1"], "rtol = -1.0 is not allowed: it must be in (0, 1]"),
        (["run", "--solver", "euler"], "solver = 'euler' is not allowed"),
        (["run", "--method", "RK4"], "method = 'RK4' is not allowed"),
        (["run", "--engine", "fast"], "engine = 'fast' is not allowed"),
        (["run", "--t-end", "0"], "t_end = 0.0 s is not allowed"),
        (["run", "--output-interval", "100"], "output_interval = 100.0 s is not allowed"),
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
    assert "fmpy" in line and "pip install 'bouncingball[fmu]'" in line


def test_ctrl_c_is_one_line_and_exit_code_130():
    import signal
    import time

    process = subprocess.Popen([sys.executable, "-m", "bouncingball.cli", "run", "undamped", "--solver", "scipy"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(3.0)  # well inside the run: the article's algorithm takes minutes on 1000 s of bouncing
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == "bouncingball: interrupted" and "Traceback" not in err


def test_bench_writes_to_a_folder_of_its_own_unless_told():
    from bouncingball.cli import _build_parser

    assert _build_parser().parse_args(["bench", "--quick"]).output_dir == "bench-results"
