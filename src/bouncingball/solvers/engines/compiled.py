"""The compiled CVODE engine: the SUNDIALS CVODE library scikit-sundae installs, driven without Python callbacks.

scikit-sundae wraps SUNDIALS' vectors into new numpy arrays on every callback, which costs far
more than the ball's equations. Here the right-hand side, the root functions and the Jacobian are
numba ``cfunc`` s compiled from equations.py's and contact_laws/' own plain-float definitions. The phase machine of a
grid run (solvers/phase_machine/machine.py, with phases.py's decisions and the grid fill of dense_output.py) is
compiled from the very source the scikit-sundae engine runs interpreted (``run_phases``,
``advance``, ``fill_grid``), its engine calls (solvers/phase_machine/engine_protocol.py) bound to CVODE's here
(``_engine_start``, ``_engine_steps``, ``_engine_exceeded``), so no Python runs between phases.
``PhaseSolver`` is one mode's CVODE, with the same settings and the same step sequence as the
scikit-sundae engine's; its ``handle`` is what the compiled calls read.

The library is the one in scikit-sundae's wheel, bound in solvers/engines/sundials.py. Every return
code is checked, and every SUNDIALS object is freed with its solver. C function addresses are passed
to the compiled code as arguments, never baked into it, so the compiled code is cached on disk
(numba ``cache=True``) and loads in a fraction of a second after the first run.

Import this module only to use the engine (it imports numba); ``unavailable_reason()`` says why it cannot run here.
"""

from __future__ import annotations

import math

import numpy as np
from numba import carray, cfunc, from_dtype, njit, types
from numba.extending import intrinsic

from ... import equations, oscillator, physics, rounding
from ...contact_laws import BallParameters, dispatch
from ...contact_laws import common as laws_common
from ...contact_laws.dispatch import LAW_MODULES
from ..phase_machine import dense_output, drivers, engine_protocol, error_estimate, layout, machine, phases
from ..phase_machine import integrated_contact as contact_steps
from ..phase_machine.engine_protocol import CV_ROOT_RETURN, CV_SUCCESS
from . import phase_solver
from .jit import (
    addresses,
    cache_allowed,
    call_i1,
    call_i2,
    call_i3,
    call_i5,
    call_p1,
    compiled_together,
    doubles,
    engine_sources,
    functions_of,
)
from .phase_solver import (
    CLEAR_STOP,
    CV_ONE_STEP,
    CVODE,
    H_CALLS,
    H_COUNTER,
    H_MEMORY,
    H_PARAMETERS,
    H_STATE,
    H_USER_DATA,
    H_VECTOR,
    H_WORK,
    LOOP_FUNCTIONS,
    NUM_RHS,
    NUM_ROOTS,
    P_BALL,
    P_HOP,
    P_J00,
    P_J01,
    P_J10,
    P_J11,
    P_LENGTH,
    P_LOAD,
    P_MODE,
    P_ORIGIN,
    P_OWN_SIDE,
    P_SIZE,
    P_SPEED,
    REINIT,
    ROOT_INFO,
    SET_STOP,
    U_COLUMNS,
    U_EVALUATIONS,
    U_GET_ARRAY,
    U_MAX_EVALUATIONS,
    U_PARAMETERS,
    U_SIZE,
)
from .sundials import EngineUnavailable, library, unavailable_reason

_CACHE = cache_allowed(engine_sources())

_BUFFER_FULL = engine_protocol.BUFFER_FULL


@njit(cache=_CACHE)
def _steps(f, memory, vector, state, t_end, out, count, one_step, work):
    """CVODE steps from its current point towards t_end until a terminal root, t_end, an error or a full buffer.

    Like scikit-sundae's solve(): each step end (t, h, v) is stored in out[count]; a root of
    only the extremum root function (non-terminal) is stepped through without storing it. With
    one_step, a single call of CVode (scikit-sundae's step(method="onestep")). work[0] receives
    CVode's time, work[1:4] the root information of the last root. Returns (CVode's flag, or
    _BUFFER_FULL, and the new count).
    """
    info = np.zeros(NUM_ROOTS, dtype=np.int32)
    while True:
        flag = call_i5(f[CVODE], memory, t_end, vector, work.ctypes.data, CV_ONE_STEP)
        if flag == CV_ROOT_RETURN:
            check = call_i2(f[ROOT_INFO], memory, info.ctypes.data)
            if check < 0:
                return check, count
            work[1], work[2], work[3] = info[0], info[1], info[2]
            if info[0] == 0 and info[2] == 0 and not one_step:
                continue
        out[count, 0], out[count, 1], out[count, 2] = work[0], state[0], state[1]
        count += 1
        if flag != CV_SUCCESS or one_step:
            return flag, count
        if count == out.shape[0]:
            return _BUFFER_FULL, count


