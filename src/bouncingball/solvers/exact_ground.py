"""The exact solution of a rigid ball on a moving ground: parabolas, certified first touches, rides.

Each flight is a parabola in the world frame; its impact is the first root of its gap to the ground, found by
Ground.first_touch, which steps over no grazing impact. The impact acts on the velocity relative to the ground,
v+ - s' = -e (v- - s'); a rebound slower than v_min relative to the ground, or (v_min = 0) one whose bounces
would rise less than ZENO_APEX R above it while the ground pushes (complete chattering, summed as the still
ground's Zeno series in the ground's frame, under the relative load m (g_eff + s'')), ends in a ride: the
ball on the ground, h = R + s, v = s', until s'' falls below -g_eff (Ground.ride_end), where it leaves at no
relative speed. The rigid law's contact mode is that ride; on a still ground it is today's rest on R.

The error estimate (exact_error.RoundingCarry) carries each parabola's rounding through its flow; an impact's
time error enters as the state error it leaves (on a moving ground it is no pure delay), and the impact's
saltation matrix is the rigid law's in the ground's frame (relative speed, relative load). A ride forgets what
came before: its position is the ground's.
"""

from __future__ import annotations

import math

from ..codes import FLIGHT as FLIGHT_CODE
from ..contact_laws import rigid_rebound
from ..contact_laws.rigid import ZENO_APEX
from ..equations import load_value
from ..ground import first_touch
from ..physics import Mode
from ..rounding import later
from . import forcing
from .result import DEPARTURE, IMPACT, Event


def build_on_moving_ground(solution, h: float, v: float) -> None:
    """Fill solution's phases, events and rest_time (an ExactSolution on a moving ground) from (h, v) at t_start."""
    ball, ground, R = solution.ball, solution.ground, solution.ball.R
    surface = ground.position(solution.t_start)
    if h - R - surface < -16.0 * 2.0**-52 * (abs(h) + R + abs(surface)):  # below it by more than a rounding
        raise ValueError(f"h0 = {h!r} m is not allowed: under the rigid contact law it must be >= R + s(t_start) = "
                         f"{R + surface!r} m (the ball cannot start inside the ground)")
    pieces = forcing.pieces(solution.F_ext, solution.t_start, solution.t_end)
    mode, on_ground = None, False
    for number, (t, piece_end, F_ext) in enumerate(pieces):
        a = ball.effective_gravity(F_ext)
        if mode is None:
            mode, on_ground = _initial_mode(ground, R, t, h, v, a)
        elif mode == Mode.FLIGHT:
            phase = solution.phases[-1]
            tau = t - phase.t_start
            a_before = ball.effective_gravity(phase.F_ext)
            h, v = phase.h0 + tau * (phase.v0 - 0.5 * a_before * tau), phase.v0 - a_before * tau
            on_ground = False
        mode, h, v, on_ground = _phases_in_piece(solution, t, piece_end, F_ext, a, mode, h, v, on_ground,
                                                 number == len(pieces) - 1)


def _initial_mode(ground, R, t, h, v, a):
    """(mode, on_ground) of a ball starting at (h, v) at t: riding where it is on the ground with it and pressed."""
    gap, relative = h - R - ground.position(t), v - ground.velocity(t)
    on_ground = gap <= 16.0 * 2.0**-52 * (abs(h) + R)
    if on_ground and relative == 0.0 and a + ground.acceleration(t) >= 0.0:
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


def check_moving_ground(ball, ground) -> None:
    """ValueError where the exact solver cannot take this ground under this ball's law (before any work)."""
    if ground.moves and not ball.rigid:
        raise ValueError(f"contact = {ball.contact!r} is not allowed on a moving ground ({ground.describe()}): "
                         "a moving ground is taken by the rigid law so far (contact = 'rigid'); run the compliant "
                         "laws on a still ground")


__all__ = ["build_on_moving_ground", "check_moving_ground"]
