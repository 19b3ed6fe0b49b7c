"""The phase machine of a grid run: CVODE phase by phase to t_end, written once for both engines.

``run_phases`` takes the ball from its state to t_end: at each phase start it decides (phases.py)
whether the contact is a rest (then the rest on the contact's exact flow ends the run), whether the
phase is taken in closed form, or else restarts CVODE in the phase's frame and takes its steps to
the terminal root (an impact or a departure, polished on the exact flow) or to t_end, checking that
no step end lies beyond R on the other side. It records every step end (t, x = h - R, v, mode) and
every event, for the grid values to be read off the dense output afterwards (dense_output.py).

It is written in plain Python over floats and numpy arrays, and calls its engine through four
functions (engine_start, engine_steps, engine_finish, engine_exceeded): as written here they drive
the scikit-sundae engine's solvers (stepper.SksundaePhaseSolver), and it runs interpreted; the
compiled engine compiles this very source with numba (compiled.py), the four bound to its own
calls into SUNDIALS, so that no Python runs between phases. Whatever needs a search on the exact
flow (phases.UNDECIDED) is handed back (HANDOFF) to BallIntegrator, which takes that one phase and
calls again; so is every step_budget steps (RETURNED), for progress and Ctrl-C.
"""

from __future__ import annotations

import math

import numpy as np

from ..physics import gap_flow_value
from .phases import (
    CONTACT,
    FLIGHT,
    UNDECIDED,
    closed_form,
    flight_impact,
    frame,
    on_wrong_side,
    polish_event,
    rest_decision,
    side_margin,
    taylor_step,
)

# run_phases's state array: the state, the phase's constants and the counters.
# RESTING: the contact is a rest (CVODE stopped at its rest root); DECIDED: CVODE integrates the phase (BallIntegrator
# decided it after a HANDOFF).
(T, X, V, MODE, LOAD, HOP, IMPACTS, DEPARTURES, LAST_IMPACT, STEPS, RHS_CALLS, RESTING, DECIDED, REST_T, REST_X,
 REST_V, FAIL_T, FAIL_X, FAIL_FLAG, STATE_SIZE) = range(20)
# What run_phases returns.
DONE, HANDOFF, RETURNED, CVODE_FAILED, TOO_MANY_STEPS, STEPPED_OVER = range(6)
IMPACT, DEPARTURE = 0, 1  # an event row's kind: (t, kind, v)
CV_ROOT_RETURN = 2
BUFFER_FULL = 99  # engine_steps: its buffer is full, call it again for the phase's further steps


def new_state(t, x, v, mode, load, hop, impacts, departures, last_impact_time, steps, rhs_calls):
    """The state array of run_phases; last_impact_time NaN for none."""
    state = np.zeros(STATE_SIZE)
    state[T], state[X], state[V], state[MODE], state[LOAD], state[HOP] = t, x, v, mode, load, hop
    state[IMPACTS], state[DEPARTURES], state[LAST_IMPACT] = impacts, departures, last_impact_time
    state[STEPS], state[RHS_CALLS], state[REST_T] = steps, rhs_calls, math.nan
    return state


