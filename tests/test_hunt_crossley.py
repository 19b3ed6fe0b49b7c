"""contact="hunt-crossley" against its independent mpmath solution (tests/hunt_crossley_truth.py).

Both CVODE engines (simulate) and the stepping API (BallIntegrator.advance in 1 ms steps), every output point
and every event time; the truth itself against the Hertz contact's invariants.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from bouncingball import Ball, simulate
from bouncingball.physics import Mode
from bouncingball.solvers.cvode import BallIntegrator, CvodeSettings
from bouncingball.solvers.phase_machine.settings import hop_tolerance, merged_hop_limit
from hunt_crossley_truth import HuntCrossleyTruth, hertz_contact_duration, mp

TOLERANCE = 1e-6  # of the height scale, the promise; measured errors are ~1e-9 (see MEASURED)
EVENT_TOLERANCE = 1e-9  # s
# The error estimate against the true error (max |h - h_true| [m] on the grid): never below, and over-estimating
# by at most this much. Measured (both engines): benchmark 24, elastic 96, grazing 39, linear-n 494, stiff-n 36,
# lifted 39, free-start 17.
ESTIMATE_RATIO = {}
ESTIMATE_RATIO_DEFAULT = 1e3

# name: (k, n, alpha, m, R, g, h0, v0, t_end, F_ext)
CASES = {
    "benchmark": (1e6, 1.5, 0.05, 1.0, 0.06, 9.81, 2.0, 0.0, 3.0, 0.0),
    "elastic": (1e6, 1.5, 0.0, 1.0, 0.06, 9.81, 0.5, 0.0, 1.0, 0.0),
    "grazing": (1e6, 1.5, 0.05, 1.0, 0.06, 9.81, 0.0601, 0.0, 0.3, 0.0),
    "linear-n": (1e4, 1.0, 0.2, 1.0, 0.06, 9.81, 0.5, 0.0, 0.8, 0.0),
    "stiff-n": (1e7, 2.5, 0.5, 0.5, 0.06, 9.81, 0.3, -1.0, 0.6, 0.0),
    # resting at its static deflection, then lifted by 3 m g: the clip engages (a release, free, a departure)
    "lifted": (1e6, 1.5, 20.0, 1.0, 0.06, 9.81, 0.06 - (9.81 / 1e6) ** (1 / 1.5), 0.0, 0.1, 3 * 9.81),
    # 5 cm deep, rising at 1 m/s past the release speed 2/3 m/s: it starts free, and is pressed again below R
    "free-start": (1e4, 1.5, 1.0, 1.0, 0.06, 9.81, 0.01, 1.0, 0.3, 0.0),
}


@functools.cache
def truth(name):
    k, n, alpha, m, R, g, h0, v0, t_end, F_ext = CASES[name]
    return HuntCrossleyTruth(m, k, n, alpha, R, g, h0, v0, t_end, F_ext)


def ball_of(name):
    k, n, alpha, m, R, g, *_ = CASES[name]
    return Ball(m=m, k=k, R=R, g=g, contact="hunt-crossley", n=n, alpha=alpha)


def _compare(name, t, h, events):
    k, n, alpha, m, R, g, h0, v0, t_end, F_ext = CASES[name]
    tr = truth(name)
    h_true = np.array([float(tr.state(ti)[0]) for ti in t])
    scale = max(float(np.max(np.abs(h_true))), R)
    error = float(np.max(np.abs(h - h_true))) / scale
    kinds = [str(e.kind) for e in events]
    assert kinds == [kind for _, kind, _ in tr.events]
    event_error = max((abs(e.time - float(te)) for e, (te, _, _) in zip(events, tr.events, strict=True)), default=0.0)
    assert error < TOLERANCE, (name, error)
    assert event_error < EVENT_TOLERANCE, (name, event_error)
    return error * scale, event_error


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
@pytest.mark.parametrize("name", list(CASES))
def test_simulate_against_truth(name, engine):
    k, n, alpha, m, R, g, h0, v0, t_end, F_ext = CASES[name]
    result = simulate(ball_of(name), h0, v0, t_end, 1e-3, F_ext=F_ext, engine=engine)
    error, _ = _compare(name, result.t, result.h, result.events)
    assert error <= result.error_estimate <= ESTIMATE_RATIO.get(name, ESTIMATE_RATIO_DEFAULT) * error, \
        (name, error, result.error_estimate)


@pytest.mark.parametrize("name", ["benchmark", "lifted"])
def test_stepping_api_against_truth(name):
    k, n, alpha, m, R, g, h0, v0, t_end, F_ext = CASES[name]
    integrator = BallIntegrator(ball_of(name), h0, v0, 0.0, F_ext, CvodeSettings(engine="compiled"))
    steps = int(round(t_end / 1e-3))
    t, h, events, estimates = [0.0], [h0], [], [integrator.error_estimate]
    try:
        for i in range(1, steps + 1):
            events += integrator.advance(i * 1e-3)
            t.append(integrator.t)
            h.append(integrator.h)
            estimates.append(integrator.error_estimate)  # inside CVODE's kept step, read off its interpolant
    finally:
        integrator.close()
    _compare(name, np.array(t), np.array(h), events)
    tr = truth(name)
    errors = np.abs(np.array(h) - np.array([float(tr.state(ti)[0]) for ti in t]))
    # at every step the estimate bounds the error so far
    assert np.all(np.maximum.accumulate(errors) <= np.array(estimates)), max(errors / np.array(estimates))


def test_clip_engages_where_lifted():
    kinds = [kind for _, kind, _ in truth("lifted").events]
    assert kinds[:2] == ["release", "departure"]


@pytest.mark.parametrize("name", list(CASES))
def test_force_never_negative(name):
    k, n, alpha, m, R, g, h0, v0, t_end, F_ext = CASES[name]
    ball = ball_of(name)
    result = simulate(ball, h0, v0, t_end, 1e-3, F_ext=F_ext, engine="compiled")
    forces = [ball.contact_force(h, v, Mode.CONTACT) for h, v in zip(result.h, result.v, strict=True)]
    assert min(forces) >= 0.0


def test_truth_elastic_contact_conserves_speed_and_takes_hertz_time():
    """alpha = 0, g = 0: the rebound speed is the impact's; the contact lasts 3.2181 (m^2/(k^2 v))^(1/5) (Hertz)."""
    tr = HuntCrossleyTruth(1.0, 1e6, 1.5, 0.0, 0.06, 0.0, 0.06, -2.0, 0.02)
    (t_dep, kind, v_dep), = tr.events
    assert kind == "departure" and abs(v_dep - 2) < mp.mpf(10) ** -20
    duration = hertz_contact_duration(1.0, 1e6, 1.5, 2.0)
    assert abs(t_dep - duration) < mp.mpf(10) ** -20
    # the closed form's constant for n = 3/2: 2 sqrt(pi) Gamma(7/5) / Gamma(9/10) (5/4)^(2/5)
    constant = duration / (mp.mpf(1) / (mp.mpf(10) ** 12 * 2)) ** (mp.mpf(1) / 5)
    assert abs(constant - mp.mpf("3.2180654597190430845")) < mp.mpf(10) ** -18


