"""BallIntegrator: CVODE advanced phase by phase, with contact and departure found by root-finding.

Each mode has its own CVODE solver (solvers/stepper.py: either engine), right-hand side and
terminal root function (h - R, with direction -1 in flight and +1 in contact). At each root the
integrator switches mode and re-initialises CVODE at the event, so no step ever straddles the
discontinuity. The decisions around CVODE (scales, rests, phases in closed form, the polish of an
event) are the plain functions of solvers/phases.py.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from .. import limits, validation
from ..limits import check_resolvable, resolvable_until
from ..physics import Ball, Mode, gap_acceleration, load_value
from . import engines, machine, phases, stepper
from . import state as state_checks
from .dense_output import interpolate, step_state
from .engines import choose_engine
from .exact import time_to_departure, velocity_at_departure
from .result import DEPARTURE, IMPACT, Event
from .settings import CvodeSettings, choose_method, hop_tolerance
from .state import IntegratorState, RestartPoint
from .stepper import SolverError

_CV_ROOT_RETURN = 2
# The value the root function h - R takes at h == R: the mode's own side (see _own_side).
_OWN_SIDE = 1e-300
_STEP_HORIZON = 1.0  # s; see advance()
_MAX_STEPS_PER_CALL = 1_000_000
PROGRESS_STEPS = 20_000  # CVODE steps per call of the phase machine: then Python runs (progress, Ctrl-C)
_SCRATCH_ROWS = 512  # step ends the compiled engine hands over at a time
# A phase that needs more steps than this is a method fighting stiffness (Adams creeping through
# an over-damped contact on a k = 1e12 spring): fail with a reason instead of running for hours.
MAX_STEPS_PER_PHASE = 500_000


class BallIntegrator:
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

    Raises
    ------
    ValueError
        A value outside its range (naming it), or contacts too short to resolve in double
        precision at t0 (see check_resolvable).

    Examples
    --------
    >>> from bouncingball import Ball
    >>> from bouncingball.solvers.cvode import BallIntegrator
    >>> integrator = BallIntegrator(Ball(), h0=2.0, v0=0.0)
    >>> [str(event.kind) for event in integrator.advance(1.0)]
    ['impact', 'departure']
    >>> state = integrator.get_state()  # roll back later with set_state(state)

    Notes
    -----
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

    Change F_ext between advances; a state restored by set_state(get_state()) continues bit for bit.
    """

    # integrate_grid tells it the time reached at its start and then every PROGRESS_STEPS steps or so
    progress: Callable[[float], None] | None = None

    def __init__(self, ball: Ball, h0: float, v0: float, t0: float = 0.0, F_ext: float = 0.0,
                 settings: CvodeSettings | None = None, expected_steps: float | None = None) -> None:
        self.ball = ball
        self.settings = settings or CvodeSettings()
        if self.settings.method == "auto":
            # The parabola of flight is never stiff, and Adams integrates it exactly in a few steps.
            self.methods = {Mode.FLIGHT: "Adams", Mode.CONTACT: choose_method(ball)}
        else:
            self.methods = dict.fromkeys(Mode, self.settings.method)
        h0 = validation.finite("h0", h0, "m")
        v0 = validation.finite("v0", v0, "m/s")
        t0 = validation.finite("t0", t0, "s")
        F_ext = validation.finite("F_ext", F_ext, "N")
        limits.check_scene(ball, h0, v0, F_ext, t0)
        self.resolvable_until = resolvable_until(ball)
        check_resolvable(ball, t0)
        self._cvode_called = False
        loaded, started = engines.loaded(), time.perf_counter()
        self.engine, self.engine_reason = choose_engine(self.settings.engine, expected_steps)
        # The phase's frame: CVODE's time is t - origin, its state (x / length, v / speed); see _start_frame.
        self._frames = {mode: [0.0, 1.0, 1.0] for mode in Mode}  # origin, length, speed
        s = self.settings
        self._solvers = {mode: stepper.acquire(self.engine, ball, mode, self.methods[mode], s.rtol, s.max_step,
                                               _MAX_STEPS_PER_CALL, self._own_side(mode),
                                               self._root_directions(mode), MAX_STEPS_PER_PHASE)
                         for mode in Mode}
        # s: the engine's first use in the process (its import, and its first CVODE objects); 0 after
        self.first_use_time = 0.0 if self.engine in loaded else time.perf_counter() - started
        self.set_state(IntegratorState(t=t0, h=h0, v=v0, mode=ball.initial_mode(h0, v0, F_ext), F_ext=F_ext,
                                       t_start=t0))

    # --- CVODE set-up ---------------------------------------------------------------------
    # x = h - R is exactly 0 where a phase starts (at each event). CVODE takes a root function that
    # is 0 at the start as inactive until it turns non-zero, and then misses the crossing (the ball
    # fell through the floor); one that turns 0 later is a root (an "impact" on the way up). So
    # x == 0 counts as the mode's own side: the crossing is where the ball truly leaves it.
    @staticmethod
    def _own_side(mode: Mode) -> float:
        return _OWN_SIDE if mode == Mode.FLIGHT else -_OWN_SIDE

    @staticmethod
    def _root_directions(mode: Mode) -> list[int]:
        """h - R: an impact downwards, a departure upwards; v: every extremum; the rest margin: turning positive."""
        return [-1 if mode == Mode.FLIGHT else 1, 0, 1]

    def _too_many_steps(self, mode: Mode, t: float) -> SolverError:
        return SolverError(
            f"CVODE ({self.methods[mode]}) took more than {MAX_STEPS_PER_PHASE} steps in one "
            f"{mode.name.lower()} phase, at t = {t!r} s: the problem is stiff for this method; "
            "use method 'BDF' (or 'auto')")

    @property
    def hop_tolerance(self) -> float:
        """The highest hop [m] merged into the contact around it at the current F_ext; see hop_tolerance()."""
        return hop_tolerance(self.ball, self.settings.rtol, self.settings.atol, self._F_ext)

    def _start_frame(self) -> tuple[float, float, float]:
        """Fix the current phase's frame at the current state; (origin [s], length [m], speed [m/s]).

        Scales from phases.frame.
        """
        s, mode = self.settings, self._mode
        length, speed = phases.frame(self.ball.parameters, mode, self._x, self._v, self._load, s.rtol,
                                     0.0 if s.atol is None else s.atol)
        self._frames[mode][:] = self._t, length, speed
        self._solvers[mode].set_frame(length, speed, self.hop_tolerance)
        return self._t, length, speed

    # --- read-only view --------------------------------------------------------------------
    @property
    def t(self) -> float:
        """Current time [s]."""
        return self._t

    @property
    def h(self) -> float:
        """Height of the centre [m] at t."""
        return self.ball.R + self._x

    @property
    def v(self) -> float:
        """Velocity [m/s] at t, positive upwards."""
        return self._v

    @property
    def mode(self) -> Mode:
        """The mode held at t: flight or contact."""
        return self._mode

    @property
    def impacts(self) -> int:
        """Impacts so far."""
        return self._impacts

    @property
    def departures(self) -> int:
        """Departures so far."""
        return self._departures

    @property
    def rhs_calls(self) -> int:
        """Right-hand-side evaluations so far."""
        return self._rhs_calls + self._nfev_since_init

    @property
    def steps(self) -> int:
        """CVODE's internal steps so far."""
        return self._steps

    @property
    def F_ext(self) -> float:
        """External force [N], positive upwards, held constant until changed; setting it restarts CVODE."""
        return self._F_ext

    @F_ext.setter
    def F_ext(self, value: float) -> None:
        value = validation.finite("F_ext", value, "N")
        if value != self._F_ext:
            self._F_ext = value
            self._sync_F_ext()
            self._reinit_needed()

    @property
    def acceleration(self) -> float:
        """dv/dt [m/s2] at t in the current mode."""
        ball = self.ball
        return gap_acceleration(self._x, self._v, self._mode, self._load, ball.m, ball.k, ball.b)

    @property
    def contact_force(self) -> float:
        """Force of the ground on the ball [N] at t, positive upwards; zero in flight."""
        return 0.0 if self._mode == Mode.FLIGHT else -self.ball.k * self._x - self.ball.b * self._v

    @property
    def rest_time(self) -> float | None:
        """Start of the current contact if it can never again lift the ball above R + hop_tolerance, else None.

        F_ext is taken as held constant from now on.
        """
        if self._at_rest():
            return self._last_impact_time if self._last_impact_time is not None else self._t_start
        return None

    # --- state ---------------------------------------------------------------------------------
    def get_state(self) -> IntegratorState:
        """A snapshot to resume from; taking it does not disturb the integration.

        It holds the point where CVODE last restarted (see RestartPoint): set_state integrates again
        from there, so a restored snapshot continues bit for bit as the run it was taken from, in
        this integrator or a fresh one with the same ball and settings.
        """
        return IntegratorState(t=self._t, h=self.h, v=self._v, mode=self._mode, F_ext=self._F_ext,
                               impacts=self._impacts, departures=self._departures,
                               last_impact_time=self._last_impact_time, t_start=self._t_start,
                               rhs_calls=self.rhs_calls, steps=self._steps, gap=self._x, restart=self._restart)

    def set_state(self, state: IntegratorState) -> None:
        """Resume from state (one of get_state()); ValueError names a bad field, and then nothing changed.

        With a restart point, CVODE restarts there and integrates to state.t again (at most the
        current phase), then the state is exactly the one taken.
        """
        checked = state_checks.checked(self.ball, state)
        t, x, v, mode, F_ext = checked.point
        counts, t_start = checked.counts, checked.t_start
        check_resolvable(self.ball, t)
        previous = self.get_state() if hasattr(self, "_restart") else None
        if checked.restart_point is None:
            self._restart_at((t, x, v, mode), F_ext, counts, t_start)
            return
        self._restart_at(checked.restart_point, F_ext, checked.restart_counts, t_start)
        try:
            self._advance(t)
        except (SolverError, ValueError):
            if previous is not None:
                self.set_state(previous)
            raise
        finally:
            self._report_sundials_warnings()
        if (self._x, self._v) != (x, v):
            # Not where this restart point leads (a state made by hand, or one a Taylor step within ulps
            # of an earlier target reached): CVODE would continue another trajectory, so it restarts at
            # the state itself, which continues within the tolerance.
            self._restart_at((t, x, v, mode), F_ext, counts, t_start)
            return
        # The counters as they were: CVODE's step history is the original's.
        self._impacts, self._departures, self._last_impact_time, rhs_calls, self._steps = counts
        self._rhs_calls = rhs_calls - self._nfev_since_init

    def _restart_at(self, point, F_ext: float, counts, t_start: float) -> None:
        """Set the state (t, x, v, mode), F_ext and the counters; CVODE restarts there."""
        (self._t, self._x, self._v, self._mode), self._F_ext, self._t_start = point, F_ext, t_start
        self._impacts, self._departures, self._last_impact_time, self._rhs_calls, self._steps = counts
        self._nfev_since_init = 0
        self._sync_F_ext()
        self._reinit_needed()

    def _sync_F_ext(self) -> None:
        """The load m g - F_ext for the right-hand side; the compiled callbacks read both from their parameters."""
        self._load = load_value(self._F_ext, self.ball.m, self.ball.g)
        for solver in self._solvers.values():
            solver.F_ext = self._F_ext

    def close(self) -> None:
        """Give the CVODE objects back to the process's pool for the next integrator; unusable after.

        simulate does it; an integrator never closed frees its CVODE objects when collected.
        """
        solvers, self._solvers = self._solvers, None
        for solver in (solvers or {}).values():
            stepper.release(solver)

    def _reinit_needed(self) -> None:
        """CVODE restarts at the current state: it becomes the restart point (see get_state)."""
        self._rhs_calls += self._nfev_since_init
        self._nfev_since_init = 0
        self._needs_init = True
        self._segment = None
        self._event_pending = None
        self._rest_from = None
        self._restart = RestartPoint(self._t, self._x, self._v, self._mode, self._impacts, self._departures,
                                     self._last_impact_time, self._rhs_calls, self._steps)

    def _init_phase(self):
        """Restart CVODE at the current state in the current mode."""
        solver = self._solvers[self._mode]
        _, length, speed = self._start_frame()
        with solver.log.capturing():
            solver.init_step(0.0, np.array([self._x / length, self._v / speed]))
        self._cvode_called = True
        self._needs_init = False
        self._step_start = (self._t, self._x, self._v)
        return solver

    # --- integration -------------------------------------------------------------------------
    def advance(self, t_target: float, stop_at_event: bool = False) -> list[Event]:
        """Integrate to t_target [s], resolving every impact and departure on the way.

        CVODE takes one internal step at a time, and its steps do not depend on the sequence of
        targets; a target inside the last step is read off the step's dense output, so a short
        advance usually costs no CVODE call at all. With stop_at_event, it returns at the first
        impact or departure before t_target instead, with t the event's time and the mode switched
        (an FMI 3.0 early return); an event at t_target itself is left to the next advance.
        """
        try:
            return self._advance(float(t_target), stop_at_event)
        finally:
            self._report_sundials_warnings()

    def _advance(self, t_target: float, stop_at_event: bool = False) -> list[Event]:
        if not t_target >= self._t:
            raise ValueError(f"t_target = {t_target!r} s is not allowed: it must be >= the current time {self._t!r} s")
        if t_target > self.resolvable_until:
            check_resolvable(self.ball, t_target)
        events: list[Event] = []
        while self._t < t_target:
            segment = self._segment
            if segment is not None:
                mode, start, end = segment
                if t_target <= end[0]:
                    x, v = step_state(self.ball.parameters, self._load, mode, *start, *end, t_target)
                    self._t, self._x, self._v = t_target, float(x), float(v)
                    break
                if self._event_pending is not None:
                    self._t, self._x, self._v = self._event_pending
                    events.append(self._switch_mode())
                    if stop_at_event:
                        break
                    continue
            if self._rest_from is None and self._needs_init and self._at_rest():
                self._rest_from = (self._t, self._x, self._v)
            if self._rest_from is not None:
                t0, x0, v0 = self._rest_from
                x, v = self.ball.gap_flow(Mode.CONTACT, x0, v0, t_target - t0, self._F_ext)
                self._t, self._x, self._v = t_target, float(x), float(v)
                break
            if self._close_enough(t_target):
                break
            if self._needs_init and (event := self._event_in_closed_form()) is not None:
                self._segment = (self._mode, (self._t, self._x, self._v), event)
                self._event_pending = event
                continue
            solver = self._init_phase() if self._needs_init else self._solvers[self._mode]
            # The far target only orients CVODE and bounds its first step: the same for every
            # way of cutting the interval.
            origin, length, speed = self._frames[self._mode]
            tau_before = self._step_start[0] - origin
            result = solver.step(tau_before + _STEP_HORIZON, method="onestep")
            self._cvode_called = True
            self._check(result)
            self._nfev_since_init = result.nfev
            tau, x, v = float(result.t), length * float(result.y[0]), speed * float(result.y[1])
            end = (origin + tau, x, v)
            if result.status == _CV_ROOT_RETURN:
                roots = solver.roots_found()
                if roots[0]:
                    tau, v = phases.polish_event(self.ball.parameters, self._mode, self._load, length, tau_before,
                                                 tau, x, v)
                    end = self._event_pending = (origin + tau, 0.0, v)
                elif roots[2]:
                    self._rest_from = end
            else:
                self._steps += 1
            if self._event_pending is None:
                self._check_side(end[0], x)
            self._segment = (self._mode, self._step_start, end)
            self._step_start = end
        return events

    def integrate_grid(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[Event]]:
        """Integrate through the increasing output times grid (grid[0] = current time).

        CVODE returns each internal step, phase by phase; the grid values come from the same
        dense output as in advance(), evaluated for all grid points in one pass at the end,
        which costs far less per output point than asking CVODE for each one.
        """
        try:
            return self._integrate_grid(np.asarray(grid, dtype=float))
        finally:
            self._report_sundials_warnings()

    def _integrate_grid(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[Event]]:
        t_end = float(grid[-1])
        check_resolvable(self.ball, t_end)
        self._reinit_needed()
        run_phases, fill_grid = stepper.phase_machine(self.engine)
        last_impact = math.nan if self._last_impact_time is None else self._last_impact_time
        state = machine.new_state(self._t, self._x, self._v, int(self._mode), self._load, self.hop_tolerance,
                                  self._impacts, self._departures, last_impact, self._steps, self._rhs_calls)
        points, events, scratch = np.empty((256, 4)), np.empty((16, 3)), np.empty((_SCRATCH_ROWS, 5))
        points[0] = self._t, self._x, self._v, int(self._mode)
        n_points, n_events = 1, 0
        engine = tuple(self._solvers[mode].handle() for mode in Mode)
        s = self.settings
        atol = 0.0 if s.atol is None else s.atol
        while True:
            if self.progress is not None:
                self.progress(float(state[machine.T]))
            status, points, n_points, events, n_events = run_phases(
                engine, self.ball.parameters, s.rtol, atol, state, t_end, points, n_points, events, n_events, scratch,
                PROGRESS_STEPS)
            self._cvode_called = True
            if status == machine.DONE:
                break
            if status == machine.HANDOFF:
                points, n_points, events, n_events = self._phase_on_exact_flow(state, t_end, points, n_points,
                                                                               events, n_events)
            elif status != machine.RETURNED:
                raise self._machine_failure(status, state)
        self._t, self._x, self._v = float(state[machine.T]), float(state[machine.X]), float(state[machine.V])
        self._mode = Mode(int(state[machine.MODE]))
        self._impacts, self._departures = int(state[machine.IMPACTS]), int(state[machine.DEPARTURES])
        last_impact = float(state[machine.LAST_IMPACT])
        self._last_impact_time = None if math.isnan(last_impact) else last_impact
        self._steps, self._rhs_calls = int(state[machine.STEPS]), int(state[machine.RHS_CALLS])
        self._reinit_needed()
        if not math.isnan(state[machine.REST_T]):
            self._rest_from = (float(state[machine.REST_T]), float(state[machine.REST_X]),
                               float(state[machine.REST_V]))
        points = points[:n_points]
        if fill_grid is None:
            x_out, v_out = interpolate(self.ball.parameters, self._load, points, grid)
        else:
            x_out, v_out = np.empty_like(grid), np.empty_like(grid)
            fill_grid(self.ball.parameters, self._load, points, n_points, grid, x_out, v_out)
        kinds = (IMPACT, DEPARTURE)
        return self.ball.R + x_out, v_out, [Event(float(t), kinds[int(kind)], float(v))
                                            for t, kind, v in events[:n_events]]

    def _phase_on_exact_flow(self, state, t_end, points, n_points, events, n_events):
        """The phase the machine handed back (phases.UNDECIDED): a contact decided by the search for its departure.

        A rest if it never departs (the machine takes it on); its departure in closed form if CVODE
        cannot resolve it or F_ext lifts the ball; else CVODE integrates it after all.
        """
        t, x, v, load, hop = (float(state[i]) for i in (machine.T, machine.X, machine.V, machine.LOAD, machine.HOP))
        parameters, rtol = self.ball.parameters, self.settings.rtol
        departs = not math.isinf(tau := time_to_departure(self.ball, x, v, self._F_ext))
        if not departs and phases.rest_decision(parameters, Mode.CONTACT, x, v, load, hop, rtol) == phases.UNDECIDED:
            state[machine.RESTING] = 1.0
        elif departs and phases.closed_form(parameters, Mode.CONTACT, x, v, load, hop, rtol) == phases.UNDECIDED:
            points, n_points = machine._record(points, n_points, t, x, v, Mode.CONTACT)
            if t + tau <= t_end:
                v_departure = velocity_at_departure(self.ball, x, v, tau, self._F_ext)
                points, n_points = machine._record(points, n_points, t + tau, 0.0, v_departure, Mode.CONTACT)
                state[machine.T], state[machine.X], state[machine.V] = t + tau, 0.0, v_departure
                events, n_events = machine._switch_mode(state, events, n_events)
            else:
                x_end, v_end = self.ball.gap_flow(Mode.CONTACT, x, v, t_end - t, self._F_ext)
                points, n_points = machine._record(points, n_points, t_end, float(x_end), float(v_end), Mode.CONTACT)
                state[machine.T], state[machine.X], state[machine.V] = t_end, x_end, v_end
        else:
            state[machine.DECIDED] = 1.0  # CVODE integrates it
        return points, n_points, events, n_events

    def _machine_failure(self, status: int, state) -> SolverError:
        mode, t = Mode(int(state[machine.MODE])), float(state[machine.FAIL_T])
        if status == machine.TOO_MANY_STEPS:
            return self._too_many_steps(mode, t)
        if status == machine.STEPPED_OVER:
            return self._stepped_over(mode, t, float(state[machine.FAIL_X]))
        h, v = self.ball.R + float(state[machine.X]), float(state[machine.V])
        message = self._solvers[mode].message(int(state[machine.FAIL_FLAG]))
        return SolverError(f"CVODE failed at t = {t!r} s ({mode.name.lower()}, h = {h!r} m, v = {v!r} m/s): {message}")

    def _at_rest(self) -> bool:
        decision = phases.rest_decision(self.ball.parameters, self._mode, self._x, self._v, self._load,
                                        self.hop_tolerance, self.settings.rtol)
        return decision == 1 or (decision == phases.UNDECIDED
                                 and math.isinf(time_to_departure(self.ball, self._x, self._v, self._F_ext)))

    def _event_in_closed_form(self) -> tuple[float, float, float] | None:
        """The event ending the phase from the current state if CVODE is not to integrate it (phases.closed_form)."""
        parameters, x, v = self.ball.parameters, self._x, self._v
        closed = phases.closed_form(parameters, self._mode, x, v, self._load, self.hop_tolerance, self.settings.rtol)
        if closed == 1:
            tau, v_impact = phases.flight_impact(parameters, x, v, self._load)
            return self._t + tau, 0.0, v_impact
        if closed == phases.UNDECIDED:
            tau = time_to_departure(self.ball, x, v, self._F_ext)
            if not math.isinf(tau):
                return self._t + tau, 0.0, velocity_at_departure(self.ball, x, v, tau, self._F_ext)
        return None

    def _report_sundials_warnings(self) -> None:
        if self._cvode_called:
            self._cvode_called = False
            for solver in self._solvers.values():
                solver.log.report(stacklevel=4)

    def _check_side(self, t: float, x: float) -> None:
        """A step end (gap x [m] at t) must lie on the mode's side of R: else CVODE stepped over an event unseen."""
        margin = phases.side_margin(self.hop_tolerance, self.settings.rtol, self._frames[self._mode][1])
        if phases.on_wrong_side(self._mode, x, margin):
            raise self._stepped_over(self._mode, t, x)

    def _stepped_over(self, mode: Mode, t: float, x: float) -> SolverError:
        R = self.ball.R
        return SolverError(f"CVODE stepped over an {'impact' if mode == Mode.FLIGHT else 'departure'} unseen near "
                           f"t = {t!r} s (h = {R + x!r} m, R = {R!r} m); "
                           "the result would be wrong: tighten rtol/atol or set max_step")

    def _close_enough(self, t_target: float) -> bool:
        """Within a few ulps of t_target CVODE refuses to step (CV_TOO_CLOSE): finish by Taylor."""
        dt = t_target - self._t
        if dt > 32.0 * math.ulp(max(abs(t_target), abs(self._t), 1e-300)):
            return False
        x, v = phases.taylor_step(self.ball.parameters, self._mode, self._x, self._v, self._load, dt)
        self._t, self._x, self._v = t_target, x, v
        return True

    def _check(self, result) -> None:
        if result.status < 0 and self._solvers[self._mode].exceeded:
            raise self._too_many_steps(self._mode, float(np.atleast_1d(result.t)[-1]))
        if result.status < 0:
            t = float(np.atleast_1d(result.t)[-1])
            raise SolverError(f"CVODE failed at t = {t!r} s ({self._mode.name.lower()}, "
                              f"h = {self.h!r} m, v = {self._v!r} m/s): {result.message}")

    def _switch_mode(self) -> Event:
        if self._mode == Mode.FLIGHT:
            self._mode, self._impacts, self._last_impact_time = Mode.CONTACT, self._impacts + 1, self._t
            event = Event(self._t, IMPACT, self._v)
        else:
            self._mode, self._departures = Mode.FLIGHT, self._departures + 1
            event = Event(self._t, DEPARTURE, self._v)
        self._reinit_needed()
        return event
