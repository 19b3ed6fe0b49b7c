"""The compiled engine's entry points for a C caller: an FMU's doStep without Python, its values, the phase machine.

Their contract (what they take and return) is solvers/engines/entry_contract.py's. An FMU's C layer
(fmu/bouncingball_fmu_python.h, ``stepped_in_c``) calls the cfunc at ``step_address()`` with a context: a row of
addresses and value references (``CONTEXT_FIELDS``) that fmu/c_layer.py fills for one integrator and the FMU's
variables. It runs the FMU slave's do_step (fmu/slave_base.py) as BallIntegrator runs it, with the very compiled
calls: inside CVODE's last step (drivers.advance_in_step), else the machine's advance (drivers.advance: CVODE,
events, rests) on the integrator's own CVODE solvers and machine state, then drivers.keep_estimate; and writes each
``REPORTED`` quantity the context asks for where it says, computed as the integrator's properties compute it, so
that a step taken here and one taken through Python leave the same values to the bit. It returns what is left to do:
``NOT_TAKEN`` (nothing done: a refusal to word, a target beyond what double precision resolves, a vibrating ground,
whose motion is the Python ground's own arithmetic; the caller runs the step in Python), ``TAKEN``,
``TAKEN_WITH_CVODE`` (CVODE stepped: its warnings' files to look at) or ``FINISH + status`` (the machine ran and
Python is to finish what BallIntegrator.advance does after it: a failure to raise, the accuracy warning to check:
solvers/integrator.py's finish_advance); ``RAISED`` where the compiled code raised (its state then unknown: where
Python's step would have raised out of the FMU, ending the instance).
``report_address()`` writes the same quantities without stepping (after a step Python took).

``ENTRY_POINTS`` are all the cfuncs a native library of the engine exports (solvers/engines/native_build.py): these
two, the CVODE callbacks, and the phase machine's calls Python makes, with pointer arguments (the native engine's,
solvers/engines/native.py).

Import this module only to use it (it imports numba and the compiled engine).
"""

from __future__ import annotations

import math

from numba import carray, cfunc, njit, types

from ...codes import CONTACT
from ...contact_laws import BallParameters, dispatch
from ..phase_machine import drivers
from ..phase_machine.machine import DONE
from . import compiled
from .entry_contract import (
    COMPLETED,
    CONTEXT_FIELDS,
    ENGINE,
    EVENTS,
    FINISH,
    MACHINE_STATE,
    NOT_TAKEN,
    PAIRS,
    PARAMETERS,
    SCRATCH,
    SETTINGS,
    SETTINGS_AT,
    TAKEN,
    TAKEN_WITH_CVODE,
    VALUES,
)
from .jit import addresses, doubles
from .phase_solver import H_SIZE

_HEADER, _N_PARAMETERS = len(CONTEXT_FIELDS), len(BallParameters._fields)

_advance_in_step = compiled._compiled[drivers.advance_in_step]
_advance = compiled._compiled[drivers.advance]
_is_rounding_of = compiled._compiled[drivers.is_rounding_of]
_keep_estimate = compiled._compiled[drivers.keep_estimate]
_reported_acceleration = compiled._compiled[dispatch.reported_acceleration]
_law_contact_force = compiled._compiled[dispatch.law_contact_force]
_phase_ends, _run_estimate = compiled._phase_ends, compiled._run_estimate
_parameters_at, _load_at = compiled._parameters_at, compiled._load_at


@njit(cache=compiled._CACHE)
def _write_reported(row, parameters, state):
    """Each REPORTED quantity the context asks for, at the state, where it says."""
    t, x, v, mode = state.t, state.x, state.v, int(state.mode)
    load = _load_at(parameters, state.load, t)
    # As the integrator's properties: a still ground's motion is the 0.0 they add.
    h = parameters.R + x + 0.0
    reported = (t, h, v + 0.0, _reported_acceleration(parameters, x, v, mode, load) + 0.0,
                1.0 if mode == CONTACT else 0.0, _law_contact_force(parameters, x, v, mode, load),
                float(state.impacts), state.est, h - parameters.R)
    values = doubles(row[VALUES])
    for i in range(_HEADER, len(row), 2):
        values[row[i + 1]] = reported[row[i]]


@njit(cache=compiled._CACHE)
def _unpacked(context):
    """(the whole context row, the parameters): the machine state is read where it is used (numba returns no record)."""
    header = carray(addresses(context), _HEADER)
    row = carray(addresses(context), _HEADER + 2 * header[PAIRS])
    parameters = _parameters_at(carray(doubles(row[PARAMETERS]), _N_PARAMETERS), 0)
    return row, parameters


