"""A ball on a vibrating table through CVODE: what is its own beside the exact solver's tests.

tests/test_moving_ground.py holds both solvers to the closed forms (tests/closed_forms.py) and the mpmath truth
(tests/table_truth.py). Here: the two engines and the stepping API bit for bit alike, what CVODE refuses on a
moving ground, and the grazing family, where CVODE's own error decides what a graze does.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest

import bouncingball as bb
from bouncingball import Ground
from bouncingball.solvers.integrator import BallIntegrator
from bouncingball.solvers.phase_machine.settings import CvodeSettings
from table_runs import grazing_run, impact_times, orbit_start
from table_scenes import grazing_family

G, F, R = 9.81, 10.0, 0.01  # gravity [m/s2], the table's frequency [Hz], the ball's radius [m]
TIME_TOLERANCE = 1e-9  # s: issue 44's


def _cvode(ball, h0, v0, t_end, ground, output_interval, engine):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an AccuracyWarning would be a broken promise here
        return bb.simulate(ball, h0, v0, t_end, output_interval, solver="cvode", ground=ground, engine=engine)


def _compliant_scene(contact, b, **law):
    """(ball, ground, h0, v0): a compliant ball dropped 5 cm onto a table at Gamma 1.2 (thrown at times)."""
    ground = Ground.sine(1.2 * G / (2.0 * math.pi * F) ** 2, F, 0.3)
    ball = bb.Ball(m=1.0, k=law.pop("k", 1e5), b=b, R=R, g=G, contact=contact, **law)
    return ball, ground, R + 0.05 + ground.position(0.0), 0.0


@pytest.mark.parametrize("scene", [lambda: orbit_start(0.5, 1.25, 1.05, F, G, R),
                                   lambda: _compliant_scene("linear", 20.0),
                                   lambda: _compliant_scene("linear-no-pull", 200.0),
                                   lambda: _compliant_scene("hunt-crossley", 10.0, k=3e6, n=1.5, alpha=0.3)],
                         ids=["rigid", "linear", "no-pull", "hunt-crossley"])
def test_both_engines_and_the_stepping_api_agree_bit_for_bit(scene):
    """The scikit-sundae engine runs the same machine interpreted: the same events and heights, to the bit; the
    stepping API (advance) the same events within the promise, and its two engines alike to the bit."""
    ball, ground, h0, v0 = scene()
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
    with pytest.raises(ValueError, match="contact = 'hunt-crossley' is not allowed on a moving ground .* with the "
                                         "exact solver.*solver='cvode'"):
        bb.simulate(bb.Ball(contact="hunt-crossley"), 0.5, 0.0, 1.0, 0.01, solver="exact", ground=ground)
    with pytest.raises(ValueError, match="b = 0.0 N s/m is not allowed .* near resonance"):  # k / m = w^2, undamped
        BallIntegrator(bb.Ball(k=(2.0 * math.pi * 10.0) ** 2, b=0.0), 0.5, 0.0, ground=ground)
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
    state = integrator.get_state()
    with pytest.raises(ValueError, match=r"state gap = 0.3 m is not allowed with h = 0.5 m: R \+ gap \+ s\(t\) must"):
        integrator.set_state(dataclasses.replace(state, gap=0.3))
    assert integrator.get_state() == state  # nothing changed
    integrator.close()


@pytest.mark.parametrize("scene", [lambda: orbit_start(0.5, 1.25, 1.05, F, G, R),
                                   lambda: _compliant_scene("linear", 20.0),
                                   lambda: _compliant_scene("linear-no-pull", 200.0),
                                   lambda: _compliant_scene("hunt-crossley", 10.0, k=3e6, n=1.5, alpha=0.3),
                                   lambda: (bb.Ball(R=R, g=G, contact="rigid", e=0.5, v_min=0.0),
                                            *_compliant_scene("linear", 20.0)[1:])],
                         ids=["rigid", "linear", "no-pull", "hunt-crossley", "rigid-chattering"])
def test_a_state_restored_on_a_vibrating_table_continues_bit_for_bit(scene):
    """get_state at every 13th of 150 advances, set_state in a fresh integrator: every later h, v, impact count and
    error estimate to the bit. The state is in the world's frame (h, v), its gap and restart point the machine's, on
    the integrator's own ground. A rigid ride's end was once a bit off after a restore (its root computed from the
    ride's start, which the restart point does not keep); sine_ride_end now gives the same double from any start."""
    ball, ground, h0, v0 = scene()
    settings = CvodeSettings(engine="compiled")
    times = np.arange(1, 151) * 1e-2
    run, seen, states = BallIntegrator(ball, h0, v0, settings=settings, ground=ground), [], {}
    for i, t in enumerate(times):
        run.advance(float(t))
        seen.append((run.h, run.v, run.impacts, run.error_estimate_at_t))
        if i % 13 == 5:
            states[i] = run.get_state()
    run.close()
    for i, state in states.items():
        restored = BallIntegrator(ball, h0, v0, settings=settings, ground=ground)
        restored.set_state(state)
        for t, wanted in zip(times[i + 1:], seen[i + 1:], strict=True):
            restored.advance(float(t))
            assert (restored.h, restored.v, restored.impacts, restored.error_estimate_at_t) == wanted, (times[i], t)
        restored.close()


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
        bounces_before, truth, result, warned = grazing_run(scene, "cvode", engine="compiled")
        warned_count += warned
        resolved = np.array([float(t) for t, _, _ in truth.impacts])[:bounces_before + 1]
        impacts = impact_times(result)
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


def test_a_force_changed_during_a_ride_acts_in_the_tables_frame():
    """The stepping API on a table below its mean (s < 0, h < R): F_ext changes are taken there, not refused as a
    ball inside the ground; a ride whose table never outpulls g - F_ext/m goes on, one under twice the weight lifts."""
    ball = bb.Ball(R=R, g=G, contact="rigid", e=0.5, v_min=0.0)
    ground = Ground.sine(0.8 * G / (2.0 * math.pi * F) ** 2, F)  # Gamma 0.8: it chatters down and rides for good
    integrator = BallIntegrator(ball, R + 0.02, 0.0, settings=CvodeSettings(engine="compiled"), ground=ground)
    integrator.advance(1.275)  # riding, the table at its lowest (s = -A) at t = 1.275 s
    assert integrator.rest_time is not None and integrator.h < R
    integrator.F_ext = 0.1 * G  # a tenth of the weight: A w^2 / (g - F_ext / m) = 0.89, still pressed on it
    integrator.advance(1.5)
    assert integrator.h == pytest.approx(R + ground.position(1.5), abs=1e-12)
    integrator.F_ext = 2.0 * G  # twice the weight: lifted off
    integrator.advance(1.6)
    assert integrator.h > R + ground.position(1.6) + 1e-3 and integrator.rest_time is None
    integrator.close()


def test_searches_that_cannot_end_on_their_own_run_to_the_end_of_the_run():
    """An undamped contact pressed into the table that never reaches the surface (its energy never proves it: the
    search looks as far as the run, then is decided again), and a weightless no-pull ball's free spell (whose
    searches have no gravity to end them): both once stopped after 1e6 steps with a RuntimeError (review)."""
    w = 2.0 * math.pi * 10.0
    k, g, radius = (3.0 * w) ** 2, 9.81, 0.06
    ground = Ground.sine(4.8 * g / k, 10.0)
    ball = bb.Ball(m=1.0, k=k, b=0.0, R=radius, g=g)
    h0, v0 = radius + ground.position(0.0) - 2.761e-4, ground.velocity(0.0) + 0.04163
    exact = bb.simulate(ball, h0, v0, 0.5, 0.01, solver="exact", ground=ground)
    cvode = _cvode(ball, h0, v0, 0.5, ground, 0.01, "compiled")
    assert exact.events == cvode.events == [] and np.max(np.abs(cvode.h - exact.h)) < 1e-12
    integrator = BallIntegrator(ball, h0, v0, ground=ground)
    heights = []
    for t in np.arange(1, 51) * 0.01:
        integrator.advance(float(t))
        heights.append(integrator.h)
    integrator.close()
    assert np.max(np.abs(np.array(heights) - exact.h[1:])) < 1e-12
    weightless, ground = bb.Ball(g=0.0, contact="linear-no-pull", b=10.0), Ground.sine(1e-3, 20.0)
    exact = bb.simulate(weightless, 0.07, -1.0, 0.1, 0.01, solver="exact", ground=ground)
    cvode = _cvode(weightless, 0.07, -1.0, 0.1, ground, 0.01, "compiled")
    assert [event.kind for event in cvode.events] == [event.kind for event in exact.events]
    # its estimate once 0.06 m and a warning: the run ends where s'' = 0, and a flight's frame there scaled by the
    # relative load's apex (~1e14 m) rather than by what the world's parabola can reach (phases.frame)
    assert len(cvode.events) == 3 and np.max(np.abs(cvode.h - exact.h)) <= cvode.error_estimate < 1e-11


def test_a_weightless_flight_away_from_the_table_is_within_its_estimate():
    """g = 0: the ball flies h0 + v0 t away from a vibrating table it never meets (its flight in the table's frame
    integrated by CVODE, the table's acceleration its load). Its frame is its start's (max(|x|, R)), which it
    outgrows 40-fold: CVODE's error inside the phase is charged relative to the height reached (the estimate was
    4x below the true error before: review). Measured: the estimate 2.0x the error."""
    from fractions import Fraction

    ground = Ground.sine(0.000499, 11.7, 3.03)
    h0, v0 = 0.01159, 0.421
    result = _cvode(bb.Ball(R=0.01, g=0.0), h0, v0, 1.17, ground, 1.17 / 200, "compiled")
    assert result.events == []
    exact = [float(Fraction(h0) + Fraction(v0) * Fraction(float(t))) for t in result.t]  # h0 + v0 t, rounded once
    error = float(np.max(np.abs(result.h - np.array(exact))))
    assert 1e-13 < error <= result.error_estimate < 10.0 * error
