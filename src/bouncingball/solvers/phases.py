"""The phase machine's decisions, as plain functions of floats: written once, run interpreted or compiled.

A phase is a flight or a contact integrated by CVODE from its start (an event, a change of F_ext)
to its end. Around CVODE, these decide how: the scales it integrates relative to (phase_scales),
whether CVODE takes it at all (decide_phase: a rest, taken on the exact flow, or a phase in closed
form instead, its event from the exact flow), where exactly the event CVODE located lies
(polish_event), and how far a step end may stray to the other side of R before an event was
missed (side_margin). The arguments are the ball's parameters (Ball.parameters: m, k, b, R, g, the
contact law's code, e, v_min), the mode (0 flight, 1 contact), the gap x = h - R [m], v [m/s], the
load m g - F_ext [N] (equations.load_value), the hop tolerance [m] (settings.hop_tolerance) and rtol.

Every function here takes and returns floats only, so solvers/machine.py runs them as they are
(the scikit-sundae engine) and the compiled engine compiles the very same source with numba,
the exact flow's departure search (exact.departure_time) included.
"""

from __future__ import annotations

import math

from ..codes import CONTACT, DEPARTURE, ENGAGE, FLIGHT, FREE, IMPACT, RELEASE
from ..contact_laws import (
    HUNT_CROSSLEY,
    NO_PULL,
    RIGID,
    conserved_speed,
    hunt_crossley_acceleration,
    hunt_crossley_partials,
    hunt_crossley_rest_depth,
    law_rest_margin,
    no_pull_rest_margin_value,
    pressed_gap,
    release_speed,
)
from ..equations import gap_acceleration, gap_flow_value, rest_margin_value
from ..rounding import hypot
from .exact import departure_speed, departure_time, free_event, release_state, release_time, time_to_impact
from .settings import HOP_RESOLUTION

_EPS = 2.0**-52
# A phase whose length scale [m] is below this (a hop or contact of 1e-200 m) is taken on the exact
# flow: its scaled state would leave the range of double precision.
MIN_PHASE_SCALE = 1e-200
SOFT_CONTACT_CAP = 1e3  # a contact's length scale is at most this many max(R, |gap|): see phase_scales
# decide_phase's answers
BY_CVODE, REST, IN_CLOSED_FORM = range(3)


def phase_scales(parameters, mode, x, v, load):
    """The length [m] and speed [m/s] a phase from the gap x = h - R [m] and v [m/s] is integrated relative to.

    In flight the apex above R and the speed at impact; in contact the amplitude of the
    oscillation about the rest height (at most SOFT_CONTACT_CAP max(R, |x|)) and its largest speed.
    CVODE integrates x / length and v / speed, so its error is rtol times the phase's own size: a
    1.6e-9 m hop or a contact deflecting the ball by 1e-9 R after a 100 m fall are resolved as well
    as the article's bounce.
    A flight that never comes down is scaled by its height (at least R). A rigid ball resting on R
    (its contact) is scaled by R, at rest. The no-pull law's free sub-mode (always in closed form) by its
    depth below R and its rise.
    """
    m, k, R = parameters.m, parameters.k, parameters.R
    if mode != FLIGHT and parameters.law == RIGID:
        return R, 0.0
    if mode == FREE:
        g_eff = load / m
        rise = 0.5 * (v * v) / g_eff if g_eff > 0.0 and v > 0.0 else 0.0
        length = abs(x) + rise
        return length, max(abs(v), math.sqrt(2.0 * abs(g_eff) * length))
    if mode == FLIGHT:
        g_eff = load / m
        if g_eff > 0.0:
            rise = max(v, 0.0) / math.sqrt(g_eff)
            length = max(x, 0.0) + 0.5 * (rise * rise)  # not rise ** 2, which numba rounds otherwise at times
            return length, math.sqrt(2.0 * g_eff * length)
        length = max(abs(x), R)
        return length, max(abs(v), math.sqrt(2.0 * abs(g_eff) * length), length)
    if parameters.law == HUNT_CROSSLEY:
        return hunt_crossley_scales(parameters, x, v, load)
    w = math.sqrt(k / m)
    amplitude = hypot(x + load / k, v / w)
    # Never far beyond the scene's own scale: a contact so soft that its amplitude dwarfs R (k/m = 7e-12
    # 1/s2, 6e120 m against R = 3e97 m) is left long before it gets there, and rtol times the amplitude
    # was 4e-6 of the ball's whole motion. (A cap at max(R, |x|) itself cost an R = 1 um ball, whose
    # contact swings 1.3 R, 17 times its accuracy.)
    length = min(amplitude, SOFT_CONTACT_CAP * max(R, abs(x)))
    return length, w * length


