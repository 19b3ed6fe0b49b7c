"""The phase machine's decisions, as plain functions of floats: written once, run interpreted or compiled.

A phase is a flight or a contact integrated by CVODE from its start (an event, a change of F_ext)
to its end. Around CVODE, these decide how: the scales it integrates relative to (phase_scales),
whether CVODE takes it at all (decide_phase: a rest, taken on the exact flow, or a phase in closed
form instead, its event from the exact flow), where exactly the event CVODE located lies
(polish_event), and how far a step end may stray to the other side of R before an event was
missed (side_margin). The arguments are the ball's parameters (Ball.parameters: m, k, b, R, g, the
contact law's code, e, v_min), the mode (0 flight, 1 contact), the gap x = h - R [m], v [m/s], the
load m g - F_ext [N] (equations.load_value), the hop tolerance [m] (settings.hop_tolerance) and rtol.

Every function here takes and returns floats only, so solvers/phase_machine/machine.py runs them as they are
(the scikit-sundae engine) and the compiled engine compiles the very same source with numba,
the exact flow's departure search (contact_laws.departure_time) included.
"""

from __future__ import annotations

import math

from ...codes import CONTACT, FLIGHT, FREE, IMPACT
from ...contact_laws import (
    conserved_speed,
    contact_scales,
    decide_contact,
    ground_contact_event,
    hunt_crossley_scales,
    jacobian_varies,
    law_acceleration,
    polish_flow_mode,
    pressed_gap,
    root_values,
    varying_jacobian,
)
from ...contact_laws.common import BY_CVODE, IN_CLOSED_FORM, MIN_PHASE_SCALE, REST, SOFT_CONTACT_CAP, time_to_impact
from ...equations import flight_touch, gap_flow_value, ground_flight_flow, ground_value, load_at
from .settings import HOP_RESOLUTION

# Re-exported for the engines' callbacks and the tests: the machine's answers and limits, the laws' hooks it calls.
__all__ = ["BY_CVODE", "IN_CLOSED_FORM", "MIN_PHASE_SCALE", "REST", "SOFT_CONTACT_CAP", "hunt_crossley_scales",
           "jacobian_varies", "load_at", "root_values", "varying_jacobian"]
_EPS = 2.0**-52
UNREACHED_APEX = 1e3


def phase_scales(parameters, mode, x, v, load):
    """The length [m] and speed [m/s] a phase from the gap x = h - R [m] and v [m/s] is integrated relative to.

    In flight the apex above R and the speed at impact; in contact its law's (contact_laws.contact_scales: the
    amplitude of the oscillation about the rest height, at most SOFT_CONTACT_CAP max(R, |x|), and its largest speed).
    CVODE integrates x / length and v / speed, so its error is rtol times the phase's own size: a
    1.6e-9 m hop or a contact deflecting the ball by 1e-9 R after a 100 m fall are resolved as well
    as the article's bounce.
    A flight that never comes down is scaled by its height (at least R); the free sub-mode below R (always
    in closed form) by its depth below R and its rise.
    """
    if mode == FREE:
        g_eff = load / parameters.m
        rise = 0.5 * (v * v) / g_eff if g_eff > 0.0 and v > 0.0 else 0.0
        length = abs(x) + rise
        return length, max(abs(v), math.sqrt(2.0 * abs(g_eff) * length))
    if mode == FLIGHT:
        g_eff = load / parameters.m
        if g_eff > 0.0:
            rise = max(v, 0.0) / math.sqrt(g_eff)
            length = max(x, 0.0) + 0.5 * (rise * rise)  # not rise ** 2, which numba rounds otherwise at times
            return length, math.sqrt(2.0 * g_eff * length)
        length = max(abs(x), parameters.R)
        return length, max(abs(v), math.sqrt(2.0 * abs(g_eff) * length), length)
    return contact_scales(parameters, x, v, load)