@cfunc(types.int32(types.intp, types.float64, types.float64), cache=compiled._CACHE)
def _do_step(context, current_time, step_size):
    row, parameters = _unpacked(context)
    state = carray(compiled._record_pointer(row[MACHINE_STATE]), 1)[0]
    settings = carray(doubles(row[SETTINGS_AT]), len(SETTINGS))
    if parameters.ground_amplitude != 0.0:
        return NOT_TAKEN
    # As the slave's do_step: inside the last step from current_time, else from the state's time where current_time
    # is its rounding (a jump, a negative or endless step: refused in Python, in words); then BallIntegrator.advance.
    t, t_target = state.t, current_time + step_size
    code = TAKEN
    if not _advance_in_step(parameters, state, current_time, t_target):
        rounded = current_time != t
        if (rounded and not _is_rounding_of(current_time, t)) or not (step_size >= 0.0 and math.isfinite(t_target)):
            return NOT_TAKEN
        if rounded:
            t_target = max(t_target, t)
        if not (rounded and _advance_in_step(parameters, state, t, t_target)):
            if not t_target >= t or t_target > settings[2]:
                return NOT_TAKEN
            steps = state.steps
            engine = carray(addresses(row[ENGINE]), (int(settings[6]), H_SIZE))
            events = carray(doubles(row[EVENTS]), (int(settings[4]), 3))
            scratch = carray(doubles(row[SCRATCH]), (int(settings[5]), 3))
            status = _advance(engine, parameters, settings[0], settings[1], state, t_target, settings[3] != 0.0,
                              events, 0, scratch)[0]
            _keep_estimate(parameters, settings[0], settings[1], state)
            if status != DONE or not math.isnan(state.err_from):
                return FINISH + status
            code = TAKEN if state.steps == steps else TAKEN_WITH_CVODE
            _write_reported(row, parameters, state)
            return code
    _keep_estimate(parameters, settings[0], settings[1], state)
    _write_reported(row, parameters, state)
    return code


@cfunc(types.int32(types.intp), cache=compiled._CACHE)
def _report(context):
    row, parameters = _unpacked(context)
    state = carray(compiled._record_pointer(row[MACHINE_STATE]), 1)[0]
    if parameters.ground_amplitude != 0.0 or state.est_t != state.t:
        return 0
    _write_reported(row, parameters, state)
    return 1


# --- the phase machine's calls with pointer arguments (entry_contract.ENTRIES): the native engine's, for Python ---
_f8, _ip, _i32 = types.float64, types.intp, types.int32


@njit(cache=compiled._CACHE)
def _at(values, memory):
    """(the BallParameters at address values, the machine state's record at address memory) (numba returns no record:
    the caller indexes the carray)."""
    return _parameters_at(carray(doubles(values), _N_PARAMETERS), 0), carray(compiled._record_pointer(memory), 1)


@cfunc(_i32(_ip, _f8, _f8, _ip, _f8, _i32, _ip, _ip, _ip, _ip, _ip, _ip, _ip), cache=compiled._CACHE)
def _advance_at(values, rtol, atol, memory, t_target, stop_at_event, engine, modes, events, rows, scratch,
                scratch_rows, out):
    parameters, record = _at(values, memory)
    given = carray(doubles(events), (rows, 3))
    status, got, n = _advance(carray(addresses(engine), (modes, H_SIZE)), parameters, rtol, atol, record[0],
                              t_target, stop_at_event != 0, given, 0, carray(doubles(scratch), (scratch_rows, 3)))
    if got.shape[0] != rows:  # the machine grew its copy: what fits goes back, and the count says the rest
        for i in range(min(n, rows)):
            given[i, 0], given[i, 1], given[i, 2] = got[i, 0], got[i, 1], got[i, 2]
    _keep_estimate(parameters, rtol, atol, record[0])
    answer = carray(addresses(out), 2)
    answer[0], answer[1] = status, n
    return COMPLETED


@cfunc(_i32(_ip, _f8, _f8, _ip, _f8, _f8, _ip), cache=compiled._CACHE)
def _advance_in_step_at(values, rtol, atol, memory, t_from, t_target, out):
    parameters, record = _at(values, memory)
    advanced = _advance_in_step(parameters, record[0], t_from, t_target)
    if advanced:
        _keep_estimate(parameters, rtol, atol, record[0])
    carray(addresses(out), 1)[0] = 1 if advanced else 0
    return COMPLETED


@cfunc(_i32(_ip, _f8, _f8, _ip, _f8, _f8), cache=compiled._CACHE)
def _phase_ends_at(values, rtol, atol, memory, jump, reflection):
    parameters, record = _at(values, memory)
    _phase_ends(parameters, rtol, atol, record[0], jump, reflection)
    return COMPLETED


@cfunc(_i32(_ip, _f8, _f8, _ip, _ip), cache=compiled._CACHE)
def _run_estimate_at(values, rtol, atol, memory, out):
    parameters, record = _at(values, memory)
    estimate = _run_estimate(parameters, rtol, atol, record[0])
    answer = carray(doubles(out), 3)
    answer[0], answer[1], answer[2] = estimate[0], estimate[1], estimate[2]
    return COMPLETED


# Every entry point of entry_contract.ENTRIES, by its name there.
ENTRY_POINTS = {"do_step": _do_step, "report": _report, "rhs": compiled._rhs, "roots": compiled._roots,
                "jacobian": compiled._jacobian, "advance": _advance_at, "advance_in_step": _advance_in_step_at,
                "phase_ends": _phase_ends_at, "run_estimate": _run_estimate_at}


def step_address() -> int:
    """The address of the C function ``int step(intptr_t context, double current_time, double step_size)``: the
    FMU slave's do_step; what is left to do (NOT_TAKEN, TAKEN, TAKEN_WITH_CVODE or FINISH + the machine's status)."""
    return _do_step.address


def report_address() -> int:
    """The address of the C function ``int report(intptr_t context)``: the REPORTED quantities at the integrator's
    state, as the step writes them; 1 if written, 0 where it writes nothing (a vibrating ground, or the estimate not
    taken at the state's time)."""
    return _report.address
