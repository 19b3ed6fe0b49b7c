"""The one place the phase machine, Ball and the integrator decide on the contact law: one function per hook.

Each hook asks the ball's law (BallParameters.law, a code of common.py) once and calls that law's module; the
contract they serve is stated in contact_laws/__init__.py. numba compiles these functions with the machine, and
cannot call through a table: the dispatch is written as ``if`` on the code. A new law adds its module to
LAW_MODULES and its branch to the hooks where it differs from the linear spring-damper.
"""

from __future__ import annotations

import math

from ..codes import CONTACT, DEPARTURE, ENGAGE, FLIGHT, FREE, RELEASE, RESTART
from ..equations import gap_acceleration, gap_flow_value, ground_flight_flow, rest_margin_value, ride_end_value
from . import common, hunt_crossley, linear, no_pull, rigid
from .common import BY_CVODE, HUNT_CROSSLEY, IN_CLOSED_FORM, LINEAR, NO_PULL, RIGID
from .hunt_crossley import contact_roots as hunt_crossley_contact_roots
from .hunt_crossley import (
    hunt_crossley_acceleration,
    hunt_crossley_force,
    hunt_crossley_free_event,
    hunt_crossley_hop_tolerance,
    hunt_crossley_jacobian,
    hunt_crossley_rest_margin,
    hunt_crossley_scales,
    hunt_crossley_state,
    release_speed,
)
from .hunt_crossley import sine_free_event as hunt_crossley_sine_free_event
from .hunt_crossley import step_exit as hunt_crossley_step_exit
from .hunt_crossley import step_transition as hunt_crossley_step_transition
from .linear import contact_scales as linear_contact_scales
from .linear import decide_contact as linear_decide_contact
from .linear import departure_speed as linear_departure_speed
from .linear import departure_time as linear_departure_time
from .linear import sine_ground_departure, sine_ground_flow
from .no_pull import contact_roots as no_pull_contact_roots
from .no_pull import decide_contact as no_pull_decide_contact
from .no_pull import (
    free_event,
    no_pull_rest_margin_value,
    pressed_gap,
    release_state,
    release_time,
    sine_free_event,
    sine_ground_release,
)
from .rigid import contact_scales as rigid_contact_scales
from .rigid import decide_contact as rigid_decide_contact
from .rigid import departure_speed as rigid_departure_speed
from .rigid import departure_time as rigid_departure_time

# Every module of the package but this one, each a law's but common.py: the compiled engine compiles them all
# (solvers/engines/compiled.py) and its cache digest covers their sources (solvers/engines/jit.py).
LAW_MODULES = (common, linear, rigid, no_pull, hunt_crossley)


# --- the dispatch: each hook decides on the law once ---------------------------------------------------------------
def law_flow_value(parameters, mode, x0, v0, tau, load):
    """gap_flow_value under the ball's contact law (parameters: Ball.parameters): a rigid ball in contact rests.

    Under the rigid law the contact mode is the ball resting on R, where it stays (x0, v0 = 0, 0).
    """
    if mode == CONTACT and parameters.law == RIGID:
        return x0 + 0.0 * tau, v0 + 0.0 * tau
    if mode == CONTACT and parameters.law == HUNT_CROSSLEY:  # no closed form: never asked for (NaN if it were)
        return x0 + math.nan * tau, v0 + math.nan * tau
    return gap_flow_value(mode, x0, v0, tau, load, parameters.m, parameters.k, parameters.b)


def law_flow_at(parameters, mode, x0, v0, t0, tau, load):
    """law_flow_value from (x0, v0) at t0 [s], on the ball's ground: in its frame where it vibrates (floats).

    On a still ground (ground_amplitude 0) law_flow_value itself. On a vibrating one, x = h - R - s and v - s':
    a flight's (and the no-pull law's free sub-mode's) parabola less the ground's motion (equations.ground_flight_flow),
    the linear spring-damper's contact its forced oscillation (linear.sine_ground_flow), the rigid law's contact the
    ride (0, 0).
    """
    if parameters.ground_amplitude == 0.0 or (mode == CONTACT and parameters.law == RIGID):
        return law_flow_value(parameters, mode, x0, v0, tau, load)
    if mode != CONTACT:
        return ground_flight_flow(parameters, x0, v0, t0, tau, load)
    if parameters.law == HUNT_CROSSLEY:
        return x0 + math.nan * tau, v0 + math.nan * tau
    w = parameters.ground_omega
    return sine_ground_flow(parameters, x0, v0, tau, load, parameters.ground_amplitude * w * w, w,
                            w * t0 + parameters.ground_phase)


