"""The compiled CVODE engine: the SUNDIALS CVODE library scikit-sundae installs, driven without Python callbacks.

scikit-sundae wraps SUNDIALS' vectors into new numpy arrays on every callback, which costs far
more than the ball's equations. Here the right-hand side, the root functions and the Jacobian are
numba ``cfunc`` s compiled from physics.py's own plain-float definitions, and a numba loop takes
CVODE's internal steps of one phase, so Python is entered only once per phase (at each event).
``PhaseSolver`` offers the calls BallIntegrator makes on a scikit-sundae CVODE object
(init_step, step, solve), with the same settings and the same step sequence, so the event logic
of cvode.py (mode switches, rests and hops in closed form, polishing, dense output) serves both
engines unchanged.

The library is the one in scikit-sundae's wheel (``scikit_sundae.libs``), so the process holds one
SUNDIALS, and its version is checked (SUNDIALSGetVersion) before anything else. Every function we
call is looked up in these libraries' own handles, so a host process that exports SUNDIALS
symbols of its own (another SUNDIALS) cannot capture our calls. The libraries' calls among
themselves are bound when they are first loaded, usually by scikit-sundae's import; if we load
them first, RTLD_DEEPBIND (where the platform has it) binds them to each other too. Every return
code is checked, and every SUNDIALS object is freed with its solver. C function addresses are passed
to the compiled code as arguments, never baked into it, so the compiled code is cached on disk
(numba ``cache=True``) and loads in a fraction of a second after the first run.

Import this module only to use the engine: it imports numba. ``unavailable_reason()`` says why the
engine cannot run here (numba missing, a library not found or of another version), or None.
"""

from __future__ import annotations

import ctypes
import glob
import hashlib
import importlib.util
import os
import weakref
from dataclasses import dataclass
from types import FunctionType

import numpy as np
from llvmlite import ir
from numba import carray, cfunc, njit, types
from numba.extending import intrinsic

from .. import physics
from . import dense_output, exact, machine, phases
from .stepper import PhaseResult
from .sundials_log import SundialsLog

# SUNDIALS' major version we bind: its C API (the declarations below) is stable within a major.
SUPPORTED_MAJOR = 7
CV_ADAMS, CV_BDF = 1, 2
CV_ONE_STEP = 2
CV_SUCCESS, CV_TSTOP_RETURN, CV_ROOT_RETURN = 0, 1, 2
CV_RTFUNC_FAIL = -12
# cvode.py's defaults for scikit-sundae's options that CVODE would otherwise take from itself.
_MAX_NONLIN_ITERS = 3
_MAX_CONV_FAILS = 10
_MAX_ORDER = {CV_ADAMS: 12, CV_BDF: 5}
_NUM_ROOTS = 3
_BUFFER = 4096  # step ends stored per call of the compiled loop before it returns for more room

