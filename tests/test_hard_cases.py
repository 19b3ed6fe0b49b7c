"""Where an integrator lies: grazing contacts, long and stiff rests, contacts too short for double precision.

Every case is judged against the exact solution: events under the rule of accuracy.event_mismatches
(every hop rising more than 100 (atol + rtol R) above R found, with the right kind and time), the height
within 1e-6 of the scene's height scale on the whole output grid.
"""

import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

import bouncingball as bb
from bouncingball.accuracy import event_mismatches, height_scale, max_height_error
from bouncingball.solvers.cvode import (
    BallIntegrator,
    CvodeSettings,
    check_resolvable,
    merged_hop_limit,
    resolvable_until,
)
from bouncingball.solvers.exact import ExactSolution
from closed_forms import undamped_event_count
from oracle_counts import oracle_counts

RELATIVE_HEIGHT_TOLERANCE = 1e-6
ARTICLE = bb.Ball()
# The damping at which the article's first contact stops returning the ball to R (found by bisection
# on the exact solution; test_threshold_damping_is_the_bounce_threshold checks it).
BOUNCE_THRESHOLD_DAMPING = 145.21960354346564




def assert_exact(result, h0, v0):
    """The result's events and heights against the exact solution on its own grid."""
    exact = ExactSolution(result.ball, h0, v0, float(result.t[0]), float(result.t[-1]), result.F_ext)
    h_exact, _ = exact.state(result.t)
    tolerance = RELATIVE_HEIGHT_TOLERANCE * height_scale(h_exact, result.ball.R)
    min_hop = merged_hop_limit(result.ball, F_ext=result.F_ext)  # higher hops must be found
    assert event_mismatches(result.events, exact, tolerance, min_hop) == []
    assert max_height_error(result.h, h_exact) <= tolerance
    return exact


# --- 1. grazing contacts ----------------------------------------------------------------------
@pytest.mark.parametrize("v0", [1e-9, 1e-7, 1e-5])
def test_leaving_the_ground_at_r_with_a_tiny_speed_comes_back(v0):
    result = bb.simulate(ARTICLE, ARTICLE.R, v0, 1.0, 1e-3)
    exact = assert_exact(result, ARTICLE.R, v0)
    assert exact.events[0].kind == "impact" and exact.events[0].time == pytest.approx(2 * v0 / ARTICLE.g)
    assert all(e.velocity < 0 for e in result.events if e.kind == "impact")
    # from R with v ~ 0 the contact rings around the rest height, never lower than R - 2 d
    assert result.h.min() >= ARTICLE.R - 2 * ARTICLE.static_deflection() - 1e-9


def test_threshold_damping_is_the_bounce_threshold():
    """Just below the threshold the ball bounces a third time; just above it does not."""
    below = ExactSolution(bb.Ball(b=BOUNCE_THRESHOLD_DAMPING * (1 - 1e-8)), 2.0, 0.0, 0.0, 8.0)
    above = ExactSolution(bb.Ball(b=BOUNCE_THRESHOLD_DAMPING * (1 + 1e-8)), 2.0, 0.0, 0.0, 8.0)
    assert len(below.events) == 3 and len(above.events) == 1


@pytest.mark.parametrize("relative", [-1e-4, -1e-6, -1e-8, -1e-10, 1e-10, 1e-8, 1e-6])
def test_near_the_bounce_threshold(relative):
    ball = bb.Ball(b=BOUNCE_THRESHOLD_DAMPING * (1 + relative))
    assert_exact(bb.simulate(ball, 2.0, 0.0, 2.0, 1e-3), 2.0, 0.0)


def _threshold_damping(ball, h0, v0):
    """The damping b [N s/m] at which the first contact just fails to return the ball to R (bisection)."""
    low, high = 0.0, 2.0 * math.sqrt(ball.k * ball.m)
    for _ in range(200):
        middle = 0.5 * (low + high)
        trial = bb.Ball(m=ball.m, k=ball.k, b=middle, R=ball.R, g=ball.g)
        if len(ExactSolution(trial, h0, v0, 0.0, 50.0).events) > 1:
            low = middle
        else:
            high = middle
    return high


