"""The stepper protocol: what a CVODE engine offers for one mode of the ball, and the pool of them.

Each engine offers a ``PhaseSolver`` for one mode (compiled.PhaseSolver, numba callbacks over the
SUNDIALS library; SksundaePhaseSolver, scikit-sundae's CVODE object with Python callbacks) with the
same CVODE settings, and a phase machine (``phase_machine``: solvers/phase_machine/machine.py, compiled or as
written) that drives the two modes' solvers through ``handle()``:

- ``bind(ball)``: the ball whose equations it integrates (a pooled solver serves many balls);
- ``handle()``: what the engine's machine calls it through (for scikit-sundae, the solver itself,
  whose start, steps and exceeded are the calls of solvers/phase_machine/engine_protocol.py; for the compiled
  engine a row of integers, the addresses its compiled calls read);
- ``message(flag)`` and the ``log`` of SUNDIALS' warnings (solvers/engines/sundials_log.py).

Creating a CVODE object and its warnings file costs more than integrating a whole phase (~0.1 ms
each, two per integrator), so solvers are kept per process in a pool, by engine, mode, method and
settings: ``acquire`` takes one (or makes it), ``release`` gives it back for the next integrator.
CVODE is re-initialised at every phase, so a pooled solver integrates as a new one does, bit for bit.
"""

from __future__ import annotations

import functools
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...physics import Ball, Mode
from ..phase_machine import drivers, error_estimate, layout, machine, phases
from ..phase_machine.engine_protocol import CV_ROOT_RETURN, CV_TSTOP_RETURN
from . import sksundae_events
from .sundials import sksundae_cvode_class
from .sundials_log import ErrorsOffStdout, SundialsLog

CV_RTFUNC_FAIL = -12
_POOL_SIZE = 4  # solvers kept per kind: the sweep's worker threads each hold one integrator at a time


class SolverError(RuntimeError):
    """CVODE failed; the message carries its reason."""


@dataclass
class PhaseResult:
    """What a solver returns from step or solve: the step ends, CVode's flag and its message, RHS calls."""

    t: np.ndarray | float
    y: np.ndarray
    status: int
    message: str
    nfev: int


class _TooManyEvaluations(Exception):
    """Raised in the root function of a phase that took more evaluations than allowed."""


