"""The rigid contact law against its independent mpmath truth (tests/rigid_truth.py): bounces, heights, Zeno times.

The Done-when of the rigid law: the ideal model (v_min = 0) to 1e-9 m and its Zeno time to 1e-12 s; the
Reference-FMUs' rule (v_min = 0.1 m/s) to its exact solution; in simulate (both CVODE engines and the
exact solver) and the stepping API.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import mpmath
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import bouncingball as bb
from bouncingball.solvers.cvode import BallIntegrator, CvodeSettings
from bouncingball.solvers.forcing import ForceTable
from rigid_truth import RigidTruth

R, G = 0.06, 9.81
# (e, v_min, drop above R [m], v0 [m/s]): the Reference-FMUs' ball (h0 = 1 m over R), ideal and with their
# v_min; no bounce; elastic for ever; thrown up; a tiny grazing start; on R moving down (an impact at t = 0)
CASES = [(0.7, 0.0, 1.0, 0.0), (0.7, 0.1, 1.0, 0.0), (0.0, 0.0, 1.0, 0.0), (1.0, 0.0, 1.0, 0.0),
         (0.95, 0.0, 0.3, 2.0), (0.5, 0.0, 1e-9, -1e-3), (0.7, 0.0, 0.0, -1.0), (0.9, 0.5, 2.0, 0.0),
         (0.999, 0.0, 0.2, 0.0)]
SOLVERS = [("exact", None), ("cvode", "sksundae"), ("cvode", "compiled")]
T_END = 6.0
HEIGHT_TOLERANCE = 1e-9  # m
TIME_TOLERANCE = 1e-12  # s, the Zeno time's
EVENT_TOLERANCE = 1e-11  # s: CVODE's flights put an impact after 40 bounces 1.2e-12 s off


def _run(ball, h0, v0, solver, engine, t_end=T_END, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an AccuracyWarning here would be a broken promise
        if solver == "exact":
            return bb.simulate(ball, h0, v0, t_end, 1e-3, solver="exact", **options)
        return bb.simulate(ball, h0, v0, t_end, 1e-3, engine=engine, **options)


def test_the_truths_zeno_time_is_the_closed_form_of_the_reference_fmus_ball():
    """The truth's Zeno time, enumerated bounce by bounce, against t1 + 2 e v1 / (g (1 - e)) from the drop alone."""
    truth = RigidTruth(R, G, 0.7, 0.0, 1.0 + R, 0.0, 10.0)
    t1, v1 = math.sqrt(2.0 / G), math.sqrt(2.0 * G)
    assert float(truth.rest_time) == pytest.approx(t1 + 2.0 * 0.7 * v1 / (G * 0.3), rel=1e-15)
    assert float(truth.impacts[1][0] - truth.impacts[0][0]) == pytest.approx(2 * 0.7 * v1 / G, rel=1e-15)


