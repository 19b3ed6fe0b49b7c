"""The rigid ball on a vibrating table: the exact solver against the mpmath truth and the published closed forms.

The truth (tests/table_truth.py) is written from the equations alone in mpmath; the closed forms
(tests/closed_forms.py) are the period-n orbit's phase and take-off speed, its period doubling and the ride's end
(Holmes 1982; Luck and Mehta 1993). Issue 44's Done-when, for the solver that takes a moving ground.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import bouncingball as bb
from bouncingball import Ground
from closed_forms import (
    period_doubling_threshold,
    period_n_phase,
    period_n_threshold,
    ride_end_phase,
    table_amplitude,
)
from table_runs import grazing_run, impact_times, orbit_start
from table_scenes import grazing_family
from table_truth import SineTableTruth

G, F, R = 9.81, 10.0, 0.01  # gravity [m/s2], the table's frequency [Hz], the ball's radius [m]
W = 2.0 * math.pi * F
PHASE_TOLERANCE, TIME_TOLERANCE = 1e-9, 1e-9  # rad, s: the issue's


# The solvers that take the rigid law on a sine ground: the exact one, and CVODE (its compiled engine here; both
# engines and the stepping API alike in tests/test_moving_ground_cvode.py, with its grazing family).
SOLVERS = ["exact", "cvode"]


def _run(solver, ball, h0, v0, t_end, ground, output_interval=1e-3):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an AccuracyWarning would be a broken promise here
        options = {"engine": "compiled"} if solver == "cvode" else {}
        return bb.simulate(ball, h0, v0, t_end, output_interval, solver=solver, ground=ground, **options)


def _exact(ball, h0, v0, t_end, ground, output_interval=1e-3):
    return _run("exact", ball, h0, v0, t_end, ground, output_interval)


def _phase(t, phase):
    return np.mod(W * np.asarray(t) + phase, 2.0 * math.pi)


def _orbit_start(e, gamma, speed_factor):
    """(ball, ground, h0, v0): on the period-1 orbit's take-off point at t = 0, speed_factor times its speed."""
    return orbit_start(e, gamma, speed_factor, F, G, R)


@pytest.mark.parametrize("e", [0.5, 0.8])
@pytest.mark.parametrize("fraction", [0.3, 0.8])
@pytest.mark.parametrize("solver", SOLVERS)
def test_the_period_one_orbit_is_reached_at_its_closed_form_phase(solver, e, fraction):
    """Started 1% off the take-off speed: after 200 impacts, each at phi and 1/f after the last (1e-9)."""
    low, high = period_n_threshold(1, e), period_doubling_threshold(1, e)
    gamma = low + fraction * (high - low)
    ball, ground, h0, v0 = _orbit_start(e, gamma, 1.01)
    result = _run(solver, ball, h0, v0, 215.0 / F, ground)
    impacts = impact_times(result)
    assert len(impacts) >= 210
    after = impacts[200:]
    phi = period_n_phase(1, e, gamma)
    assert np.max(np.abs(_phase(after, ground.phase) - phi)) < PHASE_TOLERANCE
    assert np.max(np.abs(np.diff(after) - 1.0 / F)) < TIME_TOLERANCE
    assert result.error_estimate < 1e-6 * R


@pytest.mark.parametrize("solver", SOLVERS)
def test_past_the_period_doubling_threshold_the_orbit_has_period_two(solver):
    e = 0.5
    gamma = 1.02 * period_doubling_threshold(1, e)
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=0.0)
    ground = Ground.sine(table_amplitude(gamma, F, G), F)
    intervals = np.diff(impact_times(_run(solver, ball, R + 0.05, 0.0, 40.0, ground)))[-40:]
    assert np.max(np.abs(intervals[:-1] + intervals[1:] - 2.0 / F)) < TIME_TOLERANCE  # two impacts per 2 periods
    assert np.min(np.abs(intervals - 1.0 / F)) > 1e-3  # and not one per period
    assert np.max(np.abs(intervals[2:] - intervals[:-2])) < TIME_TOLERANCE


def test_below_period_doubling_the_orbit_keeps_period_one():
    """Just below the threshold (0.97 Gamma_pd), started 1% off it, the orbit is period 1: the threshold is there."""
    e = 0.5
    gamma = 0.97 * period_doubling_threshold(1, e)
    ball, ground, h0, v0 = _orbit_start(e, gamma, 1.01)
    intervals = np.diff(impact_times(_exact(ball, h0, v0, 60.0, ground)))[-20:]
    assert np.max(np.abs(intervals - 1.0 / F)) < 1e-6


