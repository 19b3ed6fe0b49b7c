"""The phase machine's decisions, as plain functions of the state: written once, taken by both engines.

A phase is a flight or a contact integrated by CVODE from its start (an event, a change of F_ext)
to its end. Around CVODE, these decide how: the scales it integrates relative to (phase_scales),
whether a contact is a rest (at_rest, then rest_state on the exact flow), whether a phase is
taken in closed form instead (event_in_closed_form), where exactly the event CVODE located lies
(polish_event), and how far a step end may stray to the other side of R before an event was
missed (side_margin). The arguments are the ball, the mode, the gap x = h - R [m], v [m/s], F_ext
[N], the hop tolerance [m] (settings.hop_tolerance) and rtol.
"""

from __future__ import annotations

import math

from ..physics import Ball, Mode, rest_margin_value
from .exact import time_to_departure, time_to_impact, velocity_at_departure
from .settings import HOP_RESOLUTION

_EPS = 2.0**-52
# A phase whose length scale [m] is below this (a hop or contact of 1e-200 m) is taken on the exact
# flow: its scaled state would leave the range of double precision.
MIN_PHASE_SCALE = 1e-200
SOFT_CONTACT_CAP = 1e3  # a contact's length scale is at most this many max(R, |gap|): see phase_scales


def phase_scales(ball: Ball, mode: Mode, x: float, v: float, F_ext: float = 0.0) -> tuple[float, float]:
    """The length [m] and speed [m/s] a phase from the gap x = h - R [m] and v [m/s] is integrated relative to.

    In flight the apex above R and the speed at impact; in contact the amplitude of the
    oscillation about the rest height (at most SOFT_CONTACT_CAP max(R, |x|)) and its largest speed.
    CVODE integrates x / length and v / speed, so its error is rtol times the phase's own size: a
    1.6e-9 m hop or a contact deflecting the ball by 1e-9 R after a 100 m fall are resolved as well
    as the article's bounce.
    A flight that never comes down is scaled by its height (at least R).
    """
    if mode == Mode.FLIGHT:
        g_eff = ball.effective_gravity(F_ext)
        if g_eff > 0.0:
            length = max(x, 0.0) + 0.5 * (max(v, 0.0) / math.sqrt(g_eff)) ** 2
            return length, math.sqrt(2.0 * g_eff * length)
        length = max(abs(x), ball.R)
        return length, max(abs(v), math.sqrt(2.0 * abs(g_eff) * length), length)
    w = ball.natural_frequency
    amplitude = math.hypot(x + ball.static_deflection(F_ext), v / w)
    # Never far beyond the scene's own scale: a contact so soft that its amplitude dwarfs R (k/m = 7e-12
    # 1/s2, 6e120 m against R = 3e97 m) is left long before it gets there, and rtol times the amplitude
    # was 4e-6 of the ball's whole motion. (A cap at max(R, |x|) itself cost an R = 1 um ball, whose
    # contact swings 1.3 R, 17 times its accuracy.)
    length = min(amplitude, SOFT_CONTACT_CAP * max(ball.R, abs(x)))
    return length, w * length


def contact_unresolved(ball: Ball, x: float, v: float, F_ext: float, rtol: float) -> bool:
    """In a contact CVODE cannot decide: smaller than MIN_PHASE_SCALE, or resting too close to R.

    Below MIN_PHASE_SCALE its scaled state would not be representable. A rest height closer to R
    than CVODE resolves (HOP_RESOLUTION rtol the contact's amplitude) makes CVODE's x cross 0 or not
    by its own error: a ball creeping to a rest height 1e-23 m below R (F_ext within 2e-16 N of its
    weight), integrated to 5e-19 m, left the ground and came back.
    """
    length, speed = phase_scales(ball, Mode.CONTACT, x, v, F_ext)
    if not (length >= MIN_PHASE_SCALE and speed > 0.0):
        return True
    return abs(ball.static_deflection(F_ext)) < HOP_RESOLUTION * rtol * length


def at_rest(ball: Ball, mode: Mode, x: float, v: float, F_ext: float, hop: float, rtol: float) -> bool:
    """In a contact that can no longer lift the ball more than hop above R, or never ends.

    The energy bound of contact_is_permanent proves a rest only once the ball's weight holds
    it down by more than its motion; a critically or over-damped ball (or one with no weight
    on the spring) creeps towards its rest height for many spring time constants, which CVODE
    would crawl through at the spring's time scale (500,000 steps for k/m = 8e12 1/s). Such
    a contact has at most one extremum, so the exact flow decides at once whether it ever
    reaches R; so it does for a contact CVODE cannot resolve (contact_unresolved).
    """
    if mode != Mode.CONTACT:
        return False
    d = ball.static_deflection(F_ext)
    if d > 0.0 and rest_margin_value(x, v, d, hop, ball.k / ball.m) > 0.0:
        return True  # Ball.contact_is_permanent, in the gap
    undecided = ball.damping_ratio >= 1.0 or d <= 0.0 or contact_unresolved(ball, x, v, F_ext, rtol)
    return undecided and math.isinf(time_to_departure(ball, x, v, F_ext))


