import subprocess
import sys

import numpy as np

from bouncingball.cli import main
from bouncingball.output import read_solution_csv
from bouncingball.physics import Ball
from bouncingball.scenes import BUILTIN_SCENES
from bouncingball.solvers.exact import ExactSolution


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
    assert "at rest from t = 0.6288996587" in text
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