@pytest.mark.parametrize(("m", "k", "h0"), [(1.0, 1e4, 2.0), (1e-3, 1e6, 0.5), (10.0, 1e3, 0.2), (1e-6, 1e9, 5.0)])
@pytest.mark.parametrize("relative", [-1e-9, -1e-6, 1e-9])
def test_generated_near_threshold_family(m, k, h0, relative):
    """Balls of other masses and stiffnesses damped within a hair of their own bounce threshold."""
    ball = bb.Ball(m=m, k=k, R=0.05)
    b = _threshold_damping(ball, h0, 0.0) * (1 + relative)
    ball = bb.Ball(m=m, k=k, b=b, R=0.05)
    t_end = 2.0 * math.sqrt(2.0 * h0 / ball.g) + 0.5
    assert_exact(bb.simulate(ball, h0, 0.0, t_end, t_end / 2000), h0, 0.0)


@pytest.mark.parametrize("relative", [1e-6, 1e-3, -1e-6])
def test_from_rest_height_with_just_enough_speed_to_leave(relative):
    """0.1058604129 m/s from the rest height brings the article's ball to R with v ~ 0."""
    v0 = 0.1058604129 * (1 + relative)
    rest = ARTICLE.rest_height()
    exact = assert_exact(bb.simulate(ARTICLE, rest, v0, 2.0, 1e-3), rest, v0)
    assert len(exact.events) == (2 if relative > 0 else 0)


@pytest.mark.parametrize("relative", [1e-9, 1e-6, 1e-3])
def test_undamped_ball_grazing_from_rest_height_keeps_hopping(relative):
    """Each hop rises d * relative above R (d = 1 mm): 1e-12 m may merge into a rest, 1e-9 m may not."""
    ball = bb.Ball(b=0.0)
    v0 = ball.natural_frequency * ball.static_deflection() * (1 + relative)
    rest = ball.rest_height()
    result = bb.simulate(ball, rest, v0, 2.0, 1e-3)
    exact = assert_exact(result, rest, v0)
    assert len(exact.events) > 50
    if ball.static_deflection() * relative > 2 * merged_hop_limit(ball):
        assert result.rest_time is None and len(result.events) == len(exact.events)


@pytest.mark.parametrize("v_departure", [1e-3, 1e-4, 3e-5, 1e-5])
def test_small_hops_are_found_in_pairs(v_departure):
    """Leaving R upwards at v: a hop of v^2/2g (5e-8 .. 5e-12 m) then a contact."""
    result = bb.simulate(ARTICLE, ARTICLE.R, v_departure, 0.5, 1e-4)
    assert_exact(result, ARTICLE.R, v_departure)


# --- 2. long and stiff rests --------------------------------------------------------------------
@pytest.mark.parametrize(("ball", "t_end"), [(ARTICLE, 1e6), (bb.Ball(m=1e-9), 1e5), (bb.Ball(m=1e-6), 1e4)],
                         ids=["article-1e6s", "m1e-9-1e5s", "tiny-mass-1e4s"])
def test_long_rests_at_one_second_output(ball, t_end):
    result = bb.simulate(ball, 2.0, 0.0, t_end, 1.0)
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, t_end)
    assert max_height_error(result.h, exact.state(result.t)[0]) <= 1e-6
    assert len(result.events) == len(exact.events)


@pytest.mark.parametrize("take_state", [False, True])
def test_advancing_in_steps_with_a_state_taken_before_each(take_state):
    ball = bb.Ball(m=1e-9)
    integrator = BallIntegrator(ball, 2.0, 0.0)
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, 60.0)
    for t in range(1, 61):
        if take_state:
            integrator.get_state()
        integrator.advance(float(t))
        h_exact, v_exact = exact.state(float(t))
        assert abs(integrator.h - h_exact[0]) <= 1e-6, t
    assert integrator.mode == bb.Mode.CONTACT and integrator.impacts == sum(e.kind == "impact" for e in exact.events)


