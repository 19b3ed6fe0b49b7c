"""The exact solution of a ball on a moving ground: parabolas, certified first touches, rides or forced contacts.

Each flight is a parabola in the world frame; its impact is the first root of its gap to the ground, found by
Ground.first_touch, which steps over no grazing impact. The impact acts on the velocity relative to the ground,
v+ - s' = -e (v- - s'); a rebound slower than v_min relative to the ground, or (v_min = 0) one whose bounces
would rise less than ZENO_APEX R above it while the ground pushes (complete chattering, summed as the still
ground's Zeno series in the ground's frame, under the relative load m (g_eff + s'')), ends in a ride: the
ball on the ground, h = R + s, v = s', until s'' falls below -g_eff (Ground.ride_end), where it leaves at no
relative speed. The rigid law's contact mode is that ride; on a still ground it is today's rest on R.

The linear law (on a sine ground) has no impact rule: its contact is the still ground's damped oscillator in the
ground's frame, x = h - R - s, forced by the ground's acceleration -s'' (contact_laws.linear.sine_ground_flow: the
still ground's closed form plus the periodic response), left at the first upward crossing of x = 0, a certified
first root (sine_ground_departure); a contact that energy proves can never reach the surface again is a rest.
The still ground's rest shortcuts (the rest at R - m g / k, the hop tolerance) do not apply: a ball resting on a
vibrating table keeps oscillating with it.

The error estimate (exact_error.RoundingCarry) carries each parabola's rounding through its flow; an impact's
time error enters as the state error it leaves (on a moving ground it is no pure delay), and the impact's
saltation matrix is the rigid law's in the ground's frame (relative speed, relative load). A ride forgets what
came before: its position is the ground's.
"""

from __future__ import annotations

import math

from .. import limits
from ..codes import CONTACT as CONTACT_CODE
from ..codes import DEPARTURE as DEPARTURE_CODE
from ..codes import FLIGHT as FLIGHT_CODE
from ..codes import IMPACT as IMPACT_CODE
from ..contact_laws import rigid_rebound
from ..contact_laws.linear import sine_ground_departure, sine_ground_flow
from ..contact_laws.rigid import ZENO_APEX
from ..equations import load_value
from ..ground import first_touch
from ..oscillator import sine_response_gain
from ..physics import Mode
from ..rounding import later
from . import forcing
from .result import DEPARTURE, IMPACT, Event


def build_on_moving_ground(solution, h: float, v: float) -> None:
    """Fill solution's phases, events and rest_time (an ExactSolution on a moving ground) from (h, v) at t_start."""
    ball, ground, R = solution.ball, solution.ground, solution.ball.R
    surface = ground.position(solution.t_start)
    if ball.rigid and h - R - surface < -16.0 * 2.0**-52 * (abs(h) + R + abs(surface)):  # below by more than a rounding
        raise ValueError(f"h0 = {h!r} m is not allowed: under the rigid contact law it must be >= R + s(t_start) = "
                         f"{R + surface!r} m (the ball cannot start inside the ground)")
    pieces = forcing.pieces(solution.F_ext, solution.t_start, solution.t_end)
    mode, on_ground = None, False
    for number, (t, piece_end, F_ext) in enumerate(pieces):
        a = ball.effective_gravity(F_ext)
        if mode is None:
            mode, on_ground = _initial_mode(ball, ground, t, h, v, a)
        elif mode == Mode.FLIGHT:
            phase = solution.phases[-1]
            tau = t - phase.t_start
            a_before = ball.effective_gravity(phase.F_ext)
            h, v = phase.h0 + tau * (phase.v0 - 0.5 * a_before * tau), phase.v0 - a_before * tau
            on_ground = False
        elif not ball.rigid:  # in contact: where its forced flow has the ball
            phase = solution.phases[-1]
            h, v = contact_state(solution, phase.t_start, phase.h0, phase.v0, t - phase.t_start,
                                 load_value(phase.F_ext, ball.m, ball.g))
        mode, h, v, on_ground = _phases_in_piece(solution, t, piece_end, F_ext, a, mode, h, v, on_ground,
                                                 number == len(pieces) - 1)


