"""Extreme finite inputs are answered, or refused up front naming the field, its value and its range.

The cases of a fault campaign: before limits.check_scene, CVODE hung on the first three, the next
two raised a raw OverflowError, b = 1e300 with m = 1e-300 gave NaN in h and v, and an output
interval below the float spacing at t_start gave a grid with repeated and decreasing times. Every
call that once hung runs in a subprocess with a timeout, so that a regression fails instead of
hanging the suite.
"""

import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import bouncingball
from bouncingball import limits
from bouncingball.physics import Ball, Mode
from bouncingball.scenes import BUILTIN_SCENES, load_scene
from bouncingball.solvers.result import output_grid

TIMEOUT = 60.0  # s: each case is refused in well under a second; a hang fails here


def _in_subprocess(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          timeout=TIMEOUT, check=False)


def _refusal(call: str) -> str:
    """The ValueError message of `call` (Python source) run in a fresh process; fails if it returns or hangs."""
    completed = _in_subprocess(f"""
        import bouncingball
        from bouncingball import Ball
        from bouncingball.solvers.cvode import BallIntegrator
        try:
            {call}
        except ValueError as error:
            print("refused:", error)
        else:
            print("answered")
        """)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.startswith("refused: "), completed.stdout
    return completed.stdout


# (call, fragments of the message): the field, its value and its range
ONCE_HUNG = [
    ("bouncingball.simulate(Ball(b=0), -1e300, 0, 1, solver={solver!r}{engine})",
     ["h0 = -1e+300 m is not allowed", "it must be in [-1e+148, ", "m2/s2"]),
    ("bouncingball.simulate(Ball(m=1e6), -1e300, 0, 1, solver={solver!r}{engine})",
     ["h0 = -1e+300 m is not allowed", "m = 1e+06 kg", "it must be in [-1e+148, "]),
    ("bouncingball.simulate(Ball(), 2, 0, 8, solver={solver!r}, F_ext=-1e300{engine})",
     ["F_ext = -1e+300 N is not allowed", "it must be in [-1e+152, 1e+152] N"]),
]
# Contacts of 3 ps near t = 1e5 s, where an ulp of t is 1.5e-11 s: the exact solution's phases stopped
# advancing t (it never ended); CVODE refused them already.
ONCE_HUNG.append(("bouncingball.simulate(Ball(k=1e15, m=1e-9, b=0.0), 1.0, 0.0, 1e5, 1.0, solver={solver!r}{engine})",
                  ["k = 1000000000000000.0 N/m with m = 1e-09 kg is not allowed up to t = ",
                   "Shorten the run to t <= 1.41"]))  # t_end (CVODE) or the first contact past 1.415 s (exact)
OVERFLOWED = [
    ("bouncingball.simulate(Ball(R=1e300), 2, 0, 1, solver={solver!r}{engine})",
     ["R = 1e+300 m is not allowed: it must be <= 1e+150 m"]),
    ("bouncingball.simulate(Ball(R=1e155), 2, 0, 1, solver={solver!r}{engine})",
     ["R = 1e+155 m is not allowed: it must be <= 1e+150 m"]),
    ("bouncingball.simulate(Ball(b=0), -1e200, 0, 1, solver={solver!r}{engine})",
     ["h0 = -1e+200 m is not allowed", "it must be in [-1e+148, "]),
]
SOLVERS = [("exact", ""), ("cvode", ", engine='sksundae'"), ("cvode", ", engine='compiled'")]


@pytest.mark.parametrize(("solver", "engine"), SOLVERS)
@pytest.mark.parametrize(("call", "fragments"), ONCE_HUNG + OVERFLOWED)
def test_once_hanging_or_overflowing_scenes_are_refused_by_every_solver(call, fragments, solver, engine):
    if engine == ", engine='compiled'":
        pytest.importorskip("numba")
    message = _refusal(call.format(solver=solver, engine=engine))
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_the_stepping_integrator_and_so_the_fmu_refuses_them_too():
    message = _refusal("BallIntegrator(Ball(b=0), -1e300, 0.0)")
    assert "h0 = -1e+300 m is not allowed" in message
    message = _refusal("BallIntegrator(Ball(), 2.0, 0.0, 0.0, -1e300)")
    assert "F_ext = -1e+300 N is not allowed" in message