# --- the phase machine's engine (solvers/phase_machine/engine_protocol.py's calls) -----------------------------------
@njit(cache=_CACHE)
def _unpacked(engine, mode):
    row = engine[mode]
    return (carray(addresses(row[H_CALLS]), len(LOOP_FUNCTIONS)), row[H_MEMORY], row[H_VECTOR],
            carray(doubles(row[H_STATE]), 2), carray(doubles(row[H_PARAMETERS]), P_SIZE),
            carray(addresses(row[H_USER_DATA]), U_SIZE), carray(doubles(row[H_WORK]), 1 + NUM_ROOTS),
            carray(addresses(row[H_COUNTER]), 1))


@njit(cache=_CACHE)
def _engine_start(engine, mode, t_stop, y0, y1, length, speed, hop, load, origin):
    calls, memory, vector, state, parameters, user_data, work, counter = _unpacked(engine, mode)
    parameters[P_LENGTH], parameters[P_SPEED], parameters[P_HOP], parameters[P_LOAD] = length, speed, hop, load
    parameters[P_ORIGIN] = origin
    parameters[P_J00], parameters[P_J01], parameters[P_J10], parameters[P_J11] = _scaled_jacobian(
        _parameters_at(parameters, P_BALL), mode, length, speed)
    user_data[U_EVALUATIONS] = 0
    state[0], state[1] = y0, y1
    flag = call_i3(calls[REINIT], memory, 0.0, vector)
    if flag < 0:
        return flag
    if t_stop == math.inf:
        return call_i1(calls[CLEAR_STOP], memory)
    return call_i2(calls[SET_STOP], memory, t_stop)


@njit(cache=_CACHE)
def _engine_steps(engine, mode, scratch, t_toward, one_step):
    calls, memory, vector, state, parameters, user_data, work, counter = _unpacked(engine, mode)
    flag, count = _steps(calls, memory, vector, state, t_toward, scratch, 0, one_step, work)
    gap_root, rest_root = (int(work[1]), int(work[3])) if flag == CV_ROOT_RETURN else (0, 0)
    if flag < 0:
        return flag, count, scratch, 0, 0, 0
    rhs_calls = call_i2(calls[NUM_RHS], memory, counter.ctypes.data)
    if rhs_calls < 0:
        return rhs_calls, 0, scratch, 0, 0, 0
    return flag, count, scratch, gap_root, rest_root, counter[0]


@njit(cache=_CACHE)
def _engine_exceeded(engine, mode):
    user_data = _unpacked(engine, mode)[5]
    return user_data[U_EVALUATIONS] > user_data[U_MAX_EVALUATIONS]


# Lazily: numba compiles a function at its first call from compiled code: only what the machine reaches, and cached.
_compiled = compiled_together(
    functions_of(rounding, oscillator, equations, *LAW_MODULES, dispatch, physics, phases, error_estimate,
                 contact_steps, machine, drivers, dense_output),
    {oscillator.oscillator_basis: oscillator.oscillator_basis_value,
     oscillator.unit_response: oscillator.unit_response_value,
     rounding.hypot: rounding.hypot_value, engine_protocol.engine_start: _engine_start,
     engine_protocol.engine_steps: _engine_steps, engine_protocol.engine_exceeded: _engine_exceeded}, _CACHE)
_run_phases, _advance = _compiled[drivers.run_phases], _compiled[drivers.advance]
_advance_in_step, _keep_estimate = _compiled[drivers.advance_in_step], _compiled[drivers.keep_estimate]
_phase_ends, _run_estimate = _compiled[machine.phase_ends], _compiled[error_estimate.run_estimate]
fill_grid = _compiled[dense_output.fill_grid]
_scaled_rates, _root_values = _compiled[phases.scaled_rates], _compiled[phases.root_values]
_scaled_jacobian = _compiled[phases.scaled_jacobian]
_parameters_at, _load_at = _compiled[laws_common.parameters_at], _compiled[equations.load_at]
_jacobian_varies, _varying_jacobian = _compiled[phases.jacobian_varies], _compiled[phases.varying_jacobian]


# --- the entry points: the machine on its state, a record of layout.STATE_DTYPE ------------------------------
# They take a float64 array over the record's memory (layout.compiled_state) and the ball's parameters as a plain
# tuple (stepper.phase_machine), and give the machine the record and the namedtuple: numba types a record argument
# (numpy.void) in ~30 us a call and a namedtuple in twice a tuple's time (measured), against a doStep's ~10 us.
_STATE_RECORD = from_dtype(layout.STATE_DTYPE)


@intrinsic
def _record_pointer(typingctx, address):
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
    return types.CPointer(_STATE_RECORD)(types.intp), codegen


@njit(cache=_CACHE)
def _record(memory):
    return carray(_record_pointer(memory.ctypes.data), 1)[0]