def _initial_mode(ball, ground, t, h, v, a):
    """(mode, on_ground) of a ball starting at (h, v) at t.

    A rigid ball rides where it is on the ground with it and pressed; a compliant one is in contact below the
    surface, or on it moving into it (or with it, pressed).
    """
    R = ball.R
    gap, relative = h - R - ground.position(t), v - ground.velocity(t)
    pressed = a + ground.acceleration(t) >= 0.0
    if not ball.rigid:
        if gap < 0.0 or (gap == 0.0 and (relative < 0.0 or (relative == 0.0 and pressed))):
            return Mode.CONTACT, False
        return Mode.FLIGHT, gap == 0.0
    on_ground = gap <= 16.0 * 2.0**-52 * (abs(h) + R)
    if on_ground and relative == 0.0 and pressed:
        return Mode.CONTACT, True
    return Mode.FLIGHT, on_ground and relative > 0.0


def _phases_in_piece(solution, t, piece_end, F_ext, a, mode, h, v, on_ground, last):
    """The phases from (h, v) in mode at t to piece_end under F_ext: (mode, h, v, on_ground) at piece_end."""
    ball, ground, R, carry = solution.ball, solution.ground, solution.ball.R, solution.rounding
    parameters, load = ball.parameters, load_value(F_ext, ball.m, ball.g)
    t_low, ride_from = 0.0, t  # t's rounding error; when a ride's chattering is over
    while True:
        if solution.add_phase(t, mode, h, v, F_ext):
            return mode, h, v, on_ground
        if mode == Mode.CONTACT and not ball.rigid:
            departure = _forced_contact(solution, t, piece_end, load, h, v, last)
            if departure is None:
                end = solution.phases[-1]
                return (mode, *contact_state(solution, end.t_start, end.h0, end.v0, piece_end - end.t_start, load),
                        False)
            t, h, v = departure
            mode, on_ground = Mode.FLIGHT, True
            continue
        if mode == Mode.CONTACT:  # riding
            t_leave = ground.ride_end(ride_from, a)
            if not t_leave <= piece_end:
                if last and math.isinf(t_leave):
                    solution.rest_time = ride_from
                return mode, R + ground.position(piece_end), ground.velocity(piece_end), True
            t, t_low = t_leave, 0.0
            h, v = R + ground.position(t), ground.velocity(t)
            solution.events.append(Event(t, DEPARTURE, v))
            carry.restart(t, abs(ground.position(t)) + R, abs(v))
            mode, on_ground = Mode.FLIGHT, True
            continue
        tau = first_touch(ground, t, h - R, v, a, piece_end - t, on_ground)
        t_event, t_event_low = later(t, t_low, tau) if tau < math.inf else (math.inf, 0.0)
        if not t_event <= piece_end:
            if piece_end < math.inf:
                carry.phase(t, FLIGHT_CODE, h - R, v, piece_end - t, load)
            return mode, h, v, on_ground
        v_minus = v - a * tau
        x_start, v_start = h - R, v
        t, t_low = t_event, t_event_low
        h, ground_speed = R + ground.position(t), ground.velocity(t)
        relative, relative_load = v_minus - ground_speed, ball.m * (a + ground.acceleration(t))
        solution.events.append(Event(t, IMPACT, v_minus))
        if not ball.rigid:  # into the forced contact: the law's saltation, the velocity unchanged
            carry.phase(solution.phases[-1].t_start, FLIGHT_CODE, x_start, v_start, tau, load)
            carry.moving_switch(t, tau, IMPACT_CODE, FLIGHT_CODE, relative, relative_load / ball.m,
                                ground.touch_rounding(solution.phases[-1].t_start, x_start, v_start, a, tau))
            v, mode, on_ground = v_minus, Mode.CONTACT, False
            continue
        rebound, zeno = rigid_rebound(parameters, min(relative, 0.0), relative_load)
        carry.phase(solution.phases[-1].t_start, FLIGHT_CODE, x_start, v_start, tau, load)
        carry.moving_impact(t, tau, relative, rebound, relative_load,
                            ground.touch_rounding(solution.phases[-1].t_start, x_start, v_start, a, tau))
        if zeno > 0.0:  # the summed bounces rise at most ZENO_APEX R above the ground
            carry.charge(t, ZENO_APEX * R)
        ride_from = later(t, t_low, zeno)[0]
        if rebound > 0.0 or (zeno == 0.0 and ground.ride_end(t, a) == t):  # on in flight (a ride that would end at
            v, on_ground = ground_speed + rebound, True  # once is none: the ball leaves with the ground)
            continue
        v, mode, on_ground = ground_speed, Mode.CONTACT, True


