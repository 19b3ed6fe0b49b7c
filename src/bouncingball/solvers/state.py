"""An integrator's saved state (IntegratorState, with the RestartPoint it came from), and its view of the state.

BallIntegrator.get_state takes one; set_state checks every field (state_checks.py) before it changes anything.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .. import limits, validation
from ..contact_laws import (
    contact_integrated,
    ground_moves,
    impact_is_instantaneous,
    law_contact_force,
    reported_acceleration,
)
from ..contact_laws.rigid import summed_bounce_state
from ..equations import load_at, load_value
from ..physics import Ball, Mode
from .phase_machine import machine
from .phase_machine.phases import REST, decide_phase
from .phase_machine.settings import hop_tolerance
from .vibrating_ground import ground_motion


@dataclass(frozen=True)
class RestartPoint:
    """Where CVODE last restarted (an event, a change of F_ext, the start): the state and counters there.

    From it, CVODE's steps depend on nothing else (not on the times it was advanced to), so
    integrating again from it to a later time gives that time's state bit for bit.
    """

    t: float
    gap: float  # h - R [m]
    v: float
    mode: Mode
    impacts: int = 0
    departures: int = 0
    last_impact_time: float | None = None
    rhs_calls: int = 0
    steps: int = 0
    t_low: float = 0.0  # the rounding error of t [s] where it is an event's time (machine.later)
    # the run's error estimate there (error_estimate.phase_error): the error of (x [m], v [m/s]), the bound on
    # |h - h_true| [m] before it, the start [s] of the first phase past the promise (None: none), the height scale [m]
    error_x: float = 0.0
    error_v: float = 0.0
    error_bound: float = 0.0
    untrusted_from: float | None = None
    height_scale: float = 0.0
    # under the Hunt-Crossley law the error lies in the sum of two ellipses (error_estimate.hunt_crossley_errors):
    # error_x and error_v are the half-widths [m, m/s] of the first, error_xv its correlation; error2_* the second's
    error_xv: float = 0.0
    error2_x: float = 0.0
    error2_v: float = 0.0
    error2_xv: float = 0.0


@dataclass(frozen=True)
class IntegratorState:
    """Everything needed to resume an integration exactly: the state at t and the restart point it came from.

    restart: the RestartPoint at which the current phase's CVODE run began (a dict of its fields is
    taken too, as a deserialized state holds); None restarts CVODE at t, within the tolerance of the
    original run instead of bit for bit.
    """

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
    gap: float | None = None  # h - R [m] to every digit (h rounds a deflection to ulp(R)); None: h - R
    restart: RestartPoint | None = None
    zeno_time: float | None = None  # when a rigid ball's summed bounces end [s] (contact_laws.rigid_rebound), or None

    def __post_init__(self) -> None:
        """Take the restart point from a dict of its fields (a deserialized state); TypeError names a bad one."""
        if isinstance(self.restart, dict):
            object.__setattr__(self, "restart", RestartPoint(**self.restart))




class IntegratorView:
    """BallIntegrator's state as the phase machine holds it (layout.py's fields): read, saved, restarted.

    The ball's quantities at t, the snapshot get_state takes, and what sets a state and restarts
    CVODE there; BallIntegrator integrates it (the attributes ball, settings, _atol, _state, _F_ext,
    _t_start, _load and _hop are its).
    """

    ball: Ball

    @property
    def t(self) -> float:
        """Current time [s]."""
        return float(self._state.t)

    @property
    def h(self) -> float:
        """Height of the centre [m] at t."""
        return self.ball.R + float(self._state.x) + ground_motion(self.ground, self.t, 0)  # the gap is to the ground

    @property
    def v(self) -> float:
        """Velocity [m/s] at t, positive upwards."""
        return float(self._state.v) + ground_motion(self.ground, self.t, 1)  # the machine's is relative to it

    @property
    def error_estimate(self) -> float:
        """An estimate of max |h - h_true| [m] over everything integrated so far.

        Each phase's own error is measured against its exact flow (the flow is affine in the start
        state, in closed form), the error it started with carried by the flow's transition matrix and,
        at an event, the saltation of the field's jump; see error_estimate.phase_error. A Hunt-Crossley
        contact, with no closed form, is bounded by what CVODE's error test let through at each step
        (error_estimate.hunt_crossley_errors). It passes 1e-6 of
        the height scale only where the run is ill-conditioned, and then an AccuracyWarning says from
        when the run cannot be trusted.
        """
        return float(self._machine.run_estimate(self._machine_parameters, self.settings.rtol, self._atol,
                                                self._machine_state)[0])

    @property
    def mode(self) -> Mode:
        """The mode held at t: flight or contact."""
        return Mode(int(self._state.mode))

    @property
    def impacts(self) -> int:
        """Impacts so far."""
        return int(self._state.impacts)

    @property
    def departures(self) -> int:
        """Departures so far."""
        return int(self._state.departures)

    @property
    def rhs_calls(self) -> int:
        """Right-hand-side evaluations so far."""
        return int(self._state.rhs_calls + self._state.nfev)

    @property
    def error_estimate_at_t(self) -> float:
        """error_estimate [m], for a caller that asks at every step (an FMU's communication points).

        The compiled engine takes it at the end of each advance (drivers.keep_estimate), so reading it costs a
        field's read; otherwise (scikit-sundae's engine, or the state changed since) it is computed and kept for
        the next read at the same state.
        """
        state = self._state
        if state.est_t == state.t:
            return float(state.est)
        estimate = self.error_estimate
        state.est, state.est_t = estimate, state.t
        return estimate

    @property
    def error_estimate_before_phase(self) -> float:
        """The error estimate [m] as of the current phase's start: the last event or change of F_ext.

        An array read (error_estimate and error_estimate_at_t add the phase so far).
        """
        return float(self._state.err_max)

    @property
    def steps(self) -> int:
        """CVODE's internal steps so far."""
        return int(self._state.steps)

    @property
    def F_ext(self) -> float:
        """External force [N], positive upwards, held constant until changed; setting it restarts CVODE."""
        return self._F_ext

    @F_ext.setter
    def F_ext(self, value: float) -> None:
        value = validation.finite("F_ext", value, "N")
        if value != self._F_ext:
            # the range double precision resolves from the current state (simulate checks it from the start), relative
            # to the ground (a vibrating one's: the machine's own; on a still one h and v themselves)
            limits.check_scene(self.ball, self.ball.R + float(self._state.x), float(self._state.v), value, self.t,
                               rtol=self.settings.rtol)
            bouncing = self._summed_bounce()
            # the phase at the old load ends here: its error carried into the next one
            self._machine.phase_ends(self._machine_parameters, self.settings.rtol, self._atol, self._machine_state,
                                     0.0, 1.0)
            if bouncing is not None:  # the ball flies on from where its summed bounces have it
                state = self._state
                state.x, state.v, state.mode = *bouncing, float(Mode.FLIGHT)
                machine.restart_needed(state)
            self._F_ext = value
            self._sync_F_ext()

    def _summed_bounce(self) -> tuple[float, float] | None:
        """(x [m], v [m/s]) now where a rigid ball's summed bounces (rigid_rebound) go on until rest_t; or None.

        The ball is taken on R while they last (each lower than ZENO_APEX R), but a change of F_ext there
        starts from where the bounce truly is: a lift from rest would lose its speed (up to 1e-6 m/s after
        the Reference-FMUs' drop, 9.4e-5 m after 100 s at F_ext = m g).
        """
        rest, t = self._zeno_time(), self.t
        if rest is None or not t < rest or self.ground.moves:  # (on a vibrating ground a ride: on it)
            return None
        impact, parameters = float(self._state.last_impact), self.ball.parameters
        e, g_eff = parameters.e, self._load / parameters.m
        v_first = 0.5 * (rest - impact) * g_eff * (1.0 - e)  # from the Zeno time rigid_rebound gave
        return summed_bounce_state(parameters, v_first, self._load, t - impact)

    @property
    def acceleration(self) -> float:
        """dv/dt [m/s2] at t in the current mode."""
        state, t = self._state, self.t
        relative = reported_acceleration(self._parameters, float(state.x), float(state.v), self.mode,
                                         load_at(self._parameters, self._load, t))
        return relative + ground_motion(self.ground, t, 2)

    @property
    def contact_force(self) -> float:
        """Force of the ground on the ball [N] at t, positive upwards; zero in flight."""
        state = self._state
        return law_contact_force(self._parameters, float(state.x), float(state.v), self.mode,
                                 load_at(self._parameters, self._load, self.t))

    @property
    def rest_time(self) -> float | None:
        """Start of the current contact if it can never again lift the ball above R + hop_tolerance, else None.

        F_ext is taken as held constant from now on. A rigid ball's rest starts at the Zeno time where
        its last bounces were summed (contact_laws.rigid_rebound). A Hunt-Crossley ball's rest starts where
        its energy criterion (contact_laws.hunt_crossley_rest_margin) became true in its current contact, found
        since CVODE last restarted (the state's hc_rest_t): CVODE integrates on through it, there being no
        closed form of the rest flow.
        """
        if contact_integrated(self._parameters):
            rest = float(self._state.hc_rest_t)
            return rest if self.mode == Mode.CONTACT and not math.isnan(rest) else None
        if ground_moves(self._parameters):  # decided where the contact began, its search run from there
            if self.mode != Mode.CONTACT or math.isnan(float(self._state.rest_t)):
                return None
        elif decide_phase(self._parameters, self.mode, float(self._state.x), float(self._state.v), self._load,
                          self._hop, self.settings.rtol, float(self._state.t), math.inf)[0] != REST:
            return None
        start = self._last_impact_time if self._last_impact_time is not None else self._t_start
        rest = float(self._state.rest_t)
        return max(start, rest) if impact_is_instantaneous(self._parameters) and not math.isnan(rest) else start

    @property
    def _last_impact_time(self) -> float | None:
        last = float(self._state.last_impact)
        return None if math.isnan(last) else last

    def get_state(self) -> IntegratorState:
        """A snapshot to resume from; taking it does not disturb the integration.

        It holds the point where CVODE last restarted (see RestartPoint): set_state integrates again
        from there, so a restored snapshot continues bit for bit as the run it was taken from, in
        this integrator or a fresh one with the same ball and settings.
        """
        state = self._state
        last = float(state.rs_last_impact)
        restart = RestartPoint(float(state.rs_t), float(state.rs_x), float(state.rs_v),
                               Mode(int(state.rs_mode)), int(state.rs_impacts),
                               int(state.rs_departures), None if math.isnan(last) else last,
                               int(state.rs_rhs_calls), int(state.rs_steps),
                               float(state.rs_t_low), *self._errors())
        return IntegratorState(t=self.t, h=self.h, v=self.v, mode=self.mode, F_ext=self._F_ext,
                               impacts=self.impacts, departures=self.departures,
                               last_impact_time=self._last_impact_time, t_start=self._t_start,
                               rhs_calls=self.rhs_calls, steps=self.steps, gap=float(state.x),
                               restart=restart, zeno_time=self._zeno_time())

    def _zeno_time(self) -> float | None:
        """When the summed bounces of a rigid ball resting on R end [s] (rest_t, after its last impact), else None."""
        rest, impact = float(self._state.rest_t), float(self._state.last_impact)
        return rest if impact_is_instantaneous(self._parameters) and self.mode == Mode.CONTACT and rest > impact \
            else None

    def _errors(self) -> tuple:
        """The error estimate's fields at the restart point, as RestartPoint holds them."""
        state = self._state
        since = float(state.err_from)
        return (float(state.err_x), float(state.err_v), float(state.err_max),
                None if math.isnan(since) else since, float(state.scale),
                float(state.err_xv), float(state.err2_x), float(state.err2_v), float(state.err2_xv))

    def _restart_at(self, point, F_ext: float, counts, t_start: float, t_low: float = 0.0,
                    errors=(0.0, 0.0, 0.0, None, 0.0, 0.0, 0.0, 0.0, 0.0)) -> None:
        """Set the state (t, x, v, mode) and what goes with it; CVODE restarts there.

        With t's rounding error t_low, F_ext, the counters and the error estimate's fields (_errors).
        """
        state = self._state
        t, x, v, mode = point
        state.t, state.x, state.v, state.mode, state.t_low = t, x, v, float(mode), t_low
        error_x, error_v, bound, since, scale, *ellipses = errors
        state.err_x, state.err_v, state.err_max = error_x, error_v, bound
        state.err_xv, state.err2_x, state.err2_v, state.err2_xv = ellipses
        state.err_from, state.scale = math.nan if since is None else since, scale
        self._F_ext, self._t_start = F_ext, t_start
        self._set_counts(counts)
        state.nfev = 0.0
        self._sync_F_ext()
        machine.restart_needed(state)

    def _set_counts(self, counts) -> None:
        """impacts, departures, last impact time [s] or None, right-hand-side calls, steps."""
        impacts, departures, last_impact_time, rhs_calls, steps = counts
        state = self._state
        state.impacts, state.departures, state.steps = float(impacts), float(departures), float(steps)
        state.last_impact = math.nan if last_impact_time is None else last_impact_time
        state.rhs_calls = float(rhs_calls)

    def _sync_F_ext(self) -> None:
        """The load m g - F_ext and the hop tolerance at F_ext, for the machine (which gives the engine the load)."""
        self._load = load_value(self._F_ext, self.ball.m, self.ball.g)
        self._hop = hop_tolerance(self.ball, self.settings.rtol, self.settings.atol, self._F_ext)
        self._state.load, self._state.hop = self._load, self._hop

    @property
    def hop_tolerance(self) -> float:
        """The highest hop [m] merged into the contact around it at the current F_ext; see hop_tolerance()."""
        return self._hop
