"""The phase machine: CVODE phase by phase, written once for both engines; its drivers are in drivers.py.

At each phase start it decides (phases.py) whether the contact is a rest (then the rest is taken on
the contact's exact flow), whether the phase is taken in closed form (its event from the exact flow),
or else restarts CVODE in the phase's frame and takes its steps to the terminal root (an impact or a
departure, polished on the exact flow), checking that no step end lies beyond R on the other side.
``phase_steps`` is the one phase routine (restart, steps, polish, side check, the last step kept),
``_take_event`` takes an event in one place; drivers.py's two drivers run them, a grid run to its end
(``run_phases``) and the stepping API's ``advance``.

The whole integrator state is one object of named fields (layout.py; BallIntegrator keeps it), read and
written by attribute. The source is plain Python over floats, numpy arrays and that state, and calls its
engine through the engine_* functions: as written
here they drive the scikit-sundae engine's solvers (stepper.SksundaePhaseSolver), and it runs
interpreted; the compiled engine compiles this very source with numba (compiled.py), the engine_*
bound to its own calls into SUNDIALS, so that no Python runs between phases. The machine decides
every phase itself (phases.decide_phase).
"""

from __future__ import annotations

import math

import numpy as np

from ...codes import CONTACT, DEPARTURE, FLIGHT, FREE, IMPACT, RELEASE, RESTART
from ...contact_laws import (
    contact_ends_in,
    contact_integrated,
    ground_moves,
    impact_is_instantaneous,
    rigid_rebound,
    root_release_speed,
    side_extreme,
    third_root_releases,
)
from ...equations import load_at, ride_end_value
from ...rounding import later
from .engine_protocol import BUFFER_FULL, CV_ROOT_RETURN, engine_exceeded, engine_start, engine_steps
from .error_estimate import carry_error, event_saltation, phase_error, start_contact_ellipses
from .integrated_contact import integrated_contact_steps, vibrating_contact_steps
from .phases import frame, on_wrong_side, polish_event, polish_release, side_margin, vibrating_flight_touch
from .settings import ERROR_WITHIN_PHASE, ESTIMATE_SAFETY

# What run_phases returns.
DONE, RETURNED, CVODE_FAILED, TOO_MANY_STEPS, STEPPED_OVER = range(5)
STEP_HORIZON = 1.0  # s: how far ahead advance's CVODE steps aim (see drivers.advance)


def restart_needed(state):
    """CVODE restarts at the current state, which becomes the restart point (the last step and any rest forgotten)."""
    state.rhs_calls += state.nfev
    state.nfev, state.needs_init, state.segment, state.pending = 0.0, 1.0, 0.0, 0.0
    state.rest_t, state.hc_rest_t, state.est_t = math.nan, math.nan, math.nan  # est: of the state before
    state.rs_t, state.rs_x, state.rs_v, state.rs_mode = state.t, state.x, state.v, state.mode
    state.rs_t_low = state.t_low
    state.rs_impacts, state.rs_departures = state.impacts, state.departures
    state.rs_last_impact = state.last_impact
    state.rs_rhs_calls, state.rs_steps = state.rhs_calls, state.steps


def phase_ends(parameters, rtol, atol, state, jump, reflection):
    """The phase from the restart point ends at the state: its error is carried, and CVODE restarts there.

    error_estimate.carry_error, with its saltation matrix's jump [1/s] and reflection there (0.0 and 1.0
    where the state and the field go on unchanged); then restart_needed.
    """
    carry_error(parameters, rtol, atol, state, jump, reflection)
    restart_needed(state)


def closed_form_phase(state, tau, x_event, v_event, kind):
    """The phase from the state ends at an event of kind tau later at (x_event, v_event), from the exact flow.

    The phase is kept as the last step.
    """
    t_event, t_low = later(state.t, state.t_low, tau)
    state.segment, state.seg_mode = 1.0, state.mode
    state.seg_t0, state.seg_x0, state.seg_v0 = state.t, state.x, state.v
    state.seg_t1, state.seg_x1, state.seg_v1 = t_event, x_event, v_event
    state.pending, state.pend_t, state.pend_v, state.pend_t_low = 1.0, t_event, v_event, t_low
    state.pend_x, state.pend_kind = x_event, kind