def run_phases(engine, parameters, rtol, atol, state, t_end, points, n_points, events, n_events, scratch,
               step_budget):
    """Integrate from state to t_end phase by phase; (status, points, n_points, events, n_events).

    parameters: (m, k, b, R, g); atol 0 for none; state: new_state's array, updated in place;
    points (n, 4: t, x, v, mode) and events (n, 3: t, kind, v) hold n_points and n_events rows so far
    and are returned grown where they filled up; scratch (n, 3) is the engine's buffer of step ends.
    status: DONE at t_end, HANDOFF for a phase BallIntegrator takes, RETURNED after step_budget steps,
    or a failure (state[FAIL_T], state[FAIL_X] and state[FAIL_FLAG] say where and CVODE's flag).
    """
    steps_at_entry = state[STEPS]
    while True:
        t, x, v, mode, load, hop = state[T], state[X], state[V], int(state[MODE]), state[LOAD], state[HOP]
        if not t < t_end:
            return DONE, points, n_points, events, n_events
        dt = t_end - t
        if dt <= 32.0 * _ulp(max(abs(t_end), abs(t), 1e-300)):  # CVODE refuses to step (CV_TOO_CLOSE)
            state[X], state[V] = taylor_step(parameters, mode, x, v, load, dt)
            state[T] = t_end
            points, n_points = _record(points, n_points, t_end, state[X], state[V], mode)
            return DONE, points, n_points, events, n_events
        if state[STEPS] - steps_at_entry >= step_budget:
            return RETURNED, points, n_points, events, n_events
        if state[DECIDED] != 0.0:
            rest, closed = 0, 0
            state[DECIDED] = 0.0
        else:
            rest = 1 if state[RESTING] != 0.0 else rest_decision(parameters, mode, x, v, load, hop, rtol)
            closed = 0 if rest != 0 else closed_form(parameters, mode, x, v, load, hop, rtol)
        if rest == UNDECIDED or closed == UNDECIDED:
            return HANDOFF, points, n_points, events, n_events
        if rest == 1:
            state[REST_T], state[REST_X], state[REST_V] = t, x, v
            x_end, v_end = gap_flow_value(CONTACT, x, v, dt, load, parameters[0], parameters[1], parameters[2])
            points, n_points = _record(points, n_points, t, x, v, mode)
            points, n_points = _record(points, n_points, t_end, x_end, v_end, mode)
            state[T], state[X], state[V] = t_end, x_end, v_end
            return DONE, points, n_points, events, n_events
        if closed == 1:
            tau, v_impact = flight_impact(parameters, x, v, load)
            points, n_points = _record(points, n_points, t, x, v, mode)
            if t + tau <= t_end:
                points, n_points = _record(points, n_points, t + tau, 0.0, v_impact, mode)
                state[T], state[X], state[V] = t + tau, 0.0, v_impact
                events, n_events = _switch_mode(state, events, n_events)
            else:
                x_end, v_end = gap_flow_value(FLIGHT, x, v, dt, load, parameters[0], parameters[1], parameters[2])
                points, n_points = _record(points, n_points, t_end, x_end, v_end, mode)
                state[T], state[X], state[V] = t_end, x_end, v_end
            continue
        status, points, n_points, events, n_events = _cvode_phase(engine, parameters, rtol, atol, state, t_end,
                                                                  points, n_points, events, n_events, scratch)
        if status != DONE:
            return status, points, n_points, events, n_events


def _cvode_phase(engine, parameters, rtol, atol, state, t_end, points, n_points, events, n_events, scratch):
    """One phase by CVODE from the state to its terminal root or t_end; DONE or a failure, as run_phases."""
    origin, x, v, mode, load, hop = state[T], state[X], state[V], int(state[MODE]), state[LOAD], state[HOP]
    length, speed = frame(parameters, mode, x, v, load, rtol, atol)
    margin = side_margin(hop, rtol, length)
    points, n_points = _record(points, n_points, origin, x, v, mode)  # as it is, not scaled and back
    t_stop = t_end - origin
    flag = engine_start(engine, mode, t_stop, x / length, v / speed, length, speed, hop, load)
    tau_before, root, rest = 0.0, 0, 0
    while flag >= 0:
        flag, count, scratch = engine_steps(engine, mode, scratch, t_stop)
        if count == 0:
            break
        # the chunk's step ends, in whole arrays: one pass each, compiled or in numpy
        points = _room(points, n_points + count)
        rows = points[n_points:n_points + count]
        rows[:, 0] = origin + scratch[:count, 0]
        rows[:, 1] = length * scratch[:count, 1]
        rows[:, 2] = speed * scratch[:count, 2]
        rows[:, 3] = mode
        checked = count
        if flag == CV_ROOT_RETURN:
            root, rest = int(scratch[count - 1, 3]), int(scratch[count - 1, 4])
            if root != 0:
                before = scratch[count - 2, 0] if count > 1 else tau_before
                tau, v = polish_event(parameters, mode, load, length, before, scratch[count - 1, 0], rows[count - 1, 1],
                                      rows[count - 1, 2])
                rows[count - 1, 0], rows[count - 1, 1], rows[count - 1, 2] = origin + tau, 0.0, v
                checked = count - 1
        elif flag != BUFFER_FULL:
            rows[count - 1, 0] = t_end  # CVODE stopped at t_end - origin, which may round off t_end
        if checked > 0:
            extreme = rows[:checked, 1].min() if mode == FLIGHT else rows[:checked, 1].max()
            if on_wrong_side(mode, extreme, margin):
                state[FAIL_T], state[FAIL_X], state[FAIL_FLAG] = rows[checked - 1, 0], extreme, 0.0
                return STEPPED_OVER, points, n_points, events, n_events
        n_points += count
        state[STEPS] += count
        tau_before = scratch[count - 1, 0]
        if flag != BUFFER_FULL:
            break
    if flag < 0:
        state[FAIL_T], state[FAIL_X], state[FAIL_FLAG] = origin + tau_before, state[X], flag
        return TOO_MANY_STEPS if engine_exceeded(engine, mode) else CVODE_FAILED, points, n_points, events, n_events
    finished, rhs_calls = engine_finish(engine, mode)
    if finished < 0:
        state[FAIL_T], state[FAIL_X], state[FAIL_FLAG] = origin + tau_before, state[X], finished
        return CVODE_FAILED, points, n_points, events, n_events
    state[RHS_CALLS] += rhs_calls
    state[T], state[X], state[V] = points[n_points - 1, 0], points[n_points - 1, 1], points[n_points - 1, 2]
    state[RESTING] = 1.0 if rest != 0 and root == 0 else 0.0
    if root != 0:
        events, n_events = _switch_mode(state, events, n_events)
    return DONE, points, n_points, events, n_events


