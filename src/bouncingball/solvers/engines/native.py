"""The compiled engine as native code: the library native_build.py makes, run without numba (an FMU's engine).

An FMU's start would otherwise import numba and read the compiled code from its cache (about 0.7 s, most of a
start-up a master pays per process). So build-fmu compiles the engine's entry points (solvers/engines/c_entry.py's
``ENTRY_POINTS``: the very code numba compiles, in the same compile) into one shared library that the FMU ships;
the slave activates it (``activate``) before it makes an integrator, and from then on, in that copy of the
package, ``stepper.phase_machine("compiled")`` is this library's: its PhaseSolver's CVODE callbacks, the phase
machine's calls (``NativeEngine.advance`` ... through ctypes) and the FMU's C-callable step. numba is not imported.

The library is used only where it fits: it loads here (this architecture), and it was compiled from these sources
(their digest, sources.py's, is the one it holds); else ``activate`` says why and the compiled engine of numba
runs instead. What it cannot do, it says: a run to a grid (run_phases) needs numba's engine.

Code compiled by numba raises Python exceptions; in the library, the runtime that stands in for numba's
(native_runtime.c) keeps none of the exception but the fact: an entry point that raised returns 0, and the calls
below raise NativeEngineError for it.

Imports neither numba nor scikit-sundae.
"""

from __future__ import annotations

import ctypes
import threading

import numpy as np

from . import phase_solver
from .entry_contract import COMPLETED, ENTRIES
from .sources import engine_sources, sources_digest
from .sundials import EngineUnavailable

DIGEST_SYMBOL = "bb_sources_digest"  # a NUL-terminated string: the sources' digest (sources.sources_digest)
EXCEPTIONS_SYMBOL = "bb_exceptions"  # a C long: how many times its compiled code raised
EVENT_ROWS = 4096  # the events one advance may give back (native code cannot hand Python the machine's grown copy)

_C_TYPES = {"int32_t": ctypes.c_int32, "intptr_t": ctypes.c_ssize_t, "double": ctypes.c_double,
            "intptr_t *": ctypes.c_ssize_t, "double *": ctypes.c_ssize_t}


class NativeEngineError(RuntimeError):
    """The native engine's compiled code raised (what it raised is not kept in native code)."""


def _signature(entry: str):
    """The ctypes prototype of entry_contract.ENTRIES[entry]."""
    returned, arguments = ENTRIES[entry].split(" (", 1)
    types = [_C_TYPES[argument.rpartition(" ")[0].strip() + (" *" if "*" in argument else "")]
             for argument in arguments.rstrip(")").split(", ")]
    return ctypes.CFUNCTYPE(_C_TYPES[returned], *types)