def test_refused_by_exact():
    with pytest.raises(ValueError, match="hunt-crossley"):
        simulate(ball_of("elastic"), 0.5, 0.0, 0.1, 1e-3, solver="exact")


@pytest.mark.parametrize("name", list(CASES))
def test_the_articles_algorithm_with_dop853_follows_the_truth(name):
    """solve_ivp (DOP853, the benchmark's peer) with a terminal event per phase: its contact's right-hand side clips
    the force, so the clip's free sub-mode is no phase of its own (no release or engage event) and the lifted ball
    leaves at the same departure."""
    pytest.importorskip("scipy")
    k, n, alpha, m, R, g, h0, v0, t_end, F_ext = CASES[name]
    result = simulate(ball_of(name), h0, v0, t_end, 1e-3, solver="scipy", F_ext=F_ext, method="DOP853", rtol=1e-12,
                      atol=1e-12 * max(abs(h0), R), max_step=0.0)
    tr = truth(name)
    h_true = np.array([float(tr.state(ti)[0]) for ti in result.t])
    assert float(np.max(np.abs(result.h - h_true))) / max(float(np.max(np.abs(h_true))), R) < TOLERANCE
    crossings = [(float(te), kind) for te, kind, _ in tr.events if kind in ("impact", "departure")]
    assert [str(e.kind) for e in result.events] == [kind for _, kind in crossings]
    assert max((abs(e.time - te) for e, (te, _) in zip(result.events, crossings, strict=True)), default=0.0) < 1e-8


