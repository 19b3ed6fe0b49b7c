"""The Hunt-Crossley law on a vibrating table through CVODE, against an independent mpmath truth.

The truth (tests/hunt_crossley_ground_truth.py) integrates the pressed contact with mpmath's Taylor method, the
table's acceleration in its right-hand side, and finds every event (impact, departure, release, engagement) by a
certified search and findroot; CVODE integrates the flights (each step searched for its touch) and the pressed
contacts (each step's interpolant searched for its exit: hunt_crossley.step_exit), the free spells in closed form.
Issue 46: Hunt-Crossley within the promise of its truth; its error estimate above the true error.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import bouncingball as bb
from bouncingball import Ground
from bouncingball.contact_laws import HUNT_CROSSLEY, BallParameters
from bouncingball.contact_laws.hunt_crossley import step_exit
from hunt_crossley_ground_truth import HuntCrossleyGroundTruth

G, F, R = 9.81, 10.0, 0.01  # gravity [m/s2], the table's frequency [Hz], the ball's radius [m]
W = 2.0 * math.pi * F


def test_a_step_whose_ends_are_pressed_but_whose_motion_leaves_departs_where_the_parabola_crosses():
    """CVODE's root function sees two ends below R and no change of sign; the step's interpolant crosses R. With a
    force negligible at these depths (k = 1e-9) the motion is the parabola x = -d + u t - g t^2 / 2, which the
    quintic interpolant holds exactly: the exit is its first root, (u - sqrt(u^2 - 2 g d)) / g."""
    parameters = BallParameters(m=1.0, k=1e-9, b=0.0, R=R, g=G, law=HUNT_CROSSLEY, e=0.0, v_min=0.0, n=1.5, alpha=0.0)
    depth, speed = 1e-6, 0.1  # the parabola rises 5.1e-4 m above R, back at -1e-6 m at the step's end
    t1 = (speed + math.sqrt(speed * speed - 2.0 * G * depth)) / G
    tau, x, v, departs, decided = step_exit(parameters, G, 0.0, -depth, speed, t1, -depth, speed - G * t1, 1e-12,
                                            True)
    crossing = (speed - math.sqrt(speed * speed - 2.0 * G * depth)) / G
    assert departs and decided and x == 0.0
    assert tau == pytest.approx(crossing, rel=1e-12) and v == pytest.approx(speed - G * crossing, rel=1e-9)
    # a rise that stops 1e-9 m short of R: no exit, and undecided where the motion's error could be 1e-8 m
    top = 1e-9
    u = math.sqrt(2.0 * G * (depth - top))
    t1 = 2.0 * u / G
    assert math.isnan(step_exit(parameters, G, 0.0, -depth, u, t1, -depth, -u, 1e-12, True)[0])
    assert step_exit(parameters, G, 0.0, -depth, u, t1, -depth, -u, 1e-12, True)[4]
    assert not step_exit(parameters, G, 0.0, -depth, u, t1, -depth, -u, 1e-8, True)[4]
    # a rise past R by 1e-9 m: a departure, undecided where the error could be 1e-8 m (review)
    u = math.sqrt(2.0 * G * (depth + top))
    t1 = 2.0 * u / G
    tau, x, v, departs, decided = step_exit(parameters, G, 0.0, -depth, u, t1, -depth, -u, 1e-8, True)
    assert departs and not decided and tau == pytest.approx((u - math.sqrt(u * u - 2.0 * G * depth)) / G, rel=1e-9)


def test_a_step_whose_speed_passes_the_release_speed_below_the_surface_releases_there():
    """v rising past the release speed 2 / (3 alpha) inside one step, x below R throughout: the release, where the
    parabola's v reaches it (a release with no departure in the step was once returned as no exit at all: review)."""
    alpha = 2.0 / (3.0 * 0.05)  # the release speed 0.05 m/s
    parameters = BallParameters(m=1.0, k=1e-9, b=0.0, R=R, g=G, law=HUNT_CROSSLEY, e=0.0, v_min=0.0, n=1.5,
                                alpha=alpha)
    depth, u, h = 1e-2, 0.0, 0.02  # lifted by F_ext = 2 m g: v = g t rises, x stays 1 cm below R
    tau, x, v, departs, decided = step_exit(parameters, -G, 0.0, -depth, u, h, -depth + 0.5 * G * h * h, G * h,
                                            1e-12, True)
    assert not departs and decided and v == 0.05 and tau == pytest.approx(0.05 / G, rel=1e-12)
    assert x == pytest.approx(-depth + 0.5 * G * tau * tau, rel=1e-12)


