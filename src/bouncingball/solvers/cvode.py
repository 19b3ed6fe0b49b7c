"""SUNDIALS CVODE (through scikit-sundae) with contact and departure found by root-finding.

Each mode has its own CVODE object, right-hand side and terminal event function (h - R, with
direction -1 in flight and +1 in contact). At each root the integrator switches mode and
re-initialises CVODE at the event, so no step ever straddles the discontinuity.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from sksundae.cvode import CVODE

from bouncingball import validation
from bouncingball.physics import Ball, Mode
from bouncingball.solvers.result import (
    DEPARTURE,
    IMPACT,
    Event,
    SimulationResult,
    SolverStats,
    output_grid,
)

METHODS = ("auto", "Adams", "BDF")
# Chosen for the hardest built-in scene: at these values the article's height error is ~3e-8 m
# (limit 1e-6), high-drop's ~1e-5 m and undamped's energy drift over 1000 s ~2e-6.
DEFAULT_RTOL = 1e-10
DEFAULT_ATOL = 1e-12
# The contact oscillator is stiff for an explicit-like Adams method when it is strongly
# over-damped (fast and slow rates far apart) or when its natural frequency is so high that
# resolving it for stability, not accuracy, would cost many steps.
STIFF_DAMPING_RATIO = 2.0
STIFF_NATURAL_FREQUENCY = 1e4  # rad/s

_CV_ROOT_RETURN = 2
_STEP_HORIZON = 1.0  # s; see advance()
_MAX_STEPS_PER_CALL = 1_000_000
# A phase that needs more steps than this is a method fighting stiffness (Adams holding a ball at
# rest on a k = 1e12 spring): fail with a reason instead of running for hours.
MAX_STEPS_PER_PHASE = 500_000


class QuinticSegment:
    """Quintic Hermite interpolant of h and v over one internal step [t0, t1].

    It matches h, v = h', a = h'' and the jerk a' at both ends, so it is exact for a parabola
    and its error, ~(w dt)^6/46080 of the contact amplitude, is far below the tolerance for
    the steps CVODE takes. Works on scalars (one step) and on arrays (one step per point).
    """

    def __init__(self, t0, t1, h0, v0, a0, h1, v1, a1, jerk0, jerk1) -> None:
        self.t0, self.t1, self.h1, self.v1 = t0, t1, h1, v1
        dt = t1 - t0
        self.dt = dt
        self.h_coefficients = _quintic_coefficients(h0, v0 * dt, a0 * dt * dt, h1, v1 * dt, a1 * dt * dt)
        self.v_coefficients = _quintic_coefficients(v0, a0 * dt, jerk0 * dt * dt, v1, a1 * dt, jerk1 * dt * dt)

    def state(self, t):
        """h [m] and v [m/s] at t (t0 <= t <= t1)."""
        s = (t - self.t0) / self.dt
        c0, c1, c2, c3, c4, c5 = self.h_coefficients
        h = c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
        c0, c1, c2, c3, c4, c5 = self.v_coefficients
        v = c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
        return h, v


def _quintic_coefficients(y0, d0, e0, y1, d1, e1):
    """Monomial coefficients in s = (t - t0)/dt from y, dt y' and dt^2 y'' at s = 0 and s = 1."""
    return (
        y0,
        d0,
        0.5 * e0,
        10.0 * (y1 - y0) - 6.0 * d0 - 4.0 * d1 - 1.5 * e0 + 0.5 * e1,
        15.0 * (y0 - y1) + 8.0 * d0 + 7.0 * d1 + 1.5 * e0 - e1,
        6.0 * (y1 - y0) - 3.0 * d0 - 3.0 * d1 - 0.5 * e0 + 0.5 * e1,
    )


class SolverError(RuntimeError):
    """CVODE failed; the message carries its reason."""


def choose_method(ball: Ball) -> str:
    """The rule behind method="auto": BDF for a stiff contact, Adams otherwise.

    Stiff means damping ratio >= 2 (over-damped, the fast and slow rates differ by >= 14x) or
    natural frequency sqrt(k/m) >= 1e4 rad/s. Flight is never stiff.
    """
    stiff = ball.damping_ratio >= STIFF_DAMPING_RATIO or ball.natural_frequency >= STIFF_NATURAL_FREQUENCY
    return "BDF" if stiff else "Adams"


