"""The exact solution against independent truth: closed forms, invariants, and high-precision integration."""

import math
import signal

import mpmath
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import bouncingball
from bouncingball.oscillator import oscillator_basis
from bouncingball.physics import Ball, Mode
from bouncingball.solvers.exact import ExactSolution
from closed_forms import undamped_event_count
from oracle_counts import oracle_counts


def test_first_impact_is_free_fall():
    ball = Ball()
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, 8.0)
    first = exact.events[0]
    assert first.kind == "impact"
    assert first.time == pytest.approx(math.sqrt(2 * (2.0 - 0.06) / 9.81), rel=1e-15)
    assert first.velocity == pytest.approx(-math.sqrt(2 * 9.81 * (2.0 - 0.06)), rel=1e-15)


def test_article_events_are_the_oracles_and_alternate():
    exact = ExactSolution(Ball(), 2.0, 0.0, 0.0, 8.0)
    kinds = [e.kind for e in exact.events]
    truth = oracle_counts(Ball())
    assert kinds == list(truth.kinds)
    assert kinds == ["impact", "departure"] * truth.departures + ["impact"] and truth.departures > 10
    times = np.array([e.time for e in exact.events])
    assert np.all(np.diff(times) > 0)


def test_flight_conserves_energy_and_contact_dissipates_it():
    ball = Ball()
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, 8.0)
    events = exact.events
    for departure, impact in zip(events[1::2], events[2::2], strict=False):
        assert impact.velocity == pytest.approx(-departure.velocity, rel=1e-12)
    for impact, departure in zip(events[0::2], events[1::2], strict=False):
        assert departure.velocity < -impact.velocity
    h, _ = exact.state([e.time for e in events])
    np.testing.assert_allclose(h, ball.R, atol=1e-15)


def test_undamped_contact_is_elastic():
    ball = Ball(b=0.0)
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, 1000.0)
    assert len(exact.events) == undamped_event_count(ball.m, ball.k, ball.R, ball.g, 2.0, 1000.0) == 1550
    speeds = np.abs([e.velocity for e in exact.events])
    np.testing.assert_allclose(speeds, speeds[0], rtol=1e-12)


def _mp_oscillator(sigma, w2, y0, v0, tau):
    """y(tau) of y'' + 2 sigma y' + w2 y = 0 by mpmath's Taylor-series integrator (40 digits)."""
    mpmath.mp.dps = 40
    f = mpmath.odefun(lambda t, u: [u[1], -2 * sigma * u[1] - w2 * u[0]], 0, [mpmath.mpf(y0), mpmath.mpf(v0)])
    y, v = f(mpmath.mpf(tau))
    return float(y), float(v)


@pytest.mark.parametrize("b", [10.0, 200.0, 200.0 * (1 + 1e-9), 1e4, 0.0])
def test_oscillator_closed_form_against_mpmath(b):
    ball = Ball(b=b)
    sigma, w2 = b / 2.0, ball.k
    y0, v0 = 9.81e-4, -6.0
    for tau in (1e-3, 0.011, 0.03):
        c, s = oscillator_basis(sigma, w2, np.array([tau]))
        y = y0 * c[0] + (v0 + sigma * y0) * s[0]
        v = v0 * c[0] - (sigma * v0 + w2 * y0) * s[0]
        y_ref, v_ref = _mp_oscillator(sigma, w2, y0, v0, tau)
        assert y == pytest.approx(y_ref, rel=1e-12, abs=1e-17)
        assert v == pytest.approx(v_ref, rel=1e-12, abs=1e-15)


def test_oscillator_is_continuous_through_critical_damping():
    w2 = 1e4
    tau = np.linspace(0.0, 0.2, 201)
    values = [oscillator_basis(100.0 * (1 + d), w2, tau) for d in (-1e-10, 0.0, 1e-10)]
    for c, s in values[::2]:
        np.testing.assert_allclose(c, values[1][0], atol=1e-9)
        np.testing.assert_allclose(s, values[1][1], atol=1e-11)


def _high_precision_run(ball, h0, v0, t_end, grid, F_ext=0.0):
    """An independent integration: DOP853 at rtol 1e-13 with a terminal event per phase."""
    t, y, mode = 0.0, np.array([h0, v0]), ball.initial_mode(h0, v0, F_ext)
    times, h_out = [], np.empty_like(grid)
    while t < t_end:
        def rhs(_t, u, mode=mode):
            return [u[1], ball.acceleration(u[0], u[1], mode, F_ext)]

        def crossing(_t, u):
            return u[0] - ball.R

        crossing.terminal = True
        crossing.direction = -1 if mode == Mode.FLIGHT else 1
        sol = solve_ivp(rhs, (t, t_end), y, method="DOP853", rtol=1e-13, atol=1e-16, events=crossing,
                        dense_output=True)
        sel = (grid >= t) & (grid <= sol.t[-1])
        h_out[sel] = sol.sol(grid[sel])[0]
        t, y = sol.t[-1], sol.y[:, -1]
        if sol.status == 1:
            times.append(t)
            mode = Mode.FLIGHT if mode == Mode.CONTACT else Mode.CONTACT
    return np.array(times), h_out