def ground_moves(parameters):
    """Whether the ball's ground vibrates (BallParameters' ground_amplitude > 0): the machine works in its frame."""
    return parameters.ground_amplitude != 0.0


def conserved_speed(parameters, mode, x_start, v_start):
    """Whether a phase from the gap x_start [m] at v_start [m/s] in mode ends on R at -v_start exactly.

    Where it starts on R leaving its own side (up in flight, down in contact) and its exact flow conserves energy (a
    flight; a contact with b = 0): the polish and the exact solver give the event that speed, not their flows'
    rounded one (an energy drift over many bounces). Never on a vibrating ground, which gives and takes energy.
    """
    if x_start != 0.0 or parameters.ground_amplitude != 0.0:
        return False
    if parameters.law == HUNT_CROSSLEY:  # alpha = 0: the Hertz contact conserves energy, its force 0 on R
        return v_start > 0.0 if mode == FLIGHT else (v_start < 0.0 and parameters.alpha == 0.0)
    return v_start > 0.0 if mode == FLIGHT else (v_start < 0.0 and parameters.b == 0.0)


def law_hop_tolerance(parameters, load, resolution):
    """The highest hop [m] above R that CVODE may merge into the contact around it (settings.hop_tolerance's rule).

    resolution (HOP_RESOLUTION rtol) times the contact's amplitude near rest, the static deflection d = load / k:
    0 where the contact never rests (b = 0, or d <= 0: lifted) and for an instantaneous impact. The Hunt-Crossley
    law's is its own (hunt_crossley_hop_tolerance).
    """
    if parameters.law == HUNT_CROSSLEY:
        return hunt_crossley_hop_tolerance(load, parameters.m, parameters.k, parameters.n, parameters.alpha,
                                           resolution)
    d = load / parameters.k
    if parameters.law == RIGID or parameters.b == 0.0 or not d > 0.0:
        return 0.0
    return resolution * d


def law_rest_margin(parameters, x, v, d, hop_tolerance):
    """The rest margin under the ball's contact law (parameters: Ball.parameters); see rest_margin_value."""
    m, k = parameters.m, parameters.k
    if parameters.law == NO_PULL:
        return no_pull_rest_margin_value(x, v, d, hop_tolerance, k / m, parameters.b / (2.0 * m))
    return rest_margin_value(x, v, d, hop_tolerance, k / m)


def starts_free(parameters, x, v, load):
    """Whether a ball below R (the gap x [m] < 0, v [m/s]) starts in the free sub-mode (Mode.FREE), not pressed.

    Under the no-pull law where its force would pull, or is 0 and turning so (pressed_gap's z); under the
    Hunt-Crossley law where 1 - 3/2 alpha v < 0 (rising faster than the release speed), or = 0 with the
    load [N] < 0 (a lift past the weight: v grows past it). Never under the other laws.
    """
    if parameters.law == HUNT_CROSSLEY:
        factor = 1.0 - 1.5 * parameters.alpha * v
        return factor < 0.0 or (factor == 0.0 and load < 0.0)
    if parameters.law != NO_PULL:
        return False
    z, rate = pressed_gap(parameters, x, v, load)
    return z > 0.0 or (z == 0.0 and rate > 0.0)


def departure_time(parameters, x0, v0, load):
    """Time [s] from (x0, v0) in contact to the first upward crossing of h = R; inf if none (linear.departure_time)."""
    if parameters.law == RIGID:
        return rigid_departure_time(parameters, x0, v0, load)
    return linear_departure_time(parameters, x0, v0, load)


def departure_speed(parameters, x0, v0, tau, load):
    """v [m/s] where a contact from (x0, v0) ends tau [s] later (departure_time): never < 0 (linear.departure_speed)."""
    if parameters.law == RIGID:
        return rigid_departure_speed(parameters, x0, v0, tau, load)
    return linear_departure_speed(parameters, x0, v0, tau, load)


