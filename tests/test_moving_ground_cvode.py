"""The rigid ball on a vibrating table through CVODE: both engines and the stepping API against the mpmath truth.

The CVODE engines integrate the flight in the ground's frame (the ground's acceleration a load of its own) and
search each step on the exact flow for the touch, certified (equations.flight_touch): the same truth
(tests/table_truth.py, mpmath from the equations alone) and the same closed forms (tests/closed_forms.py) as the
exact solver's tests (tests/test_moving_ground.py), with the engines bit for bit alike.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import bouncingball as bb
from bouncingball import Ground
from bouncingball.solvers.integrator import BallIntegrator
from bouncingball.solvers.phase_machine.settings import CvodeSettings
from closed_forms import (
    period_doubling_threshold,
    period_n_phase,
    period_n_takeoff_speed,
    period_n_threshold,
    ride_end_phase,
    table_amplitude,
)
from table_scenes import grazing_family
from table_truth import SineTableTruth

G, F, R = 9.81, 10.0, 0.01  # gravity [m/s2], the table's frequency [Hz], the ball's radius [m]
W = 2.0 * math.pi * F
PHASE_TOLERANCE, TIME_TOLERANCE = 1e-9, 1e-9  # rad, s: issue 44's


def _cvode(ball, h0, v0, t_end, ground, output_interval=1e-3, engine="compiled"):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an AccuracyWarning would be a broken promise here
        return bb.simulate(ball, h0, v0, t_end, output_interval, solver="cvode", ground=ground, engine=engine)


def _impacts(result):
    return np.array([event.time for event in result.events if event.kind == bb.EventKind.IMPACT])


def _phase(t, phase):
    return np.mod(W * np.asarray(t) + phase, 2.0 * math.pi)


def _orbit_start(e, gamma, speed_factor):
    """(ball, ground, h0, v0): on the period-1 orbit's take-off point at t = 0, speed_factor times its speed."""
    phi = period_n_phase(1, e, gamma)
    ground = Ground.sine(table_amplitude(gamma, F, G), F, phi)
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=0.0)
    h0 = R + ground.position(0.0)
    h0 = math.nextafter(h0, math.inf) if h0 - R < ground.position(0.0) else h0  # on the table, not a rounding into it
    return ball, ground, h0, speed_factor * period_n_takeoff_speed(1, F, G)


@pytest.mark.parametrize("e", [0.5, 0.8])
@pytest.mark.parametrize("fraction", [0.3, 0.8])
def test_the_period_one_orbit_is_reached_at_its_closed_form_phase(e, fraction):
    """Started 1% off the take-off speed: after 200 impacts, each at phi and 1/f after the last (1e-9)."""
    low, high = period_n_threshold(1, e), period_doubling_threshold(1, e)
    gamma = low + fraction * (high - low)
    ball, ground, h0, v0 = _orbit_start(e, gamma, 1.01)
    result = _cvode(ball, h0, v0, 215.0 / F, ground)
    impacts = _impacts(result)
    assert len(impacts) >= 210
    after = impacts[200:]
    phi = period_n_phase(1, e, gamma)
    assert np.max(np.abs(_phase(after, ground.phase) - phi)) < PHASE_TOLERANCE
    assert np.max(np.abs(np.diff(after) - 1.0 / F)) < TIME_TOLERANCE
    assert result.error_estimate < 1e-6 * R


def test_past_the_period_doubling_threshold_the_orbit_has_period_two():
    e = 0.5
    gamma = 1.02 * period_doubling_threshold(1, e)
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=0.0)
    ground = Ground.sine(table_amplitude(gamma, F, G), F)
    intervals = np.diff(_impacts(_cvode(ball, R + 0.05, 0.0, 40.0, ground, 1e-2)))[-40:]
    assert np.max(np.abs(intervals[:-1] + intervals[1:] - 2.0 / F)) < TIME_TOLERANCE  # two impacts per 2 periods
    assert np.min(np.abs(intervals - 1.0 / F)) > 1e-3  # and not one per period


@pytest.mark.parametrize("e, fraction", [(0.5, 0.3), (0.8, 0.8)])
def test_the_first_fifty_impacts_off_the_orbit_are_the_truths(e, fraction):
    low, high = period_n_threshold(1, e), period_doubling_threshold(1, e)
    gamma = low + fraction * (high - low)
    ball, ground, h0, v0 = _orbit_start(e, gamma, 1.05)
    truth = SineTableTruth(R, G, e, 0.0, ground.amplitude, F, ground.phase, h0, v0, 6.0, max_impacts=50)
    expected = np.array([float(t) for t, _, _ in truth.impacts])
    assert len(expected) == 50
    impacts = _impacts(_cvode(ball, h0, v0, float(truth.t_known) + 1e-3, ground))[:50]
    assert len(impacts) == 50
    assert np.max(np.abs(impacts - expected)) < TIME_TOLERANCE