class NativeEngine:
    """The library at path, checked: its entry points as the compiled engine's module offers them.

    Raises EngineUnavailable (the message says why) where the library does not load here or was compiled from other
    sources than this copy of the package's.
    """

    def __init__(self, path: str) -> None:
        try:
            library = ctypes.CDLL(path)
            built_from = (ctypes.c_char * 65).in_dll(library, DIGEST_SYMBOL).value.decode()
        except (OSError, ValueError) as error:
            raise EngineUnavailable(f"the native engine {path} does not load here: {error}") from None
        if built_from != sources_digest(engine_sources()):
            raise EngineUnavailable(f"the native engine {path} was compiled from other sources than this package's")
        self.path = path
        self._library = library
        self._exceptions = ctypes.c_long.in_dll(library, EXCEPTIONS_SYMBOL)
        self.addresses = {entry: ctypes.c_void_p.in_dll(library, f"bb_{entry}_address").value for entry in ENTRIES}
        self._calls = {entry: _signature(entry)(self.addresses[entry]) for entry in
                       ("advance", "advance_in_step", "phase_ends", "run_estimate")}
        self.PhaseSolver = type("PhaseSolver", (phase_solver.PhaseSolver,), {
            "__doc__": "One mode's CVODE (phase_solver.PhaseSolver) with the native engine's callbacks.",
            "callbacks": (self.addresses["rhs"], self.addresses["roots"], self.addresses["jacobian"])})
        self._buffers = threading.local()

    def _out(self, size: int, dtype) -> np.ndarray:
        """This thread's array for a call's answers (its events, its estimate)."""
        name = f"out_{size}_{np.dtype(dtype).name}"
        found = getattr(self._buffers, name, None)
        if found is None:
            found = np.zeros(size, dtype=dtype)
            setattr(self._buffers, name, found)
        return found

    def _check(self, entry: str, returned: int, exceptions_before: int) -> None:
        if returned != COMPLETED or self._exceptions.value != exceptions_before:
            raise NativeEngineError(f"the native engine's {entry} raised in its compiled code (its state may have "
                                    "changed; what it raised is not kept in native code): rerun with engine="
                                    "'sksundae' for the message")

    # --- stepper.PhaseMachine's calls, as compiled.py's --------------------------------------------------------------
    @staticmethod
    def parameters(values) -> np.ndarray:
        """The ball's parameters (BallParameters) as the entry points take them: float64 in their order."""
        return np.array(values, dtype=np.float64)

    def advance(self, engine, values, rtol, atol, memory, t_target, stop_at_event, events, n_events, scratch):
        """compiled.advance: (status, events, the events' count), events in a buffer of this thread's."""
        if n_events:
            raise ValueError("the native engine's advance takes no events given before it")
        events = getattr(self._buffers, "events", None)
        if events is None:
            events = self._buffers.events = np.empty((EVENT_ROWS, 3))
        answer = self._out(2, np.intp)
        before = self._exceptions.value
        returned = self._calls["advance"](values.ctypes.data, rtol, atol, memory.ctypes.data, t_target,
                                          1 if stop_at_event else 0, engine.ctypes.data, len(engine),
                                          events.ctypes.data, EVENT_ROWS, scratch.ctypes.data, len(scratch),
                                          answer.ctypes.data)
        self._check("advance", returned, before)
        status, count = int(answer[0]), int(answer[1])
        if count > EVENT_ROWS:
            raise NativeEngineError(f"{count} events in one advance, more than the native engine's {EVENT_ROWS}: "
                                    "take shorter steps")
        return status, events, count

    def advance_in_step(self, values, rtol, atol, memory, t_from, t_target) -> bool:
        """compiled.advance_in_step."""
        answer = self._out(1, np.intp)
        before = self._exceptions.value
        returned = self._calls["advance_in_step"](values.ctypes.data, rtol, atol, memory.ctypes.data, t_from,
                                                  t_target, answer.ctypes.data)
        self._check("advance_in_step", returned, before)
        return bool(answer[0])

    def phase_ends(self, values, rtol, atol, memory, jump, reflection) -> None:
        """compiled.phase_ends."""
        before = self._exceptions.value
        returned = self._calls["phase_ends"](values.ctypes.data, rtol, atol, memory.ctypes.data, jump, reflection)
        self._check("phase_ends", returned, before)

    def run_estimate(self, values, rtol, atol, memory) -> tuple[float, float, float]:
        """compiled.run_estimate."""
        answer = self._out(3, np.float64)
        before = self._exceptions.value
        returned = self._calls["run_estimate"](values.ctypes.data, rtol, atol, memory.ctypes.data,
                                               answer.ctypes.data)
        self._check("run_estimate", returned, before)
        return float(answer[0]), float(answer[1]), float(answer[2])

    @staticmethod
    def run_phases(*arguments):
        """A run to a grid: not in the native engine (it advances step by step, as an FMU does)."""
        raise EngineUnavailable("the native engine advances step by step: a run to a grid needs the compiled engine "
                                "of numba")


_active: NativeEngine | None = None
_activation = threading.Lock()


def activate(path: str) -> str | None:
    """Use the native engine at path for the compiled engine of this copy of the package, from now on; None if it
    is, else why not (then numba's compiled engine runs). Call it before making an integrator."""
    global _active
    with _activation:
        if _active is not None:  # another FMU's copy of the same build (this package's copy is named after its sources)
            return None
        try:
            _active = NativeEngine(path)
        except EngineUnavailable as error:
            return str(error)
    return None


def active() -> NativeEngine | None:
    """The active native engine (activate's), or None."""
    return _active