@njit(cache=_CACHE)
def run_phases(engine, values, rtol, atol, memory, t_end, points, n_points, events, n_events, scratch, budget):
    return _run_phases(engine, BallParameters(*values), rtol, atol, _record(memory), t_end, points, n_points,
                       events, n_events, scratch, budget)


@njit(cache=_CACHE)
def advance(engine, values, rtol, atol, memory, t_target, stop_at_event, events, n_events, scratch):
    parameters, state = BallParameters(*values), _record(memory)
    answer = _advance(engine, parameters, rtol, atol, state, t_target, stop_at_event, events, n_events, scratch)
    _keep_estimate(parameters, rtol, atol, state)
    return answer


@njit(cache=_CACHE)
def advance_in_step(values, rtol, atol, memory, t_from, t_target):
    parameters, state = BallParameters(*values), _record(memory)
    if not _advance_in_step(parameters, state, t_from, t_target):
        return False
    _keep_estimate(parameters, rtol, atol, state)
    return True


@njit(cache=_CACHE)
def phase_ends(values, rtol, atol, memory, jump, reflection):
    _phase_ends(BallParameters(*values), rtol, atol, _record(memory), jump, reflection)


@njit(cache=_CACHE)
def run_estimate(values, rtol, atol, memory):
    return _run_estimate(BallParameters(*values), rtol, atol, _record(memory))


_callback_data = types.CPointer(types.intp)


@cfunc(types.int32(types.float64, types.intp, types.intp, _callback_data), cache=_CACHE)
def _rhs(t, y, ydot, user_data):
    u = carray(user_data, U_SIZE)
    p = carray(doubles(u[U_PARAMETERS]), P_SIZE)
    state = carray(doubles(call_p1(u[U_GET_ARRAY], y)), 2)
    out = carray(doubles(call_p1(u[U_GET_ARRAY], ydot)), 2)
    ball = _parameters_at(p, P_BALL)
    out[0], out[1] = _scaled_rates(ball, state[0], state[1], p[P_MODE], p[P_LENGTH], p[P_SPEED],
                                   _load_at(ball, p[P_LOAD], p[P_ORIGIN] + t))
    return 0


@cfunc(types.int32(types.float64, types.intp, types.CPointer(types.float64), _callback_data), cache=_CACHE)
def _roots(t, y, gout, user_data):
    u = carray(user_data, U_SIZE)
    p = carray(doubles(u[U_PARAMETERS]), P_SIZE)
    state = carray(doubles(call_p1(u[U_GET_ARRAY], y)), 2)
    out = carray(gout, 3)
    ball = _parameters_at(p, P_BALL)
    out[0], out[1], out[2] = _root_values(ball, state[0], state[1], p[P_MODE], p[P_LENGTH], p[P_SPEED],
                                          _load_at(ball, p[P_LOAD], p[P_ORIGIN] + t), p[P_OWN_SIDE], p[P_HOP])
    u[U_EVALUATIONS] += 1
    return 1 if u[U_EVALUATIONS] > u[U_MAX_EVALUATIONS] else 0


@cfunc(types.int32(types.float64, types.intp, types.intp, types.intp, _callback_data, types.intp, types.intp,
                   types.intp), cache=_CACHE)
def _jacobian(t, y, fy, matrix, user_data, tmp1, tmp2, tmp3):
    u = carray(user_data, U_SIZE)
    p = carray(doubles(u[U_PARAMETERS]), P_SIZE)
    columns = carray(addresses(call_p1(u[U_COLUMNS], matrix)), 2)
    first, second = carray(doubles(columns[0]), 2), carray(doubles(columns[1]), 2)
    ball = _parameters_at(p, P_BALL)
    if _jacobian_varies(ball, p[P_MODE]):  # evaluated where it changes
        state = carray(doubles(call_p1(u[U_GET_ARRAY], y)), 2)
        j00, j01, j10, j11 = _varying_jacobian(ball, state[0], state[1], p[P_LENGTH], p[P_SPEED],
                                               _load_at(ball, p[P_LOAD], p[P_ORIGIN] + t))
        first[0], first[1] = j00, j10  # SUNDIALS' dense matrices are stored by columns
        second[0], second[1] = j01, j11
        return 0
    first[0], first[1] = p[P_J00], p[P_J10]  # SUNDIALS' dense matrices are stored by columns
    second[0], second[1] = p[P_J01], p[P_J11]
    return 0


class PhaseSolver(phase_solver.PhaseSolver):
    """One mode's CVODE (phase_solver.PhaseSolver) with this module's numba callbacks."""

    callbacks = (_rhs.address, _roots.address, _jacobian.address)


__all__ = ["EngineUnavailable", "PhaseSolver", "library", "unavailable_reason"]