@pytest.mark.parametrize("e, fraction", [(0.5, 0.3), (0.8, 0.8)])
@pytest.mark.parametrize("solver", SOLVERS)
def test_the_first_fifty_impacts_off_the_orbit_are_the_truths(solver, e, fraction):
    low, high = period_n_threshold(1, e), period_doubling_threshold(1, e)
    gamma = low + fraction * (high - low)
    ball, ground, h0, v0 = _orbit_start(e, gamma, 1.05)
    truth = SineTableTruth(R, G, e, 0.0, ground.amplitude, F, ground.phase, h0, v0, 6.0, max_impacts=50)
    expected = np.array([float(t) for t, _, _ in truth.impacts])
    assert len(expected) == 50
    impacts = impact_times(_run(solver, ball, h0, v0, float(truth.t_known) + 1e-3, ground))[:50]
    assert len(impacts) == 50
    assert np.max(np.abs(impacts - expected)) < TIME_TOLERANCE


@pytest.mark.parametrize("solver", SOLVERS)
def test_below_one_and_gamma_one_the_ball_chatters_and_rides_for_good(solver):
    """e = 0.5, Gamma = 0.9 < min(1, Gamma_1): complete chattering, then the ride, from the truth's accumulation."""
    e, gamma = 0.5, 0.9
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=0.0)
    ground = Ground.sine(table_amplitude(gamma, F, G), F)
    result = _run(solver, ball, R + 0.05, 0.0, 2.0, ground)
    truth = SineTableTruth(R, G, e, 0.0, ground.amplitude, F, 0.0, R + 0.05, 0.0, 2.0)
    assert truth.accumulations and truth.rides[-1][1] is None  # the truth rides for good
    assert result.rest_time is not None
    assert abs(result.rest_time - float(truth.accumulations[-1])) < TIME_TOLERANCE
    assert not [event for event in result.events if event.time > result.rest_time]
    # riding: on the table, with it
    riding = result.t > result.rest_time
    assert np.max(np.abs(result.h[riding] - R - ground.position(result.t[riding]))) < 1e-15
    assert np.max(np.abs(result.v[riding] - ground.velocity(result.t[riding]))) < 1e-15


@pytest.mark.parametrize("solver", SOLVERS)
def test_between_one_and_gamma_one_every_ride_ends_where_the_table_outpulls_gravity(solver):
    """e = 0.5, Gamma = 1.02 (1 < Gamma < Gamma_1): rides, each left at the phase asin(1 / Gamma)."""
    e, gamma = 0.5, 1.02
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=0.0)
    ground = Ground.sine(table_amplitude(gamma, F, G), F)
    result = _run(solver, ball, R + 0.05, 0.0, 3.0, ground)
    departures = [event.time for event in result.events if event.kind == bb.EventKind.DEPARTURE]
    assert len(departures) >= 20
    expected = ride_end_phase(ground.amplitude, F, G)
    assert expected == pytest.approx(math.asin(1.0 / gamma), rel=1e-12)
    assert np.max(np.abs(_phase(departures, 0.0) - expected)) < PHASE_TOLERANCE
    truth = SineTableTruth(R, G, e, 0.0, ground.amplitude, F, 0.0, R + 0.05, 0.0, 0.8)  # 1e4 impacts a second
    truth_departures = np.array([float(end) for _, end in truth.rides if end is not None])
    assert len(truth_departures) >= 4
    assert np.max(np.abs(truth_departures - departures[:len(truth_departures)])) < TIME_TOLERANCE
    assert departures[len(truth_departures)] > 0.8


@pytest.mark.parametrize("e, gamma, t_end", [(0.5, 1.25, 1.0), (0.8, 0.9, 6.0), (0.8, 1.02, 0.8)])
@pytest.mark.parametrize("solver", SOLVERS)
def test_heights_follow_the_truth_within_the_estimate(solver, e, gamma, t_end):
    """Period-1 with complex multipliers, chattering to a ride for good, rides and chattering by turns."""
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=0.0)
    ground = Ground.sine(table_amplitude(gamma, F, G), F, 0.4)
    result = _run(solver, ball, R + 0.03, 0.1, t_end, ground, output_interval=0.01)
    truth = SineTableTruth(R, G, e, 0.0, ground.amplitude, F, 0.4, R + 0.03, 0.1, t_end)
    h_true = np.array([float(truth.state(t)[0]) for t in result.t])
    assert len(truth.impacts) > 10
    error = np.max(np.abs(result.h - h_true))
    assert error <= result.error_estimate < 1e-6 * R


def test_a_chaotic_run_says_its_error_grows_and_warns_once_past_the_promise():
    """e = 0.6, Gamma = 2.2: the truth's error grows 3e4-fold a second; the estimate follows it, above it."""
    ball = bb.Ball(R=R, g=G, contact="rigid", e=0.6, v_min=0.0)
    ground = Ground.sine(table_amplitude(2.2, F, G), F, 0.4)
    errors, estimates = [], []
    for t_end in (1.0, 2.0):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = bb.simulate(ball, R + 0.03, 0.1, t_end, 0.01, solver="exact", ground=ground)
        truth = SineTableTruth(R, G, 0.6, 0.0, ground.amplitude, F, 0.4, R + 0.03, 0.1, t_end)
        errors.append(np.max(np.abs(result.h - [float(truth.state(t)[0]) for t in result.t])))
        estimates.append(result.error_estimate)
        warned = [w for w in caught if issubclass(w.category, bb.AccuracyWarning)]
        assert bool(warned) == (result.error_estimate > 1e-6 * max(np.max(np.abs(result.h)), R))
    assert errors[1] > 1e3 * errors[0]  # it is chaotic: the rounding grows
    assert all(error <= estimate <= 1e3 * error for error, estimate in zip(errors, estimates, strict=True))