@dataclass(frozen=True)
class CvodeSettings:
    """rtol, atol [-, m or m/s], method ("auto", "Adams", "BDF") and max_step [s] (0: unbounded)."""

    rtol: float = DEFAULT_RTOL
    atol: float = DEFAULT_ATOL
    method: str = "auto"
    max_step: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "rtol", validation.in_range("rtol", self.rtol, 0.0, 1.0))
        object.__setattr__(self, "atol", validation.positive("atol", self.atol))
        object.__setattr__(self, "method", validation.choice("method", self.method, METHODS))
        object.__setattr__(self, "max_step", validation.non_negative("max_step", self.max_step, "s"))


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
    """A ball integrated by CVODE that can be advanced piece by piece.

    Change F_ext between advances; get_state()/set_state() give an exact rollback.
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
        self._jacobians = {mode: ball.jacobian(mode).tolist() for mode in Mode}
        self._solvers: dict[Mode, CVODE] = {}
        self._event_functions = {}
        for mode in Mode:
            self._solvers[mode], self._event_functions[mode] = self._make_solver(mode)
        self.set_state(IntegratorState(t=t0, h=h0, v=v0, mode=ball.initial_mode(h0, v0, F_ext), F_ext=F_ext,
                                       t_start=t0))

    # --- CVODE set-up ---------------------------------------------------------------------
    def _make_solver(self, mode: Mode):
        ball = self.ball
        jacobian = ball.jacobian(mode)
        R = ball.R
        acceleration = ball.acceleration

        def rhs(t, y, yp):
            # physics computes k (R - h): R - h is exact near R, whereas k R - k h would bury the
            # deflection of a stiff ball (k = 1e12) in the round-off of two 6e10 terms.
            yp[0] = y[1]
            yp[1] = acceleration(y[0], y[1], mode, self._F_ext)

        def jac(t, y, yp, JJ):
            JJ[:, :] = jacobian

        def event(t, y, out):
            out[0] = y[0] - R
            # CVODE evaluates the root function once per step (and a few times per root found)
            self._phase_evaluations += 1
            if self._phase_evaluations > MAX_STEPS_PER_PHASE:
                raise SolverError(
                    f"CVODE ({self.methods[mode]}) took more than {MAX_STEPS_PER_PHASE} steps in one "
                    f"{mode.name.lower()} phase, at t = {t!r} s: the problem is stiff for this method; "
                    "use method 'BDF' (or 'auto')")

        event.terminal = [True]
        event.direction = [-1 if mode == Mode.FLIGHT else 1]
        s = self.settings
        solver = CVODE(rhs, method=self.methods[mode], rtol=s.rtol, atol=s.atol, max_step=s.max_step,
                       eventsfn=event, num_events=1, jacfn=jac, max_num_steps=_MAX_STEPS_PER_CALL)
        return solver, event

    # --- read-only view --------------------------------------------------------------------
    @property
    def t(self) -> float:
        return self._t

    @property
    def h(self) -> float:
        return self._h

    @property
    def v(self) -> float:
        return self._v

    @property
    def mode(self) -> Mode:
        return self._mode

    @property
    def impacts(self) -> int:
        return self._impacts

    @property
    def departures(self) -> int:
        return self._departures

    @property
    def rhs_calls(self) -> int:
        return self._rhs_calls + self._nfev_since_init

    @property
    def steps(self) -> int:
        """CVODE's internal steps so far."""
        return self._steps

    @property
    def F_ext(self) -> float:
        return self._F_ext

    @F_ext.setter
    def F_ext(self, value: float) -> None:
        value = validation.finite("F_ext", value, "N")
        if value != self._F_ext:
            self._reinit_needed()
            self._F_ext = value

    @property
    def acceleration(self) -> float:
        return self.ball.acceleration(self._h, self._v, self._mode, self._F_ext)

    @property
    def contact_force(self) -> float:
        return self.ball.contact_force(self._h, self._v, self._mode)

    @property
    def rest_time(self) -> float | None:
        """Start of the current contact if it can never end (F_ext held constant), else None."""
        if self._mode == Mode.CONTACT and self.ball.contact_is_permanent(self._h, self._v, self._F_ext):
            return self._last_impact_time if self._last_impact_time is not None else self._t_start
        return None

    # --- state ---------------------------------------------------------------------------------
    def get_state(self) -> IntegratorState:
        """A snapshot; the integrator restarts CVODE from it, so a restored copy continues identically."""
        self._reinit_needed()
        return IntegratorState(t=self._t, h=self._h, v=self._v, mode=self._mode, F_ext=self._F_ext,
                               impacts=self._impacts, departures=self._departures,
                               last_impact_time=self._last_impact_time, t_start=self._t_start,
                               rhs_calls=self._rhs_calls, steps=self._steps)

    def set_state(self, state: IntegratorState) -> None:
        self._t, self._h, self._v = float(state.t), float(state.h), float(state.v)
        self._mode = Mode(state.mode)
        self._F_ext = float(state.F_ext)
        self._impacts, self._departures = int(state.impacts), int(state.departures)
        self._last_impact_time, self._t_start = state.last_impact_time, float(state.t_start)
        self._rhs_calls, self._steps = int(state.rhs_calls), int(state.steps)
        self._nfev_since_init = 0
        self._reinit_needed()

    def _reinit_needed(self) -> None:
        self._rhs_calls += self._nfev_since_init
        self._nfev_since_init = 0
        self._phase_evaluations = 0
        self._needs_init = True
        self._segment = None
        self._root_pending = False

    # --- integration -------------------------------------------------------------------------
    def advance(self, t_target: float) -> list[Event]:
        """Integrate to t_target [s], resolving every impact and departure on the way.

        CVODE takes one internal step at a time, and its steps do not depend on the sequence of
        targets; a target inside the last step is read off a quintic Hermite interpolant of
        that step, so a short advance usually costs no CVODE call at all.
        """
        t_target = float(t_target)
        if not t_target >= self._t:
            raise ValueError(f"t_target = {t_target!r} s is not allowed: it must be >= the current time {self._t!r} s")
        events: list[Event] = []
        while self._t < t_target:
            segment = self._segment
            if segment is not None:
                if t_target <= segment.t1:
                    self._t, self._h, self._v = t_target, *segment.state(t_target)
                    break
                if self._root_pending:
                    self._t, self._h, self._v = segment.t1, segment.h1, segment.v1
                    events.append(self._switch_mode())
                    continue
            if self._close_enough(t_target):
                break
            solver = self._solvers[self._mode]
            if self._needs_init:
                solver.init_step(self._t, np.array([self._h, self._v]))
                self._needs_init = False
                self._step_start = (self._t, self._h, self._v)
            # The far target only orients CVODE and bounds its first step: the same for every
            # way of cutting the interval.
            result = solver.step(self._step_start[0] + _STEP_HORIZON, method="onestep")
            self._check(result)
            self._nfev_since_init = result.nfev
            self._steps += 1
            end = (float(result.t), float(result.y[0]), float(result.y[1]))
            self._segment = self._quintic(self._step_start, end)
            self._root_pending = result.status == _CV_ROOT_RETURN
            self._step_start = end
        return events

    def integrate_grid(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[Event]]:
        """Integrate through the increasing output times grid (grid[0] = current time).

        CVODE returns each internal step; the grid values come from the same quintic Hermite
        interpolant as in advance(), evaluated for all grid points in one pass at the end, which
        costs far less per output point than asking CVODE for each one.
        """
        grid = np.asarray(grid, dtype=float)
        t_end = grid[-1]
        times, states, modes = [np.array([self._t])], [np.array([[self._h, self._v]])], [np.array([self._mode])]
        events: list[Event] = []
        self._reinit_needed()
        while self._t < t_end and not self._close_enough(t_end):
            mode = self._mode
            result = self._solvers[mode].solve(np.array([self._t, t_end]), np.array([self._h, self._v]))
            self._check(result)
            ts, ys = result.t, result.y
            # A phase's first point is the previous phase's last: one copy per mode, so that no
            # interpolation segment straddles the switch.
            times.append(ts)
            states.append(ys)
            modes.append(np.full(len(ts), mode))
            self._t, self._h, self._v = float(ts[-1]), float(ys[-1, 0]), float(ys[-1, 1])
            self._steps += len(ts) - 1
            self._rhs_calls += int(result.nfev)
            if result.status == _CV_ROOT_RETURN:
                events.append(self._switch_mode())
        if self._t > times[-1][-1]:  # finished by a Taylor step within a few ulps of t_end
            times.append(np.array([self._t]))
            states.append(np.array([[self._h, self._v]]))
            modes.append(np.array([self._mode]))
        h_out, v_out = self._interpolate(np.concatenate(times), np.concatenate(states), np.concatenate(modes), grid)
        return h_out, v_out, events

    def _interpolate(self, ts, ys, modes, t):
        """The quintic Hermite interpolant of the step points (ts, ys) in their modes, at the times t."""
        h, v = ys[:, 0], ys[:, 1]
        contact = modes == Mode.CONTACT
        a = np.where(contact, self.ball.acceleration(h, v, Mode.CONTACT, self._F_ext),
                     self.ball.acceleration(h, v, Mode.FLIGHT, self._F_ext))
        (_, _), (dadh, dadv) = self._jacobians[Mode.CONTACT]
        jerk = np.where(contact, dadh * v + dadv * a, 0.0)  # J f; the flight Jacobian has no a row
        i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
        j = i + 1
        dt = ts[j] - ts[i]
        ok = dt > 0.0
        t1 = np.where(ok, ts[j], ts[i] + 1.0)  # a zero-length segment: take its start values
        segments = QuinticSegment(ts[i], t1, h[i], v[i], a[i], np.where(ok, h[j], h[i]), np.where(ok, v[j], v[i]),
                                  np.where(ok, a[j], a[i]), jerk[i], np.where(ok, jerk[j], jerk[i]))
        return segments.state(np.where(ok, t, ts[i]))

    def _quintic(self, start, end) -> QuinticSegment:
        """The Hermite interpolant of (t, h, v) between two step ends (scalars or arrays of them)."""
        ball, mode, F_ext = self.ball, self._mode, self._F_ext
        (t0, h0, v0), (t1, h1, v1) = start, end
        a0 = ball.acceleration(h0, v0, mode, F_ext)
        a1 = ball.acceleration(h1, v1, mode, F_ext)
        (_, _), (dadh, dadv) = self._jacobians[mode]
        # y'' = J f for this autonomous system: the jerk is J[1] . (v, a)
        return QuinticSegment(t0, t1, h0, v0, a0, h1, v1, a1, dadh * v0 + dadv * a0, dadh * v1 + dadv * a1)

    def _close_enough(self, t_target: float) -> bool:
        """Within a few ulps of t_target CVODE refuses to step (CV_TOO_CLOSE): finish by Taylor."""
        dt = t_target - self._t
        if dt > 32.0 * math.ulp(max(abs(t_target), abs(self._t), 1e-300)):
            return False
        a = self.acceleration
        self._t, self._h, self._v = t_target, self._h + dt * (self._v + 0.5 * dt * a), self._v + dt * a
        return True

    def _check(self, result) -> None:
        if result.status < 0:
            raise SolverError(f"CVODE failed at t = {float(result.t)!r} s ({self._mode.name.lower()}, "
                              f"h = {self._h!r} m, v = {self._v!r} m/s): {result.message}")

    def _switch_mode(self) -> Event:
        # scikit-sundae keeps every event on the events function and rebuilds that history on
        # each call; clearing it keeps the cost per event flat.
        event = self._event_functions[self._mode]
        event._i.clear()
        event._t.clear()
        event._y.clear()
        event._i_cnt[:] = 0
        self._reinit_needed()
        if self._mode == Mode.FLIGHT:
            self._mode, self._impacts, self._last_impact_time = Mode.CONTACT, self._impacts + 1, self._t
            return Event(self._t, IMPACT, self._v)
        self._mode, self._departures = Mode.FLIGHT, self._departures + 1
        return Event(self._t, DEPARTURE, self._v)


def simulate_cvode(ball: Ball, h0: float, v0: float, t_end: float, output_interval: float,
                   t_start: float = 0.0, F_ext: float = 0.0, rtol: float = DEFAULT_RTOL,
                   atol: float = DEFAULT_ATOL, method: str = "auto", max_step: float = 0.0) -> SimulationResult:
    """Integrate with CVODE from t_start to t_end and return the solution on the output grid."""
    settings = CvodeSettings(rtol=rtol, atol=atol, method=method, max_step=max_step)
    grid = output_grid(t_start, t_end, output_interval)
    started = time.perf_counter()
    integrator = BallIntegrator(ball, h0, v0, t_start, F_ext, settings)
    h, v, events = integrator.integrate_grid(grid)
    wall_time = time.perf_counter() - started
    stats = SolverStats(steps=integrator.steps, rhs_calls=integrator.rhs_calls, events=len(events),
                        wall_time=wall_time)
    options = {"rtol": settings.rtol, "atol": settings.atol, "method": settings.method,
               "contact_method": integrator.methods[Mode.CONTACT], "max_step": settings.max_step}
    return SimulationResult("cvode", ball, grid, h, v, events, integrator.rest_time, stats, F_ext, options)