@pytest.mark.parametrize("kwargs, h0, v0, F_ext", [
    ({}, 2.0, 0.0, 0.0),
    ({"b": 200.0}, 2.0, 0.0, 0.0),
    ({"b": 1e4}, 2.0, 0.0, 0.0),
    ({}, 0.05, 0.0, 0.0),
    ({}, 1.0, 3.0, 0.0),
    ({"m": 2.0}, 1.0, 0.0, 5.0),
    ({}, 1.0, 0.0, 12.0),  # F_ext > m g: one bounce, then lifted away for good
])
def test_exact_against_high_precision_integration(kwargs, h0, v0, F_ext):
    ball = Ball(**kwargs)
    grid = np.linspace(0.0, 4.0, 4001)
    exact = ExactSolution(ball, h0, v0, 0.0, 4.0, F_ext)
    times, h_ref = _high_precision_run(ball, h0, v0, 4.0, grid, F_ext)
    assert len(exact.events) == len(times)
    np.testing.assert_allclose([e.time for e in exact.events], times, rtol=0, atol=1e-9)
    np.testing.assert_allclose(exact.state(grid)[0], h_ref, rtol=0, atol=1e-9)


def test_rest_is_detected_when_no_maximum_reaches_R():
    ball = Ball(b=1e4)
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, 60.0)
    assert [e.kind for e in exact.events] == ["impact"]
    assert exact.rest_time == exact.events[0].time
    h, v = exact.state([60.0])  # the slow rate is w^2/(sigma + mu) ~ 1/s
    assert h[0] == pytest.approx(ball.rest_height(), abs=1e-12)


def test_starting_at_rest_stays_at_rest():
    ball = Ball(k=1e12)
    exact = ExactSolution(ball, ball.rest_height(), 0.0, 0.0, 8.0)
    assert exact.events == [] and exact.rest_time == 0.0
    h, v = exact.state(np.linspace(0, 8, 9))
    np.testing.assert_allclose(h, ball.rest_height(), rtol=0, atol=1e-17)


def test_external_force_equal_to_weight_gives_uniform_motion():
    ball = Ball()
    exact = ExactSolution(ball, 1.0, 2.0, 0.0, 5.0, F_ext=ball.m * ball.g)
    assert exact.events == []
    h, v = exact.state([0.0, 2.5, 5.0])
    np.testing.assert_allclose(h, [1.0, 6.0, 11.0], rtol=1e-15)
    np.testing.assert_allclose(v, 2.0, rtol=1e-15)


def test_state_accepts_unsorted_times():
    exact = ExactSolution(Ball(), 2.0, 0.0, 0.0, 8.0)
    t = np.array([5.0, 0.1, 7.9, 0.7])
    h_unsorted, _ = exact.state(t)
    for ti, hi in zip(t, h_unsorted, strict=True):
        assert hi == exact.state([ti])[0][0]


def test_extremum_at_the_start_found_by_round_off():
    """A contact starting at a minimum with v0 = -1e-38 (found by hypothesis) must still leave."""
    ball = Ball(m=1.0, k=100.0, b=0.0, R=0.5, g=1.0)
    reference = ExactSolution(ball, 0.0, 0.0, 0.0, 3.0)
    nudged = ExactSolution(ball, 0.0, -1.1754943508222875e-38, 0.0, 3.0)
    assert [e.kind for e in reference.events] == ["departure"]
    assert [e.kind for e in nudged.events] == ["departure"]
    assert nudged.events[0].time == pytest.approx(reference.events[0].time, rel=1e-14)
    # undamped: leaves at the speed sqrt(w^2 (y0^2 - d^2)) from energy conservation
    w2, d, y0 = 100.0, 0.01, -0.49
    assert nudged.events[0].velocity == pytest.approx(math.sqrt(w2 * (y0**2 - d**2)), rel=1e-12)


def test_state_at_the_events_is_the_event_and_continuous_across_it():
    """Each event time belongs to the phase it starts (h = R, the event's velocity); just before it, the previous
    phase's flow reaches the same state."""
    ball = Ball()
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, 8.0)
    times = np.array([e.time for e in exact.events])
    h, v = exact.state(times)
    assert np.all(h == ball.R)
    assert np.array_equal(v, [e.velocity for e in exact.events])
    h_before, v_before = exact.state(times - 1e-9)
    assert np.max(np.abs(h_before - ball.R)) <= 1e-8 and np.max(np.abs(v_before - v)) <= 1e-4