# The C functions we call, as C declares them: (return type, argument types). tests/test_compiled.py
# checks each against the declarations scikit-sundae ships (sksundae/*.pxd) where it has one.
FUNCTIONS = {
    "core": {
        "SUNDIALSGetVersion": ("int", ("char*", "int")),
        "SUNContext_Create": ("int", ("SUNComm", "SUNContext*")),
        "SUNContext_Free": ("void", ("SUNContext*",)),
        "SUNContext_ClearErrHandlers": ("int", ("SUNContext",)),
        "N_VGetArrayPointer": ("sunrealtype*", ("N_Vector",)),
        "N_VDestroy": ("void", ("N_Vector",)),
        "SUNMatDestroy": ("void", ("SUNMatrix",)),
        "SUNLinSolFree": ("int", ("SUNLinearSolver",)),
    },
    "cvode": {
        "N_VNew_Serial": ("N_Vector", ("sunindextype", "SUNContext")),
        "SUNDenseMatrix": ("SUNMatrix", ("sunindextype", "sunindextype", "SUNContext")),
        "SUNDenseMatrix_Cols": ("sunrealtype**", ("SUNMatrix",)),
        "SUNLinSol_Dense": ("SUNLinearSolver", ("N_Vector", "SUNMatrix", "SUNContext")),
        "CVodeCreate": ("void*", ("int", "SUNContext")),
        "CVodeInit": ("int", ("void*", "CVRhsFn", "sunrealtype", "N_Vector")),
        "CVodeReInit": ("int", ("void*", "sunrealtype", "N_Vector")),
        "CVodeSStolerances": ("int", ("void*", "sunrealtype", "sunrealtype")),
        "CVodeSetUserData": ("int", ("void*", "void*")),
        "CVodeSetLinearSolver": ("int", ("void*", "SUNLinearSolver", "SUNMatrix")),
        "CVodeSetJacFn": ("int", ("void*", "CVLsJacFn")),
        "CVodeSetMaxNonlinIters": ("int", ("void*", "int")),
        "CVodeSetMaxConvFails": ("int", ("void*", "int")),
        "CVodeRootInit": ("int", ("void*", "int", "CVRootFn")),
        "CVodeSetRootDirection": ("int", ("void*", "int*")),
        "CVodeSetInitStep": ("int", ("void*", "sunrealtype")),
        "CVodeSetMinStep": ("int", ("void*", "sunrealtype")),
        "CVodeSetMaxStep": ("int", ("void*", "sunrealtype")),
        "CVodeSetMaxOrd": ("int", ("void*", "int")),
        "CVodeSetMaxNumSteps": ("int", ("void*", "long int")),
        "CVodeSetStopTime": ("int", ("void*", "sunrealtype")),
        "CVodeClearStopTime": ("int", ("void*",)),
        "CVode": ("int", ("void*", "sunrealtype", "N_Vector", "sunrealtype*", "int")),
        "CVodeGetRootInfo": ("int", ("void*", "int*")),
        "CVodeGetNumRhsEvals": ("int", ("void*", "long int*")),
        "CVodeFree": ("void", ("void**",)),
    },
}
_CTYPES = {"int": ctypes.c_int, "long int": ctypes.c_long, "sunrealtype": ctypes.c_double,
           "sunindextype": ctypes.c_int, "SUNComm": ctypes.c_int, "void": None, "char*": ctypes.c_char_p}


def _ctype(name: str):
    return _CTYPES[name] if name in _CTYPES else ctypes.c_void_p  # every pointer and handle


class EngineUnavailable(RuntimeError):
    """The compiled engine cannot run here; the message says why."""


@dataclass(frozen=True)
class Library:
    """The bound SUNDIALS functions (ctypes) and their addresses, with the version found."""

    version: str
    path: str
    functions: dict
    addresses: dict


def _library_paths() -> dict[str, str]:
    spec = importlib.util.find_spec("sksundae")
    if spec is None or not spec.submodule_search_locations:
        raise EngineUnavailable("scikit-sundae is not installed")
    site = os.path.dirname(list(spec.submodule_search_locations)[0])
    folder = os.path.join(site, "scikit_sundae.libs")
    paths = {}
    for part in FUNCTIONS:
        found = sorted(glob.glob(os.path.join(folder, f"libsundials_{part}-*.so*")))
        if len(found) != 1:
            raise EngineUnavailable(f"scikit-sundae's SUNDIALS {part} library was not found as one file in {folder} "
                                    f"(found {len(found)}); the compiled engine binds the Linux wheel's libraries")
        paths[part] = found[0]
    return paths


_LIBRARY: Library | None = None
_UNAVAILABLE: str | None = None


def library() -> Library:
    """Open (once) the SUNDIALS libraries of scikit-sundae's wheel; raise EngineUnavailable if not usable."""
    global _LIBRARY, _UNAVAILABLE
    if _LIBRARY is not None:
        return _LIBRARY
    if _UNAVAILABLE is not None:
        raise EngineUnavailable(_UNAVAILABLE)
    try:
        _LIBRARY = _open()
    except EngineUnavailable as error:
        _UNAVAILABLE = str(error)
        raise
    return _LIBRARY