def _switch_mode(state, events, n_events):
    """The event at the state: the mode switches, CVODE will restart; (events, n_events) with its row."""
    if n_events == events.shape[0]:
        events = _grown(events)
    kind = IMPACT if int(state[MODE]) == FLIGHT else DEPARTURE
    events[n_events, 0], events[n_events, 1], events[n_events, 2] = state[T], kind, state[V]
    if kind == IMPACT:
        state[MODE], state[IMPACTS], state[LAST_IMPACT] = CONTACT, state[IMPACTS] + 1.0, state[T]
    else:
        state[MODE], state[DEPARTURES] = FLIGHT, state[DEPARTURES] + 1.0
    state[RESTING] = 0.0
    return events, n_events + 1


def _record(points, n_points, t, x, v, mode):
    if n_points == points.shape[0]:
        points = _grown(points)
    points[n_points, 0], points[n_points, 1], points[n_points, 2], points[n_points, 3] = t, x, v, mode
    return points, n_points + 1


def _room(rows, n_rows):
    """rows, or a copy grown to hold at least n_rows."""
    while rows.shape[0] < n_rows:
        rows = _grown(rows)
    return rows


def _grown(rows):
    bigger = np.empty((2 * rows.shape[0], rows.shape[1]))
    bigger[:rows.shape[0]] = rows
    return bigger


def _ulp(a):
    return np.spacing(a)


# --- the engine, as run interpreted: the scikit-sundae engine's two solvers (stepper.SksundaePhaseSolver) ---
def engine_start(engine, mode, t_stop, y0, y1, length, speed, hop, load):
    """Restart the mode's CVODE at 0 from (y0, y1) in the frame (length, speed), hop and load set, to stop at t_stop."""
    return engine[mode].start(t_stop, y0, y1, length, speed, hop, load)


def engine_steps(engine, mode, scratch, t_stop):
    """CVODE's step ends (tau, y0, y1, the gap root, the rest root) into scratch; (flag, count, scratch).

    The flag is CVODE's (a root, t_stop reached, a failure) or BUFFER_FULL: call again for more.
    """
    return engine[mode].steps(scratch, t_stop)


def engine_finish(engine, mode):
    """The phase is over: (flag, CVODE's right-hand-side evaluations in it)."""
    return engine[mode].finish()


def engine_exceeded(engine, mode):
    """Whether the last failure was the phase taking more steps than allowed."""
    return engine[mode].exceeded
