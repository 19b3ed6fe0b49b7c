"""Long conservative runs keep the promise: an undamped ball over thousands of bounces, against its periodic
closed form (tests/closed_forms.py, written from the equations; no solver code)."""

from __future__ import annotations

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.scenes import load_scene
from closed_forms import first_impact_time, undamped_event_count, undamped_heights

UNDAMPED = bb.Ball(b=0.0)
PROMISE = 1e-6  # of the height scale max(|h|, R)


def bounce_period(ball: bb.Ball, h0: float) -> float:
    """Seconds from one impact to the next: two falls and a contact (as undamped_event_count)."""
    fall = first_impact_time(h0, ball.R, ball.g)
    omega, deflection = np.sqrt(ball.k / ball.m), ball.m * ball.g / ball.k
    amplitude = np.hypot(deflection, ball.g * fall / omega)
    return 2.0 * fall + (np.pi + 2.0 * np.arcsin(deflection / amplitude)) / omega


def assert_within_promise(result, ball: bb.Ball, h0: float, t_end: float) -> float:
    truth = undamped_heights(ball.m, ball.k, ball.R, ball.g, h0, result.t)
    scale = max(float(np.max(np.abs(truth))), ball.R)
    error = float(np.max(np.abs(result.h - truth))) / scale
    assert error <= PROMISE
    assert len(result.events) == undamped_event_count(ball.m, ball.k, ball.R, ball.g, h0, t_end)
    speeds = np.abs([e.velocity for e in result.events])  # every bounce at the first impact's speed: energy kept
    assert np.all(speeds == speeds[0])
    return error


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_the_undamped_scene_keeps_the_promise(engine):
    """1000 s, 775 bounces: 2.2e-6 of the height scale when each event's speed was CVODE's."""
    scene = load_scene("undamped")
    result = scene.simulate(engine=engine)
    assert assert_within_promise(result, scene.ball, scene.h0, scene.t_end) <= 1e-8


# At 1e5 bounces (t ~ 1.3e5 s) the event times drift by the rounding of t + tau at each event: the same
# durations repeat, so the half-ulp roundings (ulp(1.3e5 s) = 1.5e-11 s) do not cancel, and the drift grows
# with the square of the count (1.3e-6 of the height scale, the exact solver's too). Compensated (double-
# double) event times would keep it; until then the run is off the promise.
HUNDRED_THOUSAND = pytest.param(100_000, 1.0, marks=pytest.mark.xfail(
    strict=True, reason="event times rounded to ulp(t) at each event drift with the square of the count"))


@pytest.mark.slow
@pytest.mark.parametrize("bounces, output_interval", [(10_000, 0.01), HUNDRED_THOUSAND])
def test_ten_thousand_and_a_hundred_thousand_undamped_bounces_keep_the_promise(bounces, output_interval):
    """Each phase that starts on R and conserves its energy ends at the speed it started with, so no bounce's
    error carries into the next one's energy: the event times drift linearly, not with the square of the count."""
    t_end = first_impact_time(2.0, UNDAMPED.R, UNDAMPED.g) + bounces * bounce_period(UNDAMPED, 2.0) - 0.5
    result = bb.simulate(UNDAMPED, 2.0, 0.0, t_end, output_interval, engine="compiled")
    assert sum(e.kind == "impact" for e in result.events) == bounces
    assert_within_promise(result, UNDAMPED, 2.0, t_end)