def rest_state(ball: Ball, start: tuple[float, float, float], t: float, F_ext: float) -> tuple[float, float]:
    """The gap x [m] and v [m/s] at t on a rest that began at start = (t0, x0, v0), on the contact's exact flow.

    Once at rest the ball's motion is the linear oscillator decaying to the rest height,
    which CVODE would only add its error to: where k/m ulp(R) is comparable to g, h cannot
    even represent the rest height, and the quantised spring force keeps CVODE's steps tiny.
    """
    t0, x0, v0 = start
    x, v = ball.gap_flow(Mode.CONTACT, x0, v0, t - t0, F_ext)
    return float(x), float(v)


def event_in_closed_form(ball: Ball, mode: Mode, t: float, x: float, v: float, F_ext: float, hop: float,
                         rtol: float) -> tuple[float, float, float] | None:
    """The event (t, x = 0, v) ending the phase from (t, x, v) if CVODE is not to integrate it, else None.

    A flight whose apex stays within hop of R (a hop merged into the contacts around it would be
    as right) or below MIN_PHASE_SCALE. A contact CVODE cannot resolve (contact_unresolved) that
    ends. A contact that cannot hold the ball (F_ext lifts more than its weight: the rest height is
    above R), which always ends, but may creep towards a rest height closer to R than CVODE
    resolves, where h never visibly crosses R (a weightless ball lifted by 1e-6 N stayed at R
    instead of flying 4.5e-6 m in 3 s). Each mode's flow is exact, so such a phase is taken in
    closed form: events of the right kind at the right times.
    """
    if mode == Mode.CONTACT:
        if not (ball.static_deflection(F_ext) < 0.0 or contact_unresolved(ball, x, v, F_ext, rtol)):
            return None
        tau = time_to_departure(ball, x, v, F_ext)
        if math.isinf(tau):
            return None
        return t + tau, 0.0, velocity_at_departure(ball, x, v, tau, F_ext)
    if x < 0.0:
        return None
    g_eff = ball.effective_gravity(F_ext)
    if not g_eff > 0.0:
        return None
    apex, _ = phase_scales(ball, Mode.FLIGHT, x, v, F_ext)
    if not apex < max(hop, MIN_PHASE_SCALE):
        return None
    tau, v_impact = time_to_impact(x, v, g_eff)
    return t + tau, 0.0, v_impact


def polish_event(ball: Ball, mode: Mode, F_ext: float, length: float, tau_before: float,
                 root: tuple[float, float, float]) -> tuple[float, float]:
    """The crossing of x = 0 that CVODE located at root = (tau, x, v) in the phase's frame: (tau, v) there.

    CVODE locates a root to ~100 ulps of its time, on its own trajectory, which is off the true
    one by its tolerance: a long fall leaves x off by ~rtol times the drop height where CVODE
    says 0. The next phase starts at x = 0 exactly; its start time and speed come from Newton
    on the mode's exact flow from the root, however large the correction (a 1e-11 m error of
    the fall against a contact deflecting the ball by 6e-9 m: a departure 9e-6 too fast when
    the root was kept). At a departure the damper's force also jumps the acceleration by b v /
    m, so a time error becomes a velocity error. A correction that does not converge (to 16 ulps of
    the phase's length [m]), or that would go back past the step's start tau_before, keeps CVODE's
    root (a grazing root, v ~ 0). An impact never leaves upwards, a departure never downwards.
    """
    tau_root, x_root, v_root = root
    tau, x, v = 0.0, x_root, v_root
    for _ in range(8):
        if x == 0.0 or v == 0.0:
            break
        correction = x / v
        tau -= correction
        x, v = ball.gap_flow(mode, x_root, v_root, tau, F_ext)
        if abs(correction) <= 2.0 * _EPS * abs(tau_root + tau):
            break
    if abs(x) <= 16.0 * _EPS * length and tau_root + tau >= tau_before:
        tau_root, v_root = tau_root + tau, float(v)
    return tau_root, (min(v_root, 0.0) if mode == Mode.FLIGHT else max(v_root, 0.0))


def side_margin(hop: float, rtol: float, length: float) -> float:
    """How far [m] a step end may lie on the other side of R before CVODE must have stepped over an event.

    CVODE's own error (HOP_RESOLUTION rtol the phase's length [m]), or a hop it may merge.
    """
    return max(hop, HOP_RESOLUTION * rtol * length)
