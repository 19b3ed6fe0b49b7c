"""The run's error estimate: each phase's own error measured against its exact flow, carried by the run's sensitivity.

Each phase's flow is in closed form and affine in its start state (a parabola; a linear oscillator), so
what a phase added to the error is measured, not guessed: the state at its end against the exact flow
from its start. The error it started with is carried by the flow's transition matrix (the flow of the
unit vectors under no load) and, at an impact or departure, by the saltation matrix of the field's
jump there (-+ b/m: no 1/v). The functions are plain Python over floats and the machine's state
(layout.py), run interpreted and compiled alike (machine.py calls them at each phase's end).

A contact the law integrates (contact_laws.contact_integrated: the Hunt-Crossley law's) has no closed form to
measure CVODE's error against. There the error is
bounded instead by what CVODE's error test let through: each step's local error lies in the ellipse its test
holds it in (_contact_step), and the error the step started with is carried by the step's
transition matrix (the law's contact_step_transition). The error of (x, v) is then a set, carried
as such through every phase of the run: the sum of two ellipses, the errors from before the last contact and
that contact's own (_carried_ellipses). The flights' and free spells' own errors are measured as for the
other laws, and added to the second.
"""

from __future__ import annotations

import math

from ...codes import CONTACT, DEPARTURE, FLIGHT, IMPACT
from ...contact_laws import (
    conserved_speed,
    contact_integrated,
    contact_step_transition,
    impact_is_instantaneous,
    law_acceleration,
    law_flow_at,
    law_flow_value,
    law_interpolant,
)
from ...equations import load_at
from ...rounding import hypot
from .phases import frame
from .settings import ERROR_WITHIN_PHASE, ESTIMATE_CAP, ESTIMATE_SAFETY, LOCAL_ERROR_SAFETY, PROMISE

_EPS = 2.0**-52


def phase_error(parameters, rtol, atol, state):
    """(ax, av, a_rho, bx, bv, b_rho, bound, height): the run's error of (x, v) at the state, bounds since the restart.

    ax [m], av [m/s]: the error of (x, v) itself (signed), and bx = bv = a_rho = b_rho = 0.0, where each phase
    has a closed form (_carried_error); where the law's contact is integrated (contact_laws.contact_integrated),
    the error lies in the sum of two ellipses a and b, of those half-widths and correlations (_carried_ellipses).

    bound: on |h - h_true| [m] over the phase from the restart point to the state; height: the phase's
    height scale max(|h|, R) [m] over what it integrated (the highest point a flight passed so far, or the
    state's height). |h - h_true| over the phase is at most the carried error's (at the ends of a flight; in a
    closed-form contact its energy, which never grows) plus the phase's own: CVODE's inside the phase, which is
    only measured at its end, counted as
    ERROR_WITHIN_PHASE rtol its length scale; and the hop tolerance in contact, the hops it may merge.
    """
    R, mode, load, x0 = parameters.R, int(state.rs_mode), state.load, state.rs_x
    if state.origin == state.rs_t and state.needs_init == 0.0:
        length = state.length  # the frame CVODE integrates the phase in (phases.frame, with its horizon)
    else:
        length, _ = frame(parameters, mode, x0, state.rs_v, load_at(parameters, load, state.rs_t), rtol, atol,
                          math.inf, state.rs_t)
    elapsed = (state.t - state.rs_t) + (state.t_low - state.rs_t_low)
    height = max(R, abs(R + state.x))
    if mode == FLIGHT:
        top = _flight_top(parameters, state, load)
        height = max(height, R + top)
        # CVODE's error is relative to |x| where that outgrows the frame: a flight that never comes down (g_eff <= 0,
        # scaled by its start) rising far past it
        length = max(length, top)
    # CVODE's error inside the phase, measured only at its end: none in a phase of no length
    own = (ERROR_WITHIN_PHASE * rtol * length if elapsed != 0.0 else 0.0) + 8.0 * _EPS * (abs(x0) + length + R)
    if mode == CONTACT:
        own += state.hop
    if contact_integrated(parameters):
        ax, av, a_rho, bx, bv, b_rho, carried = _carried_ellipses(parameters, rtol, state, mode, load)
    else:
        ax, av, carried = _carried_error(parameters, state, mode, load)
        a_rho, bx, bv, b_rho = 0.0, 0.0, 0.0, 0.0
    bound = ESTIMATE_SAFETY * (carried + own)
    # an error grown past double precision (inf, then nan) is no error to drop: it is the run lost
    return ax, av, a_rho, bx, bv, b_rho, bound if bound < math.inf else math.inf, height


