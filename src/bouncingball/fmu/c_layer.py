"""What the FMU's C layer does without entering Python: serve the variables' values, and take the steps.

A master reads outputs after every step (fmusim all of them), and each read through pythonfmu enters Python. The
loader (bouncingball_fmu_python.h) serves them itself from memory the slave owns and hands it while it is being made
(``bouncingball_serve``): the value of every Real, Integer and Boolean variable by value reference, and control
slots. At the end of each step it took, the slave writes its values there and marks them ready (``publish``); the
loader clears that mark before it forwards any call that may change them (a set, a reset, a restored state, a step).

The steps themselves the loader takes by calling the compiled engine (solvers/engines/c_entry.py; the same code
compiled ahead where the FMU's native engine runs: solvers/engines/native.py), which runs the
slave's do_step as BallIntegrator runs it, on the integrator's own CVODE solvers and machine state, and writes the
outputs it changes: on the compiled engine and a still ground, where the slave's variables that change in a step are
each a quantity it reports (``REPORTED_BY_VARIABLE``). What needs Python is left to it: a refusal to word, a
failure to raise, SUNDIALS' warnings to read (their files grew), the accuracy warning to check; the slave finishes a
step the loader began (``finish_begun``). Any other step runs in Python as before. A slave whose loader is not this
one (run by pythonfmu's binary alone, or in tests without a binary) serves nothing and runs as before.
"""

from __future__ import annotations

import ctypes
import glob
import os
from typing import Any, NamedTuple

import numpy as np

from ..solvers.integrator import compiled_arrays, finish_advance
from .variables import MODEL_NAME

# The control slots (bouncingball_fmu_python.h: SERVED_READY, ...).
READY, STEP, CONTEXT, BEGUN, LOG0, LOG1, SIZE0, SIZE1, SLOTS = range(9)
# The variables a step changes, by name, and the quantity of the compiled step (entry_contract.REPORTED) that is each.
# (gap, FMI 3.0's event indicator, and x, model exchange's state: h - R in co-simulation on a still ground, as slave3's
# _gap and _x compute it.)
REPORTED_BY_VARIABLE = {"time": "t", "h": "h", "v": "v", "a": "acceleration", "der(x)": "v", "der(v)": "acceleration",
                        "contact": "contact", "contact_force": "contact_force", "impacts": "impacts",
                        "error_estimate": "error_estimate_at_t", "gap": "h_minus_R", "x": "h_minus_R"}
_SERVED_TYPES = ("Real", "Float64", "Integer", "Int32", "Boolean")  # pythonfmu's and pythonfmu3's class names


def _loader(resources: str | None):
    """The FMU's own binary, loaded by the master already (never loaded here), or None."""
    if not resources:
        return None
    for path in glob.glob(os.path.join(resources, os.pardir, "binaries", "*", f"{MODEL_NAME}.so")):
        try:
            library = ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_NOW)
        except OSError:
            continue
        if hasattr(library, "bouncingball_serve"):
            return library
    return None


class _CompiledStep(NamedTuple):
    """What the loader's compiled step of one integrator needs, kept while the integrator and its state are the same."""

    integrator: Any
    machine_state: np.ndarray
    context: np.ndarray  # entry_contract.CONTEXT_FIELDS, pointing to what follows
    step_address: int
    parameters: np.ndarray
    settings: np.ndarray  # entry_contract.SETTINGS
    arrays: tuple  # solvers/integrator.py's compiled_arrays
    report: Any  # the ctypes function of the machine's report_address()