# --- 3. contacts too short for double precision ------------------------------------------------
def test_a_contact_too_short_for_the_time_span_is_refused_before_any_work():
    ball = bb.Ball(k=1e15, m=1e-9)
    refusal = r"k = 1000000000000000.0 N/m with m = 1e-09 kg.*contact lasts 3.14e-12 s.*ulp"
    with pytest.raises(ValueError, match=refusal):
        bb.simulate(ball, 2.0, 0.0, 1e5, 1.0)
    with pytest.raises(ValueError, match="k = 1000000000000000.0"):
        BallIntegrator(ball, 2.0, 0.0, t0=1e5)
    integrator = BallIntegrator(ball, 2.0, 0.0)
    with pytest.raises(ValueError, match="Shorten the run"):
        integrator.advance(1e5)
    assert integrator.t == 0.0 and integrator.h == 2.0  # nothing was done


def test_a_stiff_contact_within_the_resolvable_span_stays_exact():
    ball = bb.Ball(k=1e15, m=1e-9, b=1e-3)
    t_end = min(1.0, 0.5 * resolvable_until(ball))
    check_resolvable(ball, t_end)
    assert_exact(bb.simulate(ball, 0.1, 0.0, t_end, t_end / 1000), 0.1, 0.0)


# --- 4. the failures with the wrong reason ----------------------------------------------------
def test_stiff_tiny_ball_finishes_with_the_exact_events():
    ball = bb.Ball(m=7.845629028153048e-06, k=1273664406.973477, b=131.07385603248107, R=0.016349292318303628,
                   g=5.745576497079252)
    h0, v0, t_end = 0.01761906428125259, 26.39033834877121, 25.48148283754829
    assert_exact(bb.simulate(ball, h0, v0, t_end, t_end / 2000), h0, v0)


@pytest.mark.parametrize("rtol", [1e-11, 1e-12, 1e-13])
def test_a_stiff_undamped_ball_is_no_worse_at_tighter_tolerances(rtol):
    """14 contacts of 1e-8 s deflecting a 1 m ball by 3e-9 m (1.4e7 ulps of R): CVODE carried h = R + deflection,
    rounded to ulp(R) each step, and its error test answered that noise with ever smaller steps. Each
    departure came out too fast, and an undamped ball keeps each error: 1.9e-6 m at rtol 1e-11, 2.8e-5 m at
    1e-12, 2.1e-3 m at 1e-13. CVODE now integrates the gap h - R, which carries every digit of the deflection."""
    ball = bb.Ball(m=1e-5, k=1e12, b=0.0, R=1.0, g=9.81)
    h0, v0 = ball.rest_height(), 1.0
    result = bb.simulate(ball, h0, v0, 3.0, 1.5e-3, rtol=rtol, atol=0.1 * rtol)
    exact = assert_exact(result, h0, v0)
    assert len(exact.events) == oracle_counts(ball, h0, v0, t_end=3.0).events
    # the error follows the tolerance asked for (measured: 150 rtol times the height, ~1 m, at each rtol)
    h_exact = exact.state(result.t)[0]
    assert max_height_error(result.h, h_exact) <= 1000.0 * rtol * np.max(np.abs(h_exact))


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_an_undamped_ball_keeps_its_speed_through_2538_micro_hops(engine):
    """Hops 1.6e-9 m high between contacts deflecting the ball by 1.8e-10 m (k = 1e12 N/m), no damping.

    Energy is conserved, so every departure and impact has the first impact's speed v0 and the ball
    never rests. With h's error controlled to 1e-12 m absolute, each flight ended ~6.4e-9 s early and
    cost speed: 3541 events against 2538, 0.10 v0 at the end, then a rest at 0.0436 s with b = 0.
    """
    ball = bb.Ball(k=1e12, b=0.0)
    v0 = 1.7717787672280082e-4
    result = bb.simulate(ball, ball.R, v0, 0.05, 1e-5, engine=engine)
    assert result.rest_time is None
    # from the apex, v0 / g after the start, it is a release at rest from R + v0^2 / 2g
    apex = ball.R + v0**2 / (2.0 * ball.g)
    expected = undamped_event_count(ball.m, ball.k, ball.R, ball.g, apex, 0.05 - v0 / ball.g)
    assert expected == 2538 and len(result.events) == expected
    speeds = np.abs([event.velocity for event in result.events])
    assert np.max(np.abs(speeds / v0 - 1.0)) <= 1e-8  # measured 2.0e-9: ~1.6 rtol per contact, 1269 contacts
    assert_exact(result, ball.R, v0)


