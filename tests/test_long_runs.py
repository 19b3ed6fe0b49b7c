"""Long conservative runs keep the promise: an undamped ball over thousands of bounces, against its periodic
closed form (tests/closed_forms.py, written from the equations; no solver code)."""

from __future__ import annotations

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.scenes import load_scene
from closed_forms import first_impact_time, undamped_event_count, undamped_heights
from test_cvode import assert_readme_quotes

UNDAMPED = bb.Ball(b=0.0)
PROMISE = 1e-6  # of the height scale max(|h|, R)


def bounce_period(ball: bb.Ball, h0: float) -> float:
    """Seconds from one impact to the next: two falls and a contact (as undamped_event_count)."""
    fall = first_impact_time(h0, ball.R, ball.g)
    omega, deflection = np.sqrt(ball.k / ball.m), ball.m * ball.g / ball.k
    amplitude = np.hypot(deflection, ball.g * fall / omega)
    return 2.0 * fall + (np.pi + 2.0 * np.arcsin(deflection / amplitude)) / omega


def assert_within_promise(result, ball: bb.Ball, h0: float, t_end: float, estimate_at_least: float = 1.0) -> float:
    truth = undamped_heights(ball.m, ball.k, ball.R, ball.g, h0, result.t)
    scale = max(float(np.max(np.abs(truth))), ball.R)
    error = float(np.max(np.abs(result.h - truth))) / scale
    assert error <= PROMISE
    # the run knows how right it is (at least estimate_at_least of its true error)
    assert estimate_at_least * error * scale <= result.error_estimate <= PROMISE * scale
    assert len(result.events) == undamped_event_count(ball.m, ball.k, ball.R, ball.g, h0, t_end)
    speeds = np.abs([e.velocity for e in result.events])  # every bounce at the first impact's speed: energy kept
    assert np.all(speeds == speeds[0])
    return error


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_the_undamped_scene_keeps_the_promise(engine):
    """1000 s, 775 bounces: 2.2e-6 of the height scale when each event's speed was CVODE's."""
    scene = load_scene("undamped")
    result = scene.simulate(engine=engine)
    error = assert_within_promise(result, scene.ball, scene.h0, scene.t_end)
    assert error <= 1e-8
    assert_readme_quotes(f"775 bounces over 1000 s end within {error:.1e} of its 2 m height scale".replace("e-0", "e-"))


@pytest.mark.slow
@pytest.mark.parametrize("bounces, output_interval", [(10_000, 0.01), (100_000, 1.0)])
def test_ten_thousand_and_a_hundred_thousand_undamped_bounces_keep_the_promise(bounces, output_interval):
    """Each phase that starts on R and conserves its energy ends at the speed it started with, so no bounce's
    error carries into the next one's energy; event times carry their rounding error (rounding.later), so the
    same durations repeated do not round the same way 1e5 times. The drift grows linearly, not with the
    square of the count (1.3e-6 of the height scale at 1e5 bounces without the second, 2.2e-6 at 775 without
    the first)."""
    t_end = first_impact_time(2.0, UNDAMPED.R, UNDAMPED.g) + bounces * bounce_period(UNDAMPED, 2.0) - 0.5
    result = bb.simulate(UNDAMPED, 2.0, 0.0, t_end, output_interval, engine="compiled")
    assert sum(e.kind == "impact" for e in result.events) == bounces
    # The error from R to R is carried as a delay along the flow and a speed error on R (error_estimate's
    # _carried_error), so the delay a speed error makes grows bounce after bounce: 2.4 times the true error at 1e5
    # bounces (5.8e-7 m against 2.4e-7 m; carried by the transition matrices alone, their rounding turned the
    # growth into a slow rotation and the estimate fell to 0.76 of it), 1.3 times it at 1e4.
    error = assert_within_promise(result, UNDAMPED, 2.0, t_end)
    figure = f"{error:.1e}".replace("e-0", "e-")
    assert_readme_quotes(f"1e4 bounces within {figure}," if bounces == 10_000 else
                         f"1e5 bounces (1.3e5 s) within {figure} ")


def test_event_times_carried_with_their_rounding_error_do_not_drift():
    """1e5 repeats of one duration from t = 0.63 s: the exact sum (fractions) against later's and a plain sum's."""
    from fractions import Fraction

    from bouncingball.rounding import later

    t0, tau, n = 0.6288996587977134, 1.2894069467803926, 100_000
    t, t_low, plain = t0, 0.0, t0
    for _ in range(n):
        t, t_low = later(t, t_low, tau)
        plain += tau
    exact = Fraction(t0) + n * Fraction(tau)
    assert abs(Fraction(t) - exact) <= Fraction(np.spacing(t)) / 2  # the nearest double, or next to it
    assert Fraction(t) + Fraction(t_low) - exact == 0 or abs(Fraction(t) + Fraction(t_low) - exact) < 1e-20
    assert abs(Fraction(plain) - exact) > 1000 * Fraction(np.spacing(t))  # what each event's rounding added up to