def hunt_crossley_scales(parameters, x, v, load):
    """phase_scales of a Hunt-Crossley contact: a bound on its deepest penetration [m] and on its speed [m/s].

    With delta = -x and the energy per mass e = v^2 / 2 - g_eff delta + (k/m) delta^(n+1) / (n + 1), which
    never grows in contact, the penetration stays below the larger of ((n + 1) 2 e / (k/m))^(1/(n+1)) and
    (2 (n + 1) g_eff / (k/m))^(1/n) (past both, the spring's energy exceeds e + g_eff delta); the speed below
    sqrt(2 (e + g_eff delta_max)), and at least w delta_max with w^2 = n (k/m) delta_max^(n-1), the contact's
    own rate there.
    """
    m, k, R, n = parameters.m, parameters.k, parameters.R, parameters.n
    w2, g_eff = k / m, load / m
    depth = max(-x, 0.0)
    energy = 0.5 * (v * v) - g_eff * depth + w2 * depth ** (n + 1.0) / (n + 1.0)
    deepest = max(abs(x), (2.0 * (n + 1.0) * max(energy, 0.0) / w2) ** (1.0 / (n + 1.0)))
    if g_eff > 0.0:
        deepest = max(deepest, hunt_crossley_rest_depth(load, m, k, n))
    length = min(deepest, SOFT_CONTACT_CAP * max(R, abs(x)))
    fastest = math.sqrt(2.0 * max(energy + max(g_eff, 0.0) * length, 0.0))
    return length, max(abs(v), fastest, math.sqrt(n * w2 * length ** (n - 1.0)) * length)


def hunt_crossley_free_event(parameters, x, v, load):
    """(tau [s], x [m], v [m/s], departs): how the Hunt-Crossley free sub-mode from (x < 0, v) ends, on its parabola.

    Free, the ball rises faster than the release speed 2 / (3 alpha) (its force would pull). It departs
    on R (x = 0, at sqrt(v^2 + 2 g_eff x), energy's) unless its speed falls back to the release speed first
    (g_eff > 0): then it is pressed again there (an engagement).
    """
    g_eff = load / parameters.m
    v_release = release_speed(parameters.alpha)
    disc = v * v + 2.0 * g_eff * x
    tau_departure = -2.0 * x / (v + math.sqrt(disc)) if disc >= 0.0 and v > 0.0 else math.inf
    tau_engage = (v - v_release) / g_eff if g_eff > 0.0 else math.inf
    if tau_departure <= tau_engage:
        return tau_departure, 0.0, math.sqrt(disc), True
    tau_engage = max(tau_engage, 0.0)
    return tau_engage, min(x + (v * v - v_release * v_release) / (2.0 * g_eff), 0.0), v_release, False


def frame(parameters, mode, x, v, load, rtol, atol):
    """The phase's scales (length [m], speed [m/s]) from phase_scales, capped so that rtol length <= atol (atol > 0)."""
    length, speed = phase_scales(parameters, mode, x, v, load)
    if atol > 0.0 and rtol * length > atol:
        speed *= atol / (rtol * length)
        length = atol / rtol
    return length, speed


def contact_unresolved(parameters, x, v, load, rtol):
    """In a contact CVODE cannot decide: smaller than MIN_PHASE_SCALE, or resting too close to R.

    Below MIN_PHASE_SCALE its scaled state would not be representable. A rest height closer to R
    than CVODE resolves (HOP_RESOLUTION rtol the contact's amplitude) makes CVODE's x cross 0 or not
    by its own error: a ball creeping to a rest height 1e-23 m below R (F_ext within 2e-16 N of its
    weight), integrated to 5e-19 m, left the ground and came back.
    """
    length, speed = phase_scales(parameters, CONTACT, x, v, load)
    if not (length >= MIN_PHASE_SCALE and speed > 0.0):
        return True
    return abs(load / parameters.k) < HOP_RESOLUTION * rtol * length


