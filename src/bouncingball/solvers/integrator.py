"""BallIntegrator: CVODE advanced phase by phase, with contact and departure found by root-finding.

Each mode has its own CVODE solver (solvers/engines/stepper.py: either engine), right-hand side and
terminal root function (h - R, with direction -1 in flight and +1 in contact). At each root the
integrator switches mode and re-initialises CVODE at the event, so no step ever straddles the
discontinuity. The phases are run by the engine's phase machine (solvers/phase_machine/machine.py, its decisions
in solvers/phase_machine/phases.py); the integrator holds the machine's state, checks what it is given, and keeps
the restart point that makes a rollback bit for bit.

Each mode has its own CVODE object with three root functions: h - R, terminal, in the mode's
direction (impact downwards, departure upwards); v, non-terminal, which makes CVODE end a step
at every extremum of h so that no step can hold both crossings of a hop (h leaving R and coming
back within one step shows no sign change of h - R); and in contact the rest margin
(physics.Ball.rest_margin), terminal, which turns positive once the contact can never again
lift the ball more than hop_tolerance above R: the rest that follows is taken on the contact's
exact flow. Hops and contacts too small for CVODE to tell from its own error are also taken on
the mode's exact flow. At an impact or departure the event time CVODE located (to ~100 ulps of
t) is polished on the mode's flow to a few ulps, h is set to R, and CVODE restarts in the other
mode.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from .. import limits, validation
from ..ground import Ground, as_ground
from ..limits import check_resolvable, resolvable_until
from ..physics import Ball, Mode
from . import engine_selection, state_checks
from .engine_selection import choose_engine
from .engines import stepper
from .engines.stepper import SolverError
from .phase_machine import machine
from .phase_machine.dense_output import fill_grid, interpolate
from .phase_machine.settings import CvodeSettings, choose_method, too_many_steps_cause
from .result import EVENT_KINDS, Event, accuracy_warning, warn_at_caller
from .state import IntegratorState, IntegratorView
from .vibrating_ground import ground_motion, machine_ground, relative_start, world_events, world_grid

# The modes CVODE integrates, one solver each: the no-pull law's free sub-mode (Mode.FREE) is a parabola,
# always taken in closed form (phases.decide_phase).
_CVODE_MODES = (Mode.FLIGHT, Mode.CONTACT)
# The value the root function h - R takes at h == R: the mode's own side (see _own_side).
_OWN_SIDE = 1e-300
_MAX_STEPS_PER_CALL = 1_000_000
PROGRESS_STEPS = 20_000  # CVODE steps per call of the phase machine: then Python runs (progress, Ctrl-C)
_SCRATCH_ROWS = 512  # step ends the compiled engine hands over at a time
# A phase that needs more steps than this is a method fighting stiffness (Adams creeping through
# an over-damped contact on a k = 1e12 spring): fail with a reason instead of running for hours.
MAX_STEPS_PER_PHASE = 500_000


class BallIntegrator(IntegratorView):
    """A ball integrated by CVODE that can be advanced piece by piece (the FMU's integrator).

    Parameters
    ----------
    ball : Ball
        The ball.
    h0, v0 : float
        Height [m] and velocity [m/s] at t0.
    t0 : float, optional
        Start time [s].
    F_ext : float, optional
        External force [N], positive upwards; change it between advances with the F_ext property.
    settings : CvodeSettings, optional
        Tolerances, method, maximum step and engine; the defaults if not given.
    expected_steps : float, optional
        The CVODE steps the caller expects to ask for (see expected_steps), for engine "auto"
        (see choose_engine); None: unknown.
    ground : Ground, optional
        Still at 0 by default, or a vibrating table (Ground.sine, every law; vibrating_ground.py).

    Raises
    ------
    ValueError
        A value outside its range (naming it), or contacts too short to resolve in double precision at t0.

    Examples
    --------
    >>> from bouncingball import Ball
    >>> from bouncingball.solvers.cvode import BallIntegrator
    >>> integrator = BallIntegrator(Ball(), h0=2.0, v0=0.0)
    >>> [str(event.kind) for event in integrator.advance(1.0)]
    ['impact', 'departure']
    >>> state = integrator.get_state()  # roll back later with set_state(state)

    Change F_ext between advances; a state restored by set_state(get_state()) continues bit for bit.
    """

    # integrate_grid tells it the time reached at its start and then every PROGRESS_STEPS steps or so
    progress: Callable[[float], None] | None = None
    # Its warnings (AccuracyWarning, SundialsWarning): None issues them with warnings.warn; a list (an FMU's) holds
    # them, appended, for its owner to pass on: a list not empty after a call is the flag that there is something to
    # tell, read at the cost of a truth test (the warnings module's filters cost microseconds around every call).
    held_warnings: list[Warning] | None = None

    def __init__(self, ball: Ball, h0: float, v0: float, t0: float = 0.0, F_ext: float = 0.0,
                 settings: CvodeSettings | None = None, expected_steps: float | None = None,
                 ground: Ground | None = None) -> None:
        self.ball = ball
        self.ground = ground = as_ground(ground)
        parameters = machine_ground(ball, ground)  # before any work: a ground the engines cannot take, named
        self.settings = s = settings or CvodeSettings()
        if s.method == "auto":
            # The parabola of flight is never stiff, and Adams integrates it exactly in a few steps.
            self.methods = {Mode.FLIGHT: "Adams", Mode.CONTACT: choose_method(ball)}
        else:
            self.methods = dict.fromkeys(Mode, s.method)
        h0, v0, t0, F_ext = relative_start(ball, ground, h0, v0, t0, F_ext, s, checked_start)
        self.resolvable_until = resolvable_until(ball)
        self._unreported, self._accuracy_warned = (), False  # _unreported: the SUNDIALS logs to read next
        loaded, started = engine_selection.loaded(), time.perf_counter()
        self.engine, self.engine_reason = choose_engine(s.engine, expected_steps)
        self._solvers = {mode: stepper.acquire(self.engine, ball, mode, self.methods[mode], s.rtol, s.max_step,
                                               _MAX_STEPS_PER_CALL, _own_side(mode),
                                               _root_directions(mode), MAX_STEPS_PER_PHASE, parameters)
                         for mode in _CVODE_MODES}
        self._machine = stepper.phase_machine(self.engine)
        self._engine = self._machine.engine([self._solvers[mode] for mode in _CVODE_MODES])
        self._logs = tuple(self._solvers[mode].log for mode in _CVODE_MODES)  # indexed by the mode's value
        # s: the engine's first use in the process (its import, and its first CVODE objects); 0 after
        self.first_use_time = 0.0 if self.engine in loaded else time.perf_counter() - started
        self._parameters, self._atol = parameters, 0.0 if s.atol is None else s.atol
        self._machine_parameters = self._machine.parameters(parameters)  # as the machine's calls take them
        # _state: the machine's state as Python reads it, by name; _machine_state: what the engine's machine takes
        # (the same object on scikit-sundae's engine; a record over the same memory on the compiled one)
        self._state, self._machine_state = self._machine.new_state()
        self._scratch = np.empty((_SCRATCH_ROWS, 3))
        self._event_rows = np.empty((4, 3))  # advance's events (t, kind, v); the machine grows a copy if need be
        # What set_state would check of this state, check_scene did; its mode is the start's by construction.
        mode = ball.initial_mode(h0, v0, F_ext - ball.m * ground_motion(ground, t0, 2))
        self._restart_at((t0, h0 - ball.R, v0, mode), F_ext, (0, 0, None, 0, 0), t0)

    def _warn_if_untrusted(self, whole: bool) -> None:
        """AccuracyWarning, once, where the estimate passed the promise.

        Checked at the phases' ends (one comparison) or, with whole, over everything integrated so far.
        """
        if self._accuracy_warned or (not whole and math.isnan(self._state.err_from)):
            return
        warning = accuracy_warning(*self._machine.run_estimate(self._machine_parameters, self.settings.rtol, self._atol,
                                                           self._machine_state), self.t, self.settings.rtol)
        if warning is not None:
            self._accuracy_warned = True
            _issue(self.held_warnings, warning)

    # --- state ---------------------------------------------------------------------------------
    def set_state(self, state: IntegratorState) -> None:
        """Resume from state (one of get_state()); ValueError names a bad field, and then nothing changed.

        With a restart point, CVODE restarts there and integrates to state.t again (at most the
        current phase), then the state is exactly the one taken (on a vibrating ground: h, v in the world's frame).
        """
        checked = state_checks.checked(self.ball, state, self.settings, self.ground)
        t, x, v, mode, F_ext = checked.point
        counts, t_start = checked.counts, checked.t_start
        check_resolvable(self.ball, t)
        previous = self.get_state() if hasattr(self, "_F_ext") else None
        if checked.restart_point is None:
            self._restart_at((t, x, v, mode), F_ext, counts, t_start)
            self._resume_summed_bounces(state.zeno_time)
            return
        self._restart_at(checked.restart_point, F_ext, checked.restart_counts, t_start, checked.restart_t_low,
                         checked.restart_errors)
        try:
            self._advance(t)
        except (SolverError, ValueError):
            if previous is not None:
                self.set_state(previous)
            raise
        finally:
            self._report_sundials_warnings()
        reached = self._state
        # The world's velocity compared: a relative one taken from it (v - s') may be an ulp off the machine's own.
        if (float(reached.x), float(reached.v) + ground_motion(self.ground, t, 1)) != (x, float(state.v)):
            # Not where this restart point leads (a state made by hand, or one a Taylor step within ulps
            # of an earlier target reached): CVODE would continue another trajectory, so it restarts at
            # the state itself, which continues within the tolerance, with the error carried to t (the
            # restart point's alone left out the phase from it to t: 0.37 of the estimate, in a flight).
            self._machine.phase_ends(self._machine_parameters, self.settings.rtol, self._atol, self._machine_state,
                                     0.0, 1.0)
            self._restart_at((t, x, v, mode), F_ext, counts, t_start, errors=self._errors())
            return
        # The counters as they were: CVODE's step history is the original's.
        self._set_counts(counts)
        reached.rhs_calls -= reached.nfev
        self._resume_summed_bounces(state.zeno_time)

    def _resume_summed_bounces(self, zeno_time: float | None) -> None:
        """A rigid ball's rest on R from zeno_time [s] (its summed bounces until then), which no restart point knows."""
        if zeno_time is not None:
            state = self._state
            state.rest_t, state.rest_x, state.rest_v = zeno_time, 0.0, 0.0

    def close(self) -> None:
        """Give the CVODE objects back to the process's pool for the next integrator; unusable after.

        simulate does it; an integrator never closed frees its CVODE objects when collected.
        """
        solvers, self._solvers, self._engine = self._solvers, None, None
        for solver in (solvers or {}).values():
            stepper.release(solver)

    # --- integration -------------------------------------------------------------------------
    def advance(self, t_target: float, stop_at_event: bool = False) -> list[Event]:
        """Integrate to t_target [s], resolving every impact and departure on the way.

        CVODE takes one internal step at a time, and its steps do not depend on the sequence of
        targets; a target inside the last step is read off the step's dense output, so a short
        advance usually costs no CVODE call at all. With stop_at_event, it returns at the first
        impact or departure before t_target instead, with t the event's time and the mode switched
        (an FMI 3.0 early return); an event at t_target itself is left to the next advance.
        """
        if type(t_target) is not float:  # None, text, an int beyond 1e308: named
            t_target = validation.finite("t_target", t_target, "s")
        if self._machine.advance_in_step(self._machine_parameters, self.settings.rtol, self._atol, self._machine_state,
                                         self._state.t, t_target):
            return []
        try:
            return self._advance(t_target, stop_at_event)
        finally:
            self._report_sundials_warnings()

    def advance_within_step(self, t_target: float, t_from: float | None = None) -> bool:
        """Advance to t_target [s] if it lies inside CVODE's last step, after t; whether it did.

        Read off the step's dense output as advance() reads it (advance asks this first): no CVODE
        call, nothing that can fail or warn. Most of an FMU's short steps end there. t_from, if
        given: the time [s] the caller holds the integrator to be at (an FMU's communication point);
        unless it is t exactly, nothing is done (False), and the caller checks it as it will.
        """
        if type(t_target) is not float:
            t_target = validation.finite("t_target", t_target, "s")
        if t_from is None:
            t_from = self._state.t
        elif type(t_from) is not float:
            t_from = validation.finite("t_from", t_from, "s")
        return self._machine.advance_in_step(self._machine_parameters, self.settings.rtol, self._atol,
                                             self._machine_state, t_from, t_target)

    def _advance(self, t_target: float, stop_at_event: bool = False) -> list[Event]:
        if not t_target >= self._state.t:
            raise ValueError(f"t_target = {t_target!r} s is not allowed: it must be >= the current time {self.t!r} s")
        if t_target > self.resolvable_until:
            check_resolvable(self.ball, t_target)
        status, events, n_events = self._machine.advance(
            self._engine, self._machine_parameters, self.settings.rtol, self._atol, self._machine_state, t_target,
            stop_at_event, self._event_rows, 0, self._scratch)
        # Without an event the mode never changed: its solver alone ran (one file to read, not two).
        mode = int(self._state.mode)
        self._unreported = (self._logs if n_events or status != machine.DONE or mode >= len(self._logs)
                            else (self._logs[mode],))
        if status != machine.DONE:
            raise _machine_failure(self, status)
        self._warn_if_untrusted(whole=False)
        return world_events(self.ground, _events(events, n_events))

    def integrate_grid(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[Event]]:
        """Integrate through the increasing output times grid (grid[0] = current time).

        The phase machine runs CVODE phase by phase, keeping every step end; the grid values come
        from the same dense output as in advance(), evaluated for all grid points in one pass at
        the end, which costs far less per output point than asking CVODE for each one.
        """
        try:
            return self._integrate_grid(np.asarray(grid, dtype=float))
        finally:
            self._report_sundials_warnings()

    def _integrate_grid(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[Event]]:
        t_end, state, machine_state = float(grid[-1]), self._state, self._machine_state
        check_resolvable(self.ball, t_end)
        self._machine.phase_ends(self._machine_parameters, self.settings.rtol, self._atol, machine_state, 0.0, 1.0)
        points, events = np.empty((256, 4)), np.empty((16, 3))
        points[0] = state.t, state.x, state.v, state.mode
        n_points, n_events = 1, 0
        while True:
            if self.progress is not None:
                self.progress(float(state.t))
            status, points, n_points, events, n_events = self._machine.run_phases(
                self._engine, self._machine_parameters, self.settings.rtol, self._atol, machine_state, t_end, points,
                n_points, events, n_events, self._scratch, PROGRESS_STEPS)
            self._unreported = self._logs
            if status == machine.DONE:
                break
            if status != machine.RETURNED:
                raise _machine_failure(self, status)
        rest = state.rest_t, state.rest_x, state.rest_v, state.hc_rest_t
        self._machine.phase_ends(self._machine_parameters, self.settings.rtol, self._atol, machine_state, 0.0, 1.0)
        state.rest_t, state.rest_x, state.rest_v, state.hc_rest_t = rest  # a rest goes on
        self._warn_if_untrusted(whole=True)
        x_out, v_out = _grid_values(self._machine.fill_grid, self._parameters, self._load, points, n_points, grid)
        return *world_grid(self.ground, self.ball.R, grid, x_out, v_out), world_events(self.ground,
                                                                                       _events(events, n_events))

    def _report_sundials_warnings(self) -> None:
        logs, self._unreported = self._unreported, ()
        for log in logs:
            for warning in log.new_warnings():
                _issue(self.held_warnings, warning)


def _grid_values(compiled_fill, parameters, load: float, points: np.ndarray, n_points: int, grid: np.ndarray):
    """The machine's (x, v) at the times grid from its step ends points[:n_points].

    The compiled engine's fill, or dense_output.interpolate in numpy (on a vibrating ground, its float fill run
    interpreted: the ground's flows take floats).
    """
    if compiled_fill is None and parameters.ground_amplitude == 0.0:
        return interpolate(parameters, load, points[:n_points], grid)
    x_out, v_out = np.empty_like(grid), np.empty_like(grid)
    (compiled_fill or fill_grid)(parameters, load, points, n_points, grid, x_out, v_out)
    return x_out, v_out


def checked_start(ball: Ball, h0, v0, t0, F_ext, settings: CvodeSettings) -> tuple[float, float, float, float]:
    """(h0, v0, t0, F_ext) as floats, each checked as BallIntegrator checks its start; ValueError names a bad one."""
    t0 = validation.finite("t0", t0, "s")
    limits.check_scene(ball, h0, v0, F_ext, t0, rtol=settings.rtol)  # each value checked and named there
    h0, v0, F_ext = float(h0), float(v0), float(F_ext)
    limits.check_cvode_settings(ball, h0, settings.atol, settings.max_step, t0)
    check_resolvable(ball, t0)
    return h0, v0, t0, F_ext


def _issue(held: list | None, warning: Warning) -> None:
    """warning issued at the user's line (held None), or held for the FMU slave (BallIntegrator.held_warnings)."""
    if held is None:
        warn_at_caller(warning)
    else:
        held.append(warning)


def compiled_arrays(integrator: BallIntegrator) -> tuple:
    """(engine, event rows, scratch rows): what the compiled machine's advance takes besides the state."""
    return integrator._engine, integrator._event_rows, integrator._scratch


def finish_advance(integrator: BallIntegrator, status: int) -> None:
    """What BallIntegrator.advance does after its machine's call, for a call made by a C caller (fmu/c_layer.py).

    A failure status raises its SolverError; the accuracy warning is checked, SUNDIALS' warnings read.
    """
    integrator._unreported = integrator._logs
    try:
        if status != machine.DONE:
            raise _machine_failure(integrator, status)
        integrator._warn_if_untrusted(whole=False)
    finally:
        integrator._report_sundials_warnings()


def _machine_failure(integrator: BallIntegrator, status: int) -> SolverError:
    """The error the machine's failure status stands for, with where it failed (the state's fail_* fields)."""
    state, mode, R = integrator._state, integrator.mode, integrator.ball.R
    t, x = float(state.fail_t), float(state.fail_x)
    method = integrator.methods[mode]
    if status == machine.TOO_MANY_STEPS:
        return SolverError(f"CVODE ({method}) took more than {MAX_STEPS_PER_PHASE} steps in one "
                           f"{mode.name.lower()} phase, at t = {t!r} s: "
                           + too_many_steps_cause(integrator.settings, method, mode, MAX_STEPS_PER_PHASE))
    if status == machine.STEPPED_OVER:
        return SolverError(f"CVODE stepped over an {'impact' if mode == Mode.FLIGHT else 'departure'} unseen "
                           f"near t = {t!r} s (h = {R + x!r} m, R = {R!r} m); "
                           "the result would be wrong: tighten rtol/atol or set max_step")
    message = integrator._solvers[mode].message(int(state.fail_flag))
    return SolverError(f"CVODE failed at t = {t!r} s ({mode.name.lower()}, h = {integrator.h!r} m, "
                       f"v = {integrator.v!r} m/s): {message}")


# x = h - R is exactly 0 where a phase starts (at each event). CVODE takes a root function that
# is 0 at the start as inactive until it turns non-zero, and then misses the crossing (the ball
# fell through the floor); one that turns 0 later is a root (an "impact" on the way up). So
# x == 0 counts as the mode's own side: the crossing is where the ball truly leaves it.
def _own_side(mode: Mode) -> float:
    return _OWN_SIDE if mode == Mode.FLIGHT else -_OWN_SIDE


def _root_directions(mode: Mode) -> list[int]:
    """h - R: an impact downwards, a departure upwards; v: every extremum; the rest margin: turning positive."""
    return [-1 if mode == Mode.FLIGHT else 1, 0, 1]


def _events(rows: np.ndarray, count: int) -> list[Event]:
    """The machine's event rows (t, kind, v) as Events."""
    if count == 0:  # most of an FMU's advances
        return []
    return [Event(t, EVENT_KINDS[int(kind)], v) for t, kind, v in rows[:count].tolist()]  # tolist: Python floats
