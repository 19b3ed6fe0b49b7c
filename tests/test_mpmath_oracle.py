"""The oracle (tests/mpmath_oracle.py) checked against things that share no code with it.

Conservation of energy, the textbook free fall, the critically damped closed form, mpmath's matrix
exponential and Taylor-series ODE integrator, and numbers quoted by the issue and the article.
"""

import math

import mpmath
import numpy as np
import pytest

from closed_forms import undamped_event_count
from mpmath_oracle import CONTACT, DEPARTURE, DPS, IMPACT, Oracle, mp

ARTICLE = {"m": 1.0, "k": 1e4, "b": 10.0, "R": 0.06, "g": 9.81}


def oracle(ball, h0, v0, t_end, F_ext=0.0):
    return Oracle(ball["m"], ball["k"], ball["b"], ball["R"], ball["g"], h0, v0, t_end, F_ext=F_ext)


def test_the_oracle_works_with_more_than_40_digits_whatever_the_global_context():
    saved = mpmath.mp.dps
    try:
        mpmath.mp.dps = 15
        o = oracle(ARTICLE, 2.0, 0.0, 1.0)
        assert DPS >= 40 and mp.dps == DPS
        t_fall = mp.sqrt(2 * (mp.mpf(2) - mp.mpf(0.06)) / mp.mpf(9.81))
        assert abs(o.events[0].time - t_fall) <= mp.mpf(10) ** -45
    finally:
        mpmath.mp.dps = saved


# --- flight ---------------------------------------------------------------------------------------
def test_free_fall_from_rest():
    h0, R, g = 5.0, 0.1, 9.81
    o = oracle(dict(ARTICLE, R=R, g=g), h0, 0.0, 3.0)
    t_fall = mp.sqrt(2 * (mp.mpf(h0) - mp.mpf(R)) / mp.mpf(g))
    first = o.events[0]
    assert first.kind == IMPACT
    assert abs(first.time - t_fall) <= mp.mpf(10) ** -45
    assert abs(first.velocity + mp.mpf(g) * t_fall) <= mp.mpf(10) ** -44
    for t in np.linspace(0.0, float(t_fall) * (1 - 1e-9), 37):
        h, v = o.state_mp(t)
        assert abs(h - (mp.mpf(h0) - mp.mpf(g) * mp.mpf(t) ** 2 / 2)) <= mp.mpf(10) ** -45
        assert abs(v + mp.mpf(g) * mp.mpf(t)) <= mp.mpf(10) ** -45


def test_throw_upwards_with_a_force_lands_after_apex_plus_fall_from_apex():
    m, g, F, h0, v0, R = 2.0, 9.81, 4.5, 1.25, 3.5, 0.1
    o = Oracle(m, 1e5, 3.0, R, g, h0, v0, 5.0, F_ext=F)
    a = mp.mpf(g) - mp.mpf(F) / mp.mpf(m)
    apex_time = mp.mpf(v0) / a
    apex = mp.mpf(h0) + mp.mpf(v0) ** 2 / (2 * a)
    assert abs(o.state_mp(apex_time)[1]) <= mp.mpf(10) ** -45
    assert abs(o.state_mp(apex_time)[0] - apex) <= mp.mpf(10) ** -45
    landing = apex_time + mp.sqrt(2 * (apex - mp.mpf(R)) / a)
    assert abs(o.events[0].time - landing) <= mp.mpf(10) ** -45
    assert abs(o.events[0].velocity + a * (landing - apex_time)) <= mp.mpf(10) ** -44


def test_each_flight_is_symmetric():
    o = oracle(ARTICLE, 2.0, 0.0, 8.0)
    g = mp.mpf(9.81)
    for up, down in zip(o.events[1::2], o.events[2::2], strict=False):
        assert up.kind == DEPARTURE and down.kind == IMPACT
        assert abs(up.velocity + down.velocity) <= mp.mpf(10) ** -45
        assert abs((down.time - up.time) - 2 * up.velocity / g) <= mp.mpf(10) ** -45


def test_a_ball_lifted_by_more_than_its_weight_never_comes_down():
    o = oracle(ARTICLE, 1.0, -1.0, 10.0, F_ext=12.0)  # decelerates at 2.19 m/s2: turns at 1.23 m
    assert o.events == [] and o.rest_time is None


