"""The linear-no-pull law: the spring-damper whose force never pulls, max(0, k (R - h) - b v) (Modelica's ElastoGap).

Below R the ball is pressed (Mode.CONTACT) while that force is positive and free (Mode.FREE, the flight's parabola)
where it would pull, switching where k (R - h) - b v crosses 0: a release (pressed to free) and an engagement
(free to pressed). The force is -k z with z = x + (b / k) v (pressed_gap), which obeys the pressed contact's own
equation: its release is the linear law's departure search of (z, dz/dt). With b = 0 it is the linear law (and
Ball.parameters gives it the linear law's code).
"""

from __future__ import annotations

import math

from ..codes import CONTACT
from ..equations import gap_acceleration, sine_flight_flow, sine_flight_touch, sine_value
from ..oscillator import contact_gap_flow
from ..rounding import hypot
from .common import BY_CVODE, IN_CLOSED_FORM, NO_PULL, REST, ContactLaw, surely_below, time_to_impact
from .linear import departure_time, searches, sine_ground_departure, sine_ground_flow

_EPS = 2.0**-52


def no_pull_rest_margin_value(x, v, d, hop_tolerance, w2, sigma):
    """w2^2 (d + hop)^2 - (w2 + 4 sigma^2)(v^2 + w2 y^2) [m2/s4]: positive once a pressed no-pull ball never leaves.

    y = x + d, the deflection from the rest height. The force is k (d - y) - b v, and it reaches 0 where
    w2 y + 2 sigma v = w2 d; by Cauchy-Schwarz w2 y + 2 sigma v <= sqrt(w2 + 4 sigma^2) sqrt(v^2 + w2 y^2),
    and the energy v^2 + w2 y^2 never grows in contact (nor in the free sub-mode), so once the margin is
    positive with hop = 0 the force stays positive for ever. hop [m] (the hop tolerance) lets the force
    dip to -k hop at most, a pull the run may merge as it merges a hop. Written as
    w2^2 (hop - x)(2 d + hop + x) - 4 sigma^2 w2 y^2 - (w2 + 4 sigma^2) v^2, which keeps x's digits.
    """
    y = x + d
    return w2 * w2 * ((hop_tolerance - x) * (2.0 * d + hop_tolerance + x)) - 4.0 * sigma * sigma * w2 * (y * y) \
        - (w2 + 4.0 * sigma * sigma) * (v * v)