@pytest.mark.parametrize(("field", "value"), [("n", 0.5), ("n", 3.0), ("alpha", -1.0), ("alpha", math.inf)])
def test_parameters_validated_by_name(field, value):
    with pytest.raises(ValueError, match=f"^{field} = "):
        Ball(contact="hunt-crossley", **{field: value})


REST_CASE = (1e6, 1.5, 5.0, 1.0, 0.06, 9.81, 0.07, 0.0, 0.12)  # k, n, alpha, m, R, g, h0, v0, t_end: one impact
REST_TOLERANCE = 1e-9  # s; measured 2.7e-13 (both engines), 2.7e-13 in the stepping API


@functools.cache
def rest_truth():
    """The heavily damped ball's truth and when its energy E (contact_laws.hunt_crossley_rest_margin) turns negative."""
    k, n, alpha, m, R, g, h0, v0, t_end = REST_CASE
    tr = HuntCrossleyTruth(m, k, n, alpha, R, g, h0, v0, t_end)

    def energy(t):
        h, v = tr.state(t)
        d = mp.mpf(R) - h
        return v * v / 2 - mp.mpf(g) * d + mp.mpf(k) / m * d ** (mp.mpf(n) + 1) / (mp.mpf(n) + 1)

    start = tr.events[-1][0]
    times = [start + (mp.mpf(t_end) - start) * i / 200 for i in range(201)]
    i = next(i for i, t in enumerate(times) if energy(t) < 0)
    low, high = times[i - 1], times[i]
    for _ in range(60):
        mid = (low + high) / 2
        low, high = (low, mid) if energy(mid) < 0 else (mid, high)
    return tr, high


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_rest_where_energy_turns_negative(engine):
    """The truth's contact never ends; rest_time is where E < 0 (hop ~1e-16 m: its margin is below 1e-13 s)."""
    k, n, alpha, m, R, g, h0, v0, t_end = REST_CASE
    tr, t_rest = rest_truth()
    assert [kind for _, kind, _ in tr.events] == ["impact"]
    ball = Ball(m=m, k=k, R=R, g=g, contact="hunt-crossley", n=n, alpha=alpha)
    result = simulate(ball, h0, v0, t_end, 1e-3, engine=engine)
    assert [str(e.kind) for e in result.events] == ["impact"]
    assert abs(result.rest_time - float(t_rest)) < REST_TOLERANCE
    integrator = BallIntegrator(ball, h0, v0, 0.0, 0.0, CvodeSettings(engine=engine))
    try:
        assert integrator.rest_time is None
        for i in range(1, 121):
            integrator.advance(i * 1e-3)
            assert (integrator.rest_time is None) == (integrator.t < float(t_rest) - REST_TOLERANCE) \
                or abs(integrator.t - float(t_rest)) < 1e-3
        assert abs(integrator.rest_time - float(t_rest)) < REST_TOLERANCE
    finally:
        integrator.close()