# --- energy ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("F_ext", [0.0, 3.0])
def test_energy_is_conserved_without_damping(F_ext):
    m, k, R, g = 1.0, 1e4, 0.06, 9.81
    o = Oracle(m, k, 0.0, R, g, 2.0, 0.0, 8.0, F_ext=F_ext)
    m, k, R, g, F = (mp.mpf(x) for x in (m, k, R, g, F_ext))

    def energy(t):
        h, v = o.state_mp(t)
        spring = k * (R - h) ** 2 / 2 if h < R else 0
        return m * v * v / 2 + (m * g - F) * h + spring

    times = list(np.linspace(0.0, 8.0, 301)) + [e.time + s for e in o.events for s in (-1e-7, 1e-7)]
    e0 = energy(0.0)
    assert len(o.events) >= 10
    assert max(abs(energy(t) - e0) for t in times) <= mp.mpf(10) ** -40 * e0


def test_undamped_event_count_matches_the_periodic_closed_form():
    ball = dict(ARTICLE, b=0.0)
    o = oracle(ball, 2.0, 0.0, 30.0)
    assert len(o.events) == undamped_event_count(1.0, 1e4, 0.06, 9.81, 2.0, 30.0)


# --- contact: closed forms, expm, odefun ----------------------------------------------------------
CRITICAL = {"m": 0.25, "k": 16.0, "b": 4.0, "R": 1.0, "g": 9.81}  # b^2 = 4 k m exactly in binary


def critical_y(y0, v0, sigma, t):
    return (y0 + (v0 + sigma * y0) * t) * mp.exp(-sigma * t)


def test_critical_damping_is_the_closed_form():
    o = oracle(CRITICAL, 0.95, -2.0, 3.0)
    d = mp.mpf(0.25) * mp.mpf(9.81) / 16
    y0, sigma = mp.mpf(0.95) - 1 + d, mp.mpf(8)
    assert o.events == [] and o.rest_time == 0
    for t in np.linspace(0.0, 3.0, 61):
        y = o.state_mp(t)[0] - 1 + d
        assert abs(y - critical_y(y0, mp.mpf(-2), sigma, mp.mpf(t))) <= mp.mpf(10) ** -45


def test_critical_damping_lifted_leaves_where_the_closed_form_crosses_r():
    m, k, g = 0.25, 16.0, 9.81
    weight = m * g  # exactly representable here
    h0 = 1.0 - weight / k
    o = oracle(CRITICAL, h0, 0.0, 2.0, F_ext=2 * weight)
    d = -mp.mpf(weight) / 16
    y0 = mp.mpf(h0) - 1 + d
    assert [e.kind for e in o.events] == [DEPARTURE]
    t_dep = o.events[0].time
    assert abs(critical_y(y0, 0, 8, t_dep) - d) <= mp.mpf(10) ** -45
    assert all(critical_y(y0, 0, 8, t_dep * s) < d for s in (0.1, 0.5, 0.9, 0.999999))
    # velocity: derivative of the closed form
    v_dep = (-8 * (y0 + 8 * y0 * t_dep) + 8 * y0) * mp.exp(-8 * t_dep)
    assert abs(o.events[0].velocity - v_dep) <= mp.mpf(10) ** -45


@pytest.mark.parametrize("ratio", [0.3, 1 - 1e-15, 1 - 2**-52, 1.0, 1 + 2**-52, 1 + 1e-15, 4.0])
def test_contact_flow_is_the_matrix_exponential(ratio):
    m, k, R, g = 0.5, 2.0e3, 0.2, 9.81
    b = 2 * ratio * math.sqrt(k * m)
    o = Oracle(m, k, b, R, g, 0.17, -0.8, 1.0)
    M, K, B, G = (mp.mpf(x) for x in (m, k, b, g))
    A = mp.matrix([[0, 1], [-K / M, -B / M]])
    d = M * G / K
    x0 = mp.matrix([mp.mpf(0.17) - mp.mpf(R) + d, mp.mpf(-0.8)])
    end = o.events[0].time if o.events else mp.mpf(1)
    for t in np.linspace(0.0, float(end) * (1 - 1e-9), 12)[1:]:  # inside the contact
        x = mp.expm(A * mp.mpf(t)) * x0
        h, v = o.state_mp(t)
        assert abs(h - mp.mpf(R) + d - x[0]) <= mp.mpf(10) ** -40
        assert abs(v - x[1]) <= mp.mpf(10) ** -40 * 10


@pytest.mark.parametrize("delta", [-1e-15, 1e-15])
def test_within_1e_15_of_critical_the_flow_is_the_critical_one_to_1e_15(delta):
    ball = dict(CRITICAL, b=4.0 * (1 + delta))
    o = oracle(ball, 0.95, -2.0, 3.0)
    d = mp.mpf(0.25) * mp.mpf(9.81) / 16
    y0 = mp.mpf(0.95) - 1 + d
    for t in np.linspace(0.0, 3.0, 31):
        y = o.state_mp(t)[0] - 1 + d
        assert abs(y - critical_y(y0, mp.mpf(-2), mp.mpf(8), mp.mpf(t))) <= 1e-14 * abs(y0)