class ServedValues:
    """The slave's side of the served values: made with the slave, while its loader makes the instance.

    variables: the slave's registered variables by value reference (pythonfmu's ``vars``), each with its getter.
    stop_at_event: the slave's STOP_AT_EVENT (FMI 3.0's do_step returns at the first event inside the step).
    """

    def __init__(self, resources: str | None, variables: dict, stop_at_event: bool = False):
        self._stop_at_event = stop_at_event  # the slave's STOP_AT_EVENT: FMI 3.0's do_step returns at an event
        self.values = np.zeros(len(variables))
        self.control = np.zeros(SLOTS, dtype=np.intp)
        self.control[LOG0:LOG1 + 1] = -1
        numbers = {reference: variable for reference, variable in variables.items()
                   if type(variable).__name__ in _SERVED_TYPES}
        changing = {reference: variable for reference, variable in numbers.items()
                    if getattr(variable.causality, "name", "") in ("output", "local", "independent")}
        # Parameters and inputs change only where the master sets them; the rest in a step.
        self._set_only = [(reference, variable.getter) for reference, variable in numbers.items()
                          if reference not in changing]
        self._changing = [(reference, variable.getter) for reference, variable in changing.items()]
        # The quantity of the compiled step (entry_contract.REPORTED) each changing variable is; None: no compiled step.
        self._reported = [(REPORTED_BY_VARIABLE.get(variable.name), reference) for reference, variable in
                          changing.items()]
        self._published: dict | None = None  # the slave's values (parameters, inputs) as last published
        self._kept: _CompiledStep | None = None  # the last publish's
        library = _loader(resources)
        self.linked = bool(library) and library.bouncingball_serve(
            ctypes.c_void_p(self.values.ctypes.data), ctypes.c_void_p(self.control.ctypes.data),
            ctypes.c_size_t(len(variables))) == 1

    def publish(self, integrator, set_values: dict) -> None:
        """The slave's current values, ready to be served, and the compiled step of integrator (None: none).

        set_values: the values the master set, by name (the slave's; published again only where they changed).
        """
        if not self.linked:
            return
        values, control = self.values, self.control
        if set_values != self._published:
            for reference, getter in self._set_only:
                values[reference] = getter()
            self._published = dict(set_values)
        step = self._compiled_step(integrator)
        if step is None or not step.report(step.context.ctypes.data):
            for reference, getter in self._changing:
                values[reference] = getter()
        if step is None:
            control[STEP] = control[CONTEXT] = 0
        else:  # the step may run CVODE: the files of its warnings, as far as the integrator has read them
            control[STEP], control[CONTEXT] = step.step_address, step.context.ctypes.data
            for slot, log in enumerate(integrator._logs[:2]):  # SundialsLog, one per mode's solver
                control[LOG0 + slot], control[SIZE0 + slot] = log.descriptor, log.size()
        control[READY] = 1

    def finish_begun(self, integrator) -> bool:
        """Whether the loader's compiled step began the step the slave is asked for: then its end, as BallIntegrator
        advance's (solvers/integrator.py's finish_advance: a SolverError for a failure; the warnings read, checked)."""
        code = int(self.control[BEGUN])
        if not code:
            return False
        self.control[BEGUN] = 0
        from ..solvers.engines.entry_contract import FINISH

        finish_advance(integrator, code - FINISH)
        return True

    def _compiled_step(self, integrator) -> _CompiledStep | None:
        """The compiled step of integrator, or None where it has none."""
        if integrator is None or integrator.engine != "compiled" or integrator.ground.moves or \
                any(quantity is None for quantity, _ in self._reported):
            return None
        kept = self._kept
        if kept is None or kept.integrator is not integrator or kept.machine_state is not integrator._machine_state:
            from ..solvers.engines import entry_contract

            engine, events, scratch = arrays = compiled_arrays(integrator)
            parameters = np.array(integrator._machine_parameters, dtype=float)
            settings = np.array([integrator.settings.rtol, integrator._atol, integrator.resolvable_until,
                                 float(self._stop_at_event), len(events), len(scratch), len(engine)])
            pairs = [number for quantity, reference in self._reported
                     for number in (entry_contract.REPORTED.index(quantity), reference)]
            context = np.array([parameters.ctypes.data, settings.ctypes.data, integrator._machine_state.ctypes.data,
                                self.values.ctypes.data, engine.ctypes.data, events.ctypes.data, scratch.ctypes.data,
                                len(pairs) // 2, *pairs], dtype=np.intp)
            machine = integrator._machine  # its C entry points: numba's compiled engine's, or the native one's
            report = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_ssize_t)(machine.report_address())
            kept = self._kept = _CompiledStep(integrator, integrator._machine_state, context, machine.step_address(),
                                              parameters, settings, arrays, report)
        return kept