def contact_scales(parameters, x, v, load):
    """(length [m], speed [m/s]) of a contact from (x, v) under the ball's law: the contract's rule 1."""
    if parameters.law == RIGID:
        return rigid_contact_scales(parameters, x, v, load)
    if parameters.law == HUNT_CROSSLEY:
        return hunt_crossley_scales(parameters, x, v, load)
    return linear_contact_scales(parameters, x, v, load)


def decide_contact(parameters, mode, x, v, load, hop, resolution):
    """(answer, tau, x_event, v_event, kind) of a phase below or on R (CONTACT, or FREE: in closed form): rule 2."""
    if mode == FREE:
        if parameters.law == HUNT_CROSSLEY:
            tau, x_event, v_event, departs = hunt_crossley_free_event(parameters, x, v, load)
        else:
            tau, x_event, v_event, departs = free_event(parameters, x, v, load)
        return IN_CLOSED_FORM, tau, x_event, v_event, DEPARTURE if departs else ENGAGE
    if parameters.law == HUNT_CROSSLEY:  # no closed form: CVODE takes every contact, a rest only reported (HC_REST_T)
        return BY_CVODE, 0.0, 0.0, 0.0, DEPARTURE
    if parameters.law == RIGID:
        answer, tau, x_event, v_event = rigid_decide_contact(parameters, x, v, load, hop, resolution)
        return answer, tau, x_event, v_event, DEPARTURE
    if parameters.law == NO_PULL:
        answer, tau, x_event, v_event = no_pull_decide_contact(parameters, x, v, load, hop, resolution)
        return answer, tau, x_event, v_event, RELEASE
    answer, tau, x_event, v_event = linear_decide_contact(parameters, x, v, load, hop, resolution)
    return answer, tau, x_event, v_event, DEPARTURE


def ground_contact_event(parameters, mode, x, v, load, t, horizon):
    """(tau [s], x_event [m], v_event [m/s], kind) ending a contact (CONTACT, FREE) from (x, v) at t [s], ground moving.

    In its frame (x = h - R - s, v - s'), certified: the rigid ride's end, the linear departure, the no-pull release
    and the free spells' ends (sine_ground_departure, sine_ground_release, the laws' sine_free_event). tau inf: never
    (a rest); none within horizon [s]: codes.RESTART at a certified point past it. load: m g - F_ext [N]. A pressed
    Hunt-Crossley contact: tau nan (CVODE integrates it, contact_step_exit certifying each step).
    """
    if mode == FREE:
        tau, x_event, v_event, departs = sine_free_event(parameters, x, v, load, t) if parameters.law == NO_PULL \
            else hunt_crossley_sine_free_event(parameters, x, v, load, t)
        return tau, x_event, v_event, DEPARTURE if departs else ENGAGE
    if parameters.law == RIGID or parameters.law == HUNT_CROSSLEY:
        tau = ride_end_value(parameters, t, load / parameters.m) - t if parameters.law == RIGID else math.nan
        return tau, 0.0, 0.0, DEPARTURE
    w = parameters.ground_omega
    forcing, theta = parameters.ground_amplitude * (w * w), w * t + parameters.ground_phase
    kind = RELEASE if parameters.law == NO_PULL else DEPARTURE
    if kind == RELEASE:
        tau, x_event, v_event = sine_ground_release(parameters, x, v, load, forcing, w, theta, horizon)
    else:
        (tau, v_event), x_event = sine_ground_departure(parameters, x, v, load, forcing, w, theta, horizon), 0.0
    if math.isinf(tau) or tau <= horizon:
        return tau, x_event, v_event, kind
    x_event, v_event = sine_ground_flow(parameters, x, v, tau, load, forcing, w, theta)
    return tau, x_event, v_event, RESTART


def contact_event(parameters, x, v, load):
    """(tau [s], x_event [m], v_event [m/s], kind) ending a contact from (x, v) on its exact flow; tau = inf if none.

    The exact solver's: a departure on R (the linear and rigid laws), or the no-pull law's release below it.
    """
    if parameters.law == NO_PULL:
        tau = release_time(parameters, x, v, load)
        if math.isinf(tau):
            return tau, 0.0, math.nan, RELEASE
        x_event, v_event = release_state(parameters, x, v, tau, load)
        return tau, x_event, v_event, RELEASE
    tau = departure_time(parameters, x, v, load)
    if math.isinf(tau):
        return tau, 0.0, math.nan, DEPARTURE
    return tau, 0.0, departure_speed(parameters, x, v, tau, load), DEPARTURE