def test_departure_search_converges_by_newton(monkeypatch):
    """Newton's last ulp-sized step once landed on the bracket's end and set off ~50 bisections per departure;
    from the half-cosine start Newton needs 3 steps and one evaluation that confirms."""
    from bouncingball.contact_laws import linear

    evaluations, inside = [], []  # the flow's evaluations per search: counted inside _departure_root
    flow, search = linear.contact_gap_flow, linear._departure_root

    def counting_flow(*args):
        if inside:
            inside[-1] += 1
        return flow(*args)

    def counting_search(*args):
        inside.append(0)
        try:
            return search(*args)
        finally:
            evaluations.append(inside.pop())

    monkeypatch.setattr(linear, "contact_gap_flow", counting_flow)
    monkeypatch.setattr(linear, "_departure_root", counting_search)
    solution = ExactSolution(Ball(), 2.0, 0.0, 0.0, 8.0)
    assert len(evaluations) == len(solution.events) // 2 + 1  # each departure, and the search that finds none
    assert max(evaluations) <= 5, evaluations


def test_a_contact_that_does_not_move_leaves_without_dividing_by_zero():
    """At its (rounded) rest height with v0 ~ 0, a contact's next minimum and maximum are equal (found by hypothesis:
    the departure search's starting guess divided by their difference). Forces of 1e-15 N on 1 kg move it by at most
    0.5 * 1e-15 * t^2 m."""
    ball = Ball(m=1.0, k=10.0, b=0.0, R=1.0, g=0.0)
    F_ext = 1e-15
    solution = ExactSolution(ball, ball.rest_height(F_ext), -2.225073858507203e-309, 0.0, 3.0, F_ext)
    h, _ = solution.state(np.linspace(0.0, 3.0, 301))
    assert np.max(np.abs(h - ball.R)) <= 0.5 * F_ext * 3.0**2 + 4 * math.ulp(ball.R)


def test_bounces_below_an_ulp_of_r_lose_energy_and_come_to_rest():
    """A static deflection of 1.7 ulps of R (found by hypothesis): with the contact's deflection taken as
    h - (R - d), R - d rounded d to ulp(R) and each sub-ulp bounce regained what damping took, a chatter of
    ~1e7 hops. Each contact takes exp(-zeta pi / sqrt(1 - zeta^2)) of the impact speed u, and one ends for
    good once the speed it returns with is below w d sqrt(exp(2 zeta pi) - 1): that bounds the contacts."""
    m, k, zeta, R, g = 1.566292822959508e-05, 263564838396.437, 0.007062432519941699, 0.30717894468230245, 1.62
    ball = Ball(m=m, k=k, b=2 * zeta * math.sqrt(k * m), R=R, g=g)
    d, omega = ball.static_deflection(), math.sqrt(k / m)
    assert d < 2 * math.ulp(R)
    h0 = R + 1.566292822959508e-05
    solution = within_seconds(10, ExactSolution, ball, h0, 0.0, 0.0, 2.0)
    assert solution.rest_time is not None
    u = math.sqrt(2 * g * (h0 - R))
    loss = zeta * math.pi / math.sqrt(1 - zeta**2)
    contacts = math.log(u / (omega * d * math.sqrt(math.exp(2 * zeta * math.pi) - 1))) / loss
    assert len(solution.events) <= 2 * (1.1 * contacts + 2)


def within_seconds(seconds, function, *args):
    """function(*args), or TimeoutError after seconds: a loop that would never end fails instead of hanging."""
    def stop(signum, frame):
        raise TimeoutError(f"{function.__name__} still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, stop)
    signal.alarm(seconds)
    try:
        return function(*args)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def test_a_departure_never_leaves_downwards():
    """At R with v0 = -2e-112 m/s and a lift of 1e-18 N (found by hypothesis): the contact ended at once, but
    the flow rounded the speed it left with to -2e-112, so the flight ended at once too, and so on for ever at
    t = 0. The lift exceeds the weight (g = 0): one departure, then the ball never comes back."""
    ball = Ball(m=1.0, k=100.0, b=0.0, R=1.0, g=0.0)
    solution = within_seconds(10, ExactSolution, ball, ball.R, -2.374447051180475e-112, 0.0, 3.0, 1e-18)
    assert [(str(e.kind), e.velocity >= 0.0) for e in solution.events] == [("departure", True)]


@pytest.mark.parametrize("solver", ["exact", "cvode"])
def test_a_lift_near_critical_damping_leaves_the_ground(solver):
    """Damping ratio just below 1 (b = 2 sqrt(k m) rounds below critical), lifted by twice the weight.

    The first extremum lies many decay times away, and its height was decided on y(tau1) - d + d,
    below the rounding of d: the ball was held at R for ever. Truth from a 40-digit mpmath solution
    (the issue's): it leaves at 0.02110 s at 0.02698 m/s and is at 4.787 m at t = 1 s.
    """
    m, k = 0.1, 1e4
    ball = Ball(m=m, k=k, b=2 * math.sqrt(k * m))
    result = bouncingball.simulate(ball, 0.05, 0.0, 1.0, 1e-3, solver=solver, F_ext=2 * m * 9.81)
    assert [str(e.kind) for e in result.events] == ["departure"]
    assert result.events[0].time == pytest.approx(0.02110, abs=5e-6)
    assert result.events[0].velocity == pytest.approx(0.02698, abs=5e-6)
    assert result.h[-1] == pytest.approx(4.787, abs=5e-4)
