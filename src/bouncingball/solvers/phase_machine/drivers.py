"""The phase machine's two drivers, over its one phase routine (machine.phase_steps) and event (machine._take_event).

``run_phases`` runs to the end of a grid run, recording every step end (t, x = h - R, v, mode) and
every event, for the grid values to be read off the dense output afterwards (dense_output.py), and
returns to its caller every step_budget steps (RETURNED), for progress and Ctrl-C; ``advance`` runs
one CVODE step at a time to a target time, keeping the last step for the dense output of a target
inside it (the FMU's doStep), optionally stopping at the first event. Plain Python over floats and
the machine's state (layout.py), run interpreted by the scikit-sundae engine and compiled by the compiled one, as
machine.py is.
"""

from __future__ import annotations

import math

import numpy as np

from ...codes import CONTACT, RESTART
from ...contact_laws import law_flow_at
from ...equations import load_at
from .dense_output import step_state
from .error_estimate import run_estimate
from .machine import DONE, RETURNED, STEP_HORIZON, _take_event, closed_form_phase, grown, phase_steps
from .phases import BY_CVODE, IN_CLOSED_FORM, REST, decide_phase, taylor_step


def _decided_by_cvode(parameters, rtol, state, horizon):
    """Whether CVODE takes the phase starting at the state (phases.decide_phase); else its rest or event is set.

    horizon [s]: how far a closed-form phase's search looks ahead before it is decided again (a RESTART).
    """
    answer, tau, x_event, v_event, kind = decide_phase(parameters, int(state.mode), state.x, state.v, state.load,
                                                       state.hop, rtol, state.t, horizon)
    if answer == REST:
        state.rest_t, state.rest_x, state.rest_v = state.t, state.x, state.v
    elif answer == IN_CLOSED_FORM:
        closed_form_phase(state, tau, x_event, v_event, kind)
    return answer == BY_CVODE


def _finish_by_taylor(parameters, state, t_target):
    """Within a few ulps of t_target CVODE refuses to step (CV_TOO_CLOSE): finish by a Taylor step; whether it did."""
    dt = t_target - state.t
    if dt > 32.0 * _ulp(max(abs(t_target), abs(state.t), 1e-300)):
        return False
    state.x, state.v = taylor_step(parameters, int(state.mode), state.x, state.v, load_at(parameters, state.load,
                                                                                          state.t), dt)
    state.t, state.t_low = t_target, 0.0
    return True


def _rest_state(parameters, state, t):
    """The state at t on the rest that began at rest_*, on the contact's exact flow."""
    state.x, state.v = law_flow_at(parameters, CONTACT, state.rest_x, state.rest_v, state.rest_t, t - state.rest_t,
                                     state.load)
    state.t, state.t_low = t, 0.0


def run_phases(engine, parameters, rtol, atol, state, t_end, points, n_points, events, n_events, scratch,
               step_budget):
    """Integrate from the state to t_end phase by phase; (status, points, n_points, events, n_events).

    parameters: Ball.parameters; atol 0 for none; state: the machine's state (layout.py) after restart_needed,
    updated in place; points (n, 4: t, x, v, mode) and events (n, 3: t, kind, v) hold n_points and
    n_events rows so far and are returned grown where they filled up; scratch (n, 3) is the engine's
    buffer of step ends. status: DONE at t_end, RETURNED after step_budget steps, or a failure
    (state.fail_t, state.fail_x and state.fail_flag say where and CVODE's flag).
    """
    steps_at_entry = state.steps
    while True:
        t, mode = state.t, int(state.mode)
        if not t < t_end:
            return DONE, points, n_points, events, n_events
        if state.pending != 0.0:  # a phase in closed form: to its event, or on its flow to t_end
            points, n_points = _record(points, n_points, t, state.x, state.v, mode)
            if state.pend_t <= t_end:
                events, n_events = _take_event(parameters, rtol, atol, state, events, n_events)
            else:
                state.x, state.v = law_flow_at(parameters, mode, state.x, state.v, t, t_end - t, state.load)
                state.t, state.t_low = t_end, 0.0
            points, n_points = _record(points, n_points, state.t, state.x, state.v, mode)
            continue
        if not math.isnan(state.rest_t):
            points, n_points = _record(points, n_points, t, state.x, state.v, mode)
            _rest_state(parameters, state, t_end)
            points, n_points = _record(points, n_points, t_end, state.x, state.v, mode)
            return DONE, points, n_points, events, n_events
        if state.steps - steps_at_entry >= step_budget:
            return RETURNED, points, n_points, events, n_events
        if state.needs_init != 0.0:
            if not _decided_by_cvode(parameters, rtol, state, t_end - t):
                continue
            # Only once the phase is decided: one in closed form may end within these ulps before t_end.
            if _finish_by_taylor(parameters, state, t_end):
                points, n_points = _record(points, n_points, t_end, state.x, state.v, mode)
                return DONE, points, n_points, events, n_events
            points, n_points = _record(points, n_points, t, state.x, state.v, mode)  # as it is, not scaled and back
        status, rows, count = phase_steps(engine, parameters, rtol, atol, state, t_end, scratch)
        if status != DONE:
            return status, points, n_points, events, n_events
        points = _room(points, n_points + count)
        points[n_points:n_points + count, :3] = rows[:count, :3]
        points[n_points:n_points + count, 3] = mode
        n_points += count
        if state.pending != 0.0:
            events, n_events = _take_event(parameters, rtol, atol, state, events, n_events)
        elif not math.isnan(state.rest_t) or state.step_t == t_end:
            state.t, state.x, state.v, state.t_low = state.step_t, state.step_x, state.step_v, 0.0