def test_stiff_launch_to_a_kilometre_within_its_height_scale():
    ball = bb.Ball(m=1.061978669547503e-06, k=50252528378.98195, b=63.6285912403694, R=0.02896884121095645,
                   g=42.94743356597073)
    h0, v0, t_end = 924.8938356173458, 37.81348468340714, 24.35498984703338
    assert_exact(bb.simulate(ball, h0, v0, t_end, t_end / 2000), h0, v0)


# --- the property: random balls over wide ranges, grazing included ------------------------------
def _log_uniform(low, high):
    return st.floats(math.log10(low), math.log10(high)).map(lambda x: 10.0**x)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(
    m=_log_uniform(1e-6, 1e3), k=_log_uniform(1e1, 1e12),
    zeta=st.one_of(st.just(0.0), _log_uniform(1e-4, 10.0)), R=_log_uniform(1e-4, 1.0), g=st.floats(0.0, 100.0),
    lift=st.one_of(st.just(0.0), _log_uniform(1e-12, 1e3)), v0=st.floats(-50.0, 50.0),
    force=st.one_of(st.just(0.0), st.floats(-3.0, 3.0), _log_uniform(1e-18, 1e-6)),
)
# Found by exploring, replayed always: contacts creeping to rest (critical damping, (almost) no
# weight), undamped small balls (error growing bounce by bounce), an impact at the end of the run.
@example(m=2.317700043930019e-4, k=57428147.75181946, zeta=1.0, R=1.0, g=0.0, lift=0.0, v0=-12.5, force=0.0)
@example(m=4.07758074925151e-3, k=32647608265.54553, zeta=1.000000137244776, R=10.0**-2.00001,
         g=1.3810799475959544e-183, lift=1.0, v0=-18.906758504311465, force=0.0)
