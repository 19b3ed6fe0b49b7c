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

import ctypes
import math
import weakref

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
from .sundials import EngineUnavailable, library, unavailable_reason
from .sundials import free as _free
from .sundials import message as _message
from .sundials_log import SundialsLog

CV_ADAMS, CV_BDF = 1, 2
CV_ONE_STEP = 2
# cvode.py's defaults for scikit-sundae's options that CVODE would otherwise take from itself.
_MAX_NONLIN_ITERS = 3
_MAX_CONV_FAILS = 10
_MAX_ORDER = {CV_ADAMS: 12, CV_BDF: 5}
_NUM_ROOTS = 3

# The block user_data points to (int64): what the callbacks need besides the state.
_U_PARAMETERS, _U_GET_ARRAY, _U_COLUMNS, _U_EVALUATIONS, _U_MAX_EVALUATIONS, _U_SIZE = range(6)
# The callbacks' float64 parameters: CVODE integrates x / length, v / speed (x = h - R) from _P_ORIGIN [s] (time 0;
# a vibrating ground's load is equations.load_at's there + CVODE's time); the ball from _P_BALL (BallParameters).
(_P_MODE, _P_OWN_SIDE, _P_HOP, _P_J00, _P_J01, _P_J10, _P_J11, _P_LENGTH, _P_SPEED, _P_LOAD, _P_ORIGIN,
 _P_BALL) = range(12)
_P_SIZE = _P_BALL + len(BallParameters._fields)

_CACHE = cache_allowed(engine_sources())

# The C functions the compiled loop calls, by their place in the address array it receives.
_LOOP_FUNCTIONS = ("CVode", "CVodeGetRootInfo", "CVodeReInit", "CVodeSetStopTime", "CVodeClearStopTime",
                   "CVodeGetNumRhsEvals")
_CVODE, _ROOT_INFO, _REINIT, _SET_STOP, _CLEAR_STOP, _NUM_RHS = range(len(_LOOP_FUNCTIONS))
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
    info = np.zeros(_NUM_ROOTS, dtype=np.int32)
    while True:
        flag = call_i5(f[_CVODE], memory, t_end, vector, work.ctypes.data, CV_ONE_STEP)
        if flag == CV_ROOT_RETURN:
            check = call_i2(f[_ROOT_INFO], memory, info.ctypes.data)
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
# engine: one row per mode (PhaseSolver.handle()): the addresses of its call table and arrays, its CVODE
# memory and vector. Integers only, so that a call into the compiled machine unpacks no Python objects.
_H_CALLS, _H_MEMORY, _H_VECTOR, _H_STATE, _H_PARAMETERS, _H_USER_DATA, _H_WORK, _H_COUNTER, _H_SIZE = range(9)


@njit(cache=_CACHE)
def _unpacked(engine, mode):
    row = engine[mode]
    return (carray(addresses(row[_H_CALLS]), len(_LOOP_FUNCTIONS)), row[_H_MEMORY], row[_H_VECTOR],
            carray(doubles(row[_H_STATE]), 2), carray(doubles(row[_H_PARAMETERS]), _P_SIZE),
            carray(addresses(row[_H_USER_DATA]), _U_SIZE), carray(doubles(row[_H_WORK]), 1 + _NUM_ROOTS),
            carray(addresses(row[_H_COUNTER]), 1))


@njit(cache=_CACHE)
def _engine_start(engine, mode, t_stop, y0, y1, length, speed, hop, load, origin):
    calls, memory, vector, state, parameters, user_data, work, counter = _unpacked(engine, mode)
    parameters[_P_LENGTH], parameters[_P_SPEED], parameters[_P_HOP], parameters[_P_LOAD] = length, speed, hop, load
    parameters[_P_ORIGIN] = origin
    parameters[_P_J00], parameters[_P_J01], parameters[_P_J10], parameters[_P_J11] = _scaled_jacobian(
        _parameters_at(parameters, _P_BALL), mode, length, speed)
    user_data[_U_EVALUATIONS] = 0
    state[0], state[1] = y0, y1
    flag = call_i3(calls[_REINIT], memory, 0.0, vector)
    if flag < 0:
        return flag
    if t_stop == math.inf:
        return call_i1(calls[_CLEAR_STOP], memory)
    return call_i2(calls[_SET_STOP], memory, t_stop)


@njit(cache=_CACHE)
def _engine_steps(engine, mode, scratch, t_toward, one_step):
    calls, memory, vector, state, parameters, user_data, work, counter = _unpacked(engine, mode)
    flag, count = _steps(calls, memory, vector, state, t_toward, scratch, 0, one_step, work)
    gap_root, rest_root = (int(work[1]), int(work[3])) if flag == CV_ROOT_RETURN else (0, 0)
    if flag < 0:
        return flag, count, scratch, 0, 0, 0
    rhs_calls = call_i2(calls[_NUM_RHS], memory, counter.ctypes.data)
    if rhs_calls < 0:
        return rhs_calls, 0, scratch, 0, 0, 0
    return flag, count, scratch, gap_root, rest_root, counter[0]