def _flight_top(parameters, state, load):
    """The highest gap x [m] the flight from the restart point reached up to the state: an end, or the apex passed.

    Not the apex the flight would reach: a force near m g, soon changed, would make that any height.
    """
    x0, v0 = state.rs_x, state.rs_v
    top = max(x0, state.x)
    g_eff = load / parameters.m
    if v0 > 0.0 and g_eff > 0.0 and v0 <= g_eff * ((state.t - state.rs_t) + (state.t_low - state.rs_t_low)):
        top = max(top, x0 + 0.5 * v0 * (v0 / g_eff))
    return top


def _flow_error(parameters, state, mode, load):
    """(p00, p01, p10, p11, dx, dv): the phase's transition matrix, and the state's offset from its exact flow."""
    x0, v0 = state.rs_x, state.rs_v
    tau = (state.t - state.rs_t) + (state.t_low - state.rs_t_low)
    x_flow, v_flow = law_flow_at(parameters, mode, x0, v0, state.rs_t, tau, load)
    p00, p10 = law_flow_value(parameters, mode, 1.0, 0.0, tau, 0.0)
    p01, p11 = law_flow_value(parameters, mode, 0.0, 1.0, tau, 0.0)
    return p00, p01, p10, p11, state.x - x_flow, state.v - v_flow


def _carried_error(parameters, state, mode, load):
    """(ex [m], ev [m/s], carried [m]): the error of (x, v) at the state, where every phase has a closed form.

    Its flow is affine in its start state, so the phase's own error is measured, not guessed: the state against
    the exact flow from the phase's start (CVODE's error over the phase, the polish's); the error the start
    carried is propagated by the flow's transition matrix (the flow of the unit vectors under no load).
    carried: the largest |error of x| over the phase, at an end of a parabola, or bounded by a contact's energy.
    """
    ex0, ev0 = state.err_x, state.err_v
    p00, p01, p10, p11, dx, dv = _flow_error(parameters, state, mode, load)
    v0, v1 = state.rs_v, state.v
    if state.rs_x == 0.0 and state.x == 0.0 and v0 != 0.0 and v1 != 0.0 and parameters.ground_amplitude == 0.0:
        # From R to R: the error as a delay along the flow and a speed error on R, the delay carried to the flow's
        # direction at the end exactly (Phi f(start) = f(end)). Phi's rounding would turn an undamped bounce's
        # shear (the delay growing with the speed error) into a slow rotation: 1e5 bounces undo it. (Not on a
        # vibrating ground, whose flow is no longer the same at every time: there Phi f(start) != f(end).)
        delay = ex0 / v0
        speed_error = ev0 - delay * law_acceleration(parameters, 0.0, v0, mode, load)
        ex = delay * v1 + p01 * speed_error + dx
        ev = delay * law_acceleration(parameters, 0.0, v1, mode, load) + p11 * speed_error + dv
    else:
        ex = p00 * ex0 + p01 * ev0 + dx
        ev = p10 * ex0 + p11 * ev0 + dv
    if mode == CONTACT:
        return ex, ev, max(hypot(ex0, ev0 / math.sqrt(parameters.k / parameters.m)), abs(ex))
    return ex, ev, max(abs(ex0), abs(ex))  # a flight, or the no-pull law's free sub-mode below R


def event_saltation(parameters, kind, mode, v_impact, v_after, load):
    """(jump [1/s], reflection): the saltation matrix [[reflection, 0], [jump, reflection]] of an event (carry_error).

    kind: the event's (IMPACT ..), ending a phase in mode at v_impact [m/s], the ball leaving it at v_after [m/s]
    (a rigid impact's rebound; else v_impact). A rigid impact reflects by -e, its jump -(1 + e) g_eff / v-, or
    leaves no error where the ball stays on R; a compliant law's field jumps by -+ b/m at an impact or a
    departure from the pressed contact, and not at the no-pull law's switches below R, where the force is 0 on
    either side, nor at a departure from its free sub-mode.
    """
    if kind == IMPACT and impact_is_instantaneous(parameters):
        if not v_after > 0.0:
            return 0.0, -0.0  # on R at rest no error of x or v is left
        return -(1.0 + parameters.e) * (load / parameters.m) / v_impact, -parameters.e
    damping = parameters.b / parameters.m
    if kind == IMPACT:
        return -damping, 1.0
    if kind == DEPARTURE:
        return (damping if mode == CONTACT else 0.0), 1.0
    return 0.0, 1.0