def _open() -> Library:
    # Pointers travel through the compiled code as 64-bit integers, and C's long is 64 bits (LP64).
    if ctypes.sizeof(ctypes.c_void_p) != 8 or ctypes.sizeof(ctypes.c_long) != 8:
        raise EngineUnavailable("the compiled engine needs a 64-bit platform with 64-bit C longs (Linux)")
    paths = _library_paths()
    mode = ctypes.RTLD_LOCAL | getattr(os, "RTLD_DEEPBIND", 0) | getattr(os, "RTLD_NOW", 0)
    handles = {}
    for part in ("core", "cvode"):  # cvode needs core; a library already loaded is shared, not loaded twice
        try:
            handles[part] = ctypes.CDLL(paths[part], mode=mode)
        except OSError as error:
            raise EngineUnavailable(f"cannot load {paths[part]}: {error}") from error
    functions, addresses = {}, {}
    for part, declarations in FUNCTIONS.items():
        for name, (restype, argtypes) in declarations.items():
            try:
                function = getattr(handles[part], name)
            except AttributeError as error:
                raise EngineUnavailable(f"{paths[part]} has no {name}") from error
            function.restype = _ctype(restype)
            function.argtypes = [_ctype(a) for a in argtypes]
            functions[name] = function
            addresses[name] = ctypes.cast(function, ctypes.c_void_p).value
    buffer = ctypes.create_string_buffer(64)
    if functions["SUNDIALSGetVersion"](buffer, len(buffer)) != 0:
        raise EngineUnavailable("SUNDIALSGetVersion failed")
    version = buffer.value.decode()
    if version.split(".")[0] != str(SUPPORTED_MAJOR):
        raise EngineUnavailable(f"scikit-sundae ships SUNDIALS {version}; the compiled engine supports "
                                f"SUNDIALS {SUPPORTED_MAJOR}.x only")
    return Library(version, paths["cvode"], functions, addresses)


def unavailable_reason() -> str | None:
    """Why the compiled engine cannot run in this process, or None if it can."""
    try:
        library()
    except EngineUnavailable as error:
        return str(error)
    return None


# --- calls to C functions whose address is a run-time argument ---------------------------------------
# numba caches compiled code on disk only if it holds no process-specific constant, so the
# addresses of SUNDIALS' functions travel as plain integers and are called through these.
def _codegen(context, builder, signature, args):
    return_type = context.get_value_type(signature.return_type)
    function_type = ir.FunctionType(return_type, [context.get_value_type(a) for a in signature.args[1:]])
    return builder.call(builder.inttoptr(args[0], function_type.as_pointer()), args[1:])


@intrinsic
def _call_i1(typingctx, address, a):
    return types.int32(types.intp, a), _codegen


@intrinsic
def _call_p1(typingctx, address, a):
    return types.intp(types.intp, a), _codegen


@intrinsic
def _call_i2(typingctx, address, a, b):
    return types.int32(types.intp, a, b), _codegen


@intrinsic
def _call_i3(typingctx, address, a, b, c):
    return types.int32(types.intp, a, b, c), _codegen


@intrinsic
def _call_i5(typingctx, address, a, b, c, d, e):
    return types.int32(types.intp, a, b, c, d, e), _codegen


@intrinsic
def _doubles(typingctx, address):
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
    return types.CPointer(types.float64)(types.intp), codegen


@intrinsic
def _addresses(typingctx, address):
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
    return types.CPointer(types.intp)(types.intp), codegen


# The block user_data points to (int64): what the callbacks need besides the state.
_U_PARAMETERS, _U_GET_ARRAY, _U_COLUMNS, _U_EVALUATIONS, _U_MAX_EVALUATIONS, _U_SIZE = range(6)
# The parameters (float64) the callbacks read.
# CVODE integrates x / length and v / speed (x = h - R), the phase's frame set by PhaseSolver.set_frame.
(_P_M, _P_K, _P_B, _P_R, _P_G, _P_F_EXT, _P_MODE, _P_OWN_SIDE, _P_HOP, _P_J00, _P_J01, _P_J10, _P_J11,
 _P_LENGTH, _P_SPEED, _P_LOAD, _P_SIZE) = range(17)