def test_no_rest_while_bouncing():
    result = simulate(ball_of("benchmark"), 2.0, 0.0, 3.0, 1e-3, engine="compiled")
    assert result.rest_time is None


@pytest.mark.slow  # ~2 s an example (13 s loaded), the truth's: measured errors 3e-14 to 3e-12 of the height scale
@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(log_speed=st.sampled_from([-2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0]), n=st.floats(1.0, 2.5),
       alpha=st.floats(0.0, 1.0), engine=st.sampled_from(["sksundae", "compiled"]))
@example(log_speed=1.0, n=1.0, alpha=1.0, engine="compiled")  # the corner: fastest, most damped, still departing
def test_follows_its_truth_over_decades_of_impact_speed(log_speed, n, alpha, engine):
    """Impact speeds 0.01 to 10 m/s (drops 5e-6 to 5 m), n in [1, 2.5], alpha in [0, 1] s/m: heights to 1e-9.

    From the drop's top through its impact, contact and 20 ms after, on a 100-point grid; the events' kinds
    and times against the truth's. A drop's rebound never outruns 2 / (3 alpha) (no clip: measured over n
    in {1, 1.5, 2.5}, alpha 0.05 to 1, 10 m/s); the clip is the "lifted" case's.
    """
    k, m, R, g = 1e6, 1.0, 0.06, 9.81
    drop = (10.0**log_speed) ** 2 / (2.0 * g)
    t_end = math.sqrt(2.0 * drop / g) + 0.02
    ball = Ball(m=m, k=k, R=R, g=g, contact="hunt-crossley", n=n, alpha=alpha)
    result = simulate(ball, R + drop, 0.0, t_end, t_end / 100, engine=engine)
    tr = HuntCrossleyTruth(m, k, n, alpha, R, g, R + drop, 0.0, t_end)
    h_true = np.array([float(tr.state(ti)[0]) for ti in result.t])
    scale = max(float(np.max(np.abs(h_true))), R)
    error = float(np.max(np.abs(result.h - h_true))) / scale
    assert [str(e.kind) for e in result.events] == [kind for _, kind, _ in tr.events]
    event_error = max((abs(e.time - float(te)) for e, (te, _, _) in zip(result.events, tr.events, strict=True)),
                      default=0.0)
    assert error < 1e-9, error
    assert event_error < EVENT_TOLERANCE * max(1.0, t_end), event_error
    # the estimate is never below the true error, nor above it by more than ESTIMATE_RATIO_CAP (a ratio of
    # 1000 is passed in a few scenes of many: test_estimate_over_sampled_scenes)
    assert error * scale <= result.error_estimate <= ESTIMATE_RATIO_CAP * error * scale, \
        (error * scale, result.error_estimate)


ESTIMATE_RATIO_CAP = 1e4
# The property's scenes (log10 impact speed, n, alpha) drawn once (random.Random(1)) plus its corner: the estimate
# against the true error measured over 25 of them (both engines alike): min 5.3, median 59, 1 above 1000 (1230).
# Four of them here (11 s; the twelve first, 65 s, passed too).
SAMPLED_SCENES = ((1.0, 1.0, 1.0), (-1.5, 1.854, 0.802), (-2.0, 1.383, 0.495), (-0.5, 1.708, 0.380))