@pytest.mark.parametrize("solver", ["exact", "cvode"])
def test_a_damping_rate_whose_square_overflows_is_refused_not_nan(solver):
    # Before: a normal result with 372 of 1001 heights and velocities NaN.
    with pytest.raises(ValueError) as info:
        bouncingball.simulate(Ball(b=1e300, m=1e-300), 2.0, 0.0, 1.0, solver=solver)
    assert "b = 1e+300 N s/m is not allowed with m = 1e-300 kg: it must be <= 2e-150 N s/m" in str(info.value)
    assert "b/(2m)" in str(info.value)


@pytest.mark.parametrize("solver", ["exact", "cvode"])
def test_an_output_interval_below_the_float_spacing_is_refused(solver):
    # Before: 141 output times from 1e6 s, 20 of them repeated or decreasing.
    with pytest.raises(ValueError) as info:
        bouncingball.simulate(Ball(), 2.0, 0.0, 1e6 + 1.4e-8, 1e-10, solver=solver, t_start=1e6)
    message = str(info.value)
    assert "output_interval = 1e-10 s is not allowed from t_start = 1000000.0 s" in message
    assert f"it must be >= {4 * math.ulp(1e6 + 1.4e-8)!r} s" in message  # exactly: a rounded bound misleads
    with pytest.raises(ValueError, match="output_interval = 1e-10 s is not allowed"):
        output_grid(1e6, 1e6 + 1.4e-8, 1e-10)


@pytest.mark.parametrize("t_start", [0.5, 1e-3, 1.0, 3.0, 1e6, 7.5e8, -1e6, 1e15, -2.0**-30])
def test_the_grid_at_the_smallest_interval_allowed_increases_strictly(t_start):
    for span_ulps in (4, 5, 17, 1000):
        t_end = t_start + span_ulps * math.ulp(t_start)
        if t_end == t_start:
            continue
        interval = limits.min_output_interval(t_start, t_end)
        if interval > t_end - t_start:
            continue
        grid = output_grid(t_start, t_end, interval)
        assert grid[0] == t_start and grid[-1] == t_end and np.all(np.diff(grid) > 0.0)


@pytest.mark.parametrize("solver", ["exact", "cvode"])
@pytest.mark.parametrize(("ball", "h0", "v0", "t_end"), [
    (Ball(b=0.0), -0.99e148, 0.0, 20.0),  # just inside the h0 range of the first case above
    (Ball(m=1e6), -0.99e148, 0.0, 1.0),
    (Ball(), 2.0, 0.99e150, 2.0),  # the fastest start allowed, upwards
    (Ball(b=0.0), 2.0, -0.7e150, 5.0),  # downwards, through a contact and back
    (Ball(), 5e298, 0.0, 8.0),  # high in flight: a height is never squared
    (Ball(R=1e149), 9.05e148, 0.0, 8.0),  # a huge ball deep in contact
])
def test_large_but_resolvable_scenes_are_answered_and_agree(ball, h0, v0, t_end, solver):
    result = bouncingball.simulate(ball, h0, v0, t_end, 1e-3, solver=solver)
    assert np.all(np.isfinite(result.h)) and np.all(np.isfinite(result.v))
    exact = bouncingball.simulate(ball, h0, v0, t_end, 1e-3, solver="exact")
    assert len(result.events) == len(exact.events)
    scale = max(float(np.max(np.abs(exact.h - ball.R))), ball.R)
    assert np.max(np.abs(result.h - exact.h)) <= 1e-9 * scale


@pytest.mark.parametrize(("ball", "h0", "v0", "F_ext", "t_start", "t_end", "interval"), [
    (Ball(k=1e15, m=1e-9), 2.0, 0.0, 0.0, 0.0, 1.0, 1e-3),
    (Ball(k=1e12, b=1e4), 1000.0, 0.0, 0.0, 0.0, 200.0, 1e-2),
    (Ball(R=1e-4, m=1e-6), 1e-4, 0.0, 1e-5, 0.0, 8.0, 1e-3),
    (Ball(R=10.0, g=0.0), 5.0, -1.0, 0.0, 1e6, 1e6 + 1.0, 1e-3),
    (Ball(g=1.3810799475959544e-183), 0.06, -18.906758504311465, 1.0, 0.0, 8.0, 1e-3),
    (Ball(), 2.0, 0.0, 0.0, 0.0, 1e6, 0.02),
])
def test_ordinary_and_large_inputs_of_the_suite_are_in_range(ball, h0, v0, F_ext, t_start, t_end, interval):
    limits.check_scene(ball, h0, v0, F_ext, t_start, t_end, interval)