def _cache_here() -> bool:
    """Whether numba may cache this module's compiled code on disk, after dropping code physics.py outdated.

    numba keys each cached function by its own source file, and the callbacks below inline
    physics.py's functions: after a change to physics.py alone it loaded this module's old code
    (the compiled engine ran the previous right-hand side, found by the engines disagreeing). So a
    digest of physics.py is kept beside the cache, and this module's cached code is removed when
    the digest differs. Where a source is gone (an FMU's copy of the package, whose unzipped folder
    the master deleted after the process imported physics from it), or the cache cannot be found
    through numba's locators, nothing is cached: it compiles afresh.
    """
    if not (os.path.isfile(physics.__file__) and os.path.isfile(__file__)):
        return False
    try:
        from numba.core.caching import CacheImpl  # numba's own search for the cache folder

        locators = (cls.from_function(_cache_here, __file__) for cls in CacheImpl._locator_classes)
        folder = next(locator for locator in locators if locator is not None).get_cache_path()
        with open(physics.__file__, "rb") as source:
            digest = hashlib.sha256(source.read()).hexdigest()
        stamp = os.path.join(folder, f"{__name__.rpartition('.')[2]}.physics-sha256")
        if not os.path.isfile(stamp) or open(stamp).read() != digest:
            for stale in glob.glob(os.path.join(folder, f"{__name__.rpartition('.')[2]}.*.nb[ic]")):
                os.remove(stale)
            os.makedirs(folder, exist_ok=True)
            with open(stamp, "w") as file:
                file.write(digest)
    except Exception:  # a numba without these internals, or a cache folder we cannot write
        return False
    return True


_CACHE = _cache_here()


def _compiled_together(functions, bound):
    """numba-compiled copies of plain functions, each one's calls to the others bound to their compiled copies.

    functions: plain Python functions of floats and arrays (physics, phases, machine, dense_output);
    bound: {plain function: its stand-in}, for what only runs interpreted as written (an engine's
    calls, a float-or-array dispatch); a stand-in among functions is taken compiled. Each copy reads
    a copy of its module's globals in which every one of those functions is replaced, so the source
    stays the one that runs interpreted. Returns {plain function: compiled copy}.
    """
    compiled, namespaces = {}, []
    for function in functions:
        namespace = dict(function.__globals__)
        copy = FunctionType(function.__code__, namespace, function.__name__, function.__defaults__,
                            function.__closure__)
        copy.__qualname__ = function.__qualname__
        compiled[function] = njit(copy, cache=_CACHE)
        namespaces.append(namespace)
    replacements = {id(plain): compiled.get(stand_in, stand_in) for plain, stand_in in bound.items()}
    replacements.update({id(plain): copy for plain, copy in compiled.items()})
    for namespace in namespaces:
        for name, value in namespace.items():
            if id(value) in replacements:
                namespace[name] = replacements[id(value)]
    return compiled


_PHYSICS = (physics.gap_acceleration, physics.rest_margin_value, physics.gap_flow_value, physics.contact_gap_flow,
            physics.oscillator_basis_value, physics.unit_response_value, physics._oscillator_basis,
            physics._closed_response, physics._series_response, physics.hypot_value, physics._product_error)
_physics = _compiled_together(_PHYSICS, {physics.oscillator_basis: physics.oscillator_basis_value,
                                         physics.unit_response: physics.unit_response_value})
_acceleration = _physics[physics.gap_acceleration]
_rest_margin = _physics[physics.rest_margin_value]

_callback_data = types.CPointer(types.intp)


