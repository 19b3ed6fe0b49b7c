"""The no-pull contact law (contact="linear-no-pull") against its independent mpmath truth (tests/nopull_truth.py).

Every event (impacts, releases where the force falls to 0 below R, engagements where it rises again, departures)
and the heights, in simulate (both CVODE engines and the exact solver) and the stepping API; the error estimate
at least the true error; the force never negative where the linear law's is; b = 0 the linear law, bit for bit.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import bouncingball as bb
from bouncingball.solvers.cvode import BallIntegrator, CvodeSettings
from nopull_truth import NoPullTruth

ARTICLE = dict(m=1.0, k=1e4, b=10.0, R=0.06, g=9.81)
# name: (ball, h0, v0, t_end, F_ext, event time tolerance [s]). The article's event times drift with CVODE's
# error of each contact's speed (~2e-11 m/s a bounce), 1.2e-10 s by its 54th event; the others' stay within 1e-11 s
# but free-start's, whose bounces add up 2.1e-11 s by its 7th event.
CASES = {
    "article": (ARTICLE, 2.0, 0.0, 8.0, 0.0, 2.5e-10),
    # critical damping: impact, release, and the free ball pressed again below R (then at rest)
    "critical": ({**ARTICLE, "b": 200.0}, 0.5, 0.0, 3.0, 0.0, 1e-11),
    "zeta-0.7": ({**ARTICLE, "b": 140.0}, 0.3, 0.0, 3.0, 0.0, 1e-11),
    "over-damped": ({**ARTICLE, "b": 300.0}, 1.0, 0.0, 3.0, 0.0, 1e-11),
    # a grazing impact at 4.4 mm/s
    "slow-impact": (ARTICLE, 0.06 + 1e-6, 0.0, 1.0, 0.0, 1e-11),
    # at its rest height when F_ext = 2 m g lifts it: pressed, released below R, free, away
    "lifted": (ARTICLE, 0.06 - 9.81 / 1e4, 0.0, 0.5, 2.0 * 9.81, 1e-11),
    # thrown up from inside the ground: free at once (the force would pull), then a flight
    "free-start": ({**ARTICLE, "b": 50.0}, 0.059, 3.0, 1.5, 0.0, 5e-11),
}
SOLVERS = [("exact", None), ("cvode", "sksundae"), ("cvode", "compiled")]
HEIGHT_TOLERANCE = 1e-9  # m


def _ball(parameters, contact="linear-no-pull"):
    return bb.Ball(**parameters, contact=contact)


def _truth(name):
    parameters, h0, v0, t_end, F_ext, _ = CASES[name]
    return NoPullTruth(parameters["m"], parameters["k"], parameters["b"], parameters["R"], parameters["g"], h0, v0,
                       t_end, F_ext)


_truths = {}


def truth_of(name):
    if name not in _truths:
        _truths[name] = _truth(name)
    return _truths[name]


def _simulate(ball, h0, v0, t_end, F_ext, solver, engine):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an AccuracyWarning here would be a broken promise
        options = {} if engine is None else {"engine": engine}
        return bb.simulate(ball, h0, v0, t_end, 1e-3, solver=solver, F_ext=F_ext, **options)


def _check_events(events, truth, time_tolerance):
    assert [str(event.kind) for event in events] == [kind for _, kind, _, _ in truth.events]
    for event, (t, _, _, v) in zip(events, truth.events, strict=True):
        assert abs(event.time - float(t)) <= time_tolerance, (event, float(t))
        assert abs(event.velocity - float(v)) <= 1e-9 * max(1.0, abs(float(v))), (event, float(v))


@pytest.mark.parametrize("solver, engine", SOLVERS)
@pytest.mark.parametrize("name", list(CASES))
def test_simulate_follows_the_nopull_truth(name, solver, engine):
    parameters, h0, v0, t_end, F_ext, time_tolerance = CASES[name]
    truth = truth_of(name)
    result = _simulate(_ball(parameters), h0, v0, t_end, F_ext, solver, engine)
    _check_events(result.events, truth, time_tolerance)
    error = np.max(np.abs(result.h - np.array(truth.heights(result.t))))
    assert error <= HEIGHT_TOLERANCE
    if truth.rest_time is None:
        assert result.rest_time is None
    else:
        assert abs(result.rest_time - float(truth.rest_time)) <= time_tolerance
    if solver == "cvode":
        scale = max(h0, parameters["R"])
        assert error <= result.error_estimate <= 1e-6 * scale


def test_the_cases_show_every_switch():
    """The cases hold what they are for: releases, engagements below R, departures from the free sub-mode, a rest."""
    kinds = {name: [kind for _, kind, _, _ in truth_of(name).events] for name in CASES}
    bounces = len(kinds["article"]) // 3
    assert kinds["article"] == ["impact", "release", "departure"] * bounces and bounces > 10
    assert kinds["critical"] == ["impact", "release", "engage"] and truth_of("critical").rest_time is not None
    assert kinds["lifted"] == ["release", "departure"]
    assert kinds["free-start"][:2] == ["departure", "impact"]
    assert kinds["slow-impact"][0] == "impact"
    _, _, h_release, v_release = truth_of("critical").events[1]
    assert h_release < 0.06 and v_release > 0  # released below R, rising
    _, _, h_engage, _ = truth_of("critical").events[2]
    assert h_engage < 0.06


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
@pytest.mark.parametrize("name", ["article", "critical", "lifted"])
def test_the_stepping_api_follows_the_nopull_truth(name, engine):
    """1 ms steps of advance, as an FMU's doStep takes them; the force it reports never negative."""
    parameters, h0, v0, t_end, F_ext, time_tolerance = CASES[name]
    truth = truth_of(name)
    integrator = BallIntegrator(_ball(parameters), h0, v0, F_ext=F_ext, settings=CvodeSettings(engine=engine))
    events, worst, forces = [], 0.0, []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for t in np.arange(1, round(t_end * 1000) + 1) * 1e-3:
            events += integrator.advance(float(t))
            worst = max(worst, abs(integrator.h - float(truth.state(t)[0])))
            forces.append(integrator.contact_force)
    assert worst <= HEIGHT_TOLERANCE
    _check_events(events, truth, time_tolerance)
    assert min(forces) >= 0.0
    assert worst <= integrator.error_estimate