def test_below_one_and_gamma_one_the_ball_chatters_and_rides_for_good():
    """e = 0.5, Gamma = 0.9 < min(1, Gamma_1): complete chattering, then the ride, from the truth's accumulation."""
    e, gamma = 0.5, 0.9
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=0.0)
    ground = Ground.sine(table_amplitude(gamma, F, G), F)
    result = _cvode(ball, R + 0.05, 0.0, 2.0, ground)
    truth = SineTableTruth(R, G, e, 0.0, ground.amplitude, F, 0.0, R + 0.05, 0.0, 2.0)
    assert truth.accumulations and truth.rides[-1][1] is None  # the truth rides for good
    assert result.rest_time is not None
    assert abs(result.rest_time - float(truth.accumulations[-1])) < TIME_TOLERANCE
    assert not [event for event in result.events if event.time > result.rest_time]
    riding = result.t > result.rest_time  # on the table, with it
    assert np.max(np.abs(result.h[riding] - R - ground.position(result.t[riding]))) < 1e-15
    assert np.max(np.abs(result.v[riding] - ground.velocity(result.t[riding]))) < 1e-15


def test_between_one_and_gamma_one_every_ride_ends_where_the_table_outpulls_gravity():
    """e = 0.5, Gamma = 1.02 (1 < Gamma < Gamma_1): rides, each left at the phase asin(1 / Gamma)."""
    e, gamma = 0.5, 1.02
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=0.0)
    ground = Ground.sine(table_amplitude(gamma, F, G), F)
    result = _cvode(ball, R + 0.05, 0.0, 3.0, ground)
    departures = [event.time for event in result.events if event.kind == bb.EventKind.DEPARTURE]
    assert len(departures) >= 20
    assert np.max(np.abs(_phase(departures, 0.0) - ride_end_phase(ground.amplitude, F, G))) < PHASE_TOLERANCE
    truth = SineTableTruth(R, G, e, 0.0, ground.amplitude, F, 0.0, R + 0.05, 0.0, 0.8)
    truth_departures = np.array([float(end) for _, end in truth.rides if end is not None])
    assert len(truth_departures) >= 4
    assert np.max(np.abs(truth_departures - departures[:len(truth_departures)])) < TIME_TOLERANCE


@pytest.mark.parametrize("e, gamma, t_end", [(0.5, 1.25, 1.0), (0.8, 0.9, 6.0), (0.8, 1.02, 0.8)])
def test_heights_follow_the_truth_within_the_estimate(e, gamma, t_end):
    """Period-1 with complex multipliers, chattering to a ride for good, rides and chattering by turns."""
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=0.0)
    ground = Ground.sine(table_amplitude(gamma, F, G), F, 0.4)
    result = _cvode(ball, R + 0.03, 0.1, t_end, ground, output_interval=0.01)
    truth = SineTableTruth(R, G, e, 0.0, ground.amplitude, F, 0.4, R + 0.03, 0.1, t_end)
    h_true = np.array([float(truth.state(t)[0]) for t in result.t])
    assert len(truth.impacts) > 10
    error = np.max(np.abs(result.h - h_true))
    assert error <= result.error_estimate < 1e-6 * R


def test_both_engines_and_the_stepping_api_agree_bit_for_bit():
    """The scikit-sundae engine runs the same machine interpreted: the same events and heights, to the bit; the
    stepping API (advance) the same impacts within the promise, and its two engines alike to the bit."""
    ball, ground, h0, v0 = _orbit_start(0.5, 1.25, 1.05)
    interpreted, compiled = (_cvode(ball, h0, v0, 1.5, ground, 1e-2, engine) for engine in ("sksundae", "compiled"))
    assert interpreted.events == compiled.events and len(compiled.events) >= 14
    assert np.array_equal(interpreted.h, compiled.h) and np.array_equal(interpreted.v, compiled.v)
    stepped = {}
    for engine in ("sksundae", "compiled"):
        integrator = BallIntegrator(ball, h0, v0, settings=CvodeSettings(engine=engine), ground=ground)
        events, heights = [], []
        for t in np.arange(1, 151) * 1e-2:
            events += integrator.advance(float(t))
            heights.append(integrator.h)
        integrator.close()
        stepped[engine] = (events, heights)
    assert stepped["sksundae"] == stepped["compiled"]
    events, heights = stepped["compiled"]
    assert [event.kind for event in events] == [event.kind for event in compiled.events]
    assert max(abs(a.time - b.time) for a, b in zip(events, compiled.events, strict=True)) < TIME_TOLERANCE
    assert np.max(np.abs(np.array(heights) - compiled.h[1:])) < 1e-6 * R