def _untrusted_from(estimate, scale, since, phase_start):
    """since [s], or, where no earlier phase passed the promise and this estimate [m] does at scale [m], phase_start."""
    if math.isnan(since) and not estimate <= PROMISE * scale:
        return phase_start
    return since


def run_estimate(parameters, rtol, atol, state):
    """(estimate [m], scale [m], from [s]): the bound on |h - h_true| over the run so far, and what it is judged by.

    scale: the height scale max(|h|, R) [m]; from: the start of the first phase past PROMISE of it
    (NaN: none).
    """
    bound, height = phase_error(parameters, rtol, atol, state)[6:]
    scale, estimate = max(state.scale, height), max(state.err_max, bound)
    since = _untrusted_from(estimate, scale, state.err_from, state.rs_t)
    # past the range of the motion an estimate says nothing more (amplifications of 1e40 were measured)
    return min(estimate, ESTIMATE_CAP * scale), scale, since


def carry_error(parameters, rtol, atol, state, jump, reflection):
    """The phase from the restart point ends at the state: its error is carried to the state, the next start.

    The error (phase_error) is carried through the saltation matrix there, [[reflection, 0], [jump,
    reflection]]; err_max, err_from and scale take the phase in.

    A compliant contact's event keeps the state (reflection 1) and jumps the field: a perturbation dx
    of the state before the event moves the event by -dx/v, over which the acceleration differs by
    (a+ - a-) = -+ b v / m, so jump = -+ b / m [1/s] (0 where the field does not jump): dv after = dv
    + jump dx, with no 1/v (and 0 at the no-pull law's switches below R, where the force is 0 on either
    side, and at its departures from the free sub-mode). A rigid impact reverses the velocity, v+ = -e v-:
    reflection -e and jump -(1 + e) g_eff / v- (contact_laws.rigid_rebound's caller), or both 0 where the ball
    stays on R. An integrated contact's force is 0 on R: its events keep the state and the field, no saltation.
    """
    ax, av, a_rho, bx, bv, b_rho, bound, height = phase_error(parameters, rtol, atol, state)
    state.scale, state.err_max = max(state.scale, height), max(state.err_max, bound)
    state.err_from = _untrusted_from(state.err_max, state.scale, state.err_from, state.rs_t)
    if contact_integrated(parameters):
        state.err_x, state.err_v, state.err_xv = ax, av, a_rho
        state.err2_x, state.err2_v, state.err2_xv = bx, bv, b_rho
    else:
        state.err_x, state.err_v = reflection * ax, reflection * av + jump * ax


# --- an integrated contact (contact_laws.contact_integrated): the error as ellipses {e : e^T P^-1 e <= 1} of (x, v),
# P = [[p00, p01], [p01, p11]]
def ellipse_sum(a00, a01, a11, b00, b01, b11):
    """An ellipse holding the Minkowski sum of the ellipses A and B: (1 + p) A + (1 + 1/p) B, p = sqrt(tr B / tr A).

    Every p > 0 gives one that holds it; this p the one of least trace (exact where B is a multiple of A).
    """
    ta, tb = a00 + a11, b00 + b11
    if not tb > 0.0:
        return a00, a01, a11
    if not ta > 0.0:
        return b00, b01, b11
    p = math.sqrt(tb / ta)
    q = 1.0 + 1.0 / p
    return (1.0 + p) * a00 + q * b00, (1.0 + p) * a01 + q * b01, (1.0 + p) * a11 + q * b11