@cfunc(types.int32(types.float64, types.intp, types.intp, _callback_data), cache=_CACHE)
def _rhs(t, y, ydot, user_data):
    u = carray(user_data, _U_SIZE)
    p = carray(_doubles(u[_U_PARAMETERS]), _P_SIZE)
    state = carray(_doubles(_call_p1(u[_U_GET_ARRAY], y)), 2)
    out = carray(_doubles(_call_p1(u[_U_GET_ARRAY], ydot)), 2)
    length, speed = p[_P_LENGTH], p[_P_SPEED]
    out[0] = (speed / length) * state[1]
    out[1] = _acceleration(length * state[0], speed * state[1], p[_P_MODE], p[_P_LOAD], p[_P_M], p[_P_K],
                           p[_P_B]) / speed
    return 0


@cfunc(types.int32(types.float64, types.intp, types.CPointer(types.float64), _callback_data), cache=_CACHE)
def _roots(t, y, gout, user_data):
    u = carray(user_data, _U_SIZE)
    p = carray(_doubles(u[_U_PARAMETERS]), _P_SIZE)
    state = carray(_doubles(_call_p1(u[_U_GET_ARRAY], y)), 2)
    out = carray(gout, 3)
    # as in BallIntegrator._make_solver: the scaled gap, its own side at 0; v; the rest margin
    out[0] = state[0] if state[0] != 0.0 else p[_P_OWN_SIDE]
    out[1] = state[1] if p[_P_MODE] == 1.0 or p[_P_LOAD] != 0.0 else 1.0
    d = p[_P_LOAD] / p[_P_K]  # the static deflection (physics.static_deflection_value)
    if p[_P_MODE] == 1.0 and d > 0.0:
        out[2] = _rest_margin(p[_P_LENGTH] * state[0], p[_P_SPEED] * state[1], d, p[_P_HOP], p[_P_K] / p[_P_M])
    else:
        out[2] = -1.0
    u[_U_EVALUATIONS] += 1
    return 1 if u[_U_EVALUATIONS] > u[_U_MAX_EVALUATIONS] else 0


@cfunc(types.int32(types.float64, types.intp, types.intp, types.intp, _callback_data, types.intp, types.intp,
                   types.intp), cache=_CACHE)
def _jacobian(t, y, fy, matrix, user_data, tmp1, tmp2, tmp3):
    u = carray(user_data, _U_SIZE)
    p = carray(_doubles(u[_U_PARAMETERS]), _P_SIZE)
    columns = carray(_addresses(_call_p1(u[_U_COLUMNS], matrix)), 2)
    first, second = carray(_doubles(columns[0]), 2), carray(_doubles(columns[1]), 2)
    first[0], first[1] = p[_P_J00], p[_P_J10]  # SUNDIALS' dense matrices are stored by columns
    second[0], second[1] = p[_P_J01], p[_P_J11]
    return 0


# The C functions the compiled loop calls, by their place in the address array it receives.
_LOOP_FUNCTIONS = ("CVode", "CVodeGetRootInfo", "CVodeReInit", "CVodeSetStopTime", "CVodeClearStopTime",
                   "CVodeGetNumRhsEvals")
_CVODE, _ROOT_INFO, _REINIT, _SET_STOP, _CLEAR_STOP, _NUM_RHS = range(len(_LOOP_FUNCTIONS))
_BUFFER_FULL = machine.BUFFER_FULL


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
        flag = _call_i5(f[_CVODE], memory, t_end, vector, work.ctypes.data, CV_ONE_STEP)
        if flag == CV_ROOT_RETURN:
            check = _call_i2(f[_ROOT_INFO], memory, info.ctypes.data)
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


