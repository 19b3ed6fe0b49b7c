"""SUNDIALS CVODE (through scikit-sundae) with contact and departure found by root-finding.

Each mode has its own CVODE object, right-hand side and terminal event function (h - R, with
direction -1 in flight and +1 in contact). At each root the integrator switches mode and
re-initialises CVODE at the event, so no step ever straddles the discontinuity.
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass

import numpy as np
from sksundae.cvode import CVODE

from .. import validation
from ..physics import Ball, Mode, mode_acceleration
from . import sksundae_events
from .dense_output import interpolate, step_state
from .exact import time_to_departure, time_to_impact, velocity_at_departure
from .result import (
    DEPARTURE,
    IMPACT,
    Event,
    SimulationResult,
    SolverStats,
    output_grid,
)
from .sundials_log import SundialsLog

METHODS = ("auto", "Adams", "BDF")
ENGINES = ("auto", "compiled", "sksundae")
# At these values the article's height error is ~2e-10 m (limit 1e-6), for 10% more steps than
# rtol 1e-10 (which gave 3e-8 m); an undamped ball keeps its height error within 1e-6 of its
# scale over ~50 contacts, its error growing with the square of their number.
DEFAULT_RTOL = 1e-11
DEFAULT_ATOL = 1e-12
# The contact oscillator is stiff for Adams when it is strongly over-damped (fast and slow rates
# far apart). A high natural frequency alone is not: a bounce must be resolved for accuracy
# anyway, where Adams beats BDF (an undamped k = 1e8 N/m ball over 39 contacts: 1.1e-9 m in 1707
# steps against 5.7e-8 m in 3842), and a rest, where BDF's large steps paid off, is taken in
# closed form.
STIFF_DAMPING_RATIO = 2.0

_CV_ROOT_RETURN = 2
_EPS = 2.0**-52
# Measured: at the default tolerances the departure speed stays within 1e-8 down to contacts of
# 30 ulps of t (at 10 ulps CVODE fails its error test); 1e4 keeps a margin of 300.
MIN_CONTACT_ULPS = 1e4
# A contact deflecting the ball by less than this many tolerances of h is taken in closed form.
CONTACT_RESOLUTION = 100.0
# ... and one deflecting it by less than this many ulps of R: CVODE carries h = R + deflection, so
# each step rounds the deflection to ulp(R), and its error test, seeing that noise, shrinks the
# steps and adds more of it. Measured on one undamped contact (k = 1e12 N/m, 1 m/s): the departure
# speed is off by 1e-9 to 3e-9 at 1e9 ulps, 1e-7 at 1.4e7 ulps (1,400 steps at rtol 1e-11) and 6e-3
# at 1.4e6 ulps (100,000 steps at rtol 1e-12); an undamped ball keeps each error. At 1e10 ulps it
# stays below 1e-9, and every built-in scene's contacts deflect by more than 1e11 ulps.
MIN_DEFLECTION_ULPS = 1e10
_STEP_HORIZON = 1.0  # s; see advance()
_MAX_STEPS_PER_CALL = 1_000_000
# A phase that needs more steps than this is a method fighting stiffness (Adams creeping through
# an over-damped contact on a k = 1e12 spring): fail with a reason instead of running for hours.
MAX_STEPS_PER_PHASE = 500_000


class SolverError(RuntimeError):
    """CVODE failed; the message carries its reason."""


def choose_engine(engine: str = "auto") -> tuple[str, str]:
    """The engine that runs ("compiled" or "sksundae") and why.

    "auto" takes the compiled engine when numba is installed and scikit-sundae's SUNDIALS library
    can be bound, else scikit-sundae's own; "compiled" raises ImportError where it cannot run.
    """
    engine = validation.choice("engine", engine, ENGINES)
    if engine == "sksundae":
        return "sksundae", "requested"
    try:
        from . import compiled
    except ImportError as error:
        reason = f"numba is not installed ({error}): pip install 'bouncingball[fast]'"
    except Exception as error:  # numba is there but cannot compile the engine (an incompatible release)
        reason = f"numba could not compile the engine ({type(error).__name__}: {error})".splitlines()[0]
    else:
        reason = compiled.unavailable_reason()
        if reason is None:
            version = compiled.library().version
            return "compiled", "requested" if engine == "compiled" else f"numba and SUNDIALS {version} available"
    if engine == "compiled":
        raise ImportError(f"engine 'compiled' is not available: {reason}")
    return "sksundae", f"compiled engine unavailable: {reason}"


def choose_method(ball: Ball) -> str:
    """The rule behind method="auto": BDF for a stiff contact, Adams otherwise.

    Stiff means damping ratio >= 2 (over-damped, the fast and slow rates differ by >= 14x).
    Flight is never stiff.
    """
    return "BDF" if ball.damping_ratio >= STIFF_DAMPING_RATIO else "Adams"


@dataclass(frozen=True)
class CvodeSettings:
    """rtol, atol [-, m or m/s], method ("auto", "Adams", "BDF"), max_step [s] (0: unbounded) and engine.

    engine: "sksundae" (scikit-sundae's CVODE with Python callbacks), "compiled" (the same CVODE
    library driven by compiled callbacks and a compiled stepping loop, needs numba) or "auto"
    (compiled where it can run); see choose_engine.
    """

    rtol: float = DEFAULT_RTOL
    atol: float = DEFAULT_ATOL
    method: str = "auto"
    max_step: float = 0.0
    engine: str = "auto"

    def __post_init__(self) -> None:
        """Check every setting before the settings exist."""
        object.__setattr__(self, "rtol", validation.in_range("rtol", self.rtol, 0.0, 1.0))
        object.__setattr__(self, "atol", validation.positive("atol", self.atol))
        object.__setattr__(self, "method", validation.choice("method", self.method, METHODS))
        object.__setattr__(self, "max_step", validation.non_negative("max_step", self.max_step, "s"))
        object.__setattr__(self, "engine", validation.choice("engine", self.engine, ENGINES))


@dataclass(frozen=True)
class IntegratorState:
    """Everything needed to resume an integration exactly."""

    t: float
    h: float
    v: float
    mode: Mode
    F_ext: float
    impacts: int = 0
    departures: int = 0
    last_impact_time: float | None = None
    t_start: float = 0.0
    rhs_calls: int = 0
    steps: int = 0


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

    Change F_ext between advances; set_state(get_state()) resumes within the tolerance of the original run.
    """

    def __init__(self, ball: Ball, h0: float, v0: float, t0: float = 0.0, F_ext: float = 0.0,
                 settings: CvodeSettings | None = None) -> None:
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
        self.resolvable_until = resolvable_until(ball)
        check_resolvable(ball, t0)
        resolution = self.settings.atol + self.settings.rtol * ball.R  # CVODE's error of h near R [m]
        # A hop lower than this above R is within CVODE's own error of h: it is taken in closed
        # form, and a contact that can rise no higher than this is at rest.
        self.hop_tolerance = 10.0 * resolution
        self._min_contact_amplitude = max(CONTACT_RESOLUTION * resolution, MIN_DEFLECTION_ULPS * math.ulp(ball.R))
        self._logs = {mode: SundialsLog() for mode in Mode}
        self._cvode_called = False
        self.engine, self.engine_reason = choose_engine(self.settings.engine)
        self._solvers: dict[Mode, CVODE] = {}
        self._event_functions = {}
        for mode in Mode:
            make = self._make_compiled_solver if self.engine == "compiled" else self._make_solver
            self._solvers[mode], self._event_functions[mode] = make(mode)
        self.set_state(IntegratorState(t=t0, h=h0, v=v0, mode=ball.initial_mode(h0, v0, F_ext), F_ext=F_ext,
                                       t_start=t0))

    # --- CVODE set-up ---------------------------------------------------------------------
    def _own_side(self, mode: Mode) -> float:
        # h - R is exactly 0 where a phase starts (h is set to R at each event), and stays 0 over a
        # hop too small to move h off R in double precision. CVODE takes a root function that is 0
        # at the start as inactive until it turns non-zero, and then misses the crossing (the ball
        # fell through the floor); one that turns 0 later is a root (an "impact" on the way up).
        # So h == R counts as the mode's own side: the crossing is where h truly leaves it.
        return math.ulp(self.ball.R) if mode == Mode.FLIGHT else -math.ulp(self.ball.R)

    @staticmethod
    def _root_directions(mode: Mode) -> list[int]:
        """h - R: an impact downwards, a departure upwards; v: every extremum; the rest margin: turning positive."""
        return [-1 if mode == Mode.FLIGHT else 1, 0, 1]

    def _too_many_steps(self, mode: Mode, t: float) -> SolverError:
        return SolverError(
            f"CVODE ({self.methods[mode]}) took more than {MAX_STEPS_PER_PHASE} steps in one "
            f"{mode.name.lower()} phase, at t = {t!r} s: the problem is stiff for this method; "
            "use method 'BDF' (or 'auto')")

    def _atol(self, mode: Mode) -> float:
        """CVODE's absolute tolerance in a mode [m and m/s]."""
        s = self.settings
        if mode == Mode.FLIGHT:
            return s.atol
        # In contact h stays within a deflection of R, so rtol alone asks CVODE for rtol R on h.
        # An atol above that would loosen every contact of a small ball: each departure speed
        # then carries an error that an undamped ball accumulates from bounce to bounce (R = 1
        # mm, 50 bounces: 1.6e-8 m, 1e-6 of its height; 6e-9 m with this bound on h and v).
        return min(s.atol, s.rtol * self.ball.R)

    def _make_compiled_solver(self, mode: Mode):
        """The same CVODE set-up as _make_solver, with the callbacks compiled from physics.py."""
        from .compiled import PhaseSolver

        s = self.settings
        solver = PhaseSolver(self.ball, mode, self.methods[mode], s.rtol, self._atol(mode), s.max_step,
                             _MAX_STEPS_PER_CALL, self.hop_tolerance, self._own_side(mode), self._root_directions(mode),
                             MAX_STEPS_PER_PHASE)
        return solver, None

    def _make_solver(self, mode: Mode):
        ball = self.ball
        jacobian = ball.jacobian(mode)
        R = ball.R
        m, k, b, g = ball.m, ball.k, ball.b, ball.g
        own_side = self._own_side(mode)
        contact = mode == Mode.CONTACT
        hop_tolerance = self.hop_tolerance

        def rhs(t, y, yp):
            # physics computes k (R - h): R - h is exact near R, whereas k R - k h would bury the
            # deflection of a stiff ball (k = 1e12) in the round-off of two 6e10 terms.
            yp[0] = y[1]
            yp[1] = mode_acceleration(y[0], y[1], mode, self._F_ext, m, k, b, R, g)

        def jac(t, y, yp, JJ):
            JJ[:, :] = jacobian

        def event(t, y, out):
            out[0] = y[0] - R if y[0] != R else own_side
            # Under zero net gravity v never changes in flight: a root function identically 0 would
            # only make CVODE warn.
            out[1] = y[1] if contact or ball.effective_gravity(self._F_ext) != 0.0 else 1.0
            if contact and ball.static_deflection(self._F_ext) > 0.0:
                out[2] = ball.rest_margin(y[0], y[1], self._F_ext, hop_tolerance)
            else:
                out[2] = -1.0
            # CVODE evaluates the root functions once per step (and a few times per root found)
            self._phase_evaluations += 1
            if self._phase_evaluations > MAX_STEPS_PER_PHASE:
                raise self._too_many_steps(mode, t)

        event.terminal = [True, False, True]
        event.direction = self._root_directions(mode)
        s = self.settings
        solver = CVODE(rhs, method=self.methods[mode], rtol=s.rtol, atol=self._atol(mode), max_step=s.max_step,
                       eventsfn=event, num_events=3, jacfn=jac, max_num_steps=_MAX_STEPS_PER_CALL)
        return solver, event

    # --- read-only view --------------------------------------------------------------------
    @property
    def t(self) -> float:
        """Current time [s]."""
        return self._t

    @property
    def h(self) -> float:
        """Height of the centre [m] at t."""
        return self._h

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
            self._reinit_needed()
            self._F_ext = value
            self._sync_F_ext()

    @property
    def acceleration(self) -> float:
        """dv/dt [m/s2] at t in the current mode."""
        return self.ball.acceleration(self._h, self._v, self._mode, self._F_ext)

    @property
    def contact_force(self) -> float:
        """Force of the ground on the ball [N] at t, positive upwards; zero in flight."""
        return self.ball.contact_force(self._h, self._v, self._mode)

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

        A restored snapshot restarts CVODE there, so it continues within the tolerance of the
        original run, not bit for bit (CVODE's step history is not part of the snapshot).
        """
        return IntegratorState(t=self._t, h=self._h, v=self._v, mode=self._mode, F_ext=self._F_ext,
                               impacts=self._impacts, departures=self._departures,
                               last_impact_time=self._last_impact_time, t_start=self._t_start,
                               rhs_calls=self.rhs_calls, steps=self._steps)

    def set_state(self, state: IntegratorState) -> None:
        """Resume from state (one of get_state()); ValueError names a bad field, and then nothing changed."""
        t = validation.finite("state t", state.t, "s")
        h, v = validation.finite("state h", state.h, "m"), validation.finite("state v", state.v, "m/s")
        F_ext = validation.finite("state F_ext", state.F_ext, "N")
        t_start = validation.finite("state t_start", state.t_start, "s")
        last_impact = None if state.last_impact_time is None else validation.finite(
            "state last_impact_time", state.last_impact_time, "s")
        counts = [state.impacts, state.departures, state.rhs_calls, state.steps]
        if not all(isinstance(n, numbers.Integral) and not isinstance(n, bool) and n >= 0 for n in counts):
            raise ValueError(f"state counts (impacts, departures, rhs_calls, steps) = {counts} are not allowed: "
                             "they must be integers >= 0")
        try:
            mode = Mode(state.mode)
        except ValueError:
            raise ValueError(f"state mode = {state.mode!r} is not allowed: it must be one of "
                             f"{', '.join(f'{m.value} ({m.name})' for m in Mode)}") from None
        check_resolvable(self.ball, t)
        self._t, self._h, self._v, self._mode, self._F_ext = t, h, v, mode, F_ext
        self._impacts, self._departures = int(state.impacts), int(state.departures)
        self._last_impact_time, self._t_start = last_impact, t_start
        self._rhs_calls, self._steps = int(state.rhs_calls), int(state.steps)
        self._nfev_since_init = 0
        self._sync_F_ext()
        self._reinit_needed()

    def _sync_F_ext(self) -> None:
        """The compiled callbacks read F_ext from their solver's parameters (the Python ones from self)."""
        if self.engine == "compiled":
            for solver in self._solvers.values():
                solver.F_ext = self._F_ext

    def _roots_found(self, mode: Mode) -> list[int]:
        if self.engine == "compiled":
            return self._solvers[mode].roots_found()
        return sksundae_events.roots_found(self._event_functions[mode])

    def _clear_roots(self, mode: Mode) -> None:
        if self.engine != "compiled":
            sksundae_events.clear(self._event_functions[mode])

    def _reinit_needed(self) -> None:
        self._rhs_calls += self._nfev_since_init
        self._nfev_since_init = 0
        self._phase_evaluations = 0
        self._needs_init = True
        self._segment = None
        self._event_pending = None
        self._rest_from = None

    def _init_phase(self) -> CVODE:
        """Restart CVODE at the current state in the current mode."""
        solver = self._solvers[self._mode]
        self._clear_roots(self._mode)
        with self._logs[self._mode].capturing():
            solver.init_step(self._t, np.array([self._h, self._v]))
        self._cvode_called = True
        self._needs_init = False
        self._step_start = (self._t, self._h, self._v)
        return solver

    # --- integration -------------------------------------------------------------------------
    def advance(self, t_target: float) -> list[Event]:
        """Integrate to t_target [s], resolving every impact and departure on the way.

        CVODE takes one internal step at a time, and its steps do not depend on the sequence of
        targets; a target inside the last step is read off the step's dense output, so a short
        advance usually costs no CVODE call at all.
        """
        try:
            return self._advance(float(t_target))
        finally:
            self._report_sundials_warnings()

    def _advance(self, t_target: float) -> list[Event]:
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
                    h, v = step_state(self.ball, self._F_ext, mode, start, end, t_target)
                    self._t, self._h, self._v = t_target, float(h), float(v)
                    break
                if self._event_pending is not None:
                    self._t, self._h, self._v = self._event_pending
                    events.append(self._switch_mode())
                    continue
            if self._rest_from is None and self._needs_init and self._at_rest():
                self._rest_from = (self._t, self._h, self._v)
            if self._rest_from is not None:
                self._t, self._h, self._v = t_target, *self._rest_state(t_target)
                break
            if self._close_enough(t_target):
                break
            if self._needs_init and (event := self._event_in_closed_form()) is not None:
                self._segment = (self._mode, (self._t, self._h, self._v), event)
                self._event_pending = event
                continue
            solver = self._init_phase() if self._needs_init else self._solvers[self._mode]
            # The far target only orients CVODE and bounds its first step: the same for every
            # way of cutting the interval.
            result = solver.step(self._step_start[0] + _STEP_HORIZON, method="onestep")
            self._cvode_called = True
            self._check(result)
            self._nfev_since_init = result.nfev
            end = (float(result.t), float(result.y[0]), float(result.y[1]))
            if result.status == _CV_ROOT_RETURN:
                roots = self._roots_found(self._mode)
                if roots[0]:
                    end = self._event_pending = self._polish_event(self._step_start, end)
                elif roots[2]:
                    self._rest_from = end
                self._clear_roots(self._mode)
            else:
                self._steps += 1
            if self._event_pending is None:
                self._check_side(end[0], end[1], end[1])
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
        t_end = grid[-1]
        check_resolvable(self.ball, t_end)
        times, heights, velocities, modes = [], [], [], []
        events: list[Event] = []

        def record(ts, hs, vs, mode: Mode) -> None:
            """Keep a piece of trajectory in one mode, and move to its last point."""
            times.append(ts)
            heights.append(hs)
            velocities.append(vs)
            modes.append(np.full(len(ts), int(mode)))
            self._t, self._h, self._v = float(ts[-1]), float(hs[-1]), float(vs[-1])

        def record_to(end: tuple[float, float, float], mode: Mode) -> None:
            """A piece from here to end = (t, h, v) on the mode's exact flow."""
            record(np.array([self._t, end[0]]), np.array([self._h, end[1]]), np.array([self._v, end[2]]), mode)

        record(np.array([self._t]), np.array([self._h]), np.array([self._v]), self._mode)
        self._reinit_needed()
        resting = False  # set when CVODE stops at the start of a rest
        while self._t < t_end and not self._close_enough(t_end):
            mode = self._mode
            if resting or self._at_rest():
                self._rest_from = (self._t, self._h, self._v)
                record_to((t_end, *self._rest_state(t_end)), mode)
                break
            event = self._event_in_closed_form()
            if event is not None:
                reached = event[0] <= t_end
                if not reached:
                    h_end, v_end = self.ball.flow(mode, self._h, self._v, t_end - self._t, self._F_ext)
                    event = (t_end, float(h_end), float(v_end))
                record_to(event, mode)
                if reached:
                    events.append(self._switch_mode())
                continue
            self._clear_roots(mode)
            with self._logs[mode].capturing():
                result = self._solvers[mode].solve(np.array([self._t, t_end]), np.array([self._h, self._v]))
            self._cvode_called = True
            self._check(result)
            ts, hs, vs = result.t.copy(), result.y[:, 0].copy(), result.y[:, 1].copy()
            roots = self._roots_found(mode) if result.status == _CV_ROOT_RETURN else [0, 0, 0]
            root, resting = bool(roots[0]), bool(roots[2])
            if root:
                (t0, t1), (h0, h1), (v0, v1) = ts[-2:].tolist(), hs[-2:].tolist(), vs[-2:].tolist()
                ts[-1], hs[-1], vs[-1] = self._polish_event((t0, h0, v0), (t1, h1, v1))
                self._check_step_ends(t0, hs[:-1])
            else:
                self._check_step_ends(float(ts[-1]), hs)
            self._clear_roots(mode)
            # A phase's first point is the previous phase's last: one copy per mode, so that no
            # dense-output segment straddles the switch.
            record(ts, hs, vs, mode)
            self._steps += len(ts) - 1
            self._rhs_calls += int(result.nfev)
            if root:
                events.append(self._switch_mode())
        if self._t > times[-1][-1]:  # finished by a Taylor step within a few ulps of t_end
            record(np.array([self._t]), np.array([self._h]), np.array([self._v]), self._mode)
        h_out, v_out = interpolate(self.ball, self._F_ext, np.concatenate(times), np.concatenate(heights),
                                   np.concatenate(velocities), np.concatenate(modes), grid)
        return h_out, v_out, events

    def _report_sundials_warnings(self) -> None:
        if self._cvode_called:
            self._cvode_called = False
            for log in self._logs.values():
                log.report(stacklevel=4)

    def _at_rest(self) -> bool:
        """In a contact that can no longer lift the ball more than hop_tolerance above R, or never ends.

        The energy bound of contact_is_permanent proves a rest only once the ball's weight holds
        it down by more than its motion; a critically or over-damped ball (or one with no weight
        on the spring) creeps towards its rest height for many spring time constants, which CVODE
        would crawl through at the spring's time scale (500,000 steps for k/m = 8e12 1/s). Such
        a contact has at most one extremum, so the exact flow decides at once whether it ever
        reaches R; so it does for a contact below CVODE's resolution.
        """
        if self._mode != Mode.CONTACT:
            return False
        ball = self.ball
        if ball.contact_is_permanent(self._h, self._v, self._F_ext, self.hop_tolerance):
            return True
        undecided = (ball.damping_ratio >= 1.0 or ball.static_deflection(self._F_ext) <= 0.0
                     or self._contact_below_resolution())
        return undecided and math.isinf(time_to_departure(ball, self._h, self._v, self._F_ext))

    def _rest_state(self, t: float) -> tuple[float, float]:
        """h [m] and v [m/s] at t on a rest, on the contact's exact flow from where the rest began.

        Once at rest the ball's motion is the linear oscillator decaying to the rest height,
        which CVODE would only add its error to: where k/m ulp(R) is comparable to g, h cannot
        even represent the rest height, and the quantised spring force keeps CVODE's steps tiny.
        """
        t0, h0, v0 = self._rest_from
        h, v = self.ball.flow(Mode.CONTACT, h0, v0, t - t0, self._F_ext)
        return float(h), float(v)

    def _contact_below_resolution(self) -> bool:
        """In a contact whose amplitude about the rest height is too small for CVODE to integrate.

        Below CONTACT_RESOLUTION tolerances of h or MIN_DEFLECTION_ULPS ulps of R.

        CVODE controls h to atol + rtol R; a contact that deflects the ball by little more than
        that is integrated from noise (the departure speed of a k = 1e20 N/m, m = 1 g ball
        landing at 1.7 m/s came out 2e-3 too fast), or not at all below ulp(R). Tighter
        tolerances do not help where the rounding of h = R + deflection dominates.
        """
        if self._mode != Mode.CONTACT:
            return False
        ball, y = self.ball, self._h - self.ball.rest_height(self._F_ext)
        amplitude_squared = y * y + self._v * self._v * (ball.m / ball.k)
        return amplitude_squared < self._min_contact_amplitude**2

    def _event_in_closed_form(self) -> tuple[float, float, float] | None:
        """The event (t, R, v) ending the current phase if CVODE cannot resolve the phase, else None.

        A flight whose apex stays within hop_tolerance of R: CVODE cannot tell such a hop from its
        own error (its first steps after a restart are of low order, and it may place the impact
        on the way up or miss it: a chatter of false events, or a fall through the floor). A
        contact below CVODE's resolution (_contact_below_resolution) that ends. A contact that
        cannot hold the ball (F_ext lifts more than its weight: the rest height is above R), which
        always ends, but may creep towards a rest height closer to R than CVODE resolves, where h
        never visibly crosses R (a weightless ball lifted by 1e-6 N stayed at R instead of flying
        4.5e-6 m in 3 s). Each mode's flow is exact, so such a phase is taken in closed form:
        events of the right kind at the right times, the trajectory within the tolerance either way.
        """
        ball, R = self.ball, self.ball.R
        if self._mode == Mode.CONTACT:
            if not (self._contact_below_resolution() or ball.static_deflection(self._F_ext) < 0.0):
                return None
            tau = time_to_departure(ball, self._h, self._v, self._F_ext)
            if math.isinf(tau):
                return None
            return self._t + tau, R, velocity_at_departure(ball, self._h, self._v, tau, self._F_ext)
        if self._h < R:
            return None
        g_eff = ball.effective_gravity(self._F_ext)
        if not g_eff > 0.0:
            return None
        apex = self._h - R + 0.5 * max(self._v, 0.0) ** 2 / g_eff
        if not apex < self.hop_tolerance:
            return None
        tau, v_impact = time_to_impact(self._h - R, self._v, g_eff)
        return self._t + tau, R, v_impact

    def _polish_event(self, start, root):
        """The crossing of h = R that CVODE located at root, to a few ulps of t; h set to R.

        CVODE locates a root to ~100 ulps of t (its tolerance is not settable). At a departure the
        damper's force jumps the acceleration by b v / m, so that time error becomes a velocity
        error of (b/m) v dt: 3e-5 relative for m = 1e-6 kg, b = 64 N s/m at t = 24 s, which
        then grows through every later bounce. Newton on the mode's flow removes it. A grazing
        root (v ~ 0) is kept as CVODE found it.
        """
        ball, mode, F_ext, R = self.ball, self._mode, self._F_ext, self.ball.R
        t_root, h_root, v_root = root
        bound = 400.0 * _EPS * (abs(t_root) + abs(t_root - start[0]))
        tau, h, v = 0.0, h_root, v_root
        for _ in range(4):
            if h == R or v == 0.0:
                break
            tau -= (h - R) / v
            if not abs(tau) <= bound:
                return t_root, h_root, v_root
            h, v = ball.flow(mode, h_root, v_root, tau, F_ext)
        if not abs(h - R) <= 4.0 * math.ulp(R):
            return t_root, h_root, v_root
        return t_root + tau, R, float(v)

    def _check_side(self, t: float, lowest: float, highest: float) -> None:
        """Step ends must lie on the mode's side of R: else CVODE stepped over an event unseen."""
        R, margin = self.ball.R, self.hop_tolerance
        flight = self._mode == Mode.FLIGHT
        if (lowest < R - margin) if flight else (highest > R + margin):
            raise SolverError(f"CVODE stepped over an {'impact' if flight else 'departure'} unseen near "
                              f"t = {t!r} s (h = {float(lowest if flight else highest)!r} m, R = {R!r} m); "
                              "the result would be wrong: tighten rtol/atol or set max_step")

    def _check_step_ends(self, t: float, heights: np.ndarray) -> None:
        """_check_side for a phase's step ends up to t: only the extreme on the side an unseen event would leave."""
        extreme = float(heights.min() if self._mode == Mode.FLIGHT else heights.max())
        self._check_side(t, extreme, extreme)

    def _close_enough(self, t_target: float) -> bool:
        """Within a few ulps of t_target CVODE refuses to step (CV_TOO_CLOSE): finish by Taylor."""
        dt = t_target - self._t
        if dt > 32.0 * math.ulp(max(abs(t_target), abs(self._t), 1e-300)):
            return False
        a = self.acceleration
        self._t, self._h, self._v = t_target, self._h + dt * (self._v + 0.5 * dt * a), self._v + dt * a
        return True

    def _check(self, result) -> None:
        if result.status < 0 and self.engine == "compiled" and self._solvers[self._mode].exceeded:
            raise self._too_many_steps(self._mode, float(np.atleast_1d(result.t)[-1]))
        if result.status < 0:
            t = float(np.atleast_1d(result.t)[-1])
            raise SolverError(f"CVODE failed at t = {t!r} s ({self._mode.name.lower()}, "
                              f"h = {self._h!r} m, v = {self._v!r} m/s): {result.message}")

    def _switch_mode(self) -> Event:
        self._reinit_needed()
        if self._mode == Mode.FLIGHT:
            self._mode, self._impacts, self._last_impact_time = Mode.CONTACT, self._impacts + 1, self._t
            return Event(self._t, IMPACT, self._v)
        self._mode, self._departures = Mode.FLIGHT, self._departures + 1
        return Event(self._t, DEPARTURE, self._v)


def contact_duration(ball: Ball) -> float:
    """pi / omega_d [s]: how long a bouncing contact lasts (inf when the contact is critically or over-damped).

    omega_d = sqrt(k/m - (b/2m)^2). At damping ratio >= 1 a contact never ends by itself.
    """
    sigma = ball.b / (2.0 * ball.m)
    omega_d2 = ball.k / ball.m - sigma * sigma
    return math.pi / math.sqrt(omega_d2) if omega_d2 > 0.0 else math.inf


def resolvable_until(ball: Ball) -> float:
    """The latest time [s] up to which double precision can resolve a contact of this ball.

    Near time t, double precision separates instants 1 ulp (~2.2e-16 t) apart, and CVODE locates
    roots to ~100 ulps. A contact shorter than MIN_CONTACT_ULPS ulps of t cannot be integrated:
    CVODE misses or invents events and the ball gains energy.
    """
    return contact_duration(ball) / (MIN_CONTACT_ULPS * _EPS)


def check_resolvable(ball: Ball, t: float) -> None:
    """Raise ValueError if a contact of this ball cannot be resolved at time t [s]."""
    limit = resolvable_until(ball)
    if abs(t) > limit:
        duration = contact_duration(ball)
        raise ValueError(
            f"k = {ball.k!r} N/m with m = {ball.m!r} kg is not allowed up to t = {t!r} s: a contact lasts "
            f"{duration:.3g} s, but double precision resolves time only to {math.ulp(t):.3g} s there "
            f"(a contact must span {MIN_CONTACT_ULPS:g} ulps of t). Shorten the run to t <= {limit:.4g} s, "
            "or lower k or raise m (a longer contact)")


def simulate_cvode(ball: Ball, h0: float, v0: float, t_end: float, output_interval: float,
                   t_start: float = 0.0, F_ext: float = 0.0, rtol: float = DEFAULT_RTOL,
                   atol: float = DEFAULT_ATOL, method: str = "auto", max_step: float = 0.0,
                   engine: str = "auto") -> SimulationResult:
    """Integrate with CVODE from t_start to t_end and return the solution on the output grid.

    engine: see CvodeSettings; the engine that ran and why are in result.stats.
    """
    settings = CvodeSettings(rtol=rtol, atol=atol, method=method, max_step=max_step, engine=engine)
    check_resolvable(ball, t_end)
    grid = output_grid(t_start, t_end, output_interval)
    started = time.perf_counter()
    integrator = BallIntegrator(ball, h0, v0, t_start, F_ext, settings)
    h, v, events = integrator.integrate_grid(grid)
    wall_time = time.perf_counter() - started
    stats = SolverStats(steps=integrator.steps, rhs_calls=integrator.rhs_calls, events=len(events),
                        wall_time=wall_time, engine=integrator.engine, engine_reason=integrator.engine_reason)
    options = {"rtol": settings.rtol, "atol": settings.atol, "method": settings.method,
               "contact_method": integrator.methods[Mode.CONTACT], "max_step": settings.max_step,
               "engine": settings.engine}
    return SimulationResult("cvode", ball, grid, h, v, events, integrator.rest_time, stats, F_ext, options)