def _run(gamma, k, n, alpha, phase, drop, t_end, output_interval=1e-3, engine="compiled"):
    """(result, truth): a Hunt-Crossley ball dropped onto a sine table, through CVODE and in mpmath."""
    ground = Ground.sine(gamma * G / W**2, F, phase)
    ball = bb.Ball(m=1.0, k=k, n=n, alpha=alpha, R=R, g=G, contact="hunt-crossley")
    h0 = R + drop + ground.position(0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", bb.AccuracyWarning)  # judged below; the run must keep its promise
        result = bb.simulate(ball, h0, 0.0, t_end, output_interval, solver="cvode", engine=engine, ground=ground)
    truth = HuntCrossleyGroundTruth(1.0, k, n, alpha, R, G, ground.amplitude, F, phase, h0, 0.0, t_end)
    return result, truth


def _judged(result, truth, event_time, every=1):
    """(estimate / error, error): events one for one with the truth within event_time [s], heights within the
    estimate."""
    assert [str(event.kind) for event in result.events] == [kind for _, kind, _ in truth.events]
    times = np.array([event.time for event in result.events] or [0.0])
    true_times = np.array([float(t) for t, _, _ in truth.events] or [0.0])
    assert np.max(np.abs(times - true_times)) < event_time
    error = max(abs(float(truth.state(t)[0]) - h) for t, h in zip(result.t[::every], result.h[::every], strict=True))
    assert error <= result.error_estimate
    return result.error_estimate / error if error > 0.0 else math.inf, error


@pytest.mark.parametrize(("gamma", "k", "n", "alpha"), [
    pytest.param(0.5, 1e6, 1.5, 0.2, marks=pytest.mark.study),
    pytest.param(1.2, 1e6, 1.5, 0.2, marks=pytest.mark.study),
    pytest.param(2.0, 1e5, 1.5, 0.5, marks=pytest.mark.slow), (1.2, 1e5, 1.0, 0.0)])
def test_a_hunt_crossley_ball_on_a_vibrating_table_is_its_truth_within_the_estimate(gamma, k, n, alpha):
    """Gently vibrating (Gamma 0.5), thrown (1.2, 2.0), and the linear spring (n = 1, alpha = 0); the two at k = 1e6
    (its truth ~13 s each) are left to `pytest -m study`, the random drops below covering theirs. Measured: events one
    for one within 2.6e-10 s, heights within 7.4e-11 .. 2.8e-10 m, the estimate 26x .. 83x that."""
    result, truth = _run(gamma, k, n, alpha, 0.3, 0.02, 1.0)
    assert len(result.events) >= 6
    ratio, error = _judged(result, truth, 1e-7, every=10)
    assert result.error_estimate < 1e-6 * R and ratio < 1e3


@pytest.mark.slow
def test_released_by_the_table_it_flies_free_below_the_surface_and_departs_as_its_truth():
    """A soft ball (k = 1e4 N/m^1.5) that a strong table (Gamma 2.6) lifts faster than its release speed 2 / (3
    alpha): pressed, released where the force would pull, free below the surface, out of it, again and again.
    Measured: events within 1.8e-11 s, heights 1.4e-11 m, the estimate 113x that."""
    ground = Ground.sine(0.01, 8.0)
    ball = bb.Ball(m=1.0, k=1e4, n=1.5, alpha=0.6, R=R, g=G, contact="hunt-crossley")
    with warnings.catch_warnings():
        warnings.simplefilter("error", bb.AccuracyWarning)
        result = bb.simulate(ball, R + 0.02, 0.0, 1.0, 1e-3, solver="cvode", ground=ground)
    truth = HuntCrossleyGroundTruth(1.0, 1e4, 1.5, 0.6, R, G, 0.01, 8.0, 0.0, R + 0.02, 0.0, 1.0)
    assert [str(event.kind) for event in result.events].count("release") == 3
    _judged(result, truth, 1e-9, every=10)


def _random_scenes(count=12):
    """(gamma, k, n, alpha, phase, drop) of random drops onto a table: Gamma 0.3 to 3, k 1e4 to 1e7 N/m^n, n 1 to
    2.5, alpha 0 to 1 s/m, any phase, dropped 0 to 3 cm."""
    rng = np.random.default_rng(46)
    return [(rng.uniform(0.3, 3.0), 10.0 ** rng.uniform(4.0, 7.0), rng.uniform(1.0, 2.5), rng.uniform(0.0, 1.0),
             rng.uniform(0.0, 2.0 * math.pi), rng.uniform(0.0, 0.03)) for _ in range(count)]


def _grazing_scenes():
    """The rigid law's grazing scenes whose first impact grazes (tests/table_scenes.py: 1e-10 to 1e-6 m into the
    table, or missing it by up to 1e-6 m), each with a Hunt-Crossley ball of its own (k 1e4 to 1e7, n, alpha)."""
    import random

    from table_scenes import grazing_family

    draw = random.Random(46)
    return [(scene, 10.0 ** draw.uniform(4.0, 7.0), draw.uniform(1.0, 2.5), draw.uniform(0.0, 1.0))
            for scene in grazing_family(count=60) if scene["bounces_before"] == 0]


def _share(count, every):
    """Scene numbers as parameters: every every-th in the default run (slow), the rest for `pytest -m study`."""
    return [pytest.param(number, marks=pytest.mark.slow if number % every == 0 else pytest.mark.study)
            for number in range(count)]


@pytest.mark.parametrize("number", _share(12, 4))
def test_random_scenes_lose_no_event_and_are_within_the_estimate(number):
    """12 random drops (its truth 4 to 13 s each: every fourth in the default run). Measured: events one for one
    within 9.1e-10 s, the estimate 4.6x to 545x the error (median 30x), no warning."""
    result, truth = _run(*_random_scenes()[number], 0.5, output_interval=1e-2)
    assert _judged(result, truth, 1e-8)[0] <= 1000.0


@pytest.mark.parametrize("number", _share(19, 3))
def test_a_grazing_first_impact_is_neither_lost_nor_invented(number):
    """19 scenes whose first impact grazes the table, 2.2e-10 to 3.8e-7 m deep, or misses it by 2.5e-9 to 1.4e-7 m
    (its truth 0 to 7 s each: every third in the default run). Measured: events one for one within 2.6e-9 s, the
    estimate 2.0x to 402x the error (median 32x), no warning."""
    scene, k, n, alpha = _grazing_scenes()[number]
    ground = Ground.sine(scene["amplitude"], scene["frequency"], scene["phase"])
    ball = bb.Ball(m=1.0, k=k, n=n, alpha=alpha, R=scene["R"], g=scene["g"], contact="hunt-crossley")
    with warnings.catch_warnings():
        warnings.simplefilter("error", bb.AccuracyWarning)  # no graze here is within CVODE's error
        result = bb.simulate(ball, scene["h0"], scene["v0"], scene["t_end"], scene["t_end"] / 500, solver="cvode",
                             ground=ground)
    truth = HuntCrossleyGroundTruth(1.0, k, n, alpha, scene["R"], scene["g"], scene["amplitude"], scene["frequency"],
                                    scene["phase"], scene["h0"], scene["v0"], scene["t_end"])
    assert len(truth.events) == len(result.events) and _judged(result, truth, 1e-8)[0] <= 1000.0


def test_started_free_below_the_surface_it_engages_where_its_speed_falls_to_the_release_speed():
    """Started 5 cm into a vibrating table rising through it 1 m/s faster than the table, above the release speed
    2 / (3 alpha) = 0.67 m/s: free, its relative speed falls to the release speed before it reaches the surface
    (the engagement: a weightless flight's touch of the table's speed), then pressed, out, and back. Measured:
    events within 5e-12 s, heights within 4.4e-12 m, the estimate 43x that."""
    radius, ground = 0.1, Ground.sine(0.005, 5.0, 0.3)
    ball = bb.Ball(m=1.0, k=1e3, n=1.5, alpha=1.0, R=radius, g=G, contact="hunt-crossley")
    h0, v0 = radius + ground.position(0.0) - 0.05, ground.velocity(0.0) + 1.0
    result = bb.simulate(ball, h0, v0, 0.3, 1e-3, solver="cvode", ground=ground)
    truth = HuntCrossleyGroundTruth(1.0, 1e3, 1.5, 1.0, radius, G, 0.005, 5.0, 0.3, h0, v0, 0.3)
    assert [str(event.kind) for event in result.events] == ["engage", "departure", "impact"]
    _judged(result, truth, 1e-10, every=5)