@pytest.mark.parametrize("solver, engine", SOLVERS)
@pytest.mark.parametrize("e, v_min, drop, v0", CASES)
def test_simulate_follows_the_rigid_truth(e, v_min, drop, v0, solver, engine):
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=v_min)
    result = _run(ball, R + drop, v0, solver, engine)
    truth = RigidTruth(R, G, e, v_min, R + drop, v0, T_END)
    impacts = [(t, v) for t, v in truth.impacts if t <= T_END]
    assert [event.kind for event in result.events] == [bb.EventKind.IMPACT] * len(result.events)
    assert len(impacts) >= len(result.events) >= min(len(impacts), 1)
    # the bounces not taken one by one are summed: each too low to show at the heights' tolerance
    assert all(float(v) ** 2 / (2 * G) <= HEIGHT_TOLERANCE for _, v in impacts[len(result.events):])
    for event, (t, v) in zip(result.events, impacts[:len(result.events)], strict=True):
        assert abs(event.time - float(t)) <= EVENT_TOLERANCE, (event, float(t))
        assert abs(event.velocity - float(v)) <= 1e-9 * max(1.0, abs(float(v))), (event, float(v))
    error = np.max(np.abs(result.h - np.array(truth.heights(result.t))))
    assert error <= HEIGHT_TOLERANCE
    if truth.rest_time is None or truth.rest_time > T_END:
        assert result.rest_time is None
    else:
        assert abs(result.rest_time - float(truth.rest_time)) <= TIME_TOLERANCE
    if solver == "cvode":
        assert error <= result.error_estimate <= 1e-6 * (drop + R + v0 * v0 / (2 * G))


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_the_stepping_api_follows_the_rigid_truth_step_by_step(engine):
    """1 ms steps of advance, as an FMU's doStep takes them, through the Zeno point of the Reference-FMUs' ball."""
    ball = bb.Ball(R=R, g=G, contact="rigid", e=0.7)
    truth = RigidTruth(R, G, 0.7, 0.0, 1.0 + R, 0.0, 4.0)
    integrator = BallIntegrator(ball, 1.0 + R, 0.0, settings=CvodeSettings(engine=engine))
    events, worst = [], 0.0
    for t in np.arange(1, 4001) * 1e-3:
        events += integrator.advance(float(t))
        worst = max(worst, abs(integrator.h - float(truth.state(t)[0])))
    assert worst <= HEIGHT_TOLERANCE
    assert 0 < len(events) <= len(truth.impacts)
    pairs = zip(events, truth.impacts[:len(events)], strict=True)
    assert max(abs(event.time - float(t)) for event, (t, _) in pairs) <= EVENT_TOLERANCE
    assert abs(integrator.rest_time - float(truth.rest_time)) <= TIME_TOLERANCE
    assert integrator.h == R and integrator.v == 0.0


@pytest.mark.parametrize("solver, engine", SOLVERS)
def test_a_rigid_ball_at_rest_is_lifted_when_f_ext_exceeds_its_weight(solver, engine):
    """At rest on R until 0.5 s, then F_ext = 2 m g: it leaves R at once, at 0 m/s, and rises at g."""
    ball = bb.Ball(R=R, g=G, contact="rigid", e=0.7)
    result = _run(ball, R, 0.0, solver, engine, F_ext=ForceTable.of(([0.0, 0.5], [0.0, 2.0 * G])))
    rising = np.clip(result.t - 0.5, 0.0, None)
    assert np.max(np.abs(result.h - (R + 0.5 * G * rising**2))) <= 1e-12 * (1.0 + 0.5 * G * 5.5**2)
    assert [(event.kind, event.time, event.velocity) for event in result.events] == [
        (bb.EventKind.DEPARTURE, 0.5, 0.0)]


def test_a_rigid_ball_cannot_start_inside_the_ground():
    with pytest.raises(ValueError, match=r"h0 = 0\.05 m is not allowed: under the rigid contact law it must be >= R"):
        bb.simulate(bb.Ball(contact="rigid"), 0.05, 0.0, 1.0)


