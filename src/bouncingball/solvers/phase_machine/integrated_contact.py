"""A contact CVODE integrates (contact_laws.contact_integrated: the Hunt-Crossley law's), over CVODE's steps.

Its error ellipses carried step by step (error_estimate.contact_steps_ellipse) and its rest reported; on a vibrating
ground each step's exit certified on the step's interpolant (vibrating_contact_steps). Plain Python over floats,
numpy arrays and the machine's state, run interpreted and compiled alike (machine.phase_steps calls them).
"""

from __future__ import annotations

import math

from ...codes import CONTACT, DEPARTURE, RELEASE
from ...contact_laws import contact_step_exit, reported_rest_margin
from ...rounding import later
from .dense_output import step_state
from .error_estimate import contact_steps_ellipse
from .settings import ERROR_WITHIN_PHASE, ESTIMATE_SAFETY


def integrated_contact_steps(parameters, rtol, state, rows, count):
    """An integrated contact's steps: its error ellipses carried over them, and its rest dated if it starts there."""
    contact_steps_ellipse(parameters, rtol, state, rows, count)
    if math.isnan(state.hc_rest_t):
        _reported_rest(parameters, state, rows, count)


def vibrating_contact_steps(parameters, rtol, state, rows, count, root_last):
    """(count, exited): an integrated contact's steps rows[:count] (in the phase's frame) on a vibrating ground.

    Each step is searched on its interpolant for where it leaves the contact (contact_laws.contact_step_exit:
    the gap rising to 0, a departure, or the speed to the release speed, certified to rounding): CVODE's root
    functions see no change of sign across a graze inside a step. The first exit is the event, kept pending, and
    the steps end there. root_last: the last row is CVODE's own root, which ends its step. A graze that the
    motion's error (the run's carried into the contact and CVODE's own in it, as phase_error bounds them) could
    turn either way is not decided: the motion after it may differ by the contact's size, its length scale, which
    is charged to the estimate from there (it then passes the promise and warns), as a flight's undecided touch is.
    """
    origin, length, speed, load = state.origin, state.length, state.speed, state.load
    # the x error's bound so far (error_estimate.phase_error's, over the contact's steps): the carried, CVODE's own
    margin = ESTIMATE_SAFETY * (state.hc_xmax + ERROR_WITHIN_PHASE * rtol * length)
    t0, x0, v0 = state.step_t, state.step_x, state.step_v
    for i in range(count):
        t1, x1, v1 = origin + rows[i, 0], length * rows[i, 1], speed * rows[i, 2]
        tau, x, v, departs, decided = contact_step_exit(parameters, load, t0, x0, v0, t1, x1, v1, margin,
                                                        not (root_last and i == count - 1))
        if not decided:
            state.err_max = max(state.err_max, length)
            state.err_from = t0 if math.isnan(state.err_from) else state.err_from
        if not math.isnan(tau):
            tau_event = (t0 - origin) + tau
            state.pending, state.pend_x, state.pend_v = 1.0, x, v
            state.pend_kind = DEPARTURE if departs else RELEASE
            state.pend_t, state.pend_t_low = later(origin, state.origin_low, tau_event)
            rows[i, 0], rows[i, 1], rows[i, 2] = tau_event, x / length, v / speed
            return i + 1, True
        t0, x0, v0 = t1, x1, v1
    return count, False


def _reported_rest(parameters, state, rows, count):
    """state.hc_rest_t: where contact_laws.reported_rest_margin first turns positive on these steps, if it does.

    The steps run from the last step's end (step_*, the phase start after a restart) through rows[:count];
    within the step where the margin turns positive its crossing is bisected on the step's dense output
    (dense_output.step_state, the interpolant the grid is read from). An integrated contact has no closed form
    of its rest flow, so the rest is only reported: CVODE integrates on through it (the ball never
    leaves, or by a hop below HOP). A margin already positive at a restart dates the rest there.
    """
    load, hop = state.load, state.hop
    t0, x0, v0 = state.step_t, state.step_x, state.step_v
    if reported_rest_margin(parameters, x0, v0, load, hop) > 0.0:
        state.hc_rest_t = t0
        return
    for i in range(count):
        t1, x1, v1 = rows[i, 0], rows[i, 1], rows[i, 2]
        if reported_rest_margin(parameters, x1, v1, load, hop) > 0.0:
            low, high = t0, t1
            for _ in range(80):
                mid = 0.5 * (low + high)
                if not low < mid < high:
                    break
                x, v = step_state(parameters, load, CONTACT, t0, x0, v0, t1, x1, v1, mid)
                if reported_rest_margin(parameters, x, v, load, hop) > 0.0:
                    high = mid
                else:
                    low = mid
            state.hc_rest_t = high
            return
        t0, x0, v0 = t1, x1, v1