class SksundaePhaseSolver:
    """CVODE for one mode through scikit-sundae's CVODE object: the calls of compiled.PhaseSolver.

    Parameters are those of compiled.PhaseSolver: the ball, its mode, "Adams" or "BDF", rtol (also the
    absolute tolerance of the scaled state), max_step [s] (0: none), CVODE's steps per call, the value
    of the gap root at 0 (the mode's own side), the roots' directions and the root evaluations
    allowed per phase (beyond: status CV_RTFUNC_FAIL and ``exceeded``).
    """

    def __init__(self, ball: Ball, mode: Mode, method: str, rtol: float, max_step: float, max_num_steps: int,
                 own_side: float, directions, max_evaluations: int) -> None:
        self.log = SundialsLog()
        self.exceeded = False
        self._frame = [1.0, 1.0, 0.0]  # length [m], speed [m/s], hop tolerance [m]
        self._evaluations = 0
        self.bind(ball)
        # CVODE integrates x / length and v / speed (the frame's scales), in time from the phase's start.
        # The frame, the load and the ball are read from self._frame and self._constants (one lookup each):
        # these run for every right-hand side and root evaluation, ~5000 times a run.
        rates, jacobian, roots = phases.scaled_rates, phases.scaled_jacobian, phases.root_values
        varies, varying, load_at = phases.jacobian_varies, phases.varying_jacobian, phases.load_at

        def rhs(t, y, yp):
            length, speed, _ = self._frame
            load, parameters, origin = self._constants
            yp[0], yp[1] = rates(parameters, y[0], y[1], mode, length, speed, load_at(parameters, load, origin + t))

        def jac(t, y, yp, JJ):
            length, speed, _ = self._frame
            load, parameters, origin = self._constants
            if varies(parameters, mode):  # evaluated where it changes
                JJ[0, 0], JJ[0, 1], JJ[1, 0], JJ[1, 1] = varying(parameters, y[0], y[1], length, speed,
                                                                 load_at(parameters, load, origin + t))
            else:
                JJ[0, 0], JJ[0, 1], JJ[1, 0], JJ[1, 1] = jacobian(parameters, mode, length, speed)

        def event(t, y, out):
            length, speed, hop = self._frame
            load, parameters, origin = self._constants
            out[0], out[1], out[2] = roots(parameters, y[0], y[1], mode, length, speed,
                                           load_at(parameters, load, origin + t), own_side, hop)
            # CVODE evaluates the root functions once per step (and a few times per root found)
            self._evaluations += 1
            if self._evaluations > max_evaluations:
                raise _TooManyEvaluations(t)

        event.terminal = [True, False, True]
        event.direction = list(directions)
        self._event = event
        CVODE = sksundae_cvode_class()  # imported here, not with the module (~0.4 s), bound to its own SUNDIALS

        # The scaled state is of order 1: atol = rtol asks for rtol times the phase's scale.
        self._cvode = CVODE(rhs, method=method, rtol=rtol, atol=rtol, max_step=max_step, eventsfn=event,
                            num_events=3, jacfn=jac, max_num_steps=max_num_steps)

    def bind(self, ball: Ball, parameters=None) -> None:
        """Integrate ball's equations from now on (the phase's frame and load set at each start).

        parameters: the machine's BallParameters, if not ball.parameters (a vibrating ground's, Ground.on).
        """
        self._parameters = ball.parameters if parameters is None else parameters
        self._constants = (0.0, self._parameters, 0.0)  # the phase's load [N], the ball, the phase's start [s]
        self.set_frame(1.0, 1.0, 0.0)

    def set_frame(self, length: float, speed: float, hop_tolerance: float) -> None:
        """The phase's scales [m, m/s] and the rest root's margin [m]; set before init_step/solve."""
        self._frame[:] = length, speed, hop_tolerance

    def roots_found(self) -> list[int]:
        """CVodeGetRootInfo of the last root return: per root function, 0 or the crossing's sign."""
        return sksundae_events.roots_found(self._event)

    def _restart(self) -> None:
        sksundae_events.clear(self._event)
        self._evaluations = 0
        self.exceeded = False

    def init_step(self, t0: float, y0) -> None:
        """(Re)start CVODE at t0 from y0."""
        self._restart()
        with ErrorsOffStdout():
            self._cvode.init_step(t0, y0)

    def step(self, t_toward: float, method: str = "onestep"):
        """One internal step toward t_toward; its end, or the root it stopped at."""
        sksundae_events.clear(self._event)
        try:
            with ErrorsOffStdout():
                return self._cvode.step(t_toward, method=method)
        except _TooManyEvaluations as stop:
            return self._exceeded(float(stop.args[0]))

    def solve(self, tspan, y0):
        """From y0 at tspan[0] to tspan[-1] or the first terminal root: every step end."""
        self._restart()
        try:
            with ErrorsOffStdout():
                return self._cvode.solve(tspan, y0)
        except _TooManyEvaluations as stop:
            return self._exceeded(float(stop.args[0]))

    # --- the phase machine's engine calls (solvers/phase_machine/engine_protocol.py) ---------------------------------
    def start(self, t_stop: float, y0: float, y1: float, length: float, speed: float, hop: float,
              load: float, origin: float) -> int:
        """Take the phase's frame; restart CVODE at 0 from (y0, y1) for one-step calls, or in steps() to t_stop."""
        self.set_frame(length, speed, hop)
        self._constants = (load, self._parameters, origin)
        self._start = (y0, y1)
        if t_stop == math.inf:
            with self.log.capturing():
                self.init_step(0.0, np.array([y0, y1]))
        return 0

    def steps(self, scratch: np.ndarray, t_toward: float, one_step: bool):
        """One step (step) or the phase solved to t_toward (solve): engine_protocol.engine_steps."""
        if one_step:
            result = self.result = self.step(t_toward)
            rows = scratch
            rows[0, 0] = float(np.atleast_1d(result.t)[-1])
            if result.status >= 0:
                rows[0, 1], rows[0, 2] = result.y[0], result.y[1]
        else:
            with self.log.capturing():
                result = self.result = self.solve(np.array([0.0, t_toward]), np.array(self._start))
            if result.status < 0:
                return result.status, 0, scratch, 0, 0, 0
            rows = np.column_stack((result.t[1:], result.y[1:, 0], result.y[1:, 1]))
        if result.status < 0:
            return result.status, 1, rows, 0, 0, 0
        flag = result.status if one_step or result.status == CV_ROOT_RETURN else CV_TSTOP_RETURN
        gap_root, _, rest_root = self.roots_found() if flag == CV_ROOT_RETURN else (0, 0, 0)
        return flag, len(rows) if not one_step else 1, rows, gap_root, rest_root, int(result.nfev)

    def handle(self) -> SksundaePhaseSolver:
        """What the interpreted phase machine calls: the solver itself."""
        return self

    def message(self, flag: int) -> str:
        """The last failure's message, as scikit-sundae gave it."""
        return self.result.message

    def _exceeded(self, t: float) -> PhaseResult:
        self.exceeded = True
        return PhaseResult(np.array([t]), np.full((1, 2), np.nan), CV_RTFUNC_FAIL, "too many steps", 0)