@njit(cache=_CACHE)
def _engine_exceeded(engine, mode):
    user_data = _unpacked(engine, mode)[5]
    return user_data[_U_EVALUATIONS] > user_data[_U_MAX_EVALUATIONS]


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
    u = carray(user_data, _U_SIZE)
    p = carray(doubles(u[_U_PARAMETERS]), _P_SIZE)
    state = carray(doubles(call_p1(u[_U_GET_ARRAY], y)), 2)
    out = carray(doubles(call_p1(u[_U_GET_ARRAY], ydot)), 2)
    ball = _parameters_at(p, _P_BALL)
    out[0], out[1] = _scaled_rates(ball, state[0], state[1], p[_P_MODE], p[_P_LENGTH], p[_P_SPEED],
                                   _load_at(ball, p[_P_LOAD], p[_P_ORIGIN] + t))
    return 0


@cfunc(types.int32(types.float64, types.intp, types.CPointer(types.float64), _callback_data), cache=_CACHE)
def _roots(t, y, gout, user_data):
    u = carray(user_data, _U_SIZE)
    p = carray(doubles(u[_U_PARAMETERS]), _P_SIZE)
    state = carray(doubles(call_p1(u[_U_GET_ARRAY], y)), 2)
    out = carray(gout, 3)
    ball = _parameters_at(p, _P_BALL)
    out[0], out[1], out[2] = _root_values(ball, state[0], state[1], p[_P_MODE], p[_P_LENGTH], p[_P_SPEED],
                                          _load_at(ball, p[_P_LOAD], p[_P_ORIGIN] + t), p[_P_OWN_SIDE], p[_P_HOP])
    u[_U_EVALUATIONS] += 1
    return 1 if u[_U_EVALUATIONS] > u[_U_MAX_EVALUATIONS] else 0


@cfunc(types.int32(types.float64, types.intp, types.intp, types.intp, _callback_data, types.intp, types.intp,
                   types.intp), cache=_CACHE)
def _jacobian(t, y, fy, matrix, user_data, tmp1, tmp2, tmp3):
    u = carray(user_data, _U_SIZE)
    p = carray(doubles(u[_U_PARAMETERS]), _P_SIZE)
    columns = carray(addresses(call_p1(u[_U_COLUMNS], matrix)), 2)
    first, second = carray(doubles(columns[0]), 2), carray(doubles(columns[1]), 2)
    ball = _parameters_at(p, _P_BALL)
    if _jacobian_varies(ball, p[_P_MODE]):  # evaluated where it changes
        state = carray(doubles(call_p1(u[_U_GET_ARRAY], y)), 2)
        j00, j01, j10, j11 = _varying_jacobian(ball, state[0], state[1], p[_P_LENGTH], p[_P_SPEED],
                                               _load_at(ball, p[_P_LOAD], p[_P_ORIGIN] + t))
        first[0], first[1] = j00, j10  # SUNDIALS' dense matrices are stored by columns
        second[0], second[1] = j01, j11
        return 0
    first[0], first[1] = p[_P_J00], p[_P_J10]  # SUNDIALS' dense matrices are stored by columns
    second[0], second[1] = p[_P_J01], p[_P_J11]
    return 0