def phase_steps(engine, parameters, rtol, atol, state, t_stop, scratch):
    """CVODE's next steps in the phase at the state, both drivers' one phase routine; (status, rows, count).

    t_stop: the stop time [s] of a grid run, whose steps run to it or to the phase's terminal root
    (or until the engine's buffer is full: call again); inf for advance, which takes one step aimed
    STEP_HORIZON past the last step's start. rows[:count]: the step ends (t, x, v), each an ulp-true
    time; the last one is the state's last step (step_*; seg_* from the one before, for the dense
    output); a terminal root's is polished onto R and kept pending (the event to take), a rest root's
    starts the rest (rest_*). status: DONE, or a failure (fail_*): CVODE's, or STEPPED_OVER where a
    step end lies on the other side of R beyond side_margin (an event stepped over).

    Its jobs, in order: restart CVODE where the phase starts (_start_phase); take its steps (engine_steps); the
    event a root ends them on (_root_event); the steps into the world's frame, the event's row its polished
    state (_world_rows); the side check (_stepped_over); the law's bookkeeping over an integrated contact's
    steps (integrated_contact.py); the steps counted and the last one kept (_keep_last_step).
    """
    mode, one_step = int(state.mode), math.isinf(t_stop)
    if state.needs_init != 0.0:
        flag = _start_phase(engine, parameters, rtol, atol, state, mode, t_stop)
        if flag < 0:
            state.fail_t, state.fail_x, state.fail_flag = state.t, state.x, flag
            return CVODE_FAILED, scratch, 0
    tau_before = state.step_t - state.origin
    flag, count, rows, gap_root, rest_root, rhs_calls = engine_steps(
        engine, mode, scratch, tau_before + STEP_HORIZON if one_step else t_stop - state.origin, one_step)
    if flag < 0:  # a grid run's phase is reported at its start, where its state is, whichever engine ran it
        state.fail_t = (state.origin + rows[count - 1, 0] if count > 0 else state.step_t) if one_step \
            else state.origin
        state.fail_x, state.fail_flag = state.step_x if one_step else state.x, flag
        return TOO_MANY_STEPS if engine_exceeded(engine, mode) else CVODE_FAILED, rows, 0
    state.nfev = rhs_calls
    released = rest_root != 0 and gap_root == 0 and third_root_releases(parameters, mode)
    if released:
        rest_root = 0
    unconfirmed, ends_in_event = False, gap_root != 0 or released
    if mode == FLIGHT and ground_moves(parameters):  # each step searched on the exact flow: the touch, certified
        count, touched = _vibrating_flight_steps(parameters, rtol, atol, state, rows, count)
        unconfirmed = gap_root != 0 and not touched
        ends_in_event, gap_root = touched, 0
    elif mode == CONTACT and contact_integrated(parameters) and ground_moves(parameters):  # each step's exit
        count, exited = vibrating_contact_steps(parameters, rtol, state, rows, count, ends_in_event)
        if exited:  # before CVODE's root, if it had one: on the interpolant, certified
            ends_in_event, gap_root, released = True, 0, False
    _root_event(parameters, state, mode, rows, count, tau_before, gap_root != 0, released)
    _world_rows(state, rows, count, t_stop, flag, ends_in_event)
    checked = count - 1 if ends_in_event else count  # the event's row is on R (or, a release, below it)
    if checked > 0 and _stepped_over(parameters, rtol, state, mode, rows, checked):
        return STEPPED_OVER, rows, 0
    if mode == CONTACT and contact_integrated(parameters):
        integrated_contact_steps(parameters, rtol, state, rows, count)
    # A root of the extremum function alone ends no CVODE step (one_step returns at it): not counted.
    state.steps += count - 1 if flag == CV_ROOT_RETURN and not ends_in_event and rest_root == 0 else count
    _keep_last_step(state, mode, rows, count)
    if rest_root != 0:
        state.rest_t, state.rest_x, state.rest_v = rows[count - 1, 0], rows[count - 1, 1], rows[count - 1, 2]
    if unconfirmed:  # CVODE's root, off the exact flow by its error: the flight goes on, CVODE restarted there
        state.pending, state.pend_t, state.pend_x, state.pend_v = 1.0, state.step_t, state.step_x, state.step_v
        state.pend_t_low, state.pend_kind = 0.0, RESTART  # after the targets inside the step (advance)
    return DONE, rows, count