def has_free_sub_mode(parameters):
    """Whether the law has a free sub-mode below R (Mode.FREE): where its force would pull (no-pull, Hunt-Crossley)."""
    return parameters.law == NO_PULL or parameters.law == HUNT_CROSSLEY


def polish_flow_mode(parameters, mode):
    """The mode whose exact flow polishes an event CVODE located in mode (phases.polish_event).

    A Hunt-Crossley contact has no closed form, but its force k delta^n is 0 on R: within the root's few
    ulps of R the flight's parabola is its flow to within k |x|^n tau / m.
    """
    return FLIGHT if parameters.law == HUNT_CROSSLEY else mode


def law_acceleration(parameters, x, v, mode, load):
    """dv/dt [m/s2] at the gap x [m] and v [m/s] in mode under the ball's law: CVODE's right-hand side's.

    Under the Hunt-Crossley law the pressed contact's is hunt_crossley_acceleration's (its force unclipped: the clip
    is the release event into the free sub-mode, never a max() here); else equations.gap_acceleration.
    """
    m, k = parameters.m, parameters.k
    if parameters.law == HUNT_CROSSLEY and mode == CONTACT:
        return hunt_crossley_acceleration(x, v, load, m, k, parameters.n, parameters.alpha)
    return gap_acceleration(x, v, mode, load, m, k, parameters.b)


def own_interpolant(parameters, mode):
    """Whether a step in mode is read off the law's own interpolant (law_interpolant), not off its exact flow."""
    return mode == CONTACT and parameters.law == HUNT_CROSSLEY


def law_interpolant(parameters, load, mode, t0, x0, v0, t1, x1, v1, t):
    """(x [m], v [m/s]) at t on a step from (t0, x0, v0) to (t1, x1, v1) in mode, where own_interpolant. Floats."""
    return hunt_crossley_state(parameters, load, t0, x0, v0, t1, x1, v1, t)


def jacobian_varies(parameters, mode):
    """Whether CVODE's Jacobian in mode changes with the state under the ball's law; else phases.scaled_jacobian's."""
    return parameters.law == HUNT_CROSSLEY and mode == CONTACT


def varying_jacobian(parameters, y0, y1, length, speed, load):
    """(j00, j01, j10, j11): CVODE's Jacobian in the phase's frame at (y0, y1), where jacobian_varies."""
    return hunt_crossley_jacobian(y0, y1, length, speed, load, parameters.m, parameters.k, parameters.n,
                                  parameters.alpha)


def root_values(parameters, y0, y1, mode, length, speed, load, own_side, hop):
    """CVODE's three root functions: the gap (own_side where it is 0), v, and the rest margin in contact.

    Under zero net load v never changes in flight: a root function identically 0 would only make CVODE warn, so it is
    1 there. The rest margin (equations.rest_margin_value) is -1 where the contact cannot rest. A pressed no-pull or
    Hunt-Crossley contact has its own (no_pull.contact_roots, hunt_crossley.contact_roots).
    """
    m, k, law = parameters.m, parameters.k, parameters.law
    if law == HUNT_CROSSLEY and mode == CONTACT:
        return hunt_crossley_contact_roots(y0, y1, speed, own_side, parameters.alpha)
    if law == NO_PULL and mode == CONTACT:
        return no_pull_contact_roots(y0, y1, length, speed, load, own_side, hop, k, m, parameters.b)
    d = load / k
    rest = rest_margin_value(length * y0, speed * y1, d, hop, k / m) if mode == CONTACT and d > 0.0 else -1.0
    return y0 if y0 != 0.0 else own_side, y1 if mode == CONTACT or load != 0.0 else 1.0, rest


def contact_integrated(parameters):
    """Whether the law's pressed contact has no closed form (rule 3): CVODE integrates every one.

    The phase machine then carries its error step by step (contact_step_transition, in error_estimate's
    ellipses) and only reports its rest (reported_rest_margin): no closed form takes the ball on from there.
    """
    return parameters.law == HUNT_CROSSLEY


def contact_step_transition(parameters, load, t0, x0, v0, t1, x1, v1, t):
    """(p00, p01, p10, p11): the transition matrix of (x, v) over an integrated contact's step from t0 to t <= t1."""
    return hunt_crossley_step_transition(parameters, load, t0, x0, v0, t1, x1, v1, t)