def pressed_gap(parameters, x, v, load):
    """(z [m], dz/dt [m/s]) of the pressed no-pull contact at the gap x [m] and v [m/s]: z = x + (b / k) v = -force / k.

    The force k (R - h) - b v = -k z reaches 0 where z crosses 0: going up the ball is released (the
    force would pull), going down it is pressed again. z obeys the pressed contact's own equation
    (z'' + 2 sigma z' + w2 z = -g_eff, as x does), so its crossing upwards is the linear law's departure
    search of (z, dz/dt) (linear.departure_time); in the free sub-mode it moves on the flight's parabola
    from (z, dz/dt) too, and its crossing downwards is an impact's. dz/dt = v + (b / k) a, with a the
    pressed contact's acceleration. parameters: Ball.parameters.
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    c = b / k
    return x + c * v, v + c * gap_acceleration(x, v, CONTACT, load, m, k, b)


def free_gap_rate(parameters, v, load):
    """dz/dt [m/s] in the free sub-mode at v [m/s]: v - (b / k) g_eff (pressed_gap's z on the parabola)."""
    return v - (parameters.b / parameters.k) * (load / parameters.m)


def release_time(parameters, x0, v0, load):
    """Time [s] from the gap x0 [m] and v0 [m/s] in a pressed no-pull contact to its release; inf if none.

    The release is where the force k (R - h) - b v falls to 0, where contact_laws.pressed_gap's z crosses 0
    upwards; z obeys the contact's equation as x does, so it is departure_time's search of (z, dz/dt).
    Arguments as departure_time's.
    """
    z, rate = pressed_gap(parameters, x0, v0, load)
    return departure_time(parameters, z, rate, load)


def release_state(parameters, x0, v0, tau, load):
    """(x [m], v [m/s]) of a pressed no-pull contact from (x0, v0) at its release tau later (release_time): v >= 0.

    The force is 0 there, k x = -b v: below R the ball rises (v >= 0; the flow may round a grazing
    release's speed below 0).
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    x, v = contact_gap_flow(b / (2.0 * m), k / m, load / m, x0, v0, tau)
    return x, max(v, 0.0)


def free_event(parameters, x0, v0, load):
    """(tau [s], x [m], v [m/s], departs): the event ending the free sub-mode from the gap x0 <= 0 [m] at v0 [m/s].

    The ball moves on the flight's parabola (g_eff = load / m). It departs where x reaches 0 going up:
    tau = -2 x0 / (v0 + s), s = sqrt(v0^2 + 2 g_eff x0), at v = s (no cancellation, as time_to_impact);
    it is pressed again (engages) where contact_laws.pressed_gap's z, a parabola from (z0, free_gap_rate),
    falls back to 0: time_to_impact of z. The first of the two; (inf, x0, v0, True) where neither comes
    (a weightless ball at rest on R). departs: whether it is the departure (x = 0 there exactly).
    """
    g_eff = load / parameters.m
    z, rate = pressed_gap(parameters, x0, v0, load)[0], free_gap_rate(parameters, v0, load)
    disc = v0 * v0 + 2.0 * g_eff * x0
    tau_departure, s = math.inf, 0.0
    if disc >= 0.0:
        s = math.sqrt(disc)
        if v0 + s > 0.0:
            tau_departure = -2.0 * x0 / (v0 + s)
    if z <= 0.0 and rate <= 0.0:
        tau_engage = 0.0  # a grazing release (the force only touched 0): pressed again at once
    elif z < 0.0 and rate * rate + 2.0 * g_eff * z < 0.0:
        tau_engage = 0.0  # z an ulp below 0 and turning back before it: the same
    else:
        tau_engage = time_to_impact(max(z, 0.0), rate, g_eff)[0]
    if tau_departure <= tau_engage:
        return tau_departure, 0.0, s, True
    if math.isinf(tau_engage):
        return math.inf, x0, v0, True
    return tau_engage, x0 + tau_engage * (v0 - 0.5 * g_eff * tau_engage), v0 - g_eff * tau_engage, False


def decide_contact(parameters, x, v, load, hop, resolution):
    """(answer, tau, x_event, v_event) of a pressed contact from (x, v): the linear law's, its event the release.

    A rest once no_pull_rest_margin_value proves the force can never again reach 0 (or dip below -k hop); else
    the exact flow's release search (release_time) where linear.searches says so; else CVODE.
    """
    m, k = parameters.m, parameters.k
    d = load / k
    if d > 0.0 and no_pull_rest_margin_value(x, v, d, hop, k / m, parameters.b / (2.0 * m)) > 0.0:
        return REST, 0.0, 0.0, 0.0
    rest_by_search, in_closed_form = searches(parameters, x, v, load, resolution)
    if not (rest_by_search or in_closed_form):
        return BY_CVODE, 0.0, 0.0, 0.0
    tau = release_time(parameters, x, v, load)
    if math.isinf(tau):
        return (REST if rest_by_search else BY_CVODE), 0.0, 0.0, 0.0
    if in_closed_form:
        x_event, v_event = release_state(parameters, x, v, tau, load)
        return IN_CLOSED_FORM, tau, x_event, v_event
    return BY_CVODE, 0.0, 0.0, 0.0


def sine_ground_release(parameters, x0, u0, load, forcing, w, theta0, horizon):
    """(tau [s], x [m], u [m/s]) at the release of a pressed contact on a vibrating ground; (tau, nan, nan) if none.

    In the ground's frame (x = h - R - s, u = v - s', linear.sine_ground_flow) the force is -k z, z = x + c u,
    c = b / k, and z obeys the contact's equation forced by the ground's acceleration and its rate:
    z'' + 2 sigma z' + w2 z = -g_eff + forcing (sin theta + c w cos theta) = -g_eff + forcing_z sin(theta + delta),
    forcing_z = forcing sqrt(1 + (c w)^2), tan delta = c w. Its release is linear.sine_ground_departure's
    certified search of (z, z'); tau inf: never (a rest), tau > horizon [s]: none within it.
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    c = b / k
    acceleration = gap_acceleration(x0, u0, CONTACT, load, m, k, b) + forcing * math.sin(theta0)
    tau, _ = sine_ground_departure(parameters, x0 + c * u0, u0 + c * acceleration, load,
                                   forcing * hypot(1.0, c * w), w, theta0 + math.atan2(c * w, 1.0), horizon)
    if not tau <= horizon or math.isinf(tau):  # none within it; inf: never (horizon inf)
        return tau, math.nan, math.nan
    x, u = sine_ground_flow(parameters, x0, u0, tau, load, forcing, w, theta0)
    return tau, x, max(u, 0.0)  # where the force is 0 below the surface, k x = -b u: the ball rises


def sine_free_event(parameters, x0, u0, load, t0):
    """(tau [s], x [m], u [m/s], departs): the event ending a free spell from (x0 <= 0, u0) at t0 on a vibrating ground.

    In the ground's frame (x = h - R - s, u = v - s'; BallParameters' ground_* fields), the ball flies its parabola
    below the surface. It departs where x reaches 0 going up: a flight's first touch (equations.sine_flight_touch,
    certified) of -x above the ground -s; it is pressed again (engages) where z = x + c u, c = b / k, falls to 0: a
    flight's first touch of z above s + c s' = A sqrt(1 + (c w)^2) sin(theta + atan(c w)). The first of the two, a
    departure on a tie (x = 0 there exactly); the searches end where one of the two parabolas, less twice its
    ground's amplitude, is below it for certain (common.surely_below: one of the two must have come by then). Only a
    weightless ball at rest in the world (g_eff = 0, v = 0) has no such end: its searches run to their step limit
    (a RuntimeError) if neither comes. A spell starting at its release (z within its rounding of 0) leaves that
    surface.
    """
    m, c = parameters.m, parameters.b / parameters.k
    amplitude, w, phase = parameters.ground_amplitude, parameters.ground_omega, parameters.ground_phase
    g_eff = load / m
    engage_amplitude, engage_phase = amplitude * hypot(1.0, c * w), phase + math.atan2(c * w, 1.0)
    z0, z_rate = x0 + c * u0, u0 - c * (g_eff + sine_value(amplitude, w, phase, t0, 2))
    released = abs(z0) <= 16.0 * _EPS * (abs(x0) + c * abs(u0))
    slope = sine_value(amplitude, w, phase, t0, 1)  # the world's speeds: of z's parabola, and of -x's
    z_world = z_rate + sine_value(engage_amplitude, w, engage_phase, t0, 1)
    horizon = min(surely_below(z0, z_world, g_eff, engage_amplitude), surely_below(-x0, -(u0 + slope), -g_eff,
                                                                                   amplitude))
    tau_engage = sine_flight_touch(m, engage_amplitude, w, engage_phase, t0, z0, z_rate, load, horizon, released)
    tau_depart = sine_flight_touch(m, -amplitude, w, phase, t0, -x0, -u0, -load, min(horizon, tau_engage), False)
    if tau_depart <= tau_engage:
        u = sine_flight_flow(m, amplitude, w, phase, x0, u0, t0, tau_depart, load)[1]
        return tau_depart, 0.0, max(u, 0.0), True
    x, u = sine_flight_flow(m, amplitude, w, phase, x0, u0, t0, tau_engage, load)
    return tau_engage, x, u, False


def contact_roots(y0, y1, length, speed, load, own_side, hop, k, m, b):
    """CVODE's three root functions in a pressed contact, in the phase's frame (phases.root_values).

    pressed_gap's z = -force / k in the gap's place (its crossing upwards the release), dz/dt in v's (a step ends at
    each extremum of z, so that none holds both crossings of a short free spell) and no_pull_rest_margin_value.
    """
    d = load / k
    c = b / k
    z = y0 + (c * speed / length) * y1
    rate = y1 + c * gap_acceleration(length * y0, speed * y1, CONTACT, load, m, k, b) / speed
    sigma = b / (2.0 * m)
    rest = no_pull_rest_margin_value(length * y0, speed * y1, d, hop, k / m, sigma) if d > 0.0 else -1.0
    return z if z != 0.0 else own_side, rate, rest


# The law's entry in the registry (contact_laws.LAWS).
LAW = ContactLaw("linear-no-pull", NO_PULL, ("k", "b"), closed_form=True,
                 description="the spring-damper whose force never pulls",
                 article_algorithm=False, crossings_only=False, k_unit="N/m", damping_axis="zeta",
                 summary="no-pull contact, k = {k:g} N/m, b = {b:g} N s/m",
                 undamped_as="linear")  # its force k (R - h) - b v with b = 0 never pulls below R