def _grazing_runs():
    """The 100 grazing scenes (tests/table_scenes.py), each with its truth and the exact solver's run (cached)."""
    if not _GRAZING:
        for scene in grazing_family():
            bounces_before, truth, result, warned = grazing_run(scene, "exact")
            for name in ("bounces_before", "graze_time", "graze_depth"):
                scene.pop(name)
            _GRAZING.append((scene, bounces_before, truth, result, warned))
    return _GRAZING


_GRAZING: list = []


def _resolvedimpact_times(truth, scene):
    """The truth's impacts but those inside chattering that the solver sums.

    It sums the bounces after a rebound rising less than ZENO_APEX R = 2^-40 R above the table: an impact is
    resolved where the rebound before it rose more than twice that (or where the table pulled away from it).
    """
    ground = Ground.sine(scene["amplitude"], scene["frequency"], scene["phase"])
    kept, apex_before = [], math.inf
    for t, _, v_after in truth.impacts:
        t = float(t)
        if apex_before > 2.0 * 2.0**-40 * scene["R"]:
            kept.append(t)
        relative, pull = float(v_after) - ground.velocity(t), scene["g"] + ground.acceleration(t)
        apex_before = relative * relative / (2.0 * pull) if pull > 0.0 else math.inf
    return np.array(kept)


@pytest.mark.slow
def test_no_grazing_impact_is_missed():
    """100 scenes whose impact number k grazes (the ball crossing 1e-10 to 1e-5 m into the table, or missing it)."""
    lost, extra, silent = [], [], []
    for number, (scene, _, truth, result, warned) in enumerate(_grazing_runs()):
        every = np.array([float(t) for t, _, _ in truth.impacts])
        impacts = impact_times(result)
        nearest = np.min(np.abs(impacts[:, None] - every[None, :]), axis=1) if len(every) else np.full(len(impacts),
                                                                                                     np.inf)
        if np.any(nearest > 1e-7):
            extra.append((number, impacts[nearest > 1e-7][:3]))
        resolved = _resolvedimpact_times(truth, scene)
        found = np.min(np.abs(resolved[:, None] - impacts[None, :]), axis=1) if len(impacts) else \
            np.full(len(resolved), np.inf)
        if np.any(found > 1e-7):
            lost.append((number, resolved[found > 1e-7][:3]))
        h_true = np.array([float(truth.state(t)[0]) for t in result.t])
        error = np.max(np.abs(result.h - h_true))
        if error > result.error_estimate or (error > 1e-6 * max(np.max(np.abs(result.h)), scene["R"]) and not warned):
            silent.append((number, error, result.error_estimate))
    assert not lost and not extra and not silent, (lost, extra, silent)
    grazes = sum(1 for _, k, truth, *_ in _grazing_runs() if len(truth.impacts) > k)
    assert grazes >= 70  # most of the family does graze (the rest miss by a hair)


@pytest.mark.slow
def test_a_table_through_the_sine_finds_the_same_grazingimpact_times():
    """The family's deeper grazes on a spline through the table's positions every 2e-5 s (its own root search:
    pieces certified in numpy, a cubic solved exactly where not): the truth's impacts up to the graze, none lost."""
    checked = 0
    for scene in grazing_family()[:40]:
        if not scene.pop("graze_depth") > 1e-8:
            continue
        scene.pop("graze_time")
        graze = scene.pop("bounces_before") + 1  # the graze's number: after it the spline's 1e-13 m are amplified
        truth = SineTableTruth(**scene)
        times = np.arange(0.0, scene["t_end"] + 4e-5, 2e-5)
        sine = Ground.sine(scene["amplitude"], scene["frequency"], scene["phase"])
        table = Ground.table(times, sine.position(times))
        ball = bb.Ball(R=scene["R"], g=scene["g"], contact="rigid", e=scene["e"], v_min=scene["v_min"])
        result = _exact(ball, scene["h0"], scene["v0"], scene["t_end"], table, output_interval=scene["t_end"] / 100)
        expected, impacts = np.array([float(t) for t, _, _ in truth.impacts[:graze]]), impact_times(result)[:graze]
        assert len(expected) == graze and len(impacts) == graze
        assert np.max(np.abs(impacts - expected)) < 1e-6
        checked += 1
    assert checked >= 10