@example(m=10.0**0.09375, k=79147554394.1116, zeta=0.0, R=1e-3, g=36.0, lift=0.0, v0=1.0, force=0.0)
@example(m=1.0, k=1e8, zeta=0.0, R=1e-3, g=34.0, lift=0.0, v0=1.0, force=0.0)
@example(m=1.0, k=1e8, zeta=0.0, R=0.1, g=1.0, lift=0.0, v0=1.5, force=0.0)
@example(m=1e-4, k=10.0, zeta=0.0, R=1e-3, g=10.0, lift=0.0, v0=0.25, force=0.0)
# A lift too small to move the rest height off R by an ulp, on a critically damped contact: CVODE
# never saw h cross R and kept the ball at R (silently, 4.5 tolerances low after 3 s) or gave up.
@example(m=1.0, k=602851817656.5535, zeta=1.0, R=1.0, g=0.0, lift=0.0, v0=-15.082059905272018, force=1e-06)
@example(m=1.0, k=602851817656.5535, zeta=1.0, R=1.0, g=0.0, lift=0.0, v0=-15.082059905272018, force=1e-18)
# At R with v0 = -2e-112 m/s, lifted by 1e-18 N: a departure at once with that speed rounded below 0,
# then an impact at once, for ever at t = 0.
@example(m=1.0, k=100.0, zeta=0.0, R=1.0, g=0.0, lift=0.0, v0=-2.374447051180475e-112, force=1e-18)
# An undamped ball whose contacts deflect it by 1.4e7 ulps of R: CVODE rounded each step's h to ulp(R).
@example(m=1e-5, k=1e12, zeta=0.0, R=1.0, g=9.81, lift=0.0, v0=1.0, force=0.0)
def test_random_balls_against_the_exact_solution(m, k, zeta, R, g, lift, v0, force):
    """force: F_ext in units of the ball's weight (of m * 1 m/s2 when g < 1)."""
    ball = bb.Ball(m=m, k=k, b=2.0 * zeta * math.sqrt(k * m), R=R, g=g)
    F_ext = force * m * max(g, 1.0)
    h0 = ball.rest_height(F_ext) + lift
    t_end = 3.0
    exact = ExactSolution(ball, h0, v0, 0.0, t_end, F_ext)
    # At most 100 events, for time: tests/test_long_runs.py measures the long undamped runs.
    assume(len(exact.events) <= 100)
    assume(resolvable_until(ball) >= t_end)
    result = bb.simulate(ball, h0, v0, t_end, t_end / 2000, F_ext=F_ext)
    assert_exact(result, h0, v0)
    assert np.all(np.isfinite(result.h))


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_a_hop_shorter_than_the_last_ulps_of_a_grid_still_lands(engine):
    """At t0 = 1e6 s a grid end 31 ulps (3.6e-9 s) on is finished by a Taylor step; a hop from R at
    1e-9 m/s lands 2.0e-10 s after the start, before it. The Taylor step was taken over the pending
    impact: no event, the ball in flight below R, and the next grid crashed inside scikit-sundae.
    """
    ball, t0, v0 = bb.Ball(), 1e6, 1e-9
    t1 = t0 + 31 * np.spacing(t0)
    exact = ExactSolution(ball, ball.R, v0, t0, t0 + 1.0)
    integrator = BallIntegrator(ball, ball.R, v0, t0=t0, settings=CvodeSettings(engine=engine))
    _, _, events = integrator.integrate_grid(np.array([t0, t1]))
    assert [e.kind for e in events] == ["impact"] and exact.events[0].time < t1
    assert events[0].time == pytest.approx(exact.events[0].time, abs=np.spacing(t0))
    assert integrator.mode == bb.Mode.CONTACT and integrator.h <= ball.R
    h, _, _ = integrator.integrate_grid(np.array([t1, t0 + 1.0]))
    assert abs(h[-1] - exact.state(np.array([t0 + 1.0]))[0][0]) <= 1e-12


# --- 5. SUNDIALS warnings -------------------------------------------------------------------------
def test_a_late_start_is_integrated_in_phase_time_without_sundials_warnings(capfd):
    """At t0 = 1e6 s CVODE in absolute time took steps below one ulp of t ('t + h = t' at every step).

    CVODE's time runs from each phase's start, so a late start is no different from an early one.
    """
    import warnings

    from bouncingball.solvers.engines.sundials_log import SundialsWarning

    integrator = BallIntegrator(ARTICLE, 2.0, 0.0, t0=1e6)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SundialsWarning)
        integrator.advance(1e6 + 2.0)
    assert "WARNING" not in capfd.readouterr().err
    exact = ExactSolution(ARTICLE, 2.0, 0.0, 1e6, 1e6 + 2.0)
    assert abs(integrator.h - exact.state(1e6 + 2.0)[0][0]) <= 1e-9
    assert integrator.impacts == sum(e.kind == "impact" for e in exact.events)


def test_a_sundials_log_reports_each_cause_once():
    """The log on its own: a raw scikit-sundae CVODE object created under capturing()."""
    from sksundae.cvode import CVODE

    from bouncingball.solvers.engines.sundials_log import SundialsLog

    def rhs(t, y, yp):
        yp[0], yp[1] = y[1], -y[0]

    import gc

    log, solver = SundialsLog(), CVODE(rhs, rtol=1e-10, atol=1e-12)
    with log.capturing():
        solver.solve(np.array([1e9, 1e9 + 1.0]), np.array([1.0, 0.0]))
    solver.solve(np.array([2e9, 2e9 + 1.0]), np.array([1.0, 0.0]))  # same file, same causes
    del solver  # SUNDIALS writes its buffered log out when the solver is freed (no fflush(NULL): see the module)
    gc.collect()
    messages = log.new_messages()
    assert len(messages) >= 1 and all(m.startswith("CVode: ") for m in messages)
    assert len({m.split(" t = ")[0] for m in messages}) == len(messages)  # one per cause
    assert log.new_messages() == []