def _start_phase(engine, parameters, rtol, atol, state, mode, t_stop):
    """CVODE restarts in the phase's frame (phases.frame) from the state; the engine's flag (< 0: it failed)."""
    length, speed = frame(parameters, mode, state.x, state.v, load_at(parameters, state.load, state.t), rtol, atol,
                          t_stop - state.t, state.t)
    state.origin, state.length, state.speed, state.origin_low = state.t, length, speed, state.t_low
    flag = engine_start(engine, mode, t_stop - state.t, state.x / length, state.v / speed, length, speed, state.hop,
                        state.load, state.t)
    if flag < 0:
        return flag
    state.needs_init = 0.0
    state.step_t, state.step_x, state.step_v = state.t, state.x, state.v
    if mode == CONTACT and contact_integrated(parameters):
        start_contact_ellipses(state)
    return flag


def _root_event(parameters, state, mode, rows, count, tau_before, gap_root, released):
    """The event the last of rows[:count] (in the phase's frame) is a root of, kept pending (pend_*), if any.

    gap_root: the terminal root, polished on the exact flow: an impact or departure on R, or a release below it
    (contact_laws.contact_ends_in). released: the third root a release (contact_laws.third_root_releases), taken
    where CVODE located it (no closed form to polish on), at the release speed exactly; a terminal root on the
    same step comes first.
    """
    origin, length, speed, load, last = state.origin, state.length, state.speed, state.load, count - 1
    if released:
        state.pending, state.pend_v, state.pend_kind = 1.0, root_release_speed(parameters), RELEASE
        state.pend_x = min(length * rows[last, 1], 0.0)
        state.pend_t, state.pend_t_low = later(origin, state.origin_low, rows[last, 0])
    if not gap_root:
        return
    tau_step = rows[last - 1, 0] if count > 1 else tau_before
    kind = IMPACT if mode == FLIGHT else contact_ends_in(parameters)
    if kind == RELEASE:
        tau, x, v = polish_release(parameters, load, length, tau_step, rows[last, 0], length * rows[last, 1],
                                   speed * rows[last, 2])
    else:
        tau, v = polish_event(parameters, mode, load_at(parameters, load, origin + rows[last, 0]), length, tau_step,
                              rows[last, 0], length * rows[last, 1], speed * rows[last, 2], state.rs_x, state.rs_v)
        x = 0.0
    state.pending, state.pend_v, state.pend_x, state.pend_kind = 1.0, v, x, kind
    state.pend_t, state.pend_t_low = later(origin, state.origin_low, tau)


def _vibrating_flight_steps(parameters, rtol, atol, state, rows, count):
    """(count, touched): a flight's steps rows[:count] (in the phase's frame) on a vibrating ground, up to its touch.

    Each step is searched from its start on the exact flow (phases.vibrating_flight_touch, certified): where the
    flight meets the ground within one, that is the impact, kept pending on the ground at its relative speed, and
    the steps end there (CVODE's root function sees no change of sign across a graze inside a step, and its own
    root is off by its tolerance). A graze that the gap's error could turn the other way (a touch that may be a
    miss, a miss that may be a touch) is not decided: the motion after it may differ by the flight's whole size,
    its length scale, which is charged to the estimate from there (it then passes the promise and warns).
    """
    origin, length, speed = state.origin, state.length, state.speed
    t0, x0, v0 = state.step_t, state.step_x, state.step_v
    for i in range(count):
        t1 = origin + rows[i, 0]
        # the error at the step's start: the phase's start's, carried (a flight's transition: x + v tau, signed), and
        # CVODE's own (unsigned), with the estimate's safety
        elapsed = t0 - state.rs_t
        tau, v, decided = vibrating_flight_touch(
            parameters, state.load, t0, x0, v0, t1, ESTIMATE_SAFETY * (state.err_x + state.err_v * elapsed),
            ESTIMATE_SAFETY * state.err_v, ESTIMATE_SAFETY * ERROR_WITHIN_PHASE * rtol * (length + speed * elapsed))
        if not decided:
            state.err_max = max(state.err_max, length)
            state.err_from = t0 if math.isnan(state.err_from) else state.err_from
        if not math.isinf(tau):
            tau_event = (t0 - origin) + tau
            state.pending, state.pend_v, state.pend_x, state.pend_kind = 1.0, v, 0.0, IMPACT
            state.pend_t, state.pend_t_low = later(origin, state.origin_low, tau_event)
            rows[i, 0], rows[i, 1], rows[i, 2] = tau_event, 0.0, v / speed
            return i + 1, True
        t0, x0, v0 = t1, length * rows[i, 1], speed * rows[i, 2]
    return count, False