def advance_in_step(parameters, state, t_from, t_target):
    """Whether the state is at t_from and t_target lies in its kept last step, after it: then the state there.

    The state at t_target is read off the step's dense output.
    """
    if not (state.segment != 0.0 and state.t == t_from and t_from < t_target <= state.seg_t1):
        return False
    state.x, state.v = step_state(parameters, state.load, int(state.seg_mode), state.seg_t0, state.seg_x0,
                                    state.seg_v0, state.seg_t1, state.seg_x1, state.seg_v1, t_target)
    state.t, state.t_low = t_target, 0.0
    return True


def is_rounding_of(current_time, t):
    """Whether a stepping caller's time current_time [s] is t [s] up to the caller's own rounding.

    The tolerance is 1e-9 relative (1e-9 s below 1 s): a step from it is a step from t; a farther one is a jump.
    """
    return abs(current_time - t) <= 1e-9 * max(1.0, abs(t))


def keep_estimate(parameters, rtol, atol, state):
    """The run's estimate at the state, the current phase so far included (error_estimate.run_estimate), kept in est.

    The compiled engine's advance and advance_in_step take it at their end, where its arithmetic costs a fraction
    of a microsecond, for an FMU that reads it at every communication point: a call of run_estimate of its own
    costs ~6 us, most of a doStep. est_t says at which time it was taken.
    """
    state.est = run_estimate(parameters, rtol, atol, state)[0]
    state.est_t = state.t


def advance(engine, parameters, rtol, atol, state, t_target, stop_at_event, events, n_events, scratch):
    """Integrate from the state to t_target one CVODE step at a time; (status, events, n_events).

    CVODE's steps do not depend on the targets: each aims machine.STEP_HORIZON past the last step's
    start, and a target inside a step is read off its dense output. With stop_at_event it returns at the
    first event before t_target (the state there, the mode switched). Arguments and statuses as
    run_phases (scratch: at least one row); state.t <= t_target.
    """
    while state.t < t_target:
        if advance_in_step(parameters, state, state.t, t_target):
            break
        if state.pending != 0.0:  # the kept step ends at an event before t_target
            restart = state.pend_kind == RESTART
            events, n_events = _take_event(parameters, rtol, atol, state, events, n_events)
            if stop_at_event and not restart:
                break
            continue
        if state.needs_init != 0.0 and math.isnan(state.rest_t) and \
                not _decided_by_cvode(parameters, rtol, state, max(t_target - state.t, STEP_HORIZON)):
            continue  # a rest, or a phase in closed form: taken above
        if not math.isnan(state.rest_t):
            _rest_state(parameters, state, t_target)
            break
        if _finish_by_taylor(parameters, state, t_target):
            break
        status, _, _ = phase_steps(engine, parameters, rtol, atol, state, math.inf, scratch)
        if status != DONE:
            return status, events, n_events
    return DONE, events, n_events


def _record(points, n_points, t, x, v, mode):
    if n_points == points.shape[0]:
        points = grown(points)
    points[n_points, 0], points[n_points, 1], points[n_points, 2], points[n_points, 3] = t, x, v, mode
    return points, n_points + 1


def _room(rows, n_rows):
    """rows, or a copy grown to hold at least n_rows."""
    while rows.shape[0] < n_rows:
        rows = grown(rows)
    return rows


def _ulp(a):
    return np.spacing(a)