@njit(cache=_CACHE)
def _start_phase(f, memory, vector, state, t0, h0, v0, t_end, reinit, out, work, counter):
    """Restart CVODE at (t0, h0, v0) with t_end as stop time and take its steps, as _steps.

    Unless the buffer filled up, also clears the stop time and reads the right-hand-side count
    into counter[0] (_finish_phase). Returns the flag, the count stored, and which call failed
    (0 none, 1 CVodeReInit, 2 CVodeSetStopTime, 3 CVodeClearStopTime or CVodeGetNumRhsEvals).
    """
    state[0], state[1] = h0, v0
    work[1], work[2], work[3] = 0.0, 0.0, 0.0
    if reinit:
        flag = _call_i3(f[_REINIT], memory, t0, vector)
        if flag < 0:
            return flag, 0, 1
    flag = _call_i2(f[_SET_STOP], memory, t_end)
    if flag < 0:
        return flag, 0, 2
    out[0, 0], out[0, 1], out[0, 2] = t0, h0, v0
    flag, count = _steps(f, memory, vector, state, t_end, out, 1, False, work)
    if flag != _BUFFER_FULL:
        finished = _finish_phase(f, memory, counter)
        if finished < 0:
            return finished, count, 3
    return flag, count, 0


@njit(cache=_CACHE)
def _finish_phase(f, memory, counter):
    """Clear the stop time; returns its flag and CVODE's right-hand-side evaluations in counter[0]."""
    flag = _call_i1(f[_CLEAR_STOP], memory)
    if flag < 0:
        return flag
    return _call_i2(f[_NUM_RHS], memory, counter.ctypes.data)


# --- the phase machine's engine (solvers/machine.py's engine_* calls), over one PhaseSolver.handle() per mode ---
@njit(cache=_CACHE)
def _engine_start(engine, mode, t_stop, y0, y1, length, speed, hop, load):
    calls, memory, vector, state, parameters, user_data, work, counter = engine[mode]
    parameters[_P_LENGTH], parameters[_P_SPEED], parameters[_P_HOP], parameters[_P_LOAD] = length, speed, hop, load
    # the Jacobian in the scaled variables (x / length, v / speed), as PhaseSolver.set_frame
    contact = mode == 1
    parameters[_P_J00], parameters[_P_J01] = 0.0, 1.0 * speed / length
    parameters[_P_J10] = (-parameters[_P_K] / parameters[_P_M] if contact else 0.0) * length / speed
    parameters[_P_J11] = -parameters[_P_B] / parameters[_P_M] if contact else 0.0
    user_data[_U_EVALUATIONS] = 0
    state[0], state[1] = y0, y1
    flag = _call_i3(calls[_REINIT], memory, 0.0, vector)
    if flag < 0:
        return flag
    return _call_i2(calls[_SET_STOP], memory, t_stop)


@njit(cache=_CACHE)
def _engine_steps(engine, mode, scratch, t_stop):
    calls, memory, vector, state, parameters, user_data, work, counter = engine[mode]
    flag, count = _steps(calls, memory, vector, state, t_stop, scratch, 0, False, work)
    if flag == CV_ROOT_RETURN:
        scratch[count - 1, 3], scratch[count - 1, 4] = work[1], work[3]
    return flag, count, scratch


@njit(cache=_CACHE)
def _engine_finish(engine, mode):
    calls, memory, vector, state, parameters, user_data, work, counter = engine[mode]
    flag = _finish_phase(calls, memory, counter)
    return flag, counter[0]


@njit(cache=_CACHE)
def _engine_exceeded(engine, mode):
    user_data = engine[mode][5]
    return user_data[_U_EVALUATIONS] > user_data[_U_MAX_EVALUATIONS]


_machine = _compiled_together(
    _PHYSICS + (machine.run_phases, machine._cvode_phase, machine._switch_mode, machine._record, machine._grown,
                machine._ulp, phases.phase_scales, phases.frame, phases.contact_unresolved, phases.rest_decision,
                phases.closed_form, phases.flight_impact, phases.polish_event, phases.side_margin,
                phases.on_wrong_side, phases.taylor_step, exact.time_to_impact, dense_output.step_state,
                dense_output.fill_grid),
    {physics.oscillator_basis: physics.oscillator_basis_value, physics.unit_response: physics.unit_response_value,
     machine.engine_start: _engine_start, machine.engine_steps: _engine_steps, machine.engine_finish: _engine_finish,
     machine.engine_exceeded: _engine_exceeded})