def ellipse_image(p00, p01, p10, p11, a00, a01, a11):
    """Phi A Phi^T: the ellipse A mapped by the matrix Phi = [[p00, p01], [p10, p11]]."""
    c00, c01 = p00 * a00 + p01 * a01, p00 * a01 + p01 * a11  # the rows of Phi A
    c10, c11 = p10 * a00 + p11 * a01, p10 * a01 + p11 * a11
    return c00 * p00 + c01 * p01, c00 * p10 + c01 * p11, c10 * p10 + c11 * p11


def ellipse_of(ex, ev, rho):
    """(p00, p01, p11) of the ellipse of half-widths ex, ev and correlation rho."""
    return ex * ex, rho * ex * ev, ev * ev


def widths_of(p00, p01, p11):
    """(ex, ev, rho): the ellipse's half-widths (the box holding it) and correlation in [-1, 1]."""
    ex, ev = math.sqrt(max(p00, 0.0)), math.sqrt(max(p11, 0.0))
    rho = p01 / (ex * ev) if ex > 0.0 and ev > 0.0 else 0.0
    return ex, ev, min(max(rho, -1.0), 1.0)


def start_contact_ellipses(state):
    """An integrated contact CVODE starts in its frame (length, speed): the restart point's two ellipses are one.

    Its own error (the second) starts at 0. Merged here, after a flight that sheared both alike.
    """
    sx, sv = state.length, state.speed
    a00, a01, a11 = ellipse_of(abs(state.err_x) / sx, abs(state.err_v) / sv, state.err_xv)
    b00, b01, b11 = ellipse_of(abs(state.err2_x) / sx, abs(state.err2_v) / sv, state.err2_xv)
    a00, a01, a11 = ellipse_sum(a00, a01, a11, b00, b01, b11)
    state.hc_a00, state.hc_a01, state.hc_a11 = a00, a01, a11
    state.hc_qa00, state.hc_qa01, state.hc_qa11 = a00, a01, a11
    state.hc_b00, state.hc_b01, state.hc_b11 = 0.0, 0.0, 0.0
    state.hc_qb00, state.hc_qb01, state.hc_qb11 = 0.0, 0.0, 0.0
    state.hc_xmax = math.sqrt(a00) * sx


def _contact_step(parameters, load, rtol, length, speed, t0, x0, v0, t1, x1, v1, t, a00, a01, a11, b00, b01, b11):
    """The two ellipses at t in a contact's step from t0 to t1, from (a, b) at t0, in the phase's frame.

    In the frame (x / length, v / speed), where CVODE integrates with rtol = atol: both carried by the step's
    transition matrix (contact_laws.contact_step_transition), and b plus the step's local error. CVODE's error test
    passes a step whose estimated local error e has the weighted RMS norm sqrt((e0^2 / w0^2 + e1^2 / w1^2) / 2)
    <= 1, with the weights w = rtol (|y| + 1) at the step's start: the ellipse diag(2 w0^2, 2 w1^2), taken
    LOCAL_ERROR_SAFETY times (the test judges an estimate of the error, not the error).
    """
    p00, p01, p10, p11 = contact_step_transition(parameters, load, t0, x0, v0, t1, x1, v1, t)
    ratio = speed / length
    p00, p01, p10, p11 = _along_the_flow(parameters, load, length, speed, t0, x0, v0, t1, x1, v1, t,
                                         p00, p01 * ratio, p10 / ratio, p11)
    a00, a01, a11 = ellipse_image(p00, p01, p10, p11, a00, a01, a11)
    b00, b01, b11 = ellipse_image(p00, p01, p10, p11, b00, b01, b11)
    w0 = LOCAL_ERROR_SAFETY * rtol * (abs(x0) / length + 1.0)
    w1 = LOCAL_ERROR_SAFETY * rtol * (abs(v0) / speed + 1.0)
    b00, b01, b11 = ellipse_sum(b00, b01, b11, 2.0 * (w0 * w0), 0.0, 2.0 * (w1 * w1))
    return a00, a01, a11, b00, b01, b11


