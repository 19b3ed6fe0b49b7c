"""The linear and no-pull laws on a vibrating table: the exact solver and CVODE against an independent mpmath truth.

The truth (tests/linear_table_truth.py) solves the contact as a forced damped oscillator from complex exponentials
and finds its departure (no-pull: release, departure from the free spell, engagement) by a fine scan and findroot;
the solvers take the still ground's closed form plus the periodic response and certified searches (CVODE: the
flights integrated, each step searched for its touch; the linear law's contact in closed form). Issue 46's first
Done-when, for these laws: the exact solver within 1e-12 of scale, CVODE within its estimate and the promise.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import bouncingball as bb
from bouncingball import Ground
from linear_table_truth import LinearTableTruth

G, F, R = 9.81, 10.0, 0.05  # gravity [m/s2], the table's frequency [Hz], the ball's radius [m]
W = 2.0 * math.pi * F


SOLVERS = ["exact", "cvode"]
EVENT_TIME = {"exact": 1e-10, "cvode": 1e-7}  # s: the exact solver's rounding; CVODE's (measured <= 4.1e-8 s)


def _both(gamma, k, b, phase, drop, t_end, m=1.0, output_interval=1e-3, law="linear", solver="exact"):
    ground = Ground.sine(gamma * G / W**2, F, phase)
    ball = bb.Ball(m=m, k=k, b=b, R=R, g=G, contact=law)
    with warnings.catch_warnings():
        # judged below against the truth; CVODE's run must also keep its promise (no warning)
        warnings.simplefilter("error" if solver == "cvode" else "ignore", bb.AccuracyWarning)
        result = bb.simulate(ball, R + drop, 0.0, t_end, output_interval, solver=solver, ground=ground)
    truth = LinearTableTruth(R, G, m, k, b, ground.amplitude, F, phase, R + drop, 0.0, t_end,
                             no_pull=law == "linear-no-pull")
    return result, truth


def _height_errors(result, truth, every=1):
    return np.array([abs(float(truth.state(t)[0]) - h) for t, h in zip(result.t[::every], result.h[::every],
                                                                       strict=True)])


@pytest.mark.parametrize("solver", SOLVERS)
def test_bouncing_on_a_gently_vibrating_table_is_the_truth_within_1e_12_of_its_scale(solver):
    """The exact solver within 1e-12 of scale (measured 4.9e-16 m); CVODE within its estimate (7e-12 m, 2.1x)."""
    result, truth = _both(0.5, 1e5, 20.0, 0.3, 0.05, 2.0, solver=solver)
    events = [(event.time, str(event.kind)) for event in result.events]
    assert [kind for _, kind in events] == [kind for _, kind in truth.events] and len(events) == 20
    tolerance = 1e-12 if solver == "exact" else 1e-10
    assert max(abs(t - float(t_true)) for (t, _), (t_true, _) in zip(events, truth.events, strict=True)) < tolerance
    scale = max(float(np.max(np.abs(result.h))), R)
    errors = _height_errors(result, truth, every=5)
    assert np.max(errors) < (1e-12 if solver == "exact" else 1e-9) * scale
    assert np.max(errors) <= result.error_estimate


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize(("gamma", "k", "b"), [(1.2, 1e5, 20.0), (1.2, 1e4, 10.0), (2.0, 1e5, 30.0)])
def test_thrown_by_the_table_every_event_and_height_is_the_truths_within_the_estimate(gamma, k, b, solver):
    result, truth = _both(gamma, k, b, 0.3, 0.05, 2.0, solver=solver)
    times = np.array([event.time for event in result.events])
    true_times = np.array([float(t) for t, _ in truth.events])
    assert [str(event.kind) for event in result.events] == [kind for _, kind in truth.events]
    assert np.max(np.abs(times - true_times)) < EVENT_TIME[solver]
    errors = _height_errors(result, truth, every=5)
    assert np.max(errors) <= result.error_estimate < (1e-7 if solver == "exact" else 1e-5) * R


@pytest.mark.parametrize("solver", SOLVERS)
def test_a_ball_that_settles_rests_on_the_table_and_moves_with_it(solver):
    """Heavily damped on a gently vibrating table: a last contact that energy proves permanent is the rest."""
    result, truth = _both(0.3, 1e4, 100.0, 1.0, 0.01, 3.0, solver=solver)
    assert result.rest_time is not None
    assert result.events[-1].kind == bb.EventKind.IMPACT and result.rest_time == result.events[-1].time
    assert abs(result.rest_time - float(truth.events[-1][0])) < 1e-12
    after = result.t > result.rest_time
    assert np.ptp(result.h[after] - result.ground.position(result.t[after])) > 1e-5  # it oscillates with the table
    assert np.max(_height_errors(result, truth, every=20)) < 1e-12


@pytest.mark.slow
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("law", ["linear", "linear-no-pull"])
def test_random_scenes_lose_no_event_the_truth_has(law, solver):  # ~20 s each, loaded
    """Random scenes (Gamma 0.3 to 3, k 1e4 to 1e6 N/m, damping ratio 0.02 to 0.5, any phase, dropped 0 to 5 cm):
    events one for one with the truth, every height within the run's estimate."""
    rng = np.random.default_rng(46)
    for _ in range(14):
        gamma, k, zeta = rng.uniform(0.3, 3.0), 10.0 ** rng.uniform(4.0, 6.0), rng.uniform(0.02, 0.5)
        b = 2.0 * zeta * math.sqrt(k)
        result, truth = _both(gamma, k, b, rng.uniform(0.0, 2.0 * math.pi), rng.uniform(0.0, 0.05), 1.0,
                              output_interval=1e-2, law=law, solver=solver)
        scene = f"Gamma {gamma}, k {k}, b {b}"
        _judged(result, truth, EVENT_TIME[solver], scene)


