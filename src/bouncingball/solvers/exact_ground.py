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
vibrating table keeps oscillating with it. The no-pull law's pressed contact ends at its release (the same search on
its force, contact_laws.no_pull.sine_ground_release), its free spell below the surface at a departure or an
engagement, each a flight's certified first touch (_free_spell).

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
from ..codes import FREE as FREE_CODE
from ..codes import IMPACT as IMPACT_CODE
from ..contact_laws import has_pressed_gap, rigid_rebound, starts_free
from ..contact_laws.linear import sine_ground_departure, sine_ground_flow
from ..contact_laws.no_pull import sine_ground_release
from ..contact_laws.rigid import ZENO_APEX
from ..equations import load_value
from ..ground import Ground, first_touch
from ..oscillator import sine_response_gain
from ..physics import Mode
from ..rounding import later
from . import forcing
from .result import DEPARTURE, ENGAGE, IMPACT, RELEASE, Event


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
            mode, on_ground = _initial_mode(ball, ground, t, h, v, a, F_ext)
        elif mode in (Mode.FLIGHT, Mode.FREE):  # a parabola (the no-pull law's free spell too)
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


def _initial_mode(ball, ground, t, h, v, a, F_ext):
    """(mode, on_ground) of a ball starting at (h, v) at t.

    A rigid ball rides where it is on the ground with it and pressed; a compliant one is in contact below the
    surface (the no-pull law's free where its force would pull), or on it moving into it (or with it, pressed).
    """
    R = ball.R
    gap, relative = h - R - ground.position(t), v - ground.velocity(t)
    pressed = a + ground.acceleration(t) >= 0.0
    if not ball.rigid:
        if gap < 0.0 and starts_free(ball.parameters, gap, relative, load_value(F_ext, ball.m, ball.g)):
            return Mode.FREE, False
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
            ended = _forced_contact(solution, t, piece_end, load, h, v, last)
            if ended is None:
                end = solution.phases[-1]
                return (mode, *contact_state(solution, end.t_start, end.h0, end.v0, piece_end - end.t_start, load),
                        False)
            t, h, v, mode = ended
            on_ground = mode == Mode.FLIGHT  # departed (the linear law), or released below the surface (no-pull)
            continue
        if mode == Mode.FREE:
            ended = _free_spell(solution, t, piece_end, load, a, h, v)
            if ended is None:
                tau = piece_end - t
                return mode, h + tau * (v - 0.5 * a * tau), v - a * tau, False
            t, h, v, mode = ended
            on_ground = mode == Mode.FLIGHT
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
        flight_start = solution.phases[-1].t_start
        carry.phase(flight_start, FLIGHT_CODE, x_start, v_start, tau, load)
        rounding = ground.touch_rounding(flight_start, x_start, v_start, a, tau)
        if not ball.rigid:  # into the forced contact: the law's saltation, the velocity unchanged
            carry.moving_switch(t, tau, IMPACT_CODE, FLIGHT_CODE, relative, relative_load / ball.m, rounding)
            v, mode, on_ground = v_minus, Mode.CONTACT, False
            continue
        rebound, zeno = rigid_rebound(parameters, min(relative, 0.0), relative_load)
        carry.moving_impact(t, tau, relative, rebound, relative_load, rounding)
        if zeno > 0.0:  # the summed bounces rise at most ZENO_APEX R above the ground
            carry.charge(t, ZENO_APEX * R)
        ride_from = later(t, t_low, zeno)[0]
        if rebound > 0.0 or (zeno == 0.0 and ground.ride_end(t, a) == t):  # on in flight (a ride that would end at
            v, on_ground = ground_speed + rebound, True  # once is none: the ball leaves with the ground)
            continue
        v, mode, on_ground = ground_speed, Mode.CONTACT, True


def _forced_contact(solution, t, piece_end, load, h, v, last):
    """A compliant contact from (h, v) at t on a sine ground: (t, h, v, mode) where it ends, or None past piece_end.

    The linear law's departure (contact_laws.linear.sine_ground_departure) into flight, the no-pull law's release
    (no_pull.sine_ground_release) into its free spell below the surface: certified first roots. A contact that can
    never end, in the last piece, dates the rest (rest_time).
    """
    ball, ground, R, carry = solution.ball, solution.ground, solution.ball.R, solution.rounding
    if t > limits.resolvable_until(ball):  # contacts too short for the ulps of t
        limits.check_resolvable(ball, t)
    w, forcing, theta0 = ground.omega, ground.amplitude * ground.omega**2, ground.omega * t + ground.phase
    x0, u0 = h - R - ground.position(t), v - ground.velocity(t)
    no_pull = has_pressed_gap(ball.parameters)  # the no-pull law (with b = 0 its force is the linear law's)
    if no_pull:
        tau, x, u = sine_ground_release(ball.parameters, x0, u0, load, forcing, w, theta0, piece_end - t)
    else:
        (tau, u), x = sine_ground_departure(ball.parameters, x0, u0, load, forcing, w, theta0, piece_end - t), 0.0
    sigma, w2 = ball.b / (2.0 * ball.m), ball.k / ball.m
    steady = forcing * sine_response_gain(sigma, w2, w)
    forced = (steady + abs(ground.position(t)), w * steady + abs(ground.velocity(t)))
    t_event = later(t, 0.0, tau)[0] if tau < math.inf else math.inf
    if not t_event <= piece_end:
        if piece_end < math.inf:
            carry.phase(t, CONTACT_CODE, h - R, v, piece_end - t, load, forced=forced)
        if last and math.isinf(tau):
            solution.rest_time = t
        return None
    carry.phase(t, CONTACT_CODE, h - R, v, tau, load, forced=forced)
    v_event = float(ground.velocity(t_event)) + u
    h_event = R + float(ground.position(t_event)) + x
    if no_pull:  # the force is 0 on either side of a release: no saltation, its time's error no state error
        solution.events.append(Event(t_event, RELEASE, v_event))
        return t_event, h_event, v_event, Mode.FREE
    acceleration = -2.0 * sigma * u - load / ball.m - float(ground.acceleration(t_event))  # x'' at x = 0
    rounding = 16.0 * 2.0**-52 * (abs(x0) + abs(load / ball.k) + steady + abs(u0) / math.sqrt(w2))
    carry.moving_switch(t_event, tau, DEPARTURE_CODE, CONTACT_CODE, u, acceleration, rounding)
    solution.events.append(Event(t_event, DEPARTURE, v_event))
    return t_event, h_event, v_event, Mode.FLIGHT


