"""What the compiled engine's C entry points take and return: the contract between them and their callers.

The entry points are numba cfuncs (solvers/engines/c_entry.py). The FMU's C layer calls ``do_step`` and
``report`` with a context (``CONTEXT_FIELDS``) that fmu/c_layer.py fills; the FMU's native engine
(solvers/engines/native.py) calls those and the pointer-argument ones (``POINTER_ENTRIES``) from the very same code
compiled ahead into a library. The compiled code reads these constants as it is compiled (so this file is one of
jit.ENGINE_SOURCES); its callers read them here, without numba.
"""

from __future__ import annotations

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
PARAMETERS, SETTINGS_AT, MACHINE_STATE, VALUES, ENGINE, EVENTS, SCRATCH, PAIRS = range(len(CONTEXT_FIELDS))
# BallIntegrator's settings.rtol, _atol, resolvable_until (beyond it, its refusal), the slave's STOP_AT_EVENT (1.0 or
# 0.0), the rows of its event and scratch arrays and the engine's modes.
SETTINGS = ("rtol", "atol", "resolvable_until", "stop_at_event", "event_rows", "scratch_rows", "engine_modes")
# What do_step returns. 0 is what a cfunc returns when its compiled code raised (numba's wrapper reports the exception
# and returns the default): the state may have changed by then, so the caller is to end the instance, never to run the
# step again.
RAISED, NOT_TAKEN, TAKEN, TAKEN_WITH_CVODE, FINISH = 0, 1, 2, 3, 16
# What the pointer-argument entry points return where their compiled code ran to its end (0 where it raised).
COMPLETED = 1

# The entry points a library of the engine exports (each as bb_<name>), with their C signatures: the FMU's two, the
# CVODE callbacks, and the phase machine's calls that Python makes (stepper.PhaseMachine's advance, advance_in_step,
# phase_ends, run_estimate) with pointer arguments. Their arguments: values, the BallParameters as float64; memory,
# the machine state's record; engine, the engine's rows (modes of them); events and scratch, rows of 3 float64.
ENTRIES = {
    "do_step": "int32_t (intptr_t context, double current_time, double step_size)",
    "report": "int32_t (intptr_t context)",
    "rhs": "int32_t (double t, intptr_t y, intptr_t ydot, intptr_t *user_data)",
    "roots": "int32_t (double t, intptr_t y, double *gout, intptr_t *user_data)",
    "jacobian": "int32_t (double t, intptr_t y, intptr_t fy, intptr_t matrix, intptr_t *user_data, intptr_t tmp1, "
                "intptr_t tmp2, intptr_t tmp3)",
    # out: [status, the events' count]; events past the rows given are counted, not written.
    "advance": "int32_t (intptr_t values, double rtol, double atol, intptr_t memory, double t_target, "
               "int32_t stop_at_event, intptr_t engine, intptr_t modes, intptr_t events, intptr_t rows, "
               "intptr_t scratch, intptr_t scratch_rows, intptr_t out)",
    # out: [1 if advanced inside the last step, else 0]
    "advance_in_step": "int32_t (intptr_t values, double rtol, double atol, intptr_t memory, double t_from, "
                       "double t_target, intptr_t out)",
    "phase_ends": "int32_t (intptr_t values, double rtol, double atol, intptr_t memory, double jump, "
                  "double reflection)",
    # out: run_estimate's three floats
    "run_estimate": "int32_t (intptr_t values, double rtol, double atol, intptr_t memory, intptr_t out)",
}