def _judged(result, truth, event_time, scene):
    """The estimate over the true error (inf where it is 0): after the events and the bound are checked."""
    assert [str(event.kind) for event in result.events] == [kind for _, kind in truth.events], scene
    times = np.array([event.time for event in result.events] or [0.0])
    true_times = np.array([float(t) for t, _ in truth.events] or [0.0])
    assert np.max(np.abs(times - true_times)) < event_time, scene
    error = np.max(_height_errors(result, truth))
    assert error <= result.error_estimate, scene
    return result.error_estimate / error if error > 0.0 else math.inf, error


@pytest.mark.slow
@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("law", ["linear", "linear-no-pull"])
def test_a_grazing_family_loses_no_event_and_is_within_its_estimate(law, solver):
    """The rigid law's grazing scenes whose first impact grazes (tests/table_scenes.py: 1e-10 to 1e-5 m into the
    table, or missing it by up to 1e-6 m), the ball a spring-damper (k 1e4 to 1e6 N/m, damping ratio 0.02 to 0.5):
    events one for one with the truth, every height within the estimate, the estimate within 1000x of an error
    above rounding. The truth cannot follow the shallowest crossings under the linear law (3 of 19, 2e-10 to 2.3e-9
    m: its certified flight scan finds no end after a departure at a relative speed of ~1e-5 m/s, in 40 s each):
    crossings shallower than 3e-9 m are left out, 16 scenes judged."""
    import random

    from table_scenes import grazing_family

    draw, judged = random.Random(46), []
    for scene in (scene for scene in grazing_family(count=60) if scene["bounces_before"] == 0):
        k, zeta = 10.0 ** draw.uniform(4.0, 6.0), draw.uniform(0.02, 0.5)
        b = 2.0 * zeta * math.sqrt(k)
        if 0.0 < scene["graze_depth"] < 3e-9:
            continue
        ground = Ground.sine(scene["amplitude"], scene["frequency"], scene["phase"])
        truth = LinearTableTruth(scene["R"], scene["g"], 1.0, k, b, scene["amplitude"], scene["frequency"],
                                 scene["phase"], scene["h0"], scene["v0"], scene["t_end"],
                                 no_pull=law == "linear-no-pull")
        ball = bb.Ball(m=1.0, k=k, b=b, R=scene["R"], g=scene["g"], contact=law)
        with warnings.catch_warnings():
            warnings.simplefilter("error", bb.AccuracyWarning)  # no graze here is within CVODE's error
            result = bb.simulate(ball, scene["h0"], scene["v0"], scene["t_end"], scene["t_end"] / 500, solver=solver,
                                 ground=ground)
        ratio, error = _judged(result, truth, EVENT_TIME[solver], f"{scene}, k {k}, b {b}")
        scale = max(float(np.max(np.abs(result.h))), scene["R"])
        judged.append((ratio, error > 64 * 2.0**-52 * scale))
    assert len(judged) == 16
    above_rounding = [ratio for ratio, above in judged if above]
    assert all(ratio <= 1000.0 for ratio in above_rounding)
    assert solver == "exact" or len(above_rounding) == len(judged)  # CVODE's errors are its own, not rounding


def _restitution_calibrated(k, speed, e, m=1.0, radius=0.01):
    """b [N s/m] giving departure over impact speed e for one impact at speed [m/s] on a still ground (the issue's)."""
    from scipy.optimize import brentq

    def ratio(b):
        result = bb.simulate(bb.Ball(m=m, k=k, b=b, R=radius, g=G), radius, -speed, 0.2, 1e-2, solver="exact")
        departures = [event for event in result.events if event.kind == bb.EventKind.DEPARTURE]
        return departures[0].velocity / speed - e if departures else -e

    return brentq(ratio, 0.02 * math.sqrt(k * m), 0.7 * math.sqrt(k * m), xtol=1e-12 * math.sqrt(k * m))