def frame(parameters, mode, x, v, load, rtol, atol, horizon, t):
    """The phase's scales (length [m], speed [m/s]) from phase_scales, capped so that rtol length <= atol (atol > 0).

    load: on a vibrating ground the load in its frame at the phase's start t [s] (equations.load_at), whose
    flight's apex it scales by, unless far beyond what the world's parabola and the ground's motion can open
    (_world_reach: a relative load near 0, as where the ground's acceleration nearly cancels g, puts it anywhere); where
    that is 0 (a ride's end), by the ground's amplitude. horizon [s]: how long the phase can last at most (inf: not
    known). A flight whose apex is more than UNREACHED_APEX times higher than it can rise within that (a force near
    m g, changed long before the apex would come) is scaled by what it can reach: the apex is then any height, and
    CVODE's error is relative to the scale.
    """
    length, speed = phase_scales(parameters, mode, x, v, load)
    if parameters.ground_amplitude != 0.0 and not (length > 0.0 and speed > 0.0):
        # leaving a vibrating ground with it (a ride's end): the gap its motion opens, of its size
        length, speed = parameters.ground_amplitude, parameters.ground_amplitude * parameters.ground_omega
    elif parameters.ground_amplitude != 0.0 and mode == FLIGHT:
        length, speed = _world_reach(parameters, x, v, load, t, length, speed)
    if mode == FLIGHT and load > 0.0 and v > 0.0 and horizon < math.inf:
        reach = max(x, parameters.R) + v * horizon
        if length > UNREACHED_APEX * reach:
            length, speed = reach, max(v, reach / horizon)
    if atol > 0.0 and rtol * length > atol:
        speed *= atol / (rtol * length)
        length = atol / rtol
    return length, speed


def _world_reach(parameters, x, v, load, t, length, speed):
    """A flight's length scale on a vibrating ground, what it can reach where its relative apex is out of reach.

    Under g_eff > 0 (the ball's own, load / m - s''(t)) the gap never exceeds its start plus the world's apex above
    it and the ground's whole travel 2 A; a weightless or lifted ball's (g_eff <= 0) has no such bound and is scaled
    as on a still ground, by max(|x|, R). A relative apex UNREACHED_APEX times higher than that reach (a relative
    load near 0) is replaced by it. Not a closer cap: the scale changes CVODE's steps, and a chaotic run's error with
    them (measured: 5x on a thrown scene). The speed (phase_scales', near the start's) stays.
    """
    amplitude = parameters.ground_amplitude
    g_world, v_world = load / parameters.m - ground_value(parameters, t, 2), v + ground_value(parameters, t, 1)
    if g_world > 0.0:
        rise = max(v_world, 0.0)
        reach = max(x, 0.0) + 0.5 * (rise * rise) / g_world + 2.0 * amplitude
    else:
        reach = max(abs(x), parameters.R)
    return (reach if length > UNREACHED_APEX * reach else length), speed


def decide_phase(parameters, mode, x, v, load, hop, rtol, t, horizon):
    """How the phase from (x, v) in mode at t [s] is taken: (answer, tau, x_event, v_event, kind).

    BY_CVODE: CVODE integrates it. REST: a contact that can never again lift the ball more than hop
    above R, taken on its exact flow. IN_CLOSED_FORM: the phase ends tau [s] later in an event of kind
    (IMPACT ..) at the gap x_event [m] (0: on R) and v_event [m/s], from the mode's exact flow. A flight
    is taken so where its apex stays within hop of R (a hop merged into the contacts around it would be as
    right) or below MIN_PHASE_SCALE; a phase on or below R as its contact law decides
    (contact_laws.decide_contact, with what CVODE resolves relative to a phase's length, HOP_RESOLUTION rtol).
    On a vibrating ground (in its frame) CVODE takes every flight, and a contact ends in closed form, certified
    (contact_laws.ground_contact_event: the rigid law's ride, the linear law's departure, the no-pull law's
    release and its free spell's end); never, a rest; not within horizon [s], a RESTART (codes) past it, where it
    is decided again. Its hop tolerance does not apply there: no hop is merged.
    """
    if parameters.ground_amplitude != 0.0:
        if mode == FLIGHT:
            return BY_CVODE, 0.0, 0.0, 0.0, IMPACT
        tau, x_event, v_event, kind = ground_contact_event(parameters, mode, x, v, load, t, horizon)
        if math.isnan(tau):  # no closed form: CVODE integrates the contact
            return BY_CVODE, 0.0, 0.0, 0.0, kind
        return (REST, 0.0, 0.0, 0.0, kind) if math.isinf(tau) else (IN_CLOSED_FORM, tau, x_event, v_event, kind)
    if mode == FLIGHT:
        if x < 0.0 or not load / parameters.m > 0.0:
            return BY_CVODE, 0.0, 0.0, 0.0, IMPACT
        apex, _ = phase_scales(parameters, FLIGHT, x, v, load)
        if apex >= max(hop, MIN_PHASE_SCALE):
            return BY_CVODE, 0.0, 0.0, 0.0, IMPACT
        tau, v_impact = flight_impact(parameters, x, v, load)
        return IN_CLOSED_FORM, tau, 0.0, v_impact, IMPACT
    return decide_contact(parameters, mode, x, v, load, hop, HOP_RESOLUTION * rtol)