def decide_phase(parameters, mode, x, v, load, hop, rtol):
    """How the phase from (x, v) in mode is taken: (answer, tau, x_event, v_event, kind).

    BY_CVODE: CVODE integrates it. REST: a contact that can never again lift the ball more than hop
    above R; the rest is taken on the contact's exact flow. IN_CLOSED_FORM: the phase ends tau [s]
    later in an event of kind (IMPACT ..) at the gap x_event [m] (0: on R) and v_event [m/s], from the
    mode's exact flow (each mode's flow is exact, so events come out of the right kind at the right times):
    - a flight whose apex stays within hop of R (a hop merged into the contacts around it would be
      as right) or below MIN_PHASE_SCALE;
    - a contact CVODE cannot resolve (contact_unresolved), or one that cannot hold the ball (F_ext
      lifts more than its weight: the rest height is above R), which always ends but may creep
      towards a rest height closer to R than CVODE resolves, where h never visibly crosses R (a
      weightless ball lifted by 1e-6 N stayed at R instead of flying 4.5e-6 m in 3 s); when it never
      departs, CVODE integrates it.
    A contact is a rest once the energy bound (equations.rest_margin_value, as Ball.contact_is_permanent)
    proves it: the ball's weight holds it down by more than its motion. A critically or over-damped
    ball (or one with no weight on the spring) creeps towards its rest height for many spring time
    constants, which CVODE would crawl through at the spring's time scale (500,000 steps for k/m =
    8e12 1/s); such a contact has at most one extremum, so the exact flow's departure search
    (exact.departure_time) decides at once whether it ever reaches R, and so it does for a contact
    CVODE cannot resolve.
    Under the no-pull law the pressed contact's event is its release (exact.release_time, the same
    search of contact_laws.pressed_gap's z) and its rest margin contact_laws.law_rest_margin's; the free sub-mode
    is always taken in closed form (a parabola: exact.free_event).
    """
    if mode == FLIGHT:
        if x < 0.0 or not load / parameters.m > 0.0:
            return BY_CVODE, 0.0, 0.0, 0.0, IMPACT
        apex, _ = phase_scales(parameters, FLIGHT, x, v, load)
        if apex >= max(hop, MIN_PHASE_SCALE):
            return BY_CVODE, 0.0, 0.0, 0.0, IMPACT
        tau, v_impact = flight_impact(parameters, x, v, load)
        return IN_CLOSED_FORM, tau, 0.0, v_impact, IMPACT
    if mode == FREE:
        if parameters.law == HUNT_CROSSLEY:
            tau, x_event, v_event, departs = hunt_crossley_free_event(parameters, x, v, load)
        else:
            tau, x_event, v_event, departs = free_event(parameters, x, v, load)
        return IN_CLOSED_FORM, tau, x_event, v_event, DEPARTURE if departs else ENGAGE
    if parameters.law == HUNT_CROSSLEY:  # no closed form: CVODE takes every contact, a rest only reported (HC_REST_T)
        return BY_CVODE, 0.0, 0.0, 0.0, DEPARTURE
    if parameters.law == RIGID:  # a rigid ball resting on R: it stays, or F_ext lifts it at once
        tau = departure_time(parameters, x, v, load)
        if math.isinf(tau):
            return REST, 0.0, 0.0, 0.0, DEPARTURE
        return IN_CLOSED_FORM, tau, 0.0, departure_speed(parameters, x, v, tau, load), DEPARTURE
    m, k, b = parameters.m, parameters.k, parameters.b
    no_pull = parameters.law == NO_PULL
    kind = RELEASE if no_pull else DEPARTURE
    d = load / k
    if d > 0.0 and law_rest_margin(parameters, x, v, d, hop) > 0.0:
        return REST, 0.0, 0.0, 0.0, kind
    unresolved = contact_unresolved(parameters, x, v, load, rtol)
    rest_by_search = b / (2.0 * math.sqrt(k * m)) >= 1.0 or d <= 0.0 or unresolved
    departure_in_closed_form = d < 0.0 or unresolved
    if not (rest_by_search or departure_in_closed_form):
        return BY_CVODE, 0.0, 0.0, 0.0, kind
    tau = release_time(parameters, x, v, load) if no_pull else departure_time(parameters, x, v, load)
    if math.isinf(tau):
        return (REST if rest_by_search else BY_CVODE), 0.0, 0.0, 0.0, kind
    if departure_in_closed_form:
        if no_pull:
            x_event, v_event = release_state(parameters, x, v, tau, load)
            return IN_CLOSED_FORM, tau, x_event, v_event, kind
        return IN_CLOSED_FORM, tau, 0.0, departure_speed(parameters, x, v, tau, load), kind
    return BY_CVODE, 0.0, 0.0, 0.0, kind


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
    # A Hunt-Crossley contact has no closed form, but its force k delta^n is 0 on R: within the root's few
    # ulps of R the flight's parabola is its flow to within k |x|^n tau / m.
    flow_mode = FLIGHT if parameters.law == HUNT_CROSSLEY else mode
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
    m, k, b = parameters.m, parameters.k, parameters.b
    if parameters.law == HUNT_CROSSLEY and mode == CONTACT:
        a = hunt_crossley_acceleration(x, v, load, m, k, parameters.n, parameters.alpha)
    else:
        a = gap_acceleration(x, v, mode, load, m, k, b)
    return x + dt * (v + 0.5 * dt * a), v + dt * a


