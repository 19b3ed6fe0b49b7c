"""The compiled engine's entry point for a C caller: an FMU's doStep where it needs no CVODE, and its values.

An FMU's C layer (fmu/bouncingball_fmu_python.h, ``stepped_in_c``) calls the cfunc at ``step_address()`` with a
context: a row of addresses and value references (``CONTEXT_FIELDS``) that fmu/c_layer.py fills for one integrator
and the FMU's variables. Where the FMU slave's do_step would end inside CVODE's last step, or on a rest, it runs the
very compiled calls BallIntegrator runs there (drivers.advance_in_step or drivers.rest_until, then
drivers.keep_estimate) on the integrator's own machine state, then writes each ``REPORTED`` quantity the context
asks for where it says, computed as the integrator's properties compute it, so that a step taken here and one taken
through Python leave the same values to the bit. 1 if it stepped; 0 if it did nothing: the step needs CVODE, an
event, a refusal or a warning's check, or the ground vibrates (its motion is the Python ground's own arithmetic),
and the caller runs it in Python. ``report_address()`` writes the same quantities without stepping (after a step
Python took).

Import this module only to use it (it imports numba and the compiled engine).
"""

from __future__ import annotations

import math

from numba import carray, cfunc, njit, types

from ...codes import CONTACT
from ...contact_laws import BallParameters, dispatch
from ..phase_machine import drivers
from . import compiled
from .jit import addresses, doubles

# What the step reports, in this order: the names of the integrator's properties (t, h, v, acceleration, ...), and
# h - R [m] computed from h as written (the FMI 3.0 slave's gap in co-simulation).
REPORTED = ("t", "h", "v", "acceleration", "contact", "contact_force", "impacts", "error_estimate_at_t",
            "h_minus_R")
# The context (one row of intp): the addresses of the integrator's BallParameters as float64, of [rtol, atol,
# resolvable_until] (BallIntegrator's settings.rtol, _atol and resolvable_until: beyond it, its refusal), of its
# machine state (layout.STATE_DTYPE's record) and of the caller's values (float64), the number of pairs that follow,
# then each pair: a REPORTED quantity's place in REPORTED and the index in the values it is written at.
CONTEXT_FIELDS = ("parameters", "settings", "machine_state", "values", "pairs")
_PARAMETERS, _SETTINGS, _MACHINE_STATE, _VALUES, _PAIRS = range(len(CONTEXT_FIELDS))
_HEADER, _N_PARAMETERS = len(CONTEXT_FIELDS), len(BallParameters._fields)

_advance_in_step = compiled._compiled[drivers.advance_in_step]
_rest_until = compiled._compiled[drivers.rest_until]
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
def _step_without_cvode(context, current_time, step_size):
    row, parameters = _unpacked(context)
    state = carray(compiled._record_pointer(row[_MACHINE_STATE]), 1)[0]
    if parameters.ground_amplitude != 0.0:
        return 0
    # As the FMU slave's do_step and BallIntegrator.advance: inside the last step from current_time, else from the
    # state's time where current_time is its rounding, else on a rest; anything else (CVODE, an event, a refusal, a
    # warning to check: err_from set) is left to them.
    t, t_target = state.t, current_time + step_size
    if not _advance_in_step(parameters, state, current_time, t_target):
        rounded = current_time != t
        if (rounded and not abs(current_time - t) <= 1e-9 * max(1.0, abs(t))) or \
                not (step_size >= 0.0 and math.isfinite(t_target)):
            return 0
        if rounded:
            t_target = max(t_target, t)
        if not (rounded and _advance_in_step(parameters, state, t, t_target)):
            settings = carray(doubles(row[_SETTINGS]), 3)
            if not math.isnan(state.err_from) or t_target > settings[2] or \
                    not _rest_until(parameters, state, t_target):
                return 0
    settings = carray(doubles(row[_SETTINGS]), 3)
    _keep_estimate(parameters, settings[0], settings[1], state)
    _write_reported(row, parameters, state)
    return 1


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
    FMU slave's do_step (fmu/slave_base.py) where it needs no CVODE: it ends inside CVODE's last step, or on a rest;
    1 if it stepped, else 0 and nothing changed."""
    return _step_without_cvode.address


def report_address() -> int:
    """The address of the C function ``int report(intptr_t context)``: the REPORTED quantities at the integrator's
    state, as the step writes them; 1 if written, 0 where it writes nothing (a vibrating ground, or the estimate not
    taken at the state's time)."""
    return _report.address