@pytest.mark.parametrize(("g", "h0", "F_ext"), [(0.0, 1.0, 0.0), (9.81, 1.0, 9.81), (9.81, 0.06, 9.81)],
                         ids=["no-gravity", "lifted-by-its-weight", "lifted-at-the-ground"])
def test_a_hovering_ball_stays_put_without_a_warning(g, h0, F_ext):
    """Zero net force in flight: nothing moves, and no root function may sit at 0 (SUNDIALS would warn)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = bb.simulate(bb.Ball(g=g), h0, 0.0, 1.0, 0.1, F_ext=F_ext)
    assert np.all(result.h == h0) and np.all(result.v == 0.0)
    assert result.events == []


@pytest.mark.parametrize("zeta", [0.5, 1.01])
@pytest.mark.parametrize("solver", ["exact", "cvode-sksundae", "cvode-compiled"])
def test_a_lift_too_small_to_move_the_rest_height_off_r_still_lifts_the_ball_off(zeta, solver):
    """Weightless and pushed up by F_ext, the ball rests at R + F_ext/k, above R: it must leave and fly off at
    F_ext/m. Here F_ext/k is below half an ulp of R, so R + F_ext/k rounds to R; every solver once measured the
    departure as h - R on that rounded rest height, never saw it turn positive and kept the ball at R."""
    m, k, R, F_ext = 1e-5, 3e11, 0.6, 1.5e-5
    h0, v0 = R - 2e-10, 1e-3
    ball = bb.Ball(m=m, k=k, b=2.0 * zeta * math.sqrt(k * m), R=R, g=0.0)
    assert ball.rest_height(F_ext) == R and F_ext / k > 0.0
    name, _, engine = solver.partition("-")
    if engine == "compiled":
        pytest.importorskip("numba")
    result = bb.simulate(ball, h0, v0, 1.0, 0.1, name, F_ext=F_ext, **({"engine": engine} if engine else {}))
    assert [str(event.kind) for event in result.events] == ["departure"]
    departure = result.events[0].time
    assert 0.0 < departure < 1e-6
    # Then free flight from R under the lift alone, at a departure speed no larger than the oscillator's energy
    # allows: sqrt(v0^2 + (k/m) (h0 - rest height)^2).
    tau = result.t[result.t > departure] - departure
    v_bound = math.sqrt(v0**2 + k / m * (h0 - R - F_ext / k) ** 2)
    rise = result.h[result.t > departure] - R - 0.5 * (F_ext / m) * tau**2
    assert np.all(rise >= -1e-12) and np.all(rise <= v_bound * tau + 1e-12)


def test_a_killed_process_leaves_no_sundials_log_behind(tmp_path):
    """A worker killed mid-run (a time cap, a lost node) must not litter the temporary folder."""
    import subprocess
    import sys

    code = ("import os, signal\n"
            "from bouncingball.solvers.cvode import BallIntegrator\n"
            "from bouncingball.physics import Ball\n"
            "integrator = BallIntegrator(Ball(), 2.0, 0.0, t0=1e6)\n"
            "integrator.advance(1e6 + 1.0)\n"
            "os.kill(os.getpid(), signal.SIGKILL)\n")
    run = subprocess.run([sys.executable, "-W", "ignore", "-c", code], env={**os.environ, "TMPDIR": str(tmp_path)},
                         capture_output=True, text=True)
    assert run.returncode == -9, run.stderr
    assert list(tmp_path.iterdir()) == []