def flight_impact(parameters, x, v, load):
    """(tau [s], v [m/s]) of the impact ending a flight from (x, v) on its parabola; (inf, nan) if it never comes."""
    return time_to_impact(x, v, load / parameters.m)


def polish_event(parameters, mode, load, length, tau_before, tau_root, x_root, v_root, x_start, v_start):
    """The crossing of x = 0 that CVODE located at (tau_root, x_root, v_root) in the phase's frame: (tau, v) there.

    CVODE locates a root to ~100 ulps of its time, on its own trajectory, which is off the true
    one by its tolerance: a long fall leaves x off by ~rtol times the drop height where CVODE
    says 0. The next phase starts at x = 0 exactly; its start time and speed come from Newton
    on the mode's exact flow from the root, however large the correction (a 1e-11 m error of
    the fall against a contact deflecting the ball by 6e-9 m: a departure 9e-6 too fast when
    the root was kept). At a departure the damper's force also jumps the acceleration by b v /
    m, so a time error becomes a velocity error. A correction that does not converge (to 16 ulps of
    the phase's length [m]), or that would go back past the step's start tau_before, keeps CVODE's
    root (a grazing root, v ~ 0). An impact never leaves upwards, a departure never downwards.
    Where the phase started on R at (x_start, v_start) = (0, v0) and its exact flow conserves the
    speed at R (conserved_speed: a flight, an undamped contact), the event's speed is -v0 exactly,
    not CVODE's: each bounce's small error would otherwise add up to an energy drift, and the drift
    to an error of the bounces' times growing with the square of their count.
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    flow_mode = polish_flow_mode(parameters, mode)
    tau, x, v = 0.0, x_root, v_root
    for _ in range(8):
        if x == 0.0 or v == 0.0:
            break
        correction = x / v
        tau -= correction
        x, v = gap_flow_value(flow_mode, x_root, v_root, tau, load, m, k, b)
        if abs(correction) <= 2.0 * _EPS * abs(tau_root + tau):
            break
    if abs(x) <= 16.0 * _EPS * length and tau_root + tau >= tau_before:
        tau_root, v_root = tau_root + tau, v
    if conserved_speed(parameters, mode, x_start, v_start):
        v_root = -v_start
    return tau_root, (min(v_root, 0.0) if mode == FLIGHT else max(v_root, 0.0))


def polish_release(parameters, load, length, tau_before, tau_root, x_root, v_root):
    """The no-pull release CVODE located at (tau_root, x_root, v_root) in a pressed contact: (tau, x, v) there.

    polish_event's Newton on contact_laws.pressed_gap's z (which obeys the contact's own equation) instead of
    x, then the state moved on the contact's exact flow to the polished time. v >= 0 (the ball rises).
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    z, rate = pressed_gap(parameters, x_root, v_root, load)
    tau, _ = polish_event(parameters, CONTACT, load, length, tau_before, tau_root, z, rate, 1.0, 0.0)
    x, v = gap_flow_value(CONTACT, x_root, v_root, tau - tau_root, load, m, k, b)
    return tau, x, max(v, 0.0)


def side_margin(hop, rtol, length):
    """How far [m] a step end may lie on the other side of R before CVODE must have stepped over an event.

    CVODE's own error (HOP_RESOLUTION rtol the phase's length [m]), or a hop it may merge.
    """
    return max(hop, HOP_RESOLUTION * rtol * length)


def on_wrong_side(mode, x, margin):
    """Whether a step end at the gap x [m] lies beyond margin on the other side of R: an event stepped over."""
    return x < -margin if mode == FLIGHT else x > margin


def taylor_step(parameters, mode, x, v, load, dt):
    """(x, v) after dt [s] by a second-order Taylor step: where dt is a few ulps of t, too short for CVODE."""
    a = law_acceleration(parameters, x, v, mode, load)
    return x + dt * (v + 0.5 * dt * a), v + dt * a


# --- CVODE's functions of a phase, in its frame: (y0, y1) = (x / length, v / speed), both engines' callbacks ---
def scaled_rates(parameters, y0, y1, mode, length, speed, load):
    """d(y0, y1)/dt: the mode's equations (equations.gap_acceleration) in the phase's frame.

    Under the Hunt-Crossley law the pressed contact's are contact_laws.hunt_crossley_acceleration's (its force
    unclipped: the clip is the release event into the free sub-mode, never a max() here).
    """
    return (speed / length) * y1, law_acceleration(parameters, length * y0, speed * y1, mode, load) / speed


def scaled_jacobian(parameters, mode, length, speed):
    """(j00, j01, j10, j11): the constant Jacobian of scaled_rates, row by row (not the Hunt-Crossley contact's)."""
    m, k, b, contact = parameters.m, parameters.k, parameters.b, mode == CONTACT
    return 0.0, 1.0 * speed / length, (-k / m if contact else 0.0) * length / speed, -b / m if contact else 0.0




def vibrating_flight_touch(parameters, load, t0, x0, v0, t1, error_x, error_v, own):
    """(tau [s], v [m/s], decided): where a flight step from (x0, v0) at t0 to t1 [s] first meets a vibrating ground.

    In the ground's frame (x = h - R - s, v - s'), on the exact flow from the step's start (equations.flight_touch,
    certified: no graze between the step's ends is passed over, which CVODE's root function, seeing no change of
    sign, would miss). tau inf where it does not; v: the relative speed there (<= 0). decided: whether the state
    off by its error does the same. error_x [m], error_v [m/s]: the signed error carried from the phase's start to
    t0 (a shift along the flow moves no touch), own [m]: the unsigned rest (CVODE's). At a touch where the gap curves
    up (gap'' = c > 0) the flow would dip v^2 / (2 c) below the surface, which an error moves by
    |error_x - (v / c) error_v| + own (0 along the flow): a touch is decided where it dips deeper. A miss is decided
    unless the gap lower by |error_x| + own touches within the step at a graze (speed^2 <= 4 |c| times that).
    A state on the ground within that at the step's start (a lift-off) is not moved into it.
    """
    tau = flight_touch(parameters, t0, x0, v0, load, t1 - t0, x0 == 0.0)
    if not math.isinf(tau):
        v = min(ground_flight_flow(parameters, x0, v0, t0, tau, load)[1], 0.0)
        curve = -load_at(parameters, load, t0 + tau) / parameters.m
        if not curve > 0.0:  # it accelerates into the ground: no error of a size to miss it undoes it
            return tau, v, True
        return tau, v, 0.5 * v * (v / curve) > abs(error_x - (v / curve) * error_v) + own
    shift = abs(error_x) + own
    if x0 <= shift:
        return tau, 0.0, True
    lower = flight_touch(parameters, t0, x0 - shift, v0, load, t1 - t0, False)
    if math.isinf(lower):
        return tau, 0.0, True
    v_lower = ground_flight_flow(parameters, x0 - shift, v0, t0, lower, load)[1]
    curve = abs(load_at(parameters, load, t0 + lower)) / parameters.m
    return tau, 0.0, v_lower * v_lower > 4.0 * curve * shift