class PhaseSolver:
    """CVODE for one mode of the ball, with scikit-sundae's CVODE calls that BallIntegrator uses.

    Parameters
    ----------
    ball : Ball
        The ball.
    mode : Mode
        The mode whose equations this solver integrates.
    method : str
        "Adams" or "BDF".
    rtol : float
        CVODE's relative tolerance; its absolute one is the same, on the state scaled to the phase.
    max_step : float
        The largest step [s]; 0 for none.
    max_num_steps : int
        CVODE's limit of steps per call.
    own_side : float
        The value of h - R the root function reports at h == R (the mode's own side).
    directions : sequence of int
        The crossing direction CVODE reports for each root function (h - R, v, rest margin).
    max_evaluations : int
        Root-function evaluations allowed per phase; beyond, CVode fails with CV_RTFUNC_FAIL
        (see ``exceeded``).
    """

    def __init__(self, ball, mode, method: str, rtol: float, max_step: float, max_num_steps: int,
                 own_side: float, directions, max_evaluations: int) -> None:
        self._lib = library()
        self.log = SundialsLog()
        self._method = CV_ADAMS if method == "Adams" else CV_BDF
        self._settings = (rtol, rtol, max_step, max_num_steps)
        self._mode = mode
        self.parameters = np.zeros(_P_SIZE)
        self.parameters[[_P_MODE, _P_OWN_SIDE]] = int(mode), own_side
        self.bind(ball)
        self._directions = (ctypes.c_int * _NUM_ROOTS)(*directions)
        addresses = self._lib.addresses
        self._user_data = np.zeros(_U_SIZE, dtype=np.intp)
        self._user_data[[_U_PARAMETERS, _U_GET_ARRAY, _U_COLUMNS]] = (
            self.parameters.ctypes.data, addresses["N_VGetArrayPointer"], addresses["SUNDenseMatrix_Cols"])
        self._user_data[_U_MAX_EVALUATIONS] = max_evaluations
        self._calls = np.array([addresses[name] for name in _LOOP_FUNCTIONS], dtype=np.intp)
        self._work = np.zeros(1 + _NUM_ROOTS)
        self._counter = np.zeros(1, dtype=np.int64)  # a C long
        self._handles = {}
        self._state = None

    # --- set-up and clean-up ----------------------------------------------------------------------
    def _check(self, name: str, flag: int) -> None:
        if flag < 0:
            raise RuntimeError(f"{name} failed: {_message(flag)}")

    def _create(self, name, *args):
        handle = self._lib.functions[name](*args)
        if not handle:
            raise MemoryError(f"{name} returned NULL")
        return handle

    def _setup(self, t0: float, y0) -> None:
        f = self._lib.functions
        context = ctypes.c_void_p()
        self._check("SUNContext_Create", f["SUNContext_Create"](0, ctypes.byref(context)))
        handles = self._handles
        handles["context"] = context
        # Freed in reverse order of creation, even if a step below fails.
        self._finalizer = weakref.finalize(self, _free, f, handles)
        self._check("SUNContext_ClearErrHandlers", f["SUNContext_ClearErrHandlers"](context))
        handles["vector"] = vector = self._create("N_VNew_Serial", 2, context)
        data = f["N_VGetArrayPointer"](vector)
        self._state = np.ctypeslib.as_array(ctypes.cast(data, ctypes.POINTER(ctypes.c_double)), shape=(2,))
        self._state[:] = y0
        handles["matrix"] = matrix = self._create("SUNDenseMatrix", 2, 2, context)
        handles["linear_solver"] = linear_solver = self._create("SUNLinSol_Dense", vector, matrix, context)
        handles["memory"] = memory = self._create("CVodeCreate", self._method, context)
        self._memory = memory
        rtol, atol, max_step, max_num_steps = self._settings
        for name, *args in (
            ("CVodeSetUserData", self._user_data.ctypes.data),
            ("CVodeInit", _rhs.address, t0, vector),
            ("CVodeSStolerances", rtol, atol),
            ("CVodeSetLinearSolver", linear_solver, matrix),
            ("CVodeSetJacFn", _jacobian.address),
            ("CVodeSetMaxNonlinIters", _MAX_NONLIN_ITERS),
            ("CVodeSetMaxConvFails", _MAX_CONV_FAILS),
            ("CVodeRootInit", _NUM_ROOTS, _roots.address),
            ("CVodeSetRootDirection", self._directions),
            ("CVodeSetInitStep", 0.0),
            ("CVodeSetMinStep", 0.0),
            ("CVodeSetMaxStep", max_step),
            ("CVodeSetMaxOrd", _MAX_ORDER[self._method]),
            ("CVodeSetMaxNumSteps", max_num_steps),
        ):
            self._check(name, f[name](memory, *args))

    def close(self) -> None:
        """Free every SUNDIALS object now (also done when the solver is garbage-collected)."""
        if self._handles:
            self._finalizer()

    # --- the calls BallIntegrator makes (solvers/engines/stepper.py) ---------------------------------------
    def bind(self, ball, parameters=None) -> None:
        """Integrate ball's equations (or parameters, the machine's: a vibrating ground's) from now on."""
        self.parameters[_P_BALL:] = ball.parameters if parameters is None else parameters

    def handle(self) -> np.ndarray:
        """This solver's row of the compiled machine's engine (see _H_*; its CVODE made on first use)."""
        if not self._handles:
            with self.log.capturing():
                self._setup(0.0, (0.0, 0.0))
            self._row = row = np.zeros(_H_SIZE, dtype=np.intp)  # the addresses hold until close
            row[[_H_CALLS, _H_MEMORY, _H_VECTOR, _H_STATE, _H_PARAMETERS, _H_USER_DATA, _H_WORK, _H_COUNTER]] = (
                self._calls.ctypes.data, self._memory, self._handles["vector"], self._state.ctypes.data,
                self.parameters.ctypes.data, self._user_data.ctypes.data, self._work.ctypes.data,
                self._counter.ctypes.data)
        return self._row

    def message(self, flag: int) -> str:
        """CVODE's flag in words."""
        return _message(flag)


__all__ = ["EngineUnavailable", "PhaseSolver", "library", "unavailable_reason"]