@pytest.mark.parametrize(("k", "tolerance"), [(1e9, 1e-3), (1e7, 1e-2)])
def test_a_stiff_contact_orbits_at_the_rigid_laws_phase(k, tolerance):
    """The period-1 orbit of the rigid law (e = 0.5, halfway to period doubling) against the linear law's, its damping
    giving e = 0.5 at the orbit's impact speed: the impact phases part by ~0.1 w times the contact's duration
    (measured -5.7e-4 rad at k = 1e9, a 0.10 ms contact; -6.4e-3 rad at 1e7, 1.0 ms): the issue's 1e-3 rad holds from
    k ~ 2e8 N/m on, not at its 1e7."""
    from closed_forms import period_doubling_threshold, period_n_phase, period_n_takeoff_speed, period_n_threshold

    e, radius = 0.5, 0.01
    low, high = period_n_threshold(1, e), period_doubling_threshold(1, e)
    gamma = low + 0.5 * (high - low)
    phi, take_off = period_n_phase(1, e, gamma), period_n_takeoff_speed(1, F, G)
    ground = Ground.sine(gamma * G / W**2, F, phi)
    speed = (take_off - ground.amplitude * W * math.cos(phi)) / e  # the orbit's impact speed relative to the table
    ball = bb.Ball(m=1.0, k=k, b=_restitution_calibrated(k, speed, e), R=radius, g=G)
    h0 = math.nextafter(radius + ground.position(0.0), math.inf)
    result = bb.simulate(ball, h0, 1.01 * take_off, 30.0, 1e-2, solver="exact", ground=ground)
    impacts = np.array([event.time for event in result.events if event.kind == bb.EventKind.IMPACT])
    assert np.max(np.abs(np.diff(impacts[-10:]) - 1.0 / F)) < 1e-9  # period 1
    offset = math.remainder(W * impacts[-1], 2.0 * math.pi)  # the impact phase W t + phi, less phi
    assert abs(offset) < tolerance


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize(("gamma", "k", "b"), [(0.5, 1e5, 200.0), (1.2, 1e5, 200.0), (2.0, 1e4, 60.0)])
def test_the_no_pull_law_releases_flies_free_and_departs_or_engages_as_the_truth(gamma, k, b, solver):
    """Pressed, released where the force would pull, free below the surface, out of it or pressed again (the exact
    solver within 4e-15 s and 2e-15 m; CVODE within 5.5e-12 s and 1.8e-12 m, 2.3x to 8.6x below its estimate)."""
    result, truth = _both(gamma, k, b, 0.3, 0.05, 1.0, law="linear-no-pull", solver=solver)
    kinds = [str(event.kind) for event in result.events]
    assert kinds == [kind for _, kind in truth.events] and "release" in kinds
    times = np.array([event.time for event in result.events])
    tolerance = 1e-13 if solver == "exact" else 1e-10
    assert np.max(np.abs(times - np.array([float(t) for t, _ in truth.events]))) < tolerance
    scale = max(float(np.max(np.abs(result.h))), R)
    errors = _height_errors(result, truth, every=5)
    assert np.max(errors) <= result.error_estimate and np.max(errors) < (1e-12 if solver == "exact" else 1e-9) * scale


def test_a_ball_started_pressed_into_the_table_is_the_truth():
    ground = Ground.sine(1.2 * G / W**2, F, 0.3)
    ball = bb.Ball(m=1.0, k=1e5, b=20.0, R=R, g=G)
    h0 = R + ground.position(0.0) - 1e-4
    result = bb.simulate(ball, h0, 0.0, 1.0, 1e-3, solver="exact", ground=ground)
    truth = LinearTableTruth(R, G, 1.0, 1e5, 20.0, ground.amplitude, F, 0.3, h0, 0.0, 1.0)
    assert result.events[0].kind == bb.EventKind.DEPARTURE and truth.events[0][1] == "departure"
    assert abs(result.events[0].time - float(truth.events[0][0])) < 1e-13
    assert np.max(_height_errors(result, truth, every=5)) <= result.error_estimate


def test_a_force_table_of_zeros_changes_nothing_inside_contacts():
    """F_ext's pieces cut contacts and flights: each piece restarts from the forced flow's state, as if uncut."""
    ground = Ground.sine(1.2 * G / W**2, F, 0.3)
    ball = bb.Ball(m=1.0, k=1e5, b=20.0, R=R, g=G)
    whole = bb.simulate(ball, R + 0.05, 0.0, 2.0, 1e-3, solver="exact", ground=ground)
    times = np.arange(0.0, 2.0, 0.0137)
    cut = bb.simulate(ball, R + 0.05, 0.0, 2.0, 1e-3, solver="exact", ground=ground,
                      F_ext=(times, np.zeros_like(times)))
    assert [event.kind for event in cut.events] == [event.kind for event in whole.events]
    assert np.max(np.abs(cut.h - whole.h)) <= whole.error_estimate