def _along_the_flow(parameters, load, length, speed, t0, x0, v0, t1, x1, v1, t, p00, p01, p10, p11):
    """The step's transition matrix in the frame, made exact along the flow: it maps the field at t0 to the field at t.

    A shift in time of the trajectory is an error along the field f = (v, a), which the exact transition matrix
    carries from f(t0) to f(t) (the contact's equation is autonomous); the linearised one only to its own order.
    In a stiff contact f's v-part is w times its x-part (a = w^2 delta, v = w delta): the linearisation's small
    relative error there becomes an error of v w times that of the impact's time, carried to the departure and
    the flight after. A rank-one correction along f(t0) puts it back; other directions keep their matrix. Not on a
    vibrating ground: the forced equation is not autonomous, a shift in time no solution (f(t) is not f(t0) carried,
    and where the ball rides it, f(t0) ~ 0, the correction would blow the ellipses up).
    """
    if parameters.ground_amplitude != 0.0:
        return p00, p01, p10, p11
    if t < t1:
        xt, vt = law_interpolant(parameters, load, CONTACT, t0, x0, v0, t1, x1, v1, t)
    else:
        xt, vt = x1, v1
    f0x, f0v = v0 / length, law_acceleration(parameters, x0, v0, CONTACT, load) / speed
    f1x, f1v = vt / length, law_acceleration(parameters, xt, vt, CONTACT, load) / speed
    norm = f0x * f0x + f0v * f0v
    if not norm > 0.0:
        return p00, p01, p10, p11
    rx, rv = (f1x - (p00 * f0x + p01 * f0v)) / norm, (f1v - (p10 * f0x + p11 * f0v)) / norm
    return p00 + rx * f0x, p01 + rx * f0v, p10 + rv * f0x, p11 + rv * f0v


def contact_steps_ellipse(parameters, rtol, state, rows, count):
    """The two ellipses carried over CVODE's steps from the last step end (step_*) through rows[:count] (t, x, v).

    hc_a*, hc_b* at the last of them, hc_qa*, hc_qb* at the one before (the kept last step's start), hc_xmax the
    largest half-width of x's error at them (the sum of the two's: the support of a sum of sets is the sum of theirs).
    """
    length, speed, load = state.length, state.speed, state.load
    t0, x0, v0 = state.step_t, state.step_x, state.step_v
    a00, a01, a11 = state.hc_a00, state.hc_a01, state.hc_a11
    b00, b01, b11 = state.hc_b00, state.hc_b01, state.hc_b11
    qa00, qa01, qa11, qb00, qb01, qb11 = a00, a01, a11, b00, b01, b11
    largest = state.hc_xmax
    for i in range(count):
        t1, x1, v1 = rows[i, 0], rows[i, 1], rows[i, 2]
        qa00, qa01, qa11, qb00, qb01, qb11 = a00, a01, a11, b00, b01, b11
        a00, a01, a11, b00, b01, b11 = _contact_step(parameters, load, rtol, length, speed, t0, x0, v0, t1, x1, v1,
                                                     t1, a00, a01, a11, b00, b01, b11)
        largest = max(largest, (math.sqrt(max(a00, 0.0)) + math.sqrt(max(b00, 0.0))) * length)
        t0, x0, v0 = t1, x1, v1
    state.hc_a00, state.hc_a01, state.hc_a11 = a00, a01, a11
    state.hc_b00, state.hc_b01, state.hc_b11 = b00, b01, b11
    state.hc_qa00, state.hc_qa01, state.hc_qa11 = qa00, qa01, qa11
    state.hc_qb00, state.hc_qb01, state.hc_qb11 = qb00, qb01, qb11
    state.hc_xmax = largest


def _carried_ellipses(parameters, rtol, state, mode, load):
    """(ax, av, a_rho, bx, bv, b_rho, carried [m]): phase_error's two ellipses, where the contact is integrated.

    The run's error of (x, v) at the state lies in the sum of two ellipses (half-widths [m, m/s] and correlation):
    a, the errors from before the last contact, and b, the last contact's own (and the phases' after it).
    Kept apart, each is carried by the phases' transition matrices exactly; only b grows by each step's local
    error, and they are merged once per contact (start_contact_ellipses), after a flight sheared both alike: a
    sum of two ellipses held in one is wider than theirs where they differ in shape. carried: the largest x
    half-width of their sum over the phase.
    """
    ax, av, a_rho = abs(state.err_x), abs(state.err_v), state.err_xv
    bx, bv, b_rho = abs(state.err2_x), abs(state.err2_v), state.err2_xv
    if mode == CONTACT:
        if state.needs_init != 0.0:  # CVODE has not started it: the restart point's
            return ax, av, a_rho, bx, bv, b_rho, ax + bx
        return _contact_ellipses(parameters, rtol, state, load)
    return _phase_ellipses(parameters, state, mode, load, ax, av, a_rho, bx, bv, b_rho)