def test_every_builtin_scene_is_in_range():
    for name in BUILTIN_SCENES:
        scene = load_scene(name)
        limits.check_scene(scene.ball, scene.h0, scene.v0, scene.F_ext, 0.0, scene.t_end, scene.output_interval)


def test_a_ball_flying_away_is_refused_beyond_the_time_its_height_stays_finite():
    ball = Ball()  # lifted by 100 N against a 9.81 N weight: it accelerates upwards for ever
    result = bouncingball.simulate(ball, 2.0, 0.0, 1e148, 1e145, solver="exact", F_ext=100.0)
    assert result.h[-1] == pytest.approx(0.5 * 90.19 * 1e148**2) and np.isfinite(result.energy).all()
    with pytest.raises(ValueError) as info:
        bouncingball.simulate(ball, 2.0, 0.0, 1e160, 1e157, solver="exact", F_ext=100.0)
    assert "t_end = 1e+160 s is not allowed for this scene" in str(info.value)
    bound = float(str(info.value).split("it must be <= t_start + ")[1].split()[0])
    assert bound == pytest.approx(1.109e148, rel=1e-3)  # printed exactly, not to 4 digits


@pytest.mark.parametrize(("text", "fragment"), [
    ("F_ext = -1e300\n", "bouncingball: error: F_ext = -1e+300 N is not allowed"),
    ("R = 1e300\n", "bouncingball: error: R = 1e+300 m is not allowed: it must be <= 1e+150 m"),
])
def test_the_cli_refuses_an_extreme_scene_file_in_one_line_with_exit_2(tmp_path, text, fragment):
    scene = tmp_path / "extreme.toml"
    scene.write_text(text, encoding="utf-8")
    for solver in ("cvode", "exact"):
        completed = subprocess.run([sys.executable, "-m", "bouncingball.cli", "run", str(scene), "--solver", solver],
                                   capture_output=True, text=True, timeout=TIMEOUT, check=False)
        assert completed.returncode == 2, completed.stderr
        lines = completed.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(fragment), completed.stderr
        assert completed.stdout == ""


def test_a_heavy_ball_on_a_stiff_spring_names_the_combination_and_what_to_change(tmp_path):
    """m = k = 1e300 with the default g: the weight's energy at R is out of range. g, which the file does not set,
    is not the one to blame alone: the message names the three and a bound on each that lets the ball in."""
    scene = tmp_path / "heavy.toml"
    scene.write_text("m = 1e300\nk = 1e300\nh0 = 1e200\n", encoding="utf-8")
    completed = subprocess.run([sys.executable, "-m", "bouncingball.cli", "run", str(scene)], capture_output=True,
                               text=True, timeout=TIMEOUT, check=False)
    assert completed.returncode == 2 and completed.stdout == ""
    [line] = completed.stderr.splitlines()
    assert line.startswith("bouncingball: error: m = 1e+300 kg, k = 1e+300 N/m and g = 9.81 m/s2 are not allowed "
                           "together"), line
    fixes = line.split("change one: ")[1].replace(" or ", ", ").split(", ")
    assert [fix.split()[0] for fix in fixes] == ["g", "m", "k"], fixes
    for fix in fixes:
        name, relation, value = fix.split()[:3]
        value = float(value)
        assert relation == ("<=" if name in "gm" else ">=")
        limits.check_scene(Ball(**{"m": 1e300, "k": 1e300, name: value}), 0.06, 0.0)  # the bound is in range
        beyond = value * (1.0 + 1e-9) if relation == "<=" else value * (1.0 - 1e-9)
        with pytest.raises(ValueError, match="are not allowed together|is not allowed for this ball"):
            limits.check_scene(Ball(**{"m": 1e300, "k": 1e300, name: beyond}), 0.06, 0.0)


@pytest.mark.parametrize("ball, v0", [(Ball(contact="hunt-crossley", alpha=1.0), 0.8),
                                      (Ball(contact="linear-no-pull", k=1e4, b=1e4), 0.1)])
def test_a_ball_starting_free_below_R_is_checked_as_the_contact_it_is_in(ball, v0):
    """Below R in the free sub-mode (rising past the release speed; the no-pull force would pull), the range check
    measured its start as a flight's fall from below R: a negative energy, and a bare math domain error."""
    assert ball.initial_mode(0.01, v0) == Mode.FREE
    result = bouncingball.simulate(ball, 0.01, v0, 0.05, 1e-3)
    assert result.h[-1] > 0.01 and result.stats.engine in ("compiled", "sksundae")