@dataclass(frozen=True)
class PhaseMachine:
    """An engine's phase machine (solvers/phase_machine/): its drivers, its grid fill, and its engine argument.

    fill_grid None: the grid is filled by dense_output.interpolate, in numpy. engine(solvers): what the
    machine's engine_* calls take, from the two modes' solvers. new_state(): a new state of the machine
    (layout.py), as (what Python reads and writes by name, what the machine takes); parameters(ball.parameters):
    them as the machine's calls take them (a plain tuple for the compiled one's entry points, which numba types
    in half the time of a namedtuple: ~3 us a call, measured, a tenth of a doStep). phase_ends (machine.py) and
    run_estimate (error_estimate.py) as the machine runs them: the compiled engine's cost ~6 us
    a call, where Python takes ~60 us, a fifth of a short run's time outside CVODE. advance_in_step takes
    (parameters, rtol, atol, state, t_from, t_target); the compiled engine's advance and advance_in_step keep
    the run's estimate at their end (drivers.keep_estimate), the interpreted ones do not. solver: the engine's
    PhaseSolver class (one mode's CVODE). step_address() and report_address(): the addresses of the C entry points
    an FMU's loader calls (entry_contract.ENTRIES' do_step and report); None for the interpreted machine.
    """

    run_phases: Callable
    advance: Callable
    advance_in_step: Callable
    fill_grid: Callable | None
    engine: Callable
    new_state: Callable
    parameters: Callable
    phase_ends: Callable
    run_estimate: Callable
    solver: type
    step_address: Callable[[], int] | None
    report_address: Callable[[], int] | None


def phase_machine(engine: str) -> PhaseMachine:
    """The phase machine of engine: compiled for "compiled" (the native engine's where one is active: native.py),
    else machine.py's and drivers.py's as written."""
    library = None
    if engine == "compiled":
        from . import native

        library = native.active()
    return _phase_machine(engine, library)


@functools.cache
def _phase_machine(engine: str, library) -> PhaseMachine:
    """phase_machine's, made once per engine and native library (None: numba's)."""
    if engine == "compiled":
        if library is not None:
            return PhaseMachine(library.run_phases, library.advance, library.advance_in_step, None, _stacked_handles,
                                layout.compiled_state, library.parameters, library.phase_ends, library.run_estimate,
                                library.PhaseSolver, lambda: library.addresses["do_step"],
                                lambda: library.addresses["report"])
        from . import compiled

        return PhaseMachine(compiled.run_phases, compiled.advance, compiled.advance_in_step, compiled.fill_grid,
                            _stacked_handles, layout.compiled_state, tuple, compiled.phase_ends,
                            compiled.run_estimate, compiled.PhaseSolver, _compiled_step_address,
                            _compiled_report_address)
    return PhaseMachine(drivers.run_phases, drivers.advance, _advance_in_step, None, tuple,
                        layout.interpreted_state, _as_given, machine.phase_ends, error_estimate.run_estimate,
                        SksundaePhaseSolver, None, None)


def _compiled_step_address() -> int:
    from . import c_entry  # numba compiles it, or reads it from its cache, at its first import

    return c_entry.step_address()


def _compiled_report_address() -> int:
    from . import c_entry

    return c_entry.report_address()


def _stacked_handles(solvers) -> np.ndarray:
    """The compiled machine's engine: its solvers' rows (PhaseSolver.handle)."""
    return np.stack([solver.handle() for solver in solvers])


def _as_given(parameters):
    return parameters


def _advance_in_step(parameters, rtol, atol, state, t_from, t_target):
    """drivers.advance_in_step as the interpreted machine runs it: no estimate kept (run_estimate in Python costs
    ~60 us; the integrator takes it where it is read)."""
    return drivers.advance_in_step(parameters, state, t_from, t_target)


_pool: dict[tuple, list] = {}
_pool_lock = threading.Lock()


def acquire(engine: str, ball: Ball, mode: Mode, method: str, rtol: float, max_step: float, max_num_steps: int,
            own_side: float, directions, max_evaluations: int, parameters=None):
    """A solver of engine ("compiled" or "sksundae") for ball's mode, from the pool or new; see the module's doc.

    parameters: the machine's BallParameters where they are not ball.parameters (a vibrating ground's).
    """
    solver_class = phase_machine(engine).solver  # numba's compiled engine's, the native one's, scikit-sundae's
    key = (solver_class, mode, method, rtol, max_step, max_num_steps, own_side, tuple(directions), max_evaluations)
    with _pool_lock:
        kept = _pool.get(key)
        solver = kept.pop() if kept else None
    if solver is None:
        solver = solver_class(ball, mode, method, rtol, max_step, max_num_steps, own_side, directions,
                              max_evaluations)
        solver.pool_key = key
        if parameters is not None:
            solver.bind(ball, parameters)
    else:
        solver.bind(ball, parameters)
        solver.log.forget_causes()
    return solver


def release(solver) -> None:
    """Give solver back to the pool (it is freed instead when the pool holds enough of its kind)."""
    with _pool_lock:
        kept = _pool.setdefault(solver.pool_key, [])
        if len(kept) < _POOL_SIZE:
            kept.append(solver)