def _world_rows(state, rows, count, t_stop, flag, ends_in_event):
    """rows[:count] from the phase's frame into the world's (t [s], x [m], v [m/s]); an event's row its pending state.

    A grid run's last step ends at t_stop exactly (CVODE stopped at t_stop - origin, which may round it off).
    """
    rows[:count, 0] += state.origin
    rows[:count, 1] *= state.length
    rows[:count, 2] *= state.speed
    last = count - 1
    if ends_in_event:
        rows[last, 0], rows[last, 1], rows[last, 2] = state.pend_t, state.pend_x, state.pend_v
    elif flag != CV_ROOT_RETURN and not math.isinf(t_stop) and flag != BUFFER_FULL:
        rows[last, 0] = t_stop


def _stepped_over(parameters, rtol, state, mode, rows, checked):
    """Whether a step end of rows[:checked] lies beyond side_margin on the other side of its event (fail_* set)."""
    extreme = side_extreme(parameters, mode, rows[:checked, 1], rows[:checked, 2])
    if on_wrong_side(mode, extreme, side_margin(state.hop, rtol, state.length)):
        state.fail_t, state.fail_x, state.fail_flag = rows[checked - 1, 0], extreme, 0.0
        return True
    return False


def _keep_last_step(state, mode, rows, count):
    """The last of rows[:count] becomes the state's last step (step_*), kept with its start (seg_*) for dense output."""
    last = count - 1
    state.segment, state.seg_mode = 1.0, mode
    if count > 1:
        state.seg_t0, state.seg_x0, state.seg_v0 = rows[last - 1, 0], rows[last - 1, 1], rows[last - 1, 2]
    else:
        state.seg_t0, state.seg_x0, state.seg_v0 = state.step_t, state.step_x, state.step_v
    state.seg_t1, state.seg_x1, state.seg_v1 = rows[last, 0], rows[last, 1], rows[last, 2]
    state.step_t, state.step_x, state.step_v = rows[last, 0], rows[last, 1], rows[last, 2]


def _take_event(parameters, rtol, atol, state, events, n_events):
    """The pending event: the state moves there, the mode switches, the phase ends; (events, n_events) with its row.

    A pending RESTART (no event) moves the state and restarts CVODE there, in the same mode, with no row.
    """
    state.t, state.x, state.v, state.t_low = state.pend_t, state.pend_x, state.pend_v, state.pend_t_low
    if state.pend_kind == RESTART:
        phase_ends(parameters, rtol, atol, state, 0.0, 1.0)
        return events, n_events
    if n_events == events.shape[0]:
        events = grown(events)
    kind, mode = int(state.pend_kind), int(state.mode)
    events[n_events, 0], events[n_events, 1], events[n_events, 2] = state.t, kind, state.v
    if kind == IMPACT and impact_is_instantaneous(parameters):
        _bounce(parameters, rtol, atol, state)
        return events, n_events + 1
    jump, reflection = event_saltation(parameters, kind, mode, state.v, state.v, load_at(parameters, state.load,
                                                                                            state.t))
    if kind == IMPACT:
        state.mode, state.impacts, state.last_impact = CONTACT, state.impacts + 1.0, state.t
    elif kind == DEPARTURE:
        state.mode, state.departures = FLIGHT, state.departures + 1.0
        state.hc_rest_t = math.nan  # a Hunt-Crossley rest ended by a hop below HOP
    else:
        state.mode = FREE if kind == RELEASE else CONTACT
    phase_ends(parameters, rtol, atol, state, jump, reflection)
    return events, n_events + 1