def test_the_force_never_pulls_where_the_linear_laws_does():
    """The article's ball, step by step: the linear law's damper pulls before each departure, the no-pull law's not."""
    minimum = {}
    for contact in ("linear", "linear-no-pull"):
        integrator = BallIntegrator(_ball(ARTICLE, contact), 2.0, 0.0)
        forces = []
        for t in np.arange(1, 2001) * 1e-3:  # the first two contacts, in 1 ms steps
            integrator.advance(float(t))
            forces.append(integrator.contact_force)
        minimum[contact] = min(forces)
    assert minimum["linear"] < -10.0  # N: the damper's pull, b v at ~5 m/s
    assert minimum["linear-no-pull"] >= 0.0
    truth = truth_of("article")
    assert min(float(truth.force(t)) for t in np.linspace(0.62, 0.67, 501)) >= 0.0
    ball = _ball(ARTICLE)
    assert ball.contact_force(0.059, 5.0, bb.Mode.CONTACT) == 0.0  # k (R - h) - b v = 10 - 50 < 0: clipped
    assert _ball(ARTICLE, "linear").contact_force(0.059, 5.0, bb.Mode.CONTACT) == pytest.approx(-40.0)


@pytest.mark.parametrize("solver, engine", SOLVERS)
def test_undamped_it_is_the_linear_law_bit_for_bit(solver, engine):
    parameters = {**ARTICLE, "b": 0.0}
    results = [_simulate(_ball(parameters, contact), 1.0, 0.0, 3.0, 0.0, solver, engine)
               for contact in ("linear", "linear-no-pull")]
    assert np.array_equal(results[0].h, results[1].h) and np.array_equal(results[0].v, results[1].v)
    assert results[0].events == results[1].events and len(results[0].events) > 4
    truth = NoPullTruth(1.0, 1e4, 0.0, 0.06, 9.81, 1.0, 0.0, 3.0)
    _check_events(results[1].events, truth, 1e-11)
    assert np.max(np.abs(results[1].h - np.array(truth.heights(results[1].t)))) <= HEIGHT_TOLERANCE


def test_the_article_algorithm_refuses_the_nopull_law_by_name():
    with pytest.raises(ValueError, match="solver = 'scipy' is not allowed with contact = 'linear-no-pull'"):
        bb.simulate(_ball(ARTICLE), 1.0, 0.0, 1.0, solver="scipy")


def test_the_law_is_chosen_by_name():
    assert bb.Ball(contact="Linear-No-Pull").contact == "linear-no-pull"
    with pytest.raises(ValueError, match="contact = 'no-pull' is not allowed: it must be one of linear, rigid, "
                                         "linear-no-pull"):
        bb.Ball(contact="no-pull")


def test_a_free_state_is_refused_for_the_linear_law():
    integrator = BallIntegrator(_ball(ARTICLE), 0.059, 3.0)
    assert integrator.mode == bb.Mode.FREE  # thrown up from inside the ground, faster than the force allows
    state = integrator.get_state()
    with pytest.raises(ValueError, match=r"state mode = 2 \(FREE\) is not allowed for contact = 'linear'"):
        BallIntegrator(_ball(ARTICLE, "linear"), 0.059, 3.0).set_state(state)


def test_a_saved_state_in_the_free_sub_mode_continues_bit_for_bit():
    ball = _ball({**ARTICLE, "b": 200.0})
    integrator = BallIntegrator(ball, 0.5, 0.0)
    integrator.advance(0.2)
    while integrator.mode != bb.Mode.FREE:
        integrator.advance(integrator.t + 1e-5)
    state = integrator.get_state()
    integrator.advance(0.6)
    other = BallIntegrator(ball, 0.5, 0.0)
    other.set_state(state)
    other.advance(0.6)
    assert (other.h, other.v, other.mode) == (integrator.h, integrator.v, integrator.mode)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(log_drop=st.floats(-6.0, 2.0), zeta=st.sampled_from([0.02, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0, 1.5, 3.0]),
       solver=st.sampled_from(SOLVERS))
def test_the_nopull_law_follows_its_truth_over_decades_of_impact_speed(log_drop, zeta, solver):
    """Drops from 1e-6 m to 100 m (impact speeds 4e-3 to 44 m/s), damping ratios 0.02 to 3."""
    drop = 10.0**log_drop
    parameters = {**ARTICLE, "b": zeta * 2.0 * math.sqrt(1e4)}
    fall = math.sqrt(2.0 * drop / 9.81)
    t_end = 3.0 * fall + 0.2
    scale = drop + 0.06
    result = bb.simulate(_ball(parameters), 0.06 + drop, 0.0, t_end, t_end / 500, solver=solver[0],
                         **({} if solver[1] is None else {"engine": solver[1]}))
    truth = NoPullTruth(1.0, 1e4, parameters["b"], 0.06, 9.81, 0.06 + drop, 0.0, t_end)
    error = np.max(np.abs(result.h - np.array(truth.heights(result.t))))
    assert error <= 1e-9 * scale
    if solver[0] == "cvode":
        assert error <= result.error_estimate
    _check_events(result.events, truth, 1e-10 * max(1.0, t_end))
