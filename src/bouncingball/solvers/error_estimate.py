"""The run's error estimate: each phase's own error measured against its exact flow, carried by the run's sensitivity.

Each phase's flow is in closed form and affine in its start state (a parabola; a linear oscillator), so
what a phase added to the error is measured, not guessed: the state at its end against the exact flow
from its start. The error it started with is carried by the flow's transition matrix (the flow of the
unit vectors under no load) and, at an impact or departure, by the saltation matrix of the field's
jump there (-+ b/m: no 1/v). The functions are plain Python over floats and the state array
(layout.py), run interpreted and compiled alike (machine.py calls them at each phase's end).
"""

from __future__ import annotations

import math

from ..physics import HUNT_CROSSLEY, law_flow_value
from ..rounding import hypot
from .layout import (
    ERR_FROM,
    ERR_MAX,
    ERR_V,
    ERR_X,
    HOP,
    LOAD,
    RS_MODE,
    RS_T,
    RS_T_LOW,
    RS_V,
    RS_X,
    SCALE,
    T_LOW,
    T,
    V,
    X,
)
from .phases import CONTACT, FLIGHT, frame
from .settings import ERROR_WITHIN_PHASE, ESTIMATE_CAP, ESTIMATE_SAFETY, PROMISE

_EPS = 2.0**-52


def phase_error(parameters, rtol, atol, state):
    """(ex, ev, bound, height): the run's error of (x [m], v [m/s]) at the state, and bounds since the restart point.

    bound: on |h - h_true| [m] over the phase from the restart point to the state; height: the phase's
    height scale max(|h|, R) [m] (a flight's apex, or the state's height).

    Each phase's flow is exact in closed form and affine in its start state, so its own error is
    measured, not guessed: the state against the exact flow from the phase's start (CVODE's error
    over the phase, the polish's). The error the start carried is propagated by the flow's
    transition matrix (the flow of the unit vectors under no load). Over the phase, |h - h_true|
    is at most the carried error's (at the ends of a flight; in contact its energy, which never
    grows) plus the phase's own: CVODE's inside the phase, which is only measured at its end,
    counted as ERROR_WITHIN_PHASE rtol its length scale; and the hop tolerance in contact, the hops
    it may merge.
    """
    m, k, R = parameters[0], parameters[1], parameters[3]
    if parameters[5] == HUNT_CROSSLEY:
        # No closed form of the contact to measure CVODE's error against: no estimate is carried, and the
        # integrator reports none (NaN; a SimulationResult's None) rather than a wrong one.
        return 0.0, 0.0, 0.0, max(R, abs(R + state[X]))
    mode, load = int(state[RS_MODE]), state[LOAD]
    x0, v0, ex0, ev0 = state[RS_X], state[RS_V], state[ERR_X], state[ERR_V]
    tau = (state[T] - state[RS_T]) + (state[T_LOW] - state[RS_T_LOW])
    x_flow, v_flow = law_flow_value(parameters, mode, x0, v0, tau, load)
    p00, p10 = law_flow_value(parameters, mode, 1.0, 0.0, tau, 0.0)
    p01, p11 = law_flow_value(parameters, mode, 0.0, 1.0, tau, 0.0)
    ex = p00 * ex0 + p01 * ev0 + (state[X] - x_flow)
    ev = p10 * ex0 + p11 * ev0 + (state[V] - v_flow)
    length, _ = frame(parameters, mode, x0, v0, load, rtol, atol)
    own = ERROR_WITHIN_PHASE * rtol * length + 8.0 * _EPS * (abs(x0) + length + R)
    height = max(R, abs(R + state[X]))
    if mode == FLIGHT:
        carried = max(abs(ex0), abs(ex))
        height = max(height, R + length)  # the apex
    elif mode != CONTACT:  # the no-pull law's free sub-mode below R: x's error, ex0 + tau ev0, is largest at an end
        carried = max(abs(ex0), abs(ex))
    else:
        carried = max(hypot(ex0, ev0 / math.sqrt(k / m)), abs(ex))
        own += state[HOP]
    bound = ESTIMATE_SAFETY * (carried + own)
    # an error grown past double precision (inf, then nan) is no error to drop: it is the run lost
    return ex, ev, bound if bound < math.inf else math.inf, height


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
    _, _, bound, height = phase_error(parameters, rtol, atol, state)
    scale, estimate = max(state[SCALE], height), max(state[ERR_MAX], bound)
    since = _untrusted_from(estimate, scale, state[ERR_FROM], state[RS_T])
    # past the range of the motion an estimate says nothing more (amplifications of 1e40 were measured)
    return min(estimate, ESTIMATE_CAP * scale), scale, since


def carry_error(parameters, rtol, atol, state, jump, reflection):
    """The phase from the restart point ends at the state: its error is carried to the state, the next start.

    The error (phase_error) is carried through the saltation matrix there, [[reflection, 0], [jump,
    reflection]]; ERR_MAX, ERR_FROM and SCALE take the phase in.

    A compliant contact's event keeps the state (reflection 1) and jumps the field: a perturbation dx
    of the state before the event moves the event by -dx/v, over which the acceleration differs by
    (a+ - a-) = -+ b v / m, so jump = -+ b / m [1/s] (0 where the field does not jump): dv after = dv
    + jump dx, with no 1/v (and 0 at the no-pull law's switches below R, where the force is 0 on either
    side, and at its departures from the free sub-mode). A rigid impact reverses the velocity, v+ = -e v-:
    reflection -e and jump -(1 + e) g_eff / v- (physics.rigid_rebound's caller), or both 0 where the ball
    stays on R.
    """
    ex, ev, bound, height = phase_error(parameters, rtol, atol, state)
    state[SCALE], state[ERR_MAX] = max(state[SCALE], height), max(state[ERR_MAX], bound)
    state[ERR_FROM] = _untrusted_from(state[ERR_MAX], state[SCALE], state[ERR_FROM], state[RS_T])
    state[ERR_X], state[ERR_V] = reflection * ex, reflection * ev + jump * ex