def _contact_ellipses(parameters, rtol, state, load):
    """_carried_ellipses in a contact CVODE integrates: those carried over its steps (contact_steps_ellipse).

    Inside the kept last step (a target the stepping API reached on its interpolant) they are carried there from
    the step's start, with the step's local error twice (the interpolant's own, sixth order, below it).
    """
    sx, sv = state.length, state.speed
    a00, a01, a11 = state.hc_a00, state.hc_a01, state.hc_a11
    b00, b01, b11 = state.hc_b00, state.hc_b01, state.hc_b11
    if state.t < state.step_t:
        a00, a01, a11, b00, b01, b11 = _contact_step(
            parameters, load, 2.0 * rtol, sx, sv, state.seg_t0, state.seg_x0, state.seg_v0, state.seg_t1,
            state.seg_x1, state.seg_v1, state.t, state.hc_qa00, state.hc_qa01, state.hc_qa11,
            state.hc_qb00, state.hc_qb01, state.hc_qb11)
    ax, av, a_rho = widths_of(a00, a01, a11)
    bx, bv, b_rho = widths_of(b00, b01, b11)
    ax, av, bx, bv = ax * sx, av * sv, bx * sx, bv * sv
    if state.x == 0.0 and state.v == -state.rs_v and conserved_speed(parameters, CONTACT, state.rs_x, state.rs_v):
        bv, b_rho = _departure_shift(parameters, load, state.v, bx)
    return ax, av, a_rho, bx, bv, b_rho, max(state.hc_xmax, ax + bx)


def _departure_shift(parameters, load, v, bx):
    """(bv [m/s], b_rho): the contact's own error at a departure whose speed is the impact's (conserved_speed).

    Undamped, the polish gives the departure the impact's speed -v0 exactly (phases.polish_event), not CVODE's: of
    CVODE's own error only its error of x at the root is kept, as an error of the departure's time dt = -bx / v.
    The parabola shifted by dt is off by (-v dt, g_eff dt) at the departure: an error along (1, -g_eff / v), of
    x's half-width bx (the impact's error, in the other ellipse, is carried to the departure by the steps).
    """
    g_eff = load / parameters.m
    return bx * abs(g_eff) / v, -1.0 if g_eff > 0.0 else 1.0


def _phase_ellipses(parameters, state, mode, load, ax, av, a_rho, bx, bv, b_rho):
    """_carried_ellipses over a flight or a free spell (parabolas, exact): both carried by its transition matrix.

    Its own error, measured against the exact flow from its start as under the closed-form laws, is added to b.
    """
    p00, p01, p10, p11, dx, dv = _flow_error(parameters, state, mode, load)
    # in a frame where the errors are of order 1 (any frame holds the same sets; this one keeps their digits)
    sx, sv = max(ax, bx, abs(dx)), max(av, bv, abs(dv))
    sx, sv = sx if sx > 0.0 else 1.0, sv if sv > 0.0 else 1.0
    q01, q10 = p01 * (sv / sx), p10 * (sx / sv)
    carried = ax + bx
    a00, a01, a11 = ellipse_of(ax / sx, av / sv, a_rho)
    a00, a01, a11 = ellipse_image(p00, q01, q10, p11, a00, a01, a11)
    ax, av, a_rho = widths_of(a00, a01, a11)
    b00, b01, b11 = ellipse_of(bx / sx, bv / sv, b_rho)
    b00, b01, b11 = ellipse_image(p00, q01, q10, p11, b00, b01, b11)
    dx, dv = dx / sx, dv / sv
    b00, b01, b11 = ellipse_sum(b00, b01, b11, dx * dx, dx * dv, dv * dv)
    bx, bv, b_rho = widths_of(b00, b01, b11)
    ax, av, bx, bv = ax * sx, av * sv, bx * sx, bv * sv
    # x's half-widths are convex in the time along a parabola: largest at an end
    return ax, av, a_rho, bx, bv, b_rho, max(carried, ax + bx)