def _forced_contact(solution, t, piece_end, load, h, v, last):
    """The linear law's contact from (h, v) at t on a sine ground: (t, h, v) at its departure, or None past piece_end.

    Its event is a certified first root (contact_laws.linear.sine_ground_departure); a contact that can never
    reach the surface again in the last piece dates the rest (rest_time).
    """
    ball, ground, R, carry = solution.ball, solution.ground, solution.ball.R, solution.rounding
    if t > limits.resolvable_until(ball):  # contacts too short for the ulps of t
        limits.check_resolvable(ball, t)
    w, forcing, theta0 = ground.omega, ground.amplitude * ground.omega**2, ground.omega * t + ground.phase
    x0, u0 = h - R - ground.position(t), v - ground.velocity(t)
    tau, u = sine_ground_departure(ball.parameters, x0, u0, load, forcing, w, theta0, piece_end - t)
    sigma, w2 = ball.b / (2.0 * ball.m), ball.k / ball.m
    steady = forcing * sine_response_gain(sigma, w2, w)
    forced = (steady + abs(ground.position(t)), w * steady + abs(ground.velocity(t)))
    t_event, t_low = later(t, 0.0, tau) if tau < math.inf else (math.inf, 0.0)
    if not t_event <= piece_end:
        if piece_end < math.inf:
            carry.phase(t, CONTACT_CODE, h - R, v, piece_end - t, load, forced=forced)
        if last and math.isinf(tau):
            solution.rest_time = t
        return None
    carry.phase(t, CONTACT_CODE, h - R, v, tau, load, forced=forced)
    acceleration = -2.0 * sigma * u - load / ball.m - float(ground.acceleration(t_event))  # x'' at x = 0
    rounding = 16.0 * 2.0**-52 * (abs(x0) + abs(load / ball.k) + steady + abs(u0) / math.sqrt(w2))
    carry.moving_switch(t_event, tau, DEPARTURE_CODE, CONTACT_CODE, u, acceleration, rounding)
    v_event = float(ground.velocity(t_event)) + u
    solution.events.append(Event(t_event, DEPARTURE, v_event))
    return t_event, R + float(ground.position(t_event)), v_event


def contact_state(solution, t0, h0, v0, tau, load):
    """(h [m], v [m/s]) of the linear law's contact from (h0, v0) at t0 [s] on a sine ground, tau [s] later.

    t0, h0, v0, tau and load [N] floats or arrays of one shape (ExactSolution.state evaluates a grid at once).
    """
    ground, R = solution.ground, solution.ball.R
    w = ground.omega
    x0, u0 = h0 - R - ground.position(t0), v0 - ground.velocity(t0)
    x, u = sine_ground_flow(solution.ball.parameters, x0, u0, tau, load, ground.amplitude * w * w, w,
                            w * t0 + ground.phase)
    t = t0 + tau
    return R + ground.position(t) + x, ground.velocity(t) + u


def check_moving_ground(ball, ground) -> None:
    """ValueError where the exact solver cannot take this ground under this ball's law (before any work)."""
    if not ground.moves:
        return
    if ball.contact not in ("rigid", "linear"):
        raise ValueError(f"contact = {ball.contact!r} is not allowed on a moving ground ({ground.describe()}): "
                         "a moving ground is taken by the rigid and linear laws so far (contact = 'rigid' or "
                         "'linear'); run the other laws on a still ground")
    if ball.contact == "linear" and ground.kind != "sine":
        raise ValueError(f"contact = 'linear' is not allowed on a ground table ({ground.describe()}): the linear "
                         "law's contact on a moving ground is in closed form for a sine (Ground.sine); use the rigid "
                         "law on a table")
    if ball.contact == "linear" and math.isinf(sine_response_gain(ball.b / (2.0 * ball.m), ball.k / ball.m,
                                                                   ground.omega)):
        raise ValueError(f"b = 0 N s/m is not allowed with k = {ball.k!r} N/m on {ground.describe()}: undamped, the "
                         "contact is in resonance with the ground (k / m = (2 pi f)^2) and has no steady motion; "
                         "give a damping b > 0 or another frequency")


__all__ = ["build_on_moving_ground", "check_moving_ground", "contact_state"]