def _free_spell(solution, t, piece_end, load, a, h, v):
    """The no-pull law's free spell from (h, v) at t below a sine ground: (t, h, v, mode) at its end, or None.

    The ball flies its parabola; it departs where its gap x = h - R - s reaches 0 going up, or is pressed again
    (engages) where z = x + (b / k) u falls to 0: each a flight's certified first touch (ground.first_touch) of a
    ground of its own, -s for the gap seen from inside, s + (b / k) s' (a sine of its own amplitude and phase)
    for z. The first of the two, a departure on a tie. Neither switch jumps the force (0 on either side).
    """
    ball, ground, R, carry = solution.ball, solution.ground, solution.ball.R, solution.rounding
    c, w, horizon = ball.b / ball.k, ground.omega, piece_end - t
    released = bool(solution.events) and solution.events[-1].kind == RELEASE and solution.events[-1].time == t
    engaged_by = Ground.sine(ground.amplitude * math.hypot(1.0, c * w), ground.frequency,
                             ground.phase + math.atan2(c * w, 1.0))
    tau_engage = first_touch(engaged_by, t, h - R + c * v, v - c * a, a, horizon, on_ground=released)
    inside = Ground.sine(ground.amplitude, ground.frequency, ground.phase + math.pi)
    tau_depart = first_touch(inside, t, R - h, -v, -a, min(horizon, tau_engage))
    tau = min(tau_depart, tau_engage)
    t_event = later(t, 0.0, tau)[0] if tau < math.inf else math.inf
    if not t_event <= piece_end:
        if piece_end < math.inf:
            carry.phase(t, FREE_CODE, h - R, v, horizon, load)
        return None
    carry.phase(t, FREE_CODE, h - R, v, tau, load)
    h_event, v_event = h + tau * (v - 0.5 * a * tau), v - a * tau
    if tau_depart <= tau_engage:
        solution.events.append(Event(t_event, DEPARTURE, v_event))
        return t_event, R + float(ground.position(t_event)), v_event, Mode.FLIGHT
    solution.events.append(Event(t_event, ENGAGE, v_event))
    return t_event, h_event, v_event, Mode.CONTACT


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


# A compliant contact whose periodic response to the ground is more than this many times the scene's size (R, the
# ground's amplitude) is refused: near an undamped resonance the certified departure search would crawl through
# steps of 1e-10 s (a run of 1 s took 49 s at b = 1e-9 N s/m) and its closed form would cancel every digit.
RESONANCE_LIMIT = 1e6


def check_moving_ground(ball, ground) -> None:
    """ValueError where the exact solver cannot take this ground under this ball's law (before any work)."""
    if not ground.moves:
        return
    if ball.contact not in ("rigid", "linear", "linear-no-pull"):
        raise ValueError(f"contact = {ball.contact!r} is not allowed on a moving ground ({ground.describe()}) "
                         "with the exact solver: it takes the rigid, linear and linear-no-pull laws there; the "
                         "Hunt-Crossley law on a sine ground runs with the CVODE solver (solver='cvode')")
    if not ball.rigid and ground.kind != "sine":
        raise ValueError(f"contact = {ball.contact!r} is not allowed on a ground table ({ground.describe()}): a "
                         "compliant law's contact on a moving ground is in closed form for a sine (Ground.sine); use "
                         "the rigid law on a table")
    if not ball.rigid:
        gain = sine_response_gain(ball.b / (2.0 * ball.m), ball.k / ball.m, ground.omega)
        steady = ground.amplitude * ground.omega**2 * gain
        if not steady <= RESONANCE_LIMIT * max(ball.R, ground.amplitude):
            raise ValueError(
                f"b = {ball.b!r} N s/m is not allowed with k = {ball.k!r} N/m and m = {ball.m!r} kg on "
                f"{ground.describe()}: the contact is so near resonance with the ground (k / m against (2 pi f)^2) "
                f"and so little damped that its steady response, {steady:.3g} m, is more than {RESONANCE_LIMIT:g} "
                "times the scene's size max(R, A); give more damping b or "
                "another k or frequency")


__all__ = ["build_on_moving_ground", "check_moving_ground", "contact_state"]