def test_what_the_cvode_engines_do_not_take_on_a_vibrating_ground_is_refused_by_name():
    ground = Ground.sine(0.001, 10.0)
    with pytest.raises(ValueError, match="contact_law = 'linear'.*exact"):
        bb.simulate(bb.Ball(), 0.5, 0.0, 1.0, 0.01, solver="cvode", ground=ground)
    table = Ground.table([0.0, 0.5, 1.0, 1.5, 2.0], [0.0, 0.001, 0.0, -0.001, 0.0])
    with pytest.raises(ValueError, match="ground = ground through 5 points.*solver='exact'"):
        bb.simulate(bb.Ball(contact="rigid"), 0.5, 0.0, 1.0, 0.01, solver="cvode", ground=table)
    with pytest.raises(ValueError, match="F_ext table is not allowed"):
        bb.simulate(bb.Ball(contact="rigid"), 0.5, 0.0, 1.0, 0.01, solver="cvode", ground=ground,
                    F_ext=([0.0, 0.5], [0.0, 1.0]))
    with pytest.raises(ValueError, match="solver = 'scipy'"):
        bb.simulate(bb.Ball(), 0.5, 0.0, 1.0, 0.01, solver="scipy", ground=ground)
    with pytest.raises(ValueError, match="h0 = 0.009 m .* R \\+ s\\(t0\\)"):
        BallIntegrator(bb.Ball(contact="rigid", R=0.01), 0.009, 0.0, ground=ground)
    integrator = BallIntegrator(bb.Ball(contact="rigid", R=0.01), 0.5, 0.0, ground=ground)
    with pytest.raises(ValueError, match="set_state is not allowed on ground"):
        integrator.set_state(integrator.get_state())
    integrator.close()


@pytest.mark.slow
def test_no_grazing_impact_is_missed_unsaid():
    """The exact solver's 100 grazing scenes (tests/table_scenes.py; impact k + 1 grazes 1e-10 to 1e-5 m deep or
    misses by up to 1e-6 m): every impact up to the graze the truth's, or the run warned; no height past the promise
    unwarned. CVODE's state is off by ~1e-12 to 1e-9 m there: a graze that error could turn the other way is not
    decided and warns (measured: 4 of 100 warned, the 2 that lost the graze among them). The error estimate is
    above the true error in every scene (measured: 100 of 100; within 1000x in 99, every unwarned one within 303x;
    median 2.1x)."""
    lost, unsaid, warned_count, ratios = [], [], 0, []
    for number, scene in enumerate(grazing_family()):
        bounces_before = scene.pop("bounces_before")
        scene.pop("graze_time"), scene.pop("graze_depth")
        truth = SineTableTruth(**scene)
        ball = bb.Ball(R=scene["R"], g=scene["g"], contact="rigid", e=scene["e"], v_min=scene["v_min"])
        ground = Ground.sine(scene["amplitude"], scene["frequency"], scene["phase"])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = bb.simulate(ball, scene["h0"], scene["v0"], scene["t_end"], scene["t_end"] / 400,
                                 solver="cvode", ground=ground, engine="compiled")
        warned = any(issubclass(w.category, bb.AccuracyWarning) for w in caught)
        warned_count += warned
        resolved = np.array([float(t) for t, _, _ in truth.impacts])[:bounces_before + 1]
        impacts = _impacts(result)
        found = np.min(np.abs(resolved[:, None] - impacts[None, :]), axis=1) if len(impacts) else \
            np.full(len(resolved), np.inf)
        if np.any(found > 1e-7) and not warned:
            lost.append((number, resolved[found > 1e-7][:3]))
        h_true = np.array([float(truth.state(t)[0]) for t in result.t])
        error = np.max(np.abs(result.h - h_true))
        if error > result.error_estimate or (error > 1e-6 * max(np.max(np.abs(result.h)), scene["R"]) and not warned):
            unsaid.append((number, error, result.error_estimate))
        ratios.append(result.error_estimate / max(error, 1e-300))
    assert not lost and not unsaid, (lost, unsaid)
    assert warned_count <= 10  # the undecided grazes, not every run
    assert sum(ratio <= 1e3 for ratio in ratios) >= 95