run_phases = _machine[machine.run_phases]
fill_grid = _machine[dense_output.fill_grid]


# CVODE's return flags (cvode.h) and what the failures mean (CVODE's documentation of CVode). Our own
# table: CVodeGetReturnFlagName returns a string the caller must free.
_FLAGS = {
    -1: ("CV_TOO_MUCH_WORK", "could not reach the end point within the maximum number of steps"),
    -2: ("CV_TOO_MUCH_ACC", "could not satisfy the accuracy demanded for an internal step"),
    -3: ("CV_ERR_FAILURE", "error tests failed too many times, or the step reached its minimum"),
    -4: ("CV_CONV_FAILURE", "convergence tests failed too many times, or the step reached its minimum"),
    -5: ("CV_LINIT_FAIL", "the linear solver's initialisation failed"),
    -6: ("CV_LSETUP_FAIL", "the linear solver's setup failed"),
    -7: ("CV_LSOLVE_FAIL", "the linear solver's solve failed"),
    -8: ("CV_RHSFUNC_FAIL", "the right-hand side failed unrecoverably"),
    -12: ("CV_RTFUNC_FAIL", "the root function failed"),
    -20: ("CV_MEM_FAIL", "a memory allocation failed"),
    -21: ("CV_MEM_NULL", "no CVODE memory"),
    -22: ("CV_ILL_INPUT", "an input is illegal"),
    -25: ("CV_BAD_T", "the time is outside the last step"),
    -27: ("CV_TOO_CLOSE", "the output and initial times are too close to each other"),
}


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
        self._out = np.empty((_BUFFER, 3))
        self._roots = [0, 0, 0]
        self._handles = {}
        self._state = None

    # --- set-up and clean-up ----------------------------------------------------------------------
    def _check(self, name: str, flag: int) -> None:
        if flag < 0:
            raise RuntimeError(f"{name} failed: {self._message(flag)}")

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

    # --- the calls BallIntegrator makes (solvers/stepper.py) ---------------------------------------
    def bind(self, ball) -> None:
        """Integrate ball's equations from now on (F_ext 0 and a unit frame until set)."""
        self._jacobian = ball.jacobian(self._mode)
        self.parameters[[_P_M, _P_K, _P_B, _P_R, _P_G]] = ball.m, ball.k, ball.b, ball.R, ball.g
        self.F_ext = 0.0
        self.set_frame(1.0, 1.0, 0.0)

    @property
    def F_ext(self) -> float:
        return self.parameters[_P_F_EXT]

    @F_ext.setter
    def F_ext(self, value: float) -> None:
        self.parameters[_P_F_EXT] = value
        self.parameters[_P_LOAD] = physics.load_value(value, self.parameters[_P_M], self.parameters[_P_G])

    def set_frame(self, length: float, speed: float, hop_tolerance: float) -> None:
        """The phase's scales [m, m/s] and the rest root's margin [m] (Ball.rest_margin); set before init_step/solve."""
        (j00, j01), (j10, j11) = self._jacobian
        self.parameters[[_P_LENGTH, _P_SPEED, _P_HOP]] = length, speed, hop_tolerance
        # the Jacobian of (x / length, v / speed)' in those scaled variables
        self.parameters[[_P_J00, _P_J01, _P_J10, _P_J11]] = j00, j01 * speed / length, j10 * length / speed, j11

    @property
    def exceeded(self) -> bool:
        """True if the last call failed because the phase took more root evaluations than allowed."""
        return self._user_data[_U_EVALUATIONS] > self._user_data[_U_MAX_EVALUATIONS]

    def roots_found(self) -> list[int]:
        """CVodeGetRootInfo of the last root return: per root function, 0 or the crossing's sign."""
        return self._roots

    def init_step(self, t0: float, y0) -> None:
        """(Re)start CVODE at t0 from y0 (new history, statistics and root-evaluation count)."""
        self._user_data[_U_EVALUATIONS] = 0
        self._roots = [0, 0, 0]
        if not self._handles:
            self._setup(t0, y0)
            return
        self._state[:] = y0
        self._check("CVodeReInit", self._lib.functions["CVodeReInit"](self._memory, t0, self._handles["vector"]))

    def handle(self) -> tuple:
        """What the compiled phase machine calls this solver's CVODE through (its CVODE made on first use)."""
        if not self._handles:
            with self.log.capturing():
                self._setup(0.0, (0.0, 0.0))
        return (self._calls, self._memory, self._handles["vector"], self._state, self.parameters, self._user_data,
                self._work, self._counter)

    def message(self, flag: int) -> str:
        """CVODE's flag in words."""
        return self._message(flag)

    def step(self, t_toward: float, method: str = "onestep") -> PhaseResult:
        """One internal step toward t_toward; its end, or the root it stopped at."""
        out = self._out
        flag, _ = _steps(self._calls, self._memory, self._handles["vector"], self._state, t_toward, out, 0, True,
                         self._work)
        self._read_roots(flag)
        return PhaseResult(float(out[0, 0]), out[0, 1:].copy(), flag, self._message(flag), self._nfev())

    def solve(self, tspan, y0) -> PhaseResult:
        """From y0 at tspan[0] to tspan[-1] (a stop time) or the first terminal root: every step end."""
        t0, t_end = float(tspan[0]), float(tspan[-1])
        self._user_data[_U_EVALUATIONS] = 0
        reinit = bool(self._handles)
        if not reinit:
            self._setup(t0, y0)
        out, vector = self._out, self._handles["vector"]
        flag, count, failed = _start_phase(self._calls, self._memory, vector, self._state, t0, float(y0[0]),
                                           float(y0[1]), t_end, reinit, out, self._work, self._counter)
        if failed:
            self._check(("CVodeReInit", "CVodeSetStopTime", "CVodeClearStopTime or CVodeGetNumRhsEvals")[failed - 1],
                        flag)
        if flag == _BUFFER_FULL:
            while flag == _BUFFER_FULL:
                out = self._out = np.concatenate((out, np.empty_like(out)))
                flag, count = _steps(self._calls, self._memory, vector, self._state, t_end, out, count, False,
                                     self._work)
            self._check("CVodeClearStopTime or CVodeGetNumRhsEvals",
                        _finish_phase(self._calls, self._memory, self._counter))
        self._read_roots(flag)
        return PhaseResult(out[:count, 0].copy(), out[:count, 1:].copy(), flag, self._message(flag),
                           int(self._counter[0]))

    def _read_roots(self, flag: int) -> None:
        self._roots = list(map(int, self._work[1:].tolist())) if flag == CV_ROOT_RETURN else [0, 0, 0]

    def _nfev(self) -> int:
        self._check("CVodeGetNumRhsEvals", self._lib.functions["CVodeGetNumRhsEvals"](
            self._memory, self._counter.ctypes.data))
        return int(self._counter[0])

    def _message(self, flag: int) -> str:
        if flag >= 0:
            return "success"
        name, meaning = _FLAGS.get(flag, (f"flag {flag}", "see cvode.h"))
        return f"{name}: {meaning}"


def _free(functions, handles: dict) -> None:
    # A finalizer cannot raise: SUNLinSolFree's only failure is a NULL solver, which never gets here.
    if "memory" in handles:
        functions["CVodeFree"](ctypes.byref(ctypes.c_void_p(handles.pop("memory"))))
    if "linear_solver" in handles:
        functions["SUNLinSolFree"](handles.pop("linear_solver"))
    if "matrix" in handles:
        functions["SUNMatDestroy"](handles.pop("matrix"))
    if "vector" in handles:
        functions["N_VDestroy"](handles.pop("vector"))
    if "context" in handles:
        functions["SUNContext_Free"](ctypes.byref(handles.pop("context")))


__all__ = ["EngineUnavailable", "PhaseSolver", "library", "unavailable_reason"]