@pytest.mark.slow  # ~3 s a scene, the truth's
def test_estimate_over_sampled_scenes():
    """Over SAMPLED_SCENES, both engines: the estimate >= the true max height error in every run, and <= 1000 x it
    in every scene but one at most."""
    k, m, R, g = 1e6, 1.0, 0.06, 9.81
    ratios = []
    for log_speed, n, alpha in SAMPLED_SCENES:
        drop = (10.0**log_speed) ** 2 / (2.0 * g)
        t_end = math.sqrt(2.0 * drop / g) + 0.02
        tr = HuntCrossleyTruth(m, k, n, alpha, R, g, R + drop, 0.0, t_end)
        ball = Ball(m=m, k=k, R=R, g=g, contact="hunt-crossley", n=n, alpha=alpha)
        scene = []
        for engine in ("sksundae", "compiled"):
            result = simulate(ball, R + drop, 0.0, t_end, t_end / 100, engine=engine)
            error = float(np.max(np.abs(result.h - np.array([float(tr.state(ti)[0]) for ti in result.t]))))
            scene.append(result.error_estimate / error)
        ratios.append(scene)
    assert min(min(scene) for scene in ratios) >= 1.0, ratios
    assert sum(max(scene) > 1e3 for scene in ratios) <= 1, ratios


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_saved_state_resumes_its_estimate_bit_for_bit(engine):
    """A state saved inside a contact (its restart point's two ellipses) resumes to the same estimate, to the bit."""
    ball = ball_of("benchmark")
    settings_ = CvodeSettings(engine=engine)
    first = BallIntegrator(ball, 0.07, -1.0, 0.0, 0.0, settings_)
    second = BallIntegrator(ball, 0.5, 0.0, 0.0, 0.0, settings_)
    try:
        first.advance(0.0051)  # inside the contact, past its first restart point
        saved = first.get_state()
        first.advance(0.4)
        second.set_state(saved)
        second.advance(0.4)
        assert (second.t, second.h, second.error_estimate) == (first.t, first.h, first.error_estimate)
        assert first.error_estimate > 0.0
    finally:
        first.close()
        second.close()


# --- the law's own hop tolerance (contact_laws.hunt_crossley_hop_tolerance) ------------------------------------------
@pytest.mark.parametrize(("n", "alpha", "F_ext"),
                         [(1.0, 0.2, 0.0), (1.5, 0.05, 0.0), (2.5, 1.0, 3.0), (1.5, 0.5, -2.0)])
def test_hop_tolerance_is_the_contacts_resolution_near_rest(n, alpha, F_ext):
    """HOP_RESOLUTION rtol (2 (n + 1) (m g - F_ext) / k)^(1/n): the hop of CVODE's x error at R, its energy's."""
    ball = Ball(m=2.0, k=1e6, g=9.81, contact="hunt-crossley", n=n, alpha=alpha)
    load = mp.mpf(2.0) * mp.mpf(9.81) - F_ext
    depth = (2 * (mp.mpf(n) + 1) * load / mp.mpf(1e6)) ** (1 / mp.mpf(n))
    assert hop_tolerance(ball, 1e-12, None, F_ext) == pytest.approx(float(10 * mp.mpf(1e-12) * depth), rel=1e-14)
    assert hop_tolerance(ball, 1e-12, 1e-20, F_ext) == 10 * 1e-20  # an atol tightens it
    static = (load / mp.mpf(1e6)) ** (1 / mp.mpf(n))
    assert ball.static_deflection(F_ext) == pytest.approx(float(static), rel=1e-15)
    stiffness = 1e6 / 2.0 * n * float(static) ** (n - 1.0)  # d(acceleration)/dh there [1/s2]; h rounds to ulp(R)
    assert abs(ball.acceleration(ball.rest_height(F_ext), 0.0, Mode.CONTACT, F_ext)) < 2.0 * stiffness * math.ulp(0.06)


def test_no_hop_tolerance_where_the_contact_never_rests():
    assert hop_tolerance(Ball(k=1e6, contact="hunt-crossley", alpha=0.0)) == 0.0  # undamped: its energy kept
    assert hop_tolerance(Ball(k=1e6, contact="hunt-crossley", alpha=0.5), F_ext=20.0) == 0.0  # lifted


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_rests_from_its_rest_height(engine):
    ball = Ball(k=1e6, contact="hunt-crossley", n=1.5, alpha=0.5)
    result = simulate(ball, ball.rest_height(), 0.0, 0.1, 1e-3, engine=engine)
    assert result.rest_time == 0.0 and not result.events
    assert np.max(np.abs(result.h - ball.rest_height())) <= merged_hop_limit(ball)