@pytest.mark.parametrize("field, value, message", [
    ("contact", "hertz", "contact = 'hertz' is not allowed: it must be one of linear, rigid"),
    ("e", 1.5, "e = 1.5 is not allowed: it must be in [0, 1]"),
    ("e", -0.1, "e = -0.1 is not allowed: it must be in [0, 1]"),
    ("v_min", -1.0, "v_min = -1.0 m/s is not allowed: it must be finite and >= 0"),
])
def test_the_rigid_laws_parameters_are_checked_by_name(field, value, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        bb.Ball(**{"contact": "rigid", field: value})


def test_the_linear_laws_parameters_are_those_of_before():
    """The seed's law is the default, and its machine tuple starts with the five parameters it always had."""
    ball = bb.Ball()
    assert ball.contact == "linear" and ball.parameters[:5] == (1.0, 1e4, 10.0, 0.06, 9.81)


REFERENCE_SCENE = ('description = "The Reference-FMUs ball"\ncontact = "rigid"\ne = 0.7\nv_min = 0.1\nh0 = 1.06\n'
                   't_end = 3.0\n')


def test_a_scene_file_chooses_the_rigid_law_and_run_reports_its_bounces(tmp_path, capsys):
    """The Reference-FMUs' ball (v_min = 0.1 m/s): 11 impacts, then at rest on R from the last (their model's)."""
    from bouncingball.cli import main

    scene = tmp_path / "reference.toml"
    scene.write_text(REFERENCE_SCENE)
    truth = RigidTruth(R, G, 0.7, 0.1, 1.06, 0.0, 3.0)
    assert main(["run", str(scene)]) == 0
    out = capsys.readouterr().out
    assert "rigid contact, e = 0.7, v_min = 0.1 m/s" in out
    assert f"events      {len(truth.impacts)} ({len(truth.impacts)} impacts, 0 departures)" in out
    assert f"at rest from t = {float(truth.rest_time):.12g} s" in out


def test_check_judges_a_file_against_a_rigid_scene_file(tmp_path):
    """A CSV of the truth's heights passes against the rigid scene file, and fails against its linear twin."""
    from bouncingball.check.judge import check_result

    scene = tmp_path / "reference.toml"
    scene.write_text(REFERENCE_SCENE)
    t = (np.arange(3001) * 1e-3).tolist()
    h = RigidTruth(R, G, 0.7, 0.1, 1.06, 0.0, 3.0).heights(t)
    result = tmp_path / "result.csv"
    result.write_text('"time","h"\n' + "".join(f"{ti!r},{hi!r}\n" for ti, hi in zip(t, h, strict=True)))
    passed = check_result(result, scene)
    assert passed.passed and passed.max_height_error <= 1e-12
    linear = tmp_path / "linear.toml"
    linear.write_text(REFERENCE_SCENE.replace('contact = "rigid"\ne = 0.7\nv_min = 0.1\n', ""))
    assert not check_result(result, linear).passed


def test_the_article_algorithm_refuses_the_rigid_law_by_name():
    """Its terminal events switch between the linear law's two modes: a rigid ball would fall through R."""
    with pytest.raises(ValueError, match="solver = 'scipy' is not allowed with contact = 'rigid'"):
        bb.simulate(bb.Ball(contact="rigid"), 1.0, 0.0, 1.0, solver="scipy")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(e=st.floats(0.0, 1.0), v_min=st.sampled_from([0.0, 0.0, 1e-3, 0.3]), log_drop=st.floats(-8.0, 4.0),
       v0=st.floats(-3.0, 3.0), solver=st.sampled_from(SOLVERS[:2]))
def test_the_rigid_law_follows_its_truth_over_six_decades_of_impact_speed(e, v_min, log_drop, v0, solver):
    """Drops from 1e-8 m to 1e4 m (impact speeds 4e-4 to 4e2 m/s), e from 0 to 1, thrown up or down."""
    drop = 10.0**log_drop
    ball = bb.Ball(R=R, g=G, contact="rigid", e=e, v_min=v_min)
    t_end = 2.0 * math.sqrt(2.0 * (drop + v0 * v0 / G) / G) + 1.0
    scale = drop + R + v0 * v0 / (2 * G)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = bb.simulate(ball, R + drop, v0, t_end, t_end / 500, solver=solver[0],
                             **({} if solver[1] is None else {"engine": solver[1]}))
    truth = RigidTruth(R, G, e, v_min, R + drop, v0, t_end)
    error = np.max(np.abs(result.h - np.array(truth.heights(result.t))))
    assert error <= 1e-6 * scale
    if solver[0] == "cvode":
        assert error <= result.error_estimate
    impacts = [(t, v) for t, v in truth.impacts if t <= t_end]
    assert len(impacts) >= len(result.events) >= min(len(impacts), 1)
    for event, (t, _) in zip(result.events, impacts[:len(result.events)], strict=True):
        assert abs(event.time - float(t)) <= 1e-9 * t_end


@pytest.mark.parametrize("solver, engine", SOLVERS)
@pytest.mark.parametrize("F_ext, t_end", [(20.0, 4.0), (G, 100.0)])
def test_a_lift_inside_the_summed_bounces_leaves_from_where_the_bounce_is(solver, engine, F_ext, t_end):
    """The Reference-FMUs' ball, F_ext set 5e-8 s after the impact from which its bounces are summed.

    The ball is taken on R while they last (below ZENO_APEX R), but it is rising there at 4.8e-7 m/s: lifted
    from rest instead, it was 1.4e-6 m low at 4 s under 20 N, and 4.8e-5 m at 100 s under F_ext = m g
    exactly (then it flies on at that speed), with status OK. The truth's bounce, then its exact flight.
    """
    truth = RigidTruth(R, G, 0.7, 0.0, 1.0 + R, 0.0, 10.0)
    t_lift = float(truth.impacts[42][0]) + 5e-8  # the 43rd impact: the last taken one by one
    h_lift, v_lift = truth.state(t_lift)
    assert 0.0 < v_lift and h_lift - R < 1e-13  # rising, lower than the summed bounces' resolution
    table = ForceTable.of(([0.0, t_lift], [0.0, F_ext]))
    result = _run(bb.Ball(R=R, g=G, contact="rigid", e=0.7), R + 1.0, 0.0, solver, engine, F_ext=table,
                  t_end=t_end)
    after = result.t > t_lift
    a = mpmath.mpf(F_ext) - mpmath.mpf(G)  # m = 1 kg
    expected = [float(h_lift + v_lift * s + a * s * s / 2) for s in (mpmath.mpf(float(t)) - t_lift
                                                                         for t in result.t[after])]
    assert np.max(np.abs(result.h[after] - expected)) <= 1e-9 * max(1.0, np.max(np.abs(expected)))
    assert result.h[-1] > R + 0.9 * float(v_lift) * (t_end - t_lift)


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_the_stepping_api_lifts_from_inside_the_summed_bounces_as_the_truth_does(engine):
    """F_ext = m g set inside the summed bounces between two advances: the ball flies on at its bounce's speed."""
    truth = RigidTruth(R, G, 0.7, 0.0, 1.0 + R, 0.0, 10.0)
    t_lift = float(truth.impacts[42][0]) + 5e-8
    h_lift, v_lift = truth.state(t_lift)
    integrator = BallIntegrator(bb.Ball(R=R, g=G, contact="rigid", e=0.7), 1.0 + R, 0.0,
                                settings=CvodeSettings(engine=engine))
    integrator.advance(t_lift)
    integrator.F_ext = G
    integrator.advance(t_lift + 100.0)
    # CVODE's 43 impacts are 1e-14 s off the truth's: at 1e-7 m/s each bounce's speed is off by g times that
    assert integrator.h == pytest.approx(float(h_lift + v_lift * 100), abs=HEIGHT_TOLERANCE)
    assert integrator.v == pytest.approx(float(v_lift), rel=1e-6) and integrator.mode == bb.Mode.FLIGHT


@pytest.mark.parametrize("restart", [True, False])
def test_a_state_taken_inside_the_summed_bounces_keeps_them(restart):
    """get_state/set_state (an FMU's state) inside the summed bounces: its rest time, and a lift from the bounce."""
    ball = bb.Ball(R=R, g=G, contact="rigid", e=0.7)
    truth = RigidTruth(R, G, 0.7, 0.0, 1.0 + R, 0.0, 10.0)
    t_lift = float(truth.impacts[42][0]) + 5e-8
    original = BallIntegrator(ball, 1.0 + R, 0.0)
    original.advance(t_lift)
    state = original.get_state()
    assert abs(state.zeno_time - float(truth.rest_time)) <= TIME_TOLERANCE
    restored = BallIntegrator(ball, 2.0, 0.0)
    restored.set_state(state if restart else dataclasses.replace(state, restart=None))
    assert restored.rest_time == original.rest_time == state.zeno_time
    for integrator in (original, restored):
        integrator.F_ext = G
        integrator.advance(t_lift + 100.0)
    _, v_lift = truth.state(t_lift)
    assert restored.h == original.h and restored.v == pytest.approx(float(v_lift), rel=1e-6)
    with pytest.raises(ValueError, match="state zeno_time = 1.0 s is not allowed"):
        restored.set_state(dataclasses.replace(state, zeno_time=1.0))
