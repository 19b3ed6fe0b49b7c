"""The run's largest Lyapunov exponent (solvers.lyapunov), from the matrices its error estimate carries.

Truths: the closed form of a period-1 orbit on a vibrating table whose multipliers are complex (both of modulus e,
Holmes 1982: the exponent is ln(e) per impact), and the mpmath truth (tests/table_truth.py, sharing no code with
the solver) run twice from starts 2^-50 m apart: its separation is the perturbation the solver's tangent carries.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import bouncingball as bb
from bouncingball import Ground
from bouncingball.solvers.exact import ExactSolution
from closed_forms import (
    period_doubling_threshold,
    period_n_phase,
    period_n_takeoff_speed,
    period_n_threshold,
    table_amplitude,
)
from table_truth import SineTableTruth

G, F, R, E = 9.81, 10.0, 0.01, 0.5  # gravity [m/s2], the table's frequency [Hz], the ball's radius [m], restitution
CHAOTIC = 2.5  # Gamma: a ball dropped from 5 cm above the table bounces chaotically (issue 46)


def _table_run(gamma, t_end, h0=None, v0=0.0, phase=0.0, output_interval=1e-2):
    ground = Ground.sine(table_amplitude(gamma, F, G), F, phase)
    ball = bb.Ball(R=R, g=G, contact="rigid", e=E, v_min=0.0)
    h0 = R + 0.05 if h0 is None else h0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", bb.AccuracyWarning)  # a chaotic run warns: the exponent is still its own
        return bb.simulate(ball, h0, v0, t_end, output_interval, solver="exact", ground=ground)


def test_at_a_period_one_orbit_with_complex_multipliers_the_exponent_is_ln_e_per_impact():
    gamma = 1.25
    low, high = period_n_threshold(1, E), period_doubling_threshold(1, E)
    assert low < gamma < high  # the stable period-1 orbit; its multipliers are complex here (|mu| = e)
    phi = period_n_phase(1, E, gamma)
    h0 = math.nextafter(R + table_amplitude(gamma, F, G) * math.sin(phi), math.inf)
    result = _table_run(gamma, 200.0, h0, 1.01 * period_n_takeoff_speed(1, F, G), phi, output_interval=0.1)
    exponent = result.lyapunov
    assert exponent.impacts == 2000 and exponent.duration == 200.0
    assert abs(exponent.per_impact - math.log(E)) < 1e-3
    assert abs(exponent.per_second - F * math.log(E)) < 1e-2  # one impact per table period


def test_a_chaotic_run_has_a_positive_exponent():
    exponent = _table_run(CHAOTIC, 60.0).lyapunov
    assert exponent.impacts >= 250 and exponent.per_impact > 0.1 and exponent.per_second > 0.5


@pytest.mark.parametrize("impacts", [10, 25])
def test_the_carried_perturbation_is_the_truths_separation(impacts):
    """Chaotic bouncing: the tangent through flights and moving-ground saltations against two truths 2^-50 m apart.

    Compared mid-flight after the impacts, where both truths are in the same flight; the separation, grown
    1e2-1e6-fold, is still small enough to be linear (the difference between the two is its second order).
    """
    ground = Ground.sine(table_amplitude(CHAOTIC, F, G), F)
    ball = bb.Ball(R=R, g=G, contact="rigid", e=E, v_min=0.0)
    h0, delta = R + 0.05, 2.0**-50
    assert (h0 + delta) - h0 == delta
    times = [event.time for event in ExactSolution(ball, h0, 0.0, 0.0, 10.0, ground=ground).events]
    t_mid = 0.5 * (times[impacts - 1] + times[impacts])
    tangent = ExactSolution(ball, h0, 0.0, 0.0, t_mid, ground=ground).rounding.tangent
    carried = delta * math.exp(tangent.log_growth) * np.array([tangent.dh, tangent.dv])
    truths = [SineTableTruth(R, G, E, 0.0, ground.amplitude, F, 0.0, start, 0.0, t_mid) for start in (h0, h0 + delta)]
    assert [len(truth.impacts) for truth in truths] == [impacts, impacts]
    (h_a, v_a), (h_b, v_b) = (truth.state(t_mid) for truth in truths)
    separation = np.array([float(h_b - h_a), float(v_b - v_a)])
    assert np.linalg.norm(separation) > 1e2 * delta
    assert np.all(np.abs(carried - separation) <= 1e-6 * np.abs(separation))


def test_a_run_that_ends_riding_has_forgotten_its_start():
    """Below one g the ball chatters onto the table and rides it for good: its end no longer depends on its start."""
    result = _table_run(0.9, 5.0)
    exponent = result.lyapunov
    assert result.rest_time is not None and exponent.forgotten == 1
    assert exponent.per_impact == -math.inf and exponent.per_second == -math.inf


def test_a_chaotic_run_that_rode_is_measured_on_its_flights_since():
    """Gamma = 5: chaotic bouncing interrupted by a ride; measured from the ride's end, the exponent is positive."""
    ground = Ground.sine(table_amplitude(5.0, F, G), F, 0.3)
    ball = bb.Ball(R=R, g=G, contact="rigid", e=E, v_min=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", bb.AccuracyWarning)
        result = bb.simulate(ball, R + 0.01, 0.0, 20.0, 1e-3, solver="exact", ground=ground)
    exponent = result.lyapunov
    last_ride_end = [event.time for event in result.events if event.kind == bb.EventKind.DEPARTURE][-1]
    assert exponent.forgotten >= 1 and exponent.since == last_ride_end
    assert exponent.impacts == sum(event.kind == bb.EventKind.IMPACT and event.time > last_ride_end
                                   for event in result.events) >= 20
    assert exponent.per_impact > 0.1


def test_a_rest_on_a_still_ground_forgets_the_start_too():
    result = bb.simulate(bb.Ball(contact="rigid", e=0.8, v_min=0.01), 2.0, 0.0, 8.0, solver="exact")
    assert result.rest_time is not None and result.lyapunov.forgotten == 1
    assert result.lyapunov.per_impact == -math.inf


def test_a_run_with_few_impacts_is_too_short_to_say():
    result = bb.simulate(bb.Ball(), 2.0, 0.0, 2.0, solver="exact")
    assert 0 < result.impacts < 20
    assert math.isnan(result.lyapunov.per_impact) and math.isnan(result.lyapunov.per_second)


def test_the_solvers_that_do_not_compute_it_say_none():
    assert bb.simulate(bb.Ball(), 2.0, 0.0, 1.0, solver="cvode").lyapunov is None


def test_the_chaotic_run_warns_from_when_its_true_error_passes_the_promise_within_a_factor_two():
    """Issue 46's chaotic run on the exact solver: its warning's date against its true error's, from the truth."""
    with pytest.warns(bb.AccuracyWarning, match=r"past the promise of 1e-06 from t = ([0-9.]+) s") as caught:
        result = bb.simulate(bb.Ball(R=R, g=G, contact="rigid", e=E, v_min=0.0), R + 0.05, 0.0, 60.0, 1e-2,
                             solver="exact", ground=Ground.sine(table_amplitude(CHAOTIC, F, G), F))
    warned_from = float(str(caught[0].message).split("from t = ")[1].split(" s")[0])
    truth = SineTableTruth(R, G, E, 0.0, result.ground.amplitude, F, 0.0, R + 0.05, 0.0, 2.0 * warned_from)
    within = result.t <= 2.0 * warned_from
    error = np.array([abs(float(truth.state(t)[0]) - h) for t, h in zip(result.t[within], result.h[within],
                                                                        strict=True)])
    scale = max(float(np.max(np.abs(result.h))), R)
    passes = result.t[within][np.argmax(error > 1e-6 * scale)]
    assert np.any(error > 1e-6 * scale) and warned_from / 2.0 <= passes <= 2.0 * warned_from
