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
from ..contact_laws import (
    NO_PULL,
    RIGID,
    conserved_speed,
    free_gap_rate,
    pressed_gap,
    rigid_rebound,
    summed_bounce_state,
)
from ..equations import load_value
from ..oscillator import contact_gap_flow
from ..physics import Ball, Mode
from ..rounding import later
from . import forcing
from .forcing import ForceTable
from .result import DEPARTURE, ENGAGE, IMPACT, RELEASE, Event, SimulationResult, SolverStats, output_grid


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
    only a rest under the last value.
    """

    def __init__(self, ball: Ball, h0: float, v0: float, t_start: float = 0.0,
                 t_end: float = math.inf, F_ext: float | ForceTable = 0.0, max_phases: int | None = None) -> None:
        """max_phases: stop after that many phases (a count for an estimate, not a solution to t_end)."""
        if ball.hunt_crossley:  # its contact has no closed form
            raise ValueError(f"solver = 'exact' is not allowed with contact = {ball.contact!r}: the Hunt-Crossley "
                             "contact has no closed form; use cvode")
        self.ball = ball
        self._max_phases = math.inf if max_phases is None else max_phases
        self.F_ext = F_ext
        self.t_start = t_start
        self.t_end = t_end
        self.phases: list[Phase] = []
        self.events: list[Event] = []
        self.rest_time: float | None = None
        self._build(h0, v0)

    def _build(self, h: float, v: float) -> None:
        ball, R = self.ball, self.ball.R
        resolvable_until = limits.resolvable_until(ball)
        constant_pieces = forcing.pieces(self.F_ext, self.t_start, self.t_end)
        zeno_end = -math.inf  # where a rigid ball's bounces summed in this piece end (contact_laws.rigid_rebound)
        for number, (t, piece_end, F_ext) in enumerate(constant_pieces):
            last, t_low = number == len(constant_pieces) - 1, 0.0  # t_low: t's rounding error (rounding.later)
            if number == 0:
                mode = ball.initial_mode(h, v, F_ext)
            else:  # a change of F_ext: the state where the previous phase has it, the mode held
                phase = self.phases[-1]
                h, v = (float(y) for y in ball.flow(phase.mode, phase.h0, phase.v0, t - phase.t_start, phase.F_ext))
                mode = phase.mode
                if t < zeno_end:  # inside a rigid ball's summed bounces: on from where the bounce truly is
                    v_first = -ball.e * self.events[-1].velocity  # the impact that started them, at the phase's start
                    x, v = summed_bounce_state(ball.parameters, v_first, load_value(phase.F_ext, ball.m, ball.g),
                                               t - phase.t_start)
                    h, mode = R + x, Mode.FLIGHT
            zeno_end = -math.inf
            parameters = ball.parameters
            contact_start = t  # the last impact (the no-pull law's engagements start no contact), or this piece's start
            while True:
                if mode == Mode.CONTACT and t > resolvable_until:
                    # contacts too short for the ulps of t: the phases would stop advancing t (it never ended)
                    limits.check_resolvable(ball, t)
                self.phases.append(Phase(t, mode, h, v, F_ext))
                if len(self.phases) >= self._max_phases:
                    return
                x_next, load = 0.0, load_value(F_ext, ball.m, ball.g)
                if mode == Mode.FLIGHT:
                    tau, v_next = time_to_impact(h - R, v, ball.effective_gravity(F_ext))
                    kind, next_mode = IMPACT, Mode.CONTACT
                elif mode == Mode.FREE:  # below R under the no-pull law: on to R, or pressed again
                    tau, x_next, v_next, departs = free_event(parameters, h - R, v, load)
                    kind, next_mode = (DEPARTURE, Mode.FLIGHT) if departs else (ENGAGE, Mode.CONTACT)
                else:
                    no_pull = parameters.law == NO_PULL
                    tau = (release_time if no_pull else departure_time)(parameters, h - R, v, load)
                    if math.isinf(tau):
                        if last:
                            self.rest_time = max(contact_start if no_pull else t, zeno_end)
                        break
                    if no_pull:
                        x_next, v_next = release_state(parameters, h - R, v, tau, load)
                        kind, next_mode = RELEASE, Mode.FREE
                    else:
                        v_next = departure_speed(parameters, h - R, v, tau, load)
                        kind, next_mode = DEPARTURE, Mode.FLIGHT
                t_event, t_event_low = later(t, t_low, tau)
                if not t_event <= piece_end:
                    break
                t, t_low, h, v, mode = t_event, t_event_low, R + x_next, v_next, next_mode
                self.events.append(Event(t, kind, v))
                if kind == IMPACT:
                    contact_start = t
                if kind == IMPACT and ball.rigid:  # the bounce: on in flight, or the ball stays on R
                    v, zeno = rigid_rebound(ball.parameters, v, load_value(F_ext, ball.m, ball.g))
                    mode = Mode.FLIGHT if v > 0.0 else Mode.CONTACT
                    zeno_end = later(t, t_low, zeno)[0] if zeno > 0.0 else zeno_end

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
        return h, v

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


def time_to_impact(height_above_contact: float, v0: float, g_eff: float) -> tuple[float, float]:
    """Flight time [s] until h falls to R, and the impact velocity [m/s]; (inf, nan) if never.

    With D = v0^2 + 2 g (h0 - R) and s = sqrt(D), t = (v0 + s)/g when rising and
    2 (h0 - R)/(s - v0) when falling, which has no cancellation; the impact speed is s.
    """
    dh = height_above_contact
    disc = v0 * v0 + 2.0 * g_eff * dh
    if v0 < 0.0 and disc >= 0.0:
        s = math.sqrt(disc)
        return 2.0 * dh / (s - v0), -s
    if v0 >= 0.0 and g_eff > 0.0:
        s = math.sqrt(disc)
        return (v0 + s) / g_eff, -s
    return math.inf, math.nan


def departure_time(parameters, x0, v0, load):
    """Time [s] from the gap x0 = h0 - R [m] and v0 [m/s] in contact to the first upward crossing of h = R; inf if none.

    parameters: Ball.parameters; load: m g - F_ext [N] (equations.load_value). Plain floats, so that the
    compiled phase machine runs this very search. A rigid ball resting on R leaves it at once where
    F_ext lifts it (load < 0), else never.
    """
    if parameters.law == RIGID:
        return math.inf if load >= 0.0 else 0.0
    m, k, b = parameters.m, parameters.k, parameters.b
    sigma, w2 = b / (2.0 * m), k / m
    d, g_eff = load / k, load / m
    q = sigma * v0 + w2 * x0 + g_eff  # v = v0 C - q S (q = sigma v0 + w2 y0, y0 = x0 + d the deflection from rest)
    rising = v0 > 0.0 or (v0 == 0.0 and q < 0.0)
    disc = sigma * sigma - w2
    guess, at_a = math.nan, math.nan  # NaN: none known
    if disc < 0.0:
        # Under-damped: extrema every pi/omega; maxima are positive and decay, so the
        # first maximum decides whether the ball ever leaves.
        omega = math.sqrt(-disc)
        # The phase angle of the next extremum, in [0, pi], from the quadrant that holds it: atan2(a, b)
        # - pi rounds an extremum just ahead (a minimum at v0 = -1e-38) to pi instead of ~0.
        # (|omega v0|: the sign of a zero, -0.0, would turn atan2's pi into -pi)
        tau1 = math.atan2(abs(omega * v0), q if rising else -q) / omega
        # Between two extrema v keeps its sign, so the first one is a maximum when the ball starts
        # rising and a minimum when it starts falling. Decided on the direction, never on the
        # value y(tau1): near critical damping that extremum lies many decay times away, and y(tau1)
        # is below the rounding of d (a lifted ball was held at R for ever).
        if rising:
            a, b = 0.0, tau1
        else:
            at_a = contact_gap_flow(sigma, w2, g_eff, x0, v0, tau1)[0]
            a, b = tau1, tau1 + math.pi / omega
            at_b = contact_gap_flow(sigma, w2, g_eff, x0, v0, b)[0]
            if at_b <= 0.0:
                return math.inf
            # Between a minimum and the next maximum y is close to half a cosine: its crossing
            # is Newton's start, a few iterations from the root when the damping is light.
            half = 0.5 * (at_b - at_a)
            if half > 0.0:  # else the ball does not move (y constant): Newton starts in the middle
                cosine = min(1.0, max(-1.0, (0.5 * (at_b + at_a)) / half))
                guess = a + (b - a) * math.acos(cosine) / math.pi
    else:
        # Critically or over-damped: at most one extremum, then a monotone approach to rest.
        mu = math.sqrt(disc)
        tau_ext = _overdamped_extremum(v0, q, mu)
        slow_rate = w2 / (sigma + mu)
        if rising and not math.isnan(tau_ext):
            a, b = 0.0, tau_ext
        elif d < 0.0 and (rising or not math.isnan(tau_ext)):
            a = 0.0 if rising else tau_ext
            b = a + 1.0 / slow_rate
            found = False
            for _ in range(2000):
                if contact_gap_flow(sigma, w2, g_eff, x0, v0, b)[0] > 0.0:
                    found = True
                    break
                b = a + 2.0 * (b - a)
            if not found:
                return math.inf
        else:
            return math.inf
    if math.isnan(guess) and contact_gap_flow(sigma, w2, g_eff, x0, v0, b)[0] <= 0.0:
        return math.inf
    return _departure_root(sigma, w2, g_eff, x0, v0, a, b, guess, at_a)


def departure_speed(parameters, x0, v0, tau, load):
    """v [m/s] where a contact from the gap x0 = h0 - R [m] and v0 ends after tau (departure_time): never < 0.

    A departure crosses R upwards; where the ball barely moves (at R with v0 = -1e-112) the flow can
    round it to a tiny downward speed, and the flight would end at once in an impact at R, and so on
    for ever. An undamped contact from R leaves at the speed it came with, exactly
    (contact_laws.conserved_speed). Arguments as departure_time's.
    """
    if conserved_speed(parameters, 1, x0, v0):
        return -v0
    if parameters.law == RIGID:
        return max(v0, 0.0)
    m, k, b = parameters.m, parameters.k, parameters.b
    return max(contact_gap_flow(b / (2.0 * m), k / m, load / m, x0, v0, tau)[1], 0.0)


def release_time(parameters, x0, v0, load):
    """Time [s] from the gap x0 [m] and v0 [m/s] in a pressed no-pull contact to its release; inf if none.

    The release is where the force k (R - h) - b v falls to 0, where contact_laws.pressed_gap's z crosses 0
    upwards; z obeys the contact's equation as x does, so it is departure_time's search of (z, dz/dt).
    Arguments as departure_time's.
    """
    z, rate = pressed_gap(parameters, x0, v0, load)
    return departure_time(parameters, z, rate, load)


def release_state(parameters, x0, v0, tau, load):
    """(x [m], v [m/s]) of a pressed no-pull contact from (x0, v0) at its release tau later (release_time): v >= 0.

    The force is 0 there, k x = -b v: below R the ball rises (v >= 0; the flow may round a grazing
    release's speed below 0).
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    x, v = contact_gap_flow(b / (2.0 * m), k / m, load / m, x0, v0, tau)
    return x, max(v, 0.0)


def free_event(parameters, x0, v0, load):
    """(tau [s], x [m], v [m/s], departs): the event ending the free sub-mode from the gap x0 <= 0 [m] at v0 [m/s].

    The ball moves on the flight's parabola (g_eff = load / m). It departs where x reaches 0 going up:
    tau = -2 x0 / (v0 + s), s = sqrt(v0^2 + 2 g_eff x0), at v = s (no cancellation, as time_to_impact);
    it is pressed again (engages) where contact_laws.pressed_gap's z, a parabola from (z0, free_gap_rate),
    falls back to 0: time_to_impact of z. The first of the two; (inf, x0, v0, True) where neither comes
    (a weightless ball at rest on R). departs: whether it is the departure (x = 0 there exactly).
    """
    g_eff = load / parameters.m
    z, rate = pressed_gap(parameters, x0, v0, load)[0], free_gap_rate(parameters, v0, load)
    disc = v0 * v0 + 2.0 * g_eff * x0
    tau_departure, s = math.inf, 0.0
    if disc >= 0.0:
        s = math.sqrt(disc)
        if v0 + s > 0.0:
            tau_departure = -2.0 * x0 / (v0 + s)
    if z <= 0.0 and rate <= 0.0:
        tau_engage = 0.0  # a grazing release (the force only touched 0): pressed again at once
    elif z < 0.0 and rate * rate + 2.0 * g_eff * z < 0.0:
        tau_engage = 0.0  # z an ulp below 0 and turning back before it: the same
    else:
        tau_engage = time_to_impact(max(z, 0.0), rate, g_eff)[0]
    if tau_departure <= tau_engage:
        return tau_departure, 0.0, s, True
    if math.isinf(tau_engage):
        return math.inf, x0, v0, True
    return tau_engage, x0 + tau_engage * (v0 - 0.5 * g_eff * tau_engage), v0 - g_eff * tau_engage, False


def _overdamped_extremum(v0, q, mu):
    """The one time > 0 where v0 C = q S (critical or over-damped), or NaN."""
    if v0 == 0.0:
        return math.nan
    if mu == 0.0:
        tau = v0 / q if q != 0.0 else -1.0
        return tau if tau > 0.0 else math.nan
    denominator = q - v0 * mu
    if denominator == 0.0:
        return math.nan
    x = 2.0 * v0 * mu / denominator
    if not x > 0.0:
        return math.nan
    return math.log1p(x) / (2.0 * mu)


def _departure_root(sigma, w2, g_eff, x0, v0, a, b, guess, at_a):
    """The root of the gap x(tau) (contact_gap_flow, increasing on [a, b]) with x(a) <= 0 < x(b).

    Newton from guess (NaN: the middle), safeguarded by bisection of the bracket; at_a is x(a) if
    known, else NaN.
    """
    if (contact_gap_flow(sigma, w2, g_eff, x0, v0, a)[0] if math.isnan(at_a) else at_a) >= 0.0:
        return a
    tau = guess if a < guess < b else 0.5 * (a + b)
    best, best_abs = b, math.inf
    for _ in range(200):
        x, v = contact_gap_flow(sigma, w2, g_eff, x0, v0, tau)
        if abs(x) < best_abs:
            best, best_abs = tau, abs(x)
        if x == 0.0:
            return tau
        if x < 0.0:
            a = tau
        else:
            b = tau
        step = x / v if v > 0.0 else math.inf
        # Converged when Newton moves by ulps: checked before the bracket test, since such a step
        # lands on the bracket's end just moved to tau, and bisecting from there would take ~50 steps.
        if abs(step) <= 2.0 * np.spacing(tau) or b - a <= 2.0 * np.spacing(b):
            break
        tau_new = tau - step
        if not a < tau_new < b:
            tau_new = 0.5 * (a + b)
        tau = tau_new
    return best


def simulate_exact(ball: Ball, h0: float, v0: float, t_end: float, output_interval: float,
                   t_start: float = 0.0, F_ext: float | ForceTable = 0.0) -> SimulationResult:
    """The piecewise-analytic solution on the output grid; F_ext a constant [N] or a forcing.ForceTable."""
    started = time.perf_counter()
    grid = output_grid(t_start, t_end, output_interval)
    exact = ExactSolution(ball, h0, v0, t_start, t_end, F_ext)
    h, v = exact.state(grid)
    stats = SolverStats(steps=len(exact.phases), rhs_calls=0, events=len(exact.events),
                        wall_time=time.perf_counter() - started)
    # Its error is the rounding of closed forms evaluated once per point from each phase's start (at most a few
    # ulps of the height scale against the mpmath solution, tests/test_mpmath_oracle.py).
    rounding = 16.0 * np.finfo(float).eps * max(float(np.max(np.abs(h))), ball.R)
    return SimulationResult("exact", ball, grid, h, v, list(exact.events), exact.rest_time, stats, F_ext,
                            error_estimate=rounding)
