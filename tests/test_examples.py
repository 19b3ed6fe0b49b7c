"""examples/: each one run as a user runs it (a subprocess, in a temporary directory), its printed numbers checked."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bouncingball.physics import Ball
from bouncingball.solvers.exact import ExactSolution
from fmu_helpers import exact_at

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
BIN = Path(sys.executable).parent
NUMBER = r"[-+]?\d+(?:\.\d*)?(?:e[-+]?\d+)?"


def run_example(args, cwd: Path, timeout: float = 300, **env) -> str:
    """Run an example in a subprocess with cwd; its stdout, after asserting that it succeeded."""
    environment = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}", "MPLBACKEND": "Agg",
                   "PYTHONDONTWRITEBYTECODE": "1", **env}  # no __pycache__ left in examples/
    completed = subprocess.run([str(arg) for arg in args], cwd=cwd, capture_output=True, text=True,
                               timeout=timeout, env=environment, check=False)
    assert completed.returncode == 0, completed.stdout[-3000:] + completed.stderr[-3000:]
    return completed.stdout


def test_every_example_says_what_it_shows_and_what_it_needs():
    for path in sorted(EXAMPLES.rglob("*")):
        if path.suffix in (".py", ".sh"):
            head = path.read_text().splitlines()[:8]
            assert any("Needs:" in line for line in head), path
            assert len(path.read_text().splitlines()) <= 90, path


def test_api_tour(tmp_path):
    pytest.importorskip("scipy")
    pytest.importorskip("matplotlib")
    out = run_example([sys.executable, EXAMPLES / "api_tour.py", tmp_path / "out"], tmp_path)
    exact = ExactSolution(Ball(), 2.0, 0.0, 0.0, 8.0)
    h_end, _ = exact.state(8.0)
    rows = {m[0]: [float(x) for x in m[1:]] for m in re.findall(
        rf"^(exact|cvode|scipy) +({NUMBER}) +({NUMBER}) +(\d+) +(\d+) +({NUMBER})$", out, re.M)}
    assert set(rows) == {"exact", "cvode", "scipy"}, out
    impacts = sum(event.kind == "impact" for event in exact.events)
    for name, (height_error, event_error, events, found_impacts, final_h) in rows.items():
        assert abs(final_h - h_end[0]) <= height_error + 1e-15, name  # the final point is one of those compared
        bound = 1e-2 if name == "scipy" else 1e-6  # the article's RK45 is ~3e-3 m off; CVODE within 1e-6 m
        assert height_error <= bound and event_error <= bound, name
        assert (events, found_impacts) == (len(exact.events), impacts) == (41, 21), name
    assert rows["exact"][:2] == [0.0, 0.0] and rows["scipy"][0] > 1e-4  # SciPy is measurably off at its defaults
    printed = re.findall(rf"t = ({NUMBER}) s  (impact|departure) +v = ({NUMBER}) m/s", out)
    assert len(printed) == 4
    for (time, kind, velocity), event in zip(printed, exact.events, strict=False):
        assert (kind, float(time), float(velocity)) == (event.kind, pytest.approx(event.time, abs=1e-14),
                                                        pytest.approx(event.velocity, abs=1e-11))
    assert (tmp_path / "out" / "api_tour.png").stat().st_size > 10_000
    assert list(tmp_path.iterdir()) == [tmp_path / "out"]  # nothing written anywhere else


def test_fmpy_cli_script(tmp_path):
    pytest.importorskip("fmpy")
    pytest.importorskip("pythonfmu")
    out = run_example(["bash", EXAMPLES / "fmpy_cli.sh", "results"], tmp_path)
    assert "Model Name         BouncingBall" in out and "F_ext              input" in out  # fmpy info
    moon, reference = out.split("check results/moon.csv")[1].split("check results/BouncingBall_ref.csv")
    t = np.linspace(0.0, 6.0, 601)
    _, _, impacts = exact_at(t, Ball(g=1.62), h0=1.0)
    assert "points compared    601" in moon and f"{impacts[-1]} at the end, exact {impacts[-1]}" in moon
    assert float(re.search(rf"max \|h - h_exact\|  ({NUMBER}) m", moon)[1]) < 1e-8
    assert "verdict            PASS" in moon and "verdict            PASS" in reference
    assert "21 at the end, exact 21" in reference and "max |h - h_exact|  0.000e+00 m" in reference
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ["BouncingBall.fmu", "BouncingBall_ref.csv",
                                                                      "moon.csv"]


def test_regression_test_example(fmu, tmp_path):
    pytest.importorskip("fmpy")
    out = run_example([sys.executable, "-m", "pytest", "-q", "-s", "-p", "no:cacheprovider",
                       EXAMPLES / "regression_test.py"], tmp_path, BOUNCINGBALL_FMU=str(fmu))
    assert "3 passed" in out
    cases = {"article": (Ball(), 2.0, 0.0, 8.0, 8001), "moon": (Ball(g=1.62), 1.0, 0.0, 6.0, 601),
             "thrown": (Ball(k=1e6, b=50.0), 2.0, 3.0, 3.0, 61)}
    reports = out.split("check ")[1:]
    assert len(reports) == 3
    for report, (ball, h0, v0, t_end, points) in zip(reports, cases.values(), strict=True):
        t = np.linspace(0.0, t_end, points)
        _, _, impacts = exact_at(t, ball, h0=h0, v0=v0)
        assert f"points compared    {points}" in report
        assert f"{impacts[-1]} at the end, exact {impacts[-1]}; the count is right at every point" in report
        assert float(re.search(rf"max \|h - h_exact\|  ({NUMBER}) m", report)[1]) < 1e-8
    assert list(tmp_path.iterdir()) == []