def contact_step_exit(parameters, load, t0, x0, v0, t1, x1, v1, margin, to_end):
    """hunt_crossley.step_exit: where an integrated contact's step leaves it, certified (on a vibrating ground)."""
    return hunt_crossley_step_exit(parameters, load, t0, x0, v0, t1, x1, v1, margin, to_end)


def reported_rest_margin(parameters, x, v, load, hop):
    """An integrated contact's rest margin at (x [m], v [m/s]): > 0 at rest (within hop [m]); -1 on a moving ground."""
    if parameters.ground_amplitude != 0.0:  # its energy criterion holds for a constant load only
        return -1.0
    return hunt_crossley_rest_margin(x, v, load, parameters.m, parameters.k, parameters.n, hop)


def contact_ends_in(parameters):
    """The kind of a pressed contact's terminal root: DEPARTURE on R, or the no-pull law's RELEASE (z = 0, below R)."""
    return RELEASE if parameters.law == NO_PULL else DEPARTURE


def side_extreme(parameters, mode, x, v):
    """The extreme, over step ends (arrays x [m], v [m/s]) in mode, of what must keep the phase's side of its event.

    The gap's least in flight, its largest in contact, the no-pull law's largest pressed gap z = x + (b / k) v =
    -force / k; NaN where one is NaN, as numpy's (not called: numba's need a helper the native engine lacks).
    """
    least, pressed_gap = mode == FLIGHT, mode != FLIGHT and parameters.law == NO_PULL
    extreme = math.inf if least else -math.inf
    for i in range(x.shape[0]):
        value = x[i] + (parameters.b / parameters.k) * v[i] if pressed_gap else x[i]
        if math.isnan(value):
            return value
        extreme = min(extreme, value) if least else max(extreme, value)
    return extreme


def third_root_releases(parameters, mode):
    """Whether root_values' third root in mode is a release (the Hunt-Crossley force's clip engaging), not a rest.

    Found where CVODE located it (no closed form to polish it on), at root_release_speed exactly.
    """
    return mode == CONTACT and parameters.law == HUNT_CROSSLEY


def root_release_speed(parameters):
    """v [m/s] at a release found by the third root (third_root_releases): the speed where the force would pull."""
    return release_speed(parameters.alpha)


def impact_is_instantaneous(parameters):
    """Whether an impact is a jump of v on R with no contact phase after it (rigid_rebound), not a compliant contact."""
    return parameters.law == RIGID


def has_pressed_gap(parameters):
    """Whether the contact below R switches between pressed and free where its pressed gap z crosses 0 (pressed_gap).

    The no-pull law's (with b > 0: with b = 0 its force is the linear law's, never pulling, and its code LINEAR).
    """
    return parameters.law == NO_PULL


# --- what Ball and the integrator report: the ball's parameters, its contact force and acceleration -----------------
def law_contact_force(parameters, x, v, mode, load):
    """The ground's force on the ball [N] at the gap x [m] and v [m/s] in mode, positive upwards; 0 out of contact.

    As published the linear law's damper may pull (a negative force) just before departure; the no-pull and
    Hunt-Crossley forces are clipped at 0; a rigid ball resting on R carries its load [N] (0 where F_ext lifts it).
    """
    if mode != CONTACT:
        return 0.0
    law, k = parameters.law, parameters.k
    if law == RIGID:
        return max(load, 0.0)
    if law == HUNT_CROSSLEY:
        return max(hunt_crossley_force(x, v, k, parameters.n, parameters.alpha), 0.0)
    force = -k * x - parameters.b * v
    return max(force, 0.0) if law == NO_PULL else force


def reported_acceleration(parameters, x, v, mode, load):
    """dv/dt [m/s2] at the gap x [m] and v [m/s] in mode, as Ball and the integrator report it.

    From law_contact_force where the law clips it or the ball rests on R (every law's contact but the linear
    one's); else the mode's equations (equations.gap_acceleration).
    """
    if mode == CONTACT and parameters.law != LINEAR:
        return (law_contact_force(parameters, x, v, mode, load) - load) / parameters.m
    return gap_acceleration(x, v, mode, load, parameters.m, parameters.k, parameters.b)