@pytest.mark.parametrize("b", [10.0, 2 * math.sqrt(1e4) * (1 - 1e-9)])
def test_contact_agrees_with_mpmath_odefun(b):
    m, k, R, g, F = 1.0, 1e4, 0.06, 9.81, 15.0
    h0, v0 = 0.0585, -0.3
    o = Oracle(m, k, b, R, g, h0, v0, 0.2, F_ext=F)
    assert o.phases[0].mode == CONTACT and o.events[0].kind == DEPARTURE
    t_dep = o.events[0].time
    saved = mpmath.mp.dps
    try:
        mpmath.mp.dps = 40
        M, K, B, RR, G, FF = (mpmath.mpf(x) for x in (m, k, b, R, g, F))
        sol = mpmath.odefun(lambda t, u: [u[1], (-B * u[1] + K * (RR - u[0]) - M * G + FF) / M], 0,
                            [mpmath.mpf(h0), mpmath.mpf(v0)])
        for s in np.linspace(0.05, 1.0, 8):
            t = mpmath.mpf(str(t_dep)) * mpmath.mpf(s)
            h, v = sol(t)
            ho, vo = o.state_mp(mp.mpf(str(t)))
            assert abs(h - mpmath.mpf(str(ho))) <= mpmath.mpf(10) ** -30
            assert abs(v - mpmath.mpf(str(vo))) <= mpmath.mpf(10) ** -28
        crossing = mpmath.findroot(lambda t: sol(t)[0] - RR, mpmath.mpf(str(t_dep)))
        assert abs(crossing - mpmath.mpf(str(t_dep))) <= mpmath.mpf(10) ** -28
    finally:
        mpmath.mp.dps = saved


def test_rest_by_energy_bound_and_by_monotone_approach():
    # under-damped, starting at the rest height with a speed too small to reach R: rest at once
    o = oracle(ARTICLE, 0.06 - 9.81e-4, 0.05, 1.0)
    assert o.events == [] and o.rest_time == 0
    # ... and with a speed just large enough (w d = 0.0981 m/s, plus damping): leaves
    o = oracle(ARTICLE, 0.06 - 9.81e-4, 0.2, 1.0)
    assert o.events[0].kind == DEPARTURE
    # over-damped, lifted to exactly R (d = 0): approaches R for ever
    o = oracle(dict(ARTICLE, b=1e3), 0.059, 0.0, 1.0, F_ext=9.81)
    assert o.events == [] and o.rest_time == 0
    assert 0 < 0.06 - float(o.state_mp(1.0)[0]) < 1e-4


# --- numbers quoted by the article and the issue ------------------------------------------------
def test_article_scene_has_21_impacts_in_8_s():
    o = oracle(ARTICLE, 2.0, 0.0, 8.0)
    assert sum(e.kind == IMPACT for e in o.events) == 21
    assert [e.kind for e in o.events] == [IMPACT, DEPARTURE] * 20 + [IMPACT]


def test_issue_lifted_near_critical_contact():
    m, k = 0.1, 1e4
    o = Oracle(m, k, 2 * math.sqrt(k * m), 0.06, 9.81, 0.05, 0.0, 1.0, F_ext=2 * m * 9.81)
    assert [e.kind for e in o.events] == [DEPARTURE]
    assert float(o.events[0].time) == pytest.approx(0.02110, abs=5e-6)
    assert float(o.events[0].velocity) == pytest.approx(0.02698, abs=5e-6)
    assert float(o.state_mp(1.0)[0]) == pytest.approx(4.787, abs=5e-4)


@pytest.mark.slow
def test_issue_undamped_micro_hops():
    o = Oracle(1.0, 1e12, 0.0, 0.06, 9.81, 0.06, 1.7717787672280082e-4, 0.05)
    assert len(o.events) == 2538 and o.rest_time is None
    assert len(o.events) == undamped_hop_count(1.0, 1e12, 0.06, 9.81, 1.7717787672280082e-4, 0.05)


def undamped_hop_count(m, k, R, g, v0, t_end):
    """Events of an undamped ball leaving R at v0 > 0: flights 2 v0/g, contacts (pi + 2 asin(d/A))/w."""
    w = math.sqrt(k / m)
    d = m * g / k
    contact = (math.pi + 2 * math.asin(d / math.hypot(d, v0 / w))) / w
    flight = 2 * v0 / g
    cycles, rest = divmod(t_end, flight + contact)
    return 2 * int(cycles) + (rest >= flight) + (rest >= flight + contact)