HOP_SCENE = (1e6, 1.5, 1e-9, 1.0, 0.06, 9.81)  # k, n, alpha, m, R, g: nearly undamped, resting at its deflection


def _hop_from_rest(hop, engine):
    """The ball at its static deflection rising with the energy of a hop [m] above R: (run, truth, the truth's hop)."""
    k, n, alpha, m, R, g = HOP_SCENE
    ball = Ball(m=m, k=k, R=R, g=g, contact="hunt-crossley", n=n, alpha=alpha)
    d = ball.static_deflection()
    v0 = math.sqrt(2.0 * (g * hop + g * d * n / (n + 1.0)))  # E = m v0^2 / 2 - m g d + k d^(n+1) / (n + 1) = m g hop
    t_end = 0.03
    tr = HuntCrossleyTruth(m, k, n, alpha, R, g, R - d, v0, t_end)
    result = simulate(ball, R - d, v0, t_end, 1e-4, engine=engine)
    departures = [v for _, kind, v in tr.events if kind == "departure"]
    rise = float(departures[0] ** 2 / (2 * mp.mpf(g))) if departures else 0.0
    return result, tr, rise


@pytest.mark.slow  # ~20 s, the truths'
@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_hops_above_the_tolerance_are_kept_and_below_it_within_the_estimate(engine):
    """A hop of 1e-11 m (70 merged_hop_limit) is resolved as the truth makes it; one of 1e-17 m (below hop_tolerance,
    1.3e-14 m) may be merged, within the error estimate (which counts the hop tolerance in each contact)."""
    k, n, alpha, m, R, g = HOP_SCENE
    ball = Ball(m=m, k=k, R=R, g=g, contact="hunt-crossley", n=n, alpha=alpha)
    assert 50.0 * merged_hop_limit(ball) < 1e-11
    result, tr, rise = _hop_from_rest(1e-11, engine)
    assert 0.9e-11 < rise < 1.1e-11
    assert [str(e.kind) for e in result.events] == [kind for _, kind, _ in tr.events]
    assert max(abs(e.time - float(te)) for e, (te, _, _) in zip(result.events, tr.events, strict=True)) \
        < EVENT_TOLERANCE
    assert 1e-17 < 1e-2 * hop_tolerance(ball)
    result, tr, rise = _hop_from_rest(1e-17, engine)
    error = float(np.max(np.abs(result.h - np.array([float(tr.state(t)[0]) for t in result.t]))))
    assert error <= result.error_estimate


def test_the_benchmarks_scene_and_reference_follow_the_truth():
    """bench --hunt-crossley measures errors against the compiled engine at REFERENCE_RTOL: over the truth's first
    3 s of the same scene it is within REFERENCE_HELD_WITHIN (measured 3.0e-10 m), its events within 1e-9 s
    (7.6e-11 s)."""
    from bouncingball.bench.hunt_crossley_study import REFERENCE_ATOL, REFERENCE_HELD_WITHIN, REFERENCE_RTOL, SCENE

    k, n, alpha, m, R, g, h0, v0, t_end, F_ext = CASES["benchmark"]
    assert (SCENE.ball, SCENE.h0, SCENE.v0, SCENE.F_ext) == (ball_of("benchmark"), h0, v0, F_ext)
    result = simulate(SCENE.ball, h0, v0, t_end, 1e-3, rtol=REFERENCE_RTOL, atol=REFERENCE_ATOL)
    tr = truth("benchmark")
    h_true = np.array([float(tr.state(ti)[0]) for ti in result.t])
    assert float(np.max(np.abs(result.h - h_true))) < REFERENCE_HELD_WITHIN
    assert [str(e.kind) for e in result.events] == [kind for _, kind, _ in tr.events]
    assert max(abs(e.time - float(te)) for e, (te, _, _) in zip(result.events, tr.events, strict=True)) < 1e-9