# --- CVODE's functions of a phase, in its frame: (y0, y1) = (x / length, v / speed), both engines' callbacks ---
def scaled_rates(y0, y1, mode, length, speed, load, m, k, b, law, n, alpha):
    """d(y0, y1)/dt: the mode's equations (equations.gap_acceleration) in the phase's frame.

    Under the Hunt-Crossley law the pressed contact's are contact_laws.hunt_crossley_acceleration's (its force
    unclipped: the clip is the release event into the free sub-mode, never a max() here).
    """
    if law == HUNT_CROSSLEY and mode == CONTACT:
        return (speed / length) * y1, hunt_crossley_acceleration(length * y0, speed * y1, load, m, k, n, alpha) / speed
    return (speed / length) * y1, gap_acceleration(length * y0, speed * y1, mode, load, m, k, b) / speed


def scaled_jacobian(mode, length, speed, m, k, b):
    """(j00, j01, j10, j11): the constant Jacobian of scaled_rates, row by row (not the Hunt-Crossley contact's)."""
    contact = mode == CONTACT
    return 0.0, 1.0 * speed / length, (-k / m if contact else 0.0) * length / speed, -b / m if contact else 0.0


def hunt_crossley_jacobian(y0, y1, length, speed, load, m, k, n, alpha):
    """(j00, j01, j10, j11): the Jacobian of scaled_rates in a Hunt-Crossley contact at (y0, y1), where it changes."""
    a_x, a_v = hunt_crossley_partials(length * y0, speed * y1, load, m, k, n, alpha)
    return 0.0, 1.0 * speed / length, a_x * length / speed, a_v


def root_values(y0, y1, mode, length, speed, load, own_side, hop, k, m, b, law, alpha):
    """CVODE's three root functions: the gap (own_side where it is 0), v, and the rest margin in contact.

    Under zero net load v never changes in flight: a root function identically 0 would only make
    CVODE warn, so it is 1 there. The rest margin (equations.rest_margin_value, with the static
    deflection from the phase's load) is -1 where the contact cannot rest. law: Ball.parameters' code.
    Under the no-pull law the pressed contact's are its own: contact_laws.pressed_gap's z = -force / k in
    the gap's place (its crossing upwards the release), dz/dt in v's (a step ends at each extremum of
    z, so that none holds both crossings of a short free spell) and no_pull_rest_margin_value.
    """
    d = load / k
    if law == HUNT_CROSSLEY and mode == CONTACT:
        # the gap (departure), v, and 3/2 alpha v - 1, whose crossing upwards is the release (the force's clip
        # engaging: 1 + 3/2 alpha delta' turning negative); no rest root: CVODE integrates a contact to its end
        release = 1.5 * alpha * (speed * y1) - 1.0 if alpha > 0.0 else -1.0
        return y0 if y0 != 0.0 else own_side, y1, release
    if law == NO_PULL and mode == CONTACT:
        c = b / k
        z = y0 + (c * speed / length) * y1
        rate = y1 + c * gap_acceleration(length * y0, speed * y1, CONTACT, load, m, k, b) / speed
        sigma = b / (2.0 * m)
        rest = no_pull_rest_margin_value(length * y0, speed * y1, d, hop, k / m, sigma) if d > 0.0 else -1.0
        return z if z != 0.0 else own_side, rate, rest
    rest = rest_margin_value(length * y0, speed * y1, d, hop, k / m) if mode == CONTACT and d > 0.0 else -1.0
    return y0 if y0 != 0.0 else own_side, y1 if mode == CONTACT or load != 0.0 else 1.0, rest
