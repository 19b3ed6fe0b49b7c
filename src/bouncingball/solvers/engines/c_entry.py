"""The compiled engine's entry point for a C caller: an FMU's doStep without Python, and its values.

An FMU's C layer (fmu/bouncingball_fmu_python.h, ``stepped_in_c``) calls the cfunc at ``step_address()`` with a
context: a row of addresses and value references (``CONTEXT_FIELDS``) that fmu/c_layer.py fills for one integrator
and the FMU's variables. It runs the FMU slave's do_step (fmu/slave_base.py) as BallIntegrator runs it, with the
very compiled calls: inside CVODE's last step (drivers.advance_in_step), else the machine's advance
(drivers.advance: CVODE, events, rests) on the integrator's own CVODE solvers and machine state, then
drivers.keep_estimate; and writes each ``REPORTED`` quantity the context asks for where it says, computed as the
integrator's properties compute it, so that a step taken here and one taken through Python leave the same values
to the bit. It returns what is left to do: ``NOT_TAKEN`` (nothing done: a refusal to word, a target beyond what
double precision resolves, a vibrating ground, whose motion is the Python ground's own arithmetic; the caller runs
the step in Python), ``TAKEN``, ``TAKEN_WITH_CVODE`` (CVODE stepped: its warnings' files to look at) or
``FINISH + status`` (the machine ran and Python is to finish what BallIntegrator.advance does after it: a failure
to raise, the accuracy warning to check: solvers/integrator.py's finish_advance); ``RAISED`` where the compiled code
raised (its state then unknown: where Python's step would have raised out of the FMU, ending the instance).
``report_address()`` writes the same quantities without stepping (after a step Python took).

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
from .jit import addresses, doubles

# What the step reports, in this order: the names of the integrator's properties (t, h, v, acceleration, ...), and
# h - R [m] computed from h as written (the FMI 3.0 slave's gap in co-simulation).
REPORTED = ("t", "h", "v", "acceleration", "contact", "contact_force", "impacts", "error_estimate_at_t",
            "h_minus_R")
# The context (one row of intp): the addresses of the integrator's BallParameters as float64, of its settings
# (SETTINGS: float64), of its machine state (layout.STATE_DTYPE's record), of the caller's values (float64), of the
# compiled machine's engine (one row per mode, intp), of its event rows and scratch rows (float64, 3 columns), the
# number of pairs that follow, then each pair: a REPORTED quantity's place in REPORTED and the index in the values it
# is written at.
CONTEXT_FIELDS = ("parameters", "settings", "machine_state", "values", "engine", "events", "scratch", "pairs")
_PARAMETERS, _SETTINGS, _MACHINE_STATE, _VALUES, _ENGINE, _EVENTS, _SCRATCH, _PAIRS = range(len(CONTEXT_FIELDS))
# BallIntegrator's settings.rtol, _atol, resolvable_until (beyond it, its refusal), the slave's STOP_AT_EVENT (1.0 or
# 0.0), the rows of its event and scratch arrays and the engine's modes.
SETTINGS = ("rtol", "atol", "resolvable_until", "stop_at_event", "event_rows", "scratch_rows", "engine_modes")
_HEADER, _N_PARAMETERS = len(CONTEXT_FIELDS), len(BallParameters._fields)
# 0 is what a cfunc returns when its compiled code raised (numba prints the exception and returns the default): the
# state may have changed by then, so the caller is to end the instance, never to run the step again.
RAISED, NOT_TAKEN, TAKEN, TAKEN_WITH_CVODE, FINISH = 0, 1, 2, 3, 16

_advance_in_step = compiled._compiled[drivers.advance_in_step]
_advance = compiled._compiled[drivers.advance]
_is_rounding_of = compiled._compiled[drivers.is_rounding_of]
_keep_estimate = compiled._compiled[drivers.keep_estimate]
_reported_acceleration = compiled._compiled[dispatch.reported_acceleration]
_law_contact_force = compiled._compiled[dispatch.law_contact_force]
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
    values = doubles(row[_VALUES])
    for i in range(_HEADER, len(row), 2):
        values[row[i + 1]] = reported[row[i]]


@njit(cache=compiled._CACHE)
def _unpacked(context):
    """(the whole context row, the parameters): the machine state is read where it is used (numba returns no record)."""
    header = carray(addresses(context), _HEADER)
    row = carray(addresses(context), _HEADER + 2 * header[_PAIRS])
    parameters = _parameters_at(carray(doubles(row[_PARAMETERS]), _N_PARAMETERS), 0)
    return row, parameters


@cfunc(types.int32(types.intp, types.float64, types.float64), cache=compiled._CACHE)
def _do_step(context, current_time, step_size):
    row, parameters = _unpacked(context)
    state = carray(compiled._record_pointer(row[_MACHINE_STATE]), 1)[0]
    settings = carray(doubles(row[_SETTINGS]), len(SETTINGS))
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
            engine = carray(addresses(row[_ENGINE]), (int(settings[6]), compiled._H_SIZE))
            events = carray(doubles(row[_EVENTS]), (int(settings[4]), 3))
            scratch = carray(doubles(row[_SCRATCH]), (int(settings[5]), 3))
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
    state = carray(compiled._record_pointer(row[_MACHINE_STATE]), 1)[0]
    if parameters.ground_amplitude != 0.0 or state.est_t != state.t:
        return 0
    _write_reported(row, parameters, state)
    return 1


def step_address() -> int:
    """The address of the C function ``int step(intptr_t context, double current_time, double step_size)``: the
    FMU slave's do_step; what is left to do (NOT_TAKEN, TAKEN, TAKEN_WITH_CVODE or FINISH + the machine's status)."""
    return _do_step.address


def report_address() -> int:
    """The address of the C function ``int report(intptr_t context)``: the REPORTED quantities at the integrator's
    state, as the step writes them; 1 if written, 0 where it writes nothing (a vibrating ground, or the estimate not
    taken at the state's time)."""
    return _report.address
