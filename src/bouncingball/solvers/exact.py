"""The exact piecewise-analytic solution: parabolas in flight, a damped linear oscillator in contact.

Event times are found in closed form (impact) or by a safeguarded Newton iteration inside a
bracket between extrema of the oscillator (departure), to a few ulps. Under the no-pull law the
pressed contact ends where its force reaches 0 (the release: the same search, of contact_laws.pressed_gap's
z), and the free sub-mode below R, a parabola, at the first root of a quadratic: x reaching R (a
departure) or z falling back to 0 (an engagement).
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple

import numpy as np

from .. import limits
from ..contact_laws import LAWS, contact_event, free_event, impact_is_instantaneous, rigid_rebound
from ..contact_laws.common import time_to_impact
from ..contact_laws.rigid import summed_bounce_state
from ..equations import load_value
from ..ground import Ground, as_ground
from ..physics import Ball, Mode
from ..rounding import later
from . import forcing
from .exact_error import RoundingCarry
from .exact_ground import build_on_moving_ground, check_moving_ground, contact_state
from .forcing import ForceTable
from .lyapunov import LyapunovExponent
from .phase_machine.settings import PROMISE
from .result import (
    DEPARTURE,
    ENGAGE,
    EVENT_KINDS,
    IMPACT,
    RELEASE,
    AccuracyWarning,
    Event,
    SimulationResult,
    SolverStats,
    output_grid,
    warn_at_caller,
)


class Phase(NamedTuple):
    """One mode held from t_start [s], starting from the state (h0 [m], v0 [m/s])."""

    t_start: float
    mode: Mode
    h0: float
    v0: float
    F_ext: float = 0.0


class ExactSolution:
    """The ball's exact trajectory from (h0, v0) at t_start up to t_end.

    F_ext [N] is a constant or a forcing.ForceTable (piecewise constant): the phases restart at each
    change time inside (t_start, t_end), the state continuous and the mode held there; a rest is
    only a rest under the last value. ground: a moving one (exact_ground: rigid, linear, no-pull) or a still one
    (at a height: the same run raised; phases keep the heights above it).
    """

    def __init__(self, ball: Ball, h0: float, v0: float, t_start: float = 0.0,
                 t_end: float = math.inf, F_ext: float | ForceTable = 0.0, max_phases: int | None = None,
                 ground: Ground | None = None) -> None:
        """max_phases: stop after that many phases (a count for an estimate, not a solution to t_end)."""
        if not LAWS[ball.contact].closed_form:
            raise ValueError(f"solver = 'exact' is not allowed with contact = {ball.contact!r}: its contact has no "
                             "closed form; use cvode")
        self.ground = as_ground(ground)
        check_moving_ground(ball, self.ground)
        self._raised = 0.0 if self.ground.moves else self.ground.height  # a still ground's: the same run, raised
        self.ball = ball
        self.max_phases = math.inf if max_phases is None else max_phases
        self.F_ext = F_ext
        self.t_start = t_start
        self.t_end = t_end
        self.phases: list[Phase] = []
        self.events: list[Event] = []
        self.rest_time: float | None = None
        self.rounding = RoundingCarry(ball.parameters, t_start)
        self._build(h0 - self._raised, v0)

    @property
    def error_estimate(self) -> float:
        """A bound on max |h - h_true| [m] at any time up to t_end: the closed forms' rounding, carried.

        Carried by the run's transition and saltation matrices (exact_error.RoundingCarry): the judge's own error,
        said as the CVODE engines say theirs.
        """
        return self.rounding.estimate(self.t_end if self.t_end < math.inf else self.phases[-1].t_start)

    @property
    def lyapunov_exponent(self) -> LyapunovExponent:
        """The run's largest Lyapunov exponent (solvers.lyapunov), from the matrices its error estimate carries."""
        end = self.t_end if self.t_end < math.inf else self.phases[-1].t_start
        tangent = self.rounding.tangent
        impacts = sum(event.kind == IMPACT and event.time > tangent.since for event in self.events)
        return tangent.exponent(impacts, end)

    def add_phase(self, t: float, mode: Mode, h: float, v: float, F_ext: float) -> bool:
        """Record the phase from (h [m], v [m/s]) at t [s]; whether max_phases are reached."""
        self.phases.append(Phase(t, mode, h, v, F_ext))
        return len(self.phases) >= self.max_phases

    def _build(self, h: float, v: float) -> None:
        """The phases and events from (h [m], v [m/s]) at t_start, one piece of constant F_ext after another."""
        if self.ground.moves:
            build_on_moving_ground(self, h, v)
            return
        constant_pieces = forcing.pieces(self.F_ext, self.t_start, self.t_end)
        zeno_end = -math.inf  # where a rigid ball's bounces summed in the last piece end (contact_laws.rigid_rebound)
        for number, (t, piece_end, F_ext) in enumerate(constant_pieces):
            if number == 0:
                mode = self.ball.initial_mode(h, v, F_ext)
            else:
                h, v, mode = self._state_at_change(t, zeno_end)
            stopped, zeno_end = self._phases_in_piece(t, piece_end, F_ext, h, v, mode,
                                                      number == len(constant_pieces) - 1)
            if stopped:
                return

    def _state_at_change(self, t: float, zeno_end: float) -> tuple[float, float, Mode]:
        """(h, v, mode) at a change of F_ext at t: where the last phase has the ball, its mode held."""
        ball, phase = self.ball, self.phases[-1]
        h, v = (float(y) for y in ball.flow(phase.mode, phase.h0, phase.v0, t - phase.t_start, phase.F_ext))
        if t < zeno_end:  # inside a rigid ball's summed bounces: on from where the bounce truly is
            v_first = -ball.e * self.events[-1].velocity  # the impact that started them, at the phase's start
            x, v = summed_bounce_state(ball.parameters, v_first, load_value(phase.F_ext, ball.m, ball.g),
                                       t - phase.t_start)
            return ball.R + x, v, Mode.FLIGHT
        return h, v, phase.mode

    def _phases_in_piece(self, t: float, piece_end: float, F_ext: float, h: float, v: float, mode: Mode,
                         last: bool) -> tuple[bool, float]:
        """The phases from (h, v) in mode at t to piece_end [s] under F_ext [N]: (stopped at max_phases, zeno_end).

        zeno_end: where a rigid ball's bounces summed in this piece end (-inf: none). In the last piece, a
        contact that never ends dates the rest (rest_time).
        """
        ball, R, t_low = self.ball, self.ball.R, 0.0  # t_low: t's rounding error (rounding.later)
        resolvable_until, instantaneous = limits.resolvable_until(ball), impact_is_instantaneous(ball.parameters)
        zeno_end = -math.inf
        contact_start = t  # the last impact (the no-pull law's engagements start no contact), or this piece's start
        while True:
            if mode == Mode.CONTACT and t > resolvable_until:
                # contacts too short for the ulps of t: the phases would stop advancing t (it never ended)
                limits.check_resolvable(ball, t)
            if self.add_phase(t, mode, h, v, F_ext):
                return True, zeno_end
            tau, x_next, v_next, kind, next_mode = self._next_event(mode, h, v, F_ext)
            load, phase_start, x_start, v_start, mode_before = load_value(F_ext, ball.m, ball.g), t, h - R, v, mode
            t_event, t_event_low = later(t, t_low, tau)
            if (mode == Mode.CONTACT and math.isinf(tau)) or not t_event <= piece_end:
                if piece_end < math.inf:  # on its flow to the piece's end
                    self.rounding.phase(t, int(mode), h - R, v, piece_end - t, load)
                if mode == Mode.CONTACT and math.isinf(tau) and last:  # a no-pull ball pressed for good rests from
                    self.rest_time = max(contact_start if kind == RELEASE else t, zeno_end)  # its contact's start
                return False, zeno_end
            t, t_low, h, v, mode = t_event, t_event_low, R + x_next, v_next, next_mode
            self.events.append(Event(t, kind, v))
            if kind == IMPACT:
                contact_start = t
                if instantaneous:  # the bounce: on in flight, or the ball stays on R
                    v, zeno = rigid_rebound(ball.parameters, v, load)
                    mode = Mode.FLIGHT if v > 0.0 else Mode.CONTACT
                    zeno_end = later(t, t_low, zeno)[0] if zeno > 0.0 else zeno_end
            self.rounding.phase(phase_start, int(mode_before), x_start, v_start, tau, load,
                                EVENT_KINDS.index(kind), v_next, v)

    def _next_event(self, mode: Mode, h: float, v: float, F_ext: float) -> tuple:
        """(tau [s], x [m], v [m/s], kind, next mode): the event ending the phase from (h, v) in mode; tau inf: none."""
        ball, R = self.ball, self.ball.R
        parameters, load = ball.parameters, load_value(F_ext, ball.m, ball.g)
        if mode == Mode.FLIGHT:
            tau, v_next = time_to_impact(h - R, v, ball.effective_gravity(F_ext))
            return tau, 0.0, v_next, IMPACT, Mode.CONTACT
        if mode == Mode.FREE:  # below R under the no-pull law: on to R, or pressed again
            tau, x_next, v_next, departs = free_event(parameters, h - R, v, load)
            return (tau, x_next, v_next, DEPARTURE, Mode.FLIGHT) if departs else \
                (tau, x_next, v_next, ENGAGE, Mode.CONTACT)
        tau, x_next, v_next, code = contact_event(parameters, h - R, v, load)
        kind = EVENT_KINDS[code]
        return tau, x_next, v_next, kind, Mode.FREE if kind == RELEASE else Mode.FLIGHT

    # --- evaluation ---------------------------------------------------------------------------
    def state(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Height [m] and velocity [m/s] at the times t [s] (t_start <= t <= t_end).

        One vectorised evaluation per mode: each time takes the start state of the phase it lies
        in, and the mode's flow is evaluated for all of them at once.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        starts = np.array([p.t_start for p in self.phases])
        index = self._phase_index(t)
        h = np.empty_like(t)
        v = np.empty_like(t)
        modes = np.array([int(p.mode) for p in self.phases])
        h_start = np.array([p.h0 for p in self.phases])
        v_start = np.array([p.v0 for p in self.phases])
        forces = np.array([p.F_ext for p in self.phases])
        point_modes, point_forces = modes[index], forces[index]
        for mode in Mode:
            for F_ext in np.unique(forces):
                selected = (point_modes == mode) & (point_forces == F_ext)
                if np.any(selected):
                    i = index[selected]
                    h[selected], v[selected] = self.ball.flow(mode, h_start[i], v_start[i], t[selected] - starts[i],
                                                              float(F_ext))
        if self.ground.moves:  # a rigid ball's contact there is a ride: on the ground, with it; a linear one's forced
            riding = point_modes == Mode.CONTACT
            if self.ball.rigid:
                h[riding] = self.ball.R + self.ground.position(t[riding])
                v[riding] = self.ground.velocity(t[riding])
            elif np.any(riding):
                i = index[riding]
                loads = load_value(point_forces[riding], self.ball.m, self.ball.g)
                h[riding], v[riding] = contact_state(self, starts[i], h_start[i], v_start[i], t[riding] - starts[i],
                                                     loads)
        return (h + self._raised if self._raised else h), v

    def modes(self, t) -> np.ndarray:
        """The mode (0 flight, 1 contact; Mode's values) at the times t [s]; at an event, the mode it starts."""
        modes = np.array([int(p.mode) for p in self.phases])
        return modes[self._phase_index(np.atleast_1d(np.asarray(t, dtype=float)))]

    def _phase_index(self, t: np.ndarray) -> np.ndarray:
        starts = np.array([p.t_start for p in self.phases])
        # a time equal to a phase's start belongs to that phase (its state there is the event's)
        index = np.searchsorted(starts, t, side="right") - 1
        np.clip(index, 0, len(starts) - 1, out=index)
        return index


def simulate_exact(ball: Ball, h0: float, v0: float, t_end: float, output_interval: float,
                   t_start: float = 0.0, F_ext: float | ForceTable = 0.0,
                   ground: Ground | None = None) -> SimulationResult:
    """The piecewise-analytic solution on the output grid; F_ext a constant [N] or a forcing.ForceTable."""
    started = time.perf_counter()
    grid = output_grid(t_start, t_end, output_interval)
    exact = ExactSolution(ball, h0, v0, t_start, t_end, F_ext, ground=ground)
    h, v = exact.state(grid)
    stats = SolverStats(steps=len(exact.phases), rhs_calls=0, events=len(exact.events),
                        wall_time=time.perf_counter() - started)
    estimate, carry = exact.error_estimate, exact.rounding
    scale = max(carry.scale, float(np.max(np.abs(h))))
    if not estimate <= PROMISE * scale:
        # from the first phase past it; where only the output's own rounding takes it past (none did), the end
        since = carry.untrusted_from if not math.isnan(carry.untrusted_from) else t_end
        warn_at_caller(AccuracyWarning(
            f"by t = {t_end:.6g} s the exact solution's error estimate (its rounding, carried) is {estimate:.2g} m, "
            f"{estimate / scale:.2g} of its height scale {scale:.3g} m: past the promise of {PROMISE:g} from t = "
            f"{since:.6g} s on; a small error grows faster here than double precision can follow "
            "(an ill-conditioned run): shorten the run"))
    return SimulationResult("exact", ball, grid, h, v, list(exact.events), exact.rest_time, stats, F_ext,
                            error_estimate=estimate, ground=exact.ground, lyapunov=exact.lyapunov_exponent)