def _bounce(parameters, rtol, atol, state):
    """A rigid impact at the state (on R, at v < 0): the ball flies on at -e v, or stays on R (rigid_rebound).

    Where it stays after bounces summed as their series, its rest starts at the Zeno time, after the
    state's time; between them the ball is taken on R (the bounces there are lower than ZENO_APEX R).
    """
    v_impact, load = state.v, load_at(parameters, state.load, state.t)
    v_after, zeno = rigid_rebound(parameters, v_impact, load)
    if parameters.v_min > 0.0 and _undecided_rebound(parameters, rtol, atol, state, v_impact, load):
        state.err_max = max(state.err_max, state.length)
        state.err_from = state.t if math.isnan(state.err_from) else state.err_from
    jump, reflection = event_saltation(parameters, IMPACT, FLIGHT, v_impact, v_after, load)
    if not v_after > 0.0 and load < 0.0:  # no rebound, but a vibrating ground pulls away at once: the ball leaves
        jump, reflection = -(load / parameters.m) / v_impact, 0.0  # with it, as after an impact with e = 0
    carry_error(parameters, rtol, atol, state, jump, reflection)  # the error of the state before the impact
    state.impacts, state.last_impact, state.v = state.impacts + 1.0, state.t, v_after
    state.mode = FLIGHT if v_after > 0.0 else CONTACT
    if state.mode == CONTACT and ground_moves(parameters):
        _ride(parameters, state, later(state.t, state.t_low, zeno)[0])
        return
    restart_needed(state)
    if zeno > 0.0:
        state.rest_t, state.rest_x, state.rest_v = later(state.t, state.t_low, zeno)[0], 0.0, 0.0


def _undecided_rebound(parameters, rtol, atol, state, v_impact, load):
    """Whether a rigid bounce at v_impact [m/s] is as near v_min as its speed's error: on, or stays, is not decided.

    The speed's error: the run's error of v at the impact (error_estimate.phase_error), that of x turned into one
    of the speed through the impact's time (g_eff |x error| / |v|, large at a graze), CVODE's own, with the
    estimate's safety. Either way the motion after it may differ by the flight's size (a bounce of v_min or a
    ride), which the caller charges to the estimate.
    """
    ax, av = phase_error(parameters, rtol, atol, state)[:2]
    error = ESTIMATE_SAFETY * (abs(av) + abs(load / parameters.m) * abs(ax) / abs(v_impact)
                               + ERROR_WITHIN_PHASE * rtol * state.speed)
    return abs(parameters.e * abs(v_impact) - parameters.v_min) <= parameters.e * error


def _ride(parameters, state, t_ride):
    """A rigid ball stays on a vibrating ground from its impact at the state: its ride, from t_ride [s] on.

    Its bounces until t_ride (the Zeno time of those summed; else the impact's) are taken on the ground, as on a
    still one. The ride ends where s'' falls below -g_eff (equations.ride_end_value), the departure pending in
    closed form; at once, it is none: the ball leaves with the ground (as the exact solution has it); never, a rest.
    """
    t_leave = ride_end_value(parameters, t_ride, state.load / parameters.m)
    if t_leave == state.t:
        state.mode = FLIGHT
    restart_needed(state)
    if t_leave == state.t:
        return
    if math.isinf(t_leave):
        state.rest_t, state.rest_x, state.rest_v = t_ride, 0.0, 0.0
        return
    closed_form_phase(state, t_leave - state.t, 0.0, 0.0, DEPARTURE)


def grown(rows):
    """rows with as many more, uninitialised: an array of rows made room in."""
    return np.concatenate((rows, np.empty_like(rows)))
