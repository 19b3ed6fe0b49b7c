"""An integrator's saved state (IntegratorState, with the RestartPoint it came from) and its checks.

BallIntegrator.get_state takes one; set_state checks every field here before it changes anything.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from .. import limits, validation
from ..physics import HUNT_CROSSLEY, NO_PULL, Ball, Mode, gap_acceleration, load_value, summed_bounce_state
from . import layout, machine
from .phases import REST, decide_phase, frame, on_wrong_side, side_margin
from .settings import CvodeSettings, hop_tolerance


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
    zeno_time: float | None = None  # a rigid ball's summed bounces end then [s] (physics.rigid_rebound); None: none

    def __post_init__(self) -> None:
        """Take the restart point from a dict of its fields (a deserialized state); TypeError names a bad one."""
        if isinstance(self.restart, dict):
            object.__setattr__(self, "restart", RestartPoint(**self.restart))




class IntegratorView:
    """BallIntegrator's state as the phase machine holds it (machine.new_state's array): read, saved, restarted.

    The ball's quantities at t, the snapshot get_state takes, and what sets a state and restarts
    CVODE there; BallIntegrator integrates it (the attributes ball, settings, _atol, _state, _F_ext,
    _t_start, _load and _hop are its).
    """

    ball: Ball

    @property
    def t(self) -> float:
        """Current time [s]."""
        return float(self._state[layout.T])

    @property
    def h(self) -> float:
        """Height of the centre [m] at t."""
        return self.ball.R + float(self._state[layout.X])

    @property
    def v(self) -> float:
        """Velocity [m/s] at t, positive upwards."""
        return float(self._state[layout.V])

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
        return float(self._machine.run_estimate(self.ball.parameters, self.settings.rtol, self._atol, self._state)[0])

    @property
    def mode(self) -> Mode:
        """The mode held at t: flight or contact."""
        return Mode(int(self._state[layout.MODE]))

    @property
    def impacts(self) -> int:
        """Impacts so far."""
        return int(self._state[layout.IMPACTS])

    @property
    def departures(self) -> int:
        """Departures so far."""
        return int(self._state[layout.DEPARTURES])

    @property
    def rhs_calls(self) -> int:
        """Right-hand-side evaluations so far."""
        return int(self._state[layout.RHS_CALLS] + self._state[layout.NFEV])

    @property
    def error_estimate_before_phase(self) -> float:
        """The error estimate [m] as of the current phase's start: the last event or change of F_ext.

        An array read, for a caller that asks at every step (error_estimate adds the phase so far).
        """
        return float(self._state[layout.ERR_MAX])

    @property
    def steps(self) -> int:
        """CVODE's internal steps so far."""
        return int(self._state[layout.STEPS])

    @property
    def F_ext(self) -> float:
        """External force [N], positive upwards, held constant until changed; setting it restarts CVODE."""
        return self._F_ext

    @F_ext.setter
    def F_ext(self, value: float) -> None:
        value = validation.finite("F_ext", value, "N")
        if value != self._F_ext:
            # the range double precision resolves from the current state (simulate checks it from the start)
            limits.check_scene(self.ball, self.h, self.v, value, self.t)
            bouncing = self._summed_bounce()
            # the phase at the old load ends here: its error carried into the next one
            self._machine.phase_ends(self.ball.parameters, self.settings.rtol, self._atol, self._state, 0.0, 1.0)
            if bouncing is not None:  # the ball flies on from where its summed bounces have it
                state = self._state
                state[layout.X], state[layout.V], state[layout.MODE] = *bouncing, Mode.FLIGHT
                machine.restart_needed(state)
            self._F_ext = value
            self._sync_F_ext()

    def _summed_bounce(self) -> tuple[float, float] | None:
        """(x [m], v [m/s]) now where a rigid ball's summed bounces (physics.rigid_rebound) go on until REST_T; or None.

        The ball is taken on R while they last (each lower than ZENO_APEX R), but a change of F_ext there
        starts from where the bounce truly is: a lift from rest would lose its speed (up to 1e-6 m/s after
        the Reference-FMUs' drop, 9.4e-5 m after 100 s at F_ext = m g).
        """
        rest, t = self._zeno_time(), self.t
        if rest is None or not t < rest:
            return None
        impact, parameters = float(self._state[layout.LAST_IMPACT]), self.ball.parameters
        e, g_eff = parameters[6], self._load / parameters[0]
        v_first = 0.5 * (rest - impact) * g_eff * (1.0 - e)  # from the Zeno time rigid_rebound gave
        return summed_bounce_state(parameters, v_first, self._load, t - impact)

    @property
    def acceleration(self) -> float:
        """dv/dt [m/s2] at t in the current mode."""
        ball, state = self.ball, self._state
        if ball.rigid or ball.hunt_crossley:
            return ball.acceleration(ball.R + float(state[layout.X]), float(state[layout.V]), self.mode, self._F_ext)
        return gap_acceleration(float(state[layout.X]), float(state[layout.V]), self.mode, self._load, ball.m,
                                ball.k, ball.b)

    @property
    def contact_force(self) -> float:
        """Force of the ground on the ball [N] at t, positive upwards; zero in flight."""
        x, v = float(self._state[layout.X]), float(self._state[layout.V])
        if self.ball.rigid or self.ball.hunt_crossley:
            return self.ball.contact_force(self.ball.R + x, v, self.mode, self._F_ext)
        if self.ball.no_pull:  # max(0, ...), and 0 in the free sub-mode
            return 0.0 if self.mode != Mode.CONTACT else max(-self.ball.k * x - self.ball.b * v, 0.0)
        return 0.0 if self.mode == Mode.FLIGHT else -self.ball.k * x - self.ball.b * v

    @property
    def rest_time(self) -> float | None:
        """Start of the current contact if it can never again lift the ball above R + hop_tolerance, else None.

        F_ext is taken as held constant from now on. A rigid ball's rest starts at the Zeno time where
        its last bounces were summed (physics.rigid_rebound). A Hunt-Crossley ball's rest starts where
        its energy criterion (physics.hunt_crossley_rest_margin) became true in its current contact, found
        since CVODE last restarted (layout.HC_REST_T): CVODE integrates on through it, there being no
        closed form of the rest flow.
        """
        if self.ball.hunt_crossley:
            rest = float(self._state[layout.HC_REST_T])
            return rest if self.mode == Mode.CONTACT and not math.isnan(rest) else None
        x, v = float(self._state[layout.X]), float(self._state[layout.V])
        if decide_phase(self._parameters, self.mode, x, v, self._load, self._hop, self.settings.rtol)[0] != REST:
            return None
        start = self._last_impact_time if self._last_impact_time is not None else self._t_start
        rest = float(self._state[layout.REST_T])
        return max(start, rest) if self.ball.rigid and not math.isnan(rest) else start

    @property
    def _last_impact_time(self) -> float | None:
        last = float(self._state[layout.LAST_IMPACT])
        return None if math.isnan(last) else last

    def get_state(self) -> IntegratorState:
        """A snapshot to resume from; taking it does not disturb the integration.

        It holds the point where CVODE last restarted (see RestartPoint): set_state integrates again
        from there, so a restored snapshot continues bit for bit as the run it was taken from, in
        this integrator or a fresh one with the same ball and settings.
        """
        state = self._state
        last = float(state[layout.RS_LAST_IMPACT])
        restart = RestartPoint(float(state[layout.RS_T]), float(state[layout.RS_X]), float(state[layout.RS_V]),
                               Mode(int(state[layout.RS_MODE])), int(state[layout.RS_IMPACTS]),
                               int(state[layout.RS_DEPARTURES]), None if math.isnan(last) else last,
                               int(state[layout.RS_RHS_CALLS]), int(state[layout.RS_STEPS]),
                               float(state[layout.RS_T_LOW]), *self._errors())
        return IntegratorState(t=self.t, h=self.h, v=self.v, mode=self.mode, F_ext=self._F_ext,
                               impacts=self.impacts, departures=self.departures,
                               last_impact_time=self._last_impact_time, t_start=self._t_start,
                               rhs_calls=self.rhs_calls, steps=self.steps, gap=float(state[layout.X]),
                               restart=restart, zeno_time=self._zeno_time())

    def _zeno_time(self) -> float | None:
        """When the summed bounces of a rigid ball resting on R end [s] (REST_T, after its last impact), else None."""
        rest, impact = float(self._state[layout.REST_T]), float(self._state[layout.LAST_IMPACT])
        return rest if self.ball.rigid and self.mode == Mode.CONTACT and rest > impact else None

    def _errors(self) -> tuple:
        """The error estimate's fields at the restart point, as RestartPoint holds them."""
        state = self._state
        since = float(state[layout.ERR_FROM])
        return (float(state[layout.ERR_X]), float(state[layout.ERR_V]), float(state[layout.ERR_MAX]),
                None if math.isnan(since) else since, float(state[layout.SCALE]),
                *(float(state[i]) for i in (layout.ERR_XV, layout.ERR2_X, layout.ERR2_V, layout.ERR2_XV)))

    def _restart_at(self, point, F_ext: float, counts, t_start: float, t_low: float = 0.0,
                    errors=(0.0, 0.0, 0.0, None, 0.0, 0.0, 0.0, 0.0, 0.0)) -> None:
        """Set the state (t, x, v, mode) and what goes with it; CVODE restarts there.

        With t's rounding error t_low, F_ext, the counters and the error estimate's fields (_errors).
        """
        state = self._state
        state[layout.T], state[layout.X], state[layout.V], state[layout.MODE] = point
        state[layout.T_LOW] = t_low
        error_x, error_v, bound, since, scale, *ellipses = errors
        state[layout.ERR_X], state[layout.ERR_V], state[layout.ERR_MAX] = error_x, error_v, bound
        state[[layout.ERR_XV, layout.ERR2_X, layout.ERR2_V, layout.ERR2_XV]] = ellipses
        state[layout.ERR_FROM], state[layout.SCALE] = math.nan if since is None else since, scale
        self._F_ext, self._t_start = F_ext, t_start
        self._set_counts(counts)
        state[layout.NFEV] = 0.0
        self._sync_F_ext()
        machine.restart_needed(state)

    def _set_counts(self, counts) -> None:
        """impacts, departures, last impact time [s] or None, right-hand-side calls, steps."""
        impacts, departures, last_impact_time, rhs_calls, steps = counts
        state = self._state
        state[layout.IMPACTS], state[layout.DEPARTURES], state[layout.STEPS] = impacts, departures, steps
        state[layout.LAST_IMPACT] = math.nan if last_impact_time is None else last_impact_time
        state[layout.RHS_CALLS] = rhs_calls

    def _sync_F_ext(self) -> None:
        """The load m g - F_ext and the hop tolerance at F_ext, for the machine (which gives the engine the load)."""
        self._load = load_value(self._F_ext, self.ball.m, self.ball.g)
        self._hop = hop_tolerance(self.ball, self.settings.rtol, self.settings.atol, self._F_ext)
        self._state[layout.LOAD], self._state[layout.HOP] = self._load, self._hop

    @property
    def hop_tolerance(self) -> float:
        """The highest hop [m] merged into the contact around it at the current F_ext; see hop_tolerance()."""
        return self._hop


Counts = tuple[int, int, float | None, int, int]  # impacts, departures, last impact time [s], RHS calls, steps


@dataclass(frozen=True)
class CheckedState:
    """A saved state's fields, checked: point (t, x, v, mode, F_ext), counts and t_start; the restart's too."""

    point: tuple[float, float, float, Mode, float]
    counts: Counts
    t_start: float
    restart_point: tuple[float, float, float, Mode] | None
    restart_counts: Counts | None
    restart_t_low: float = 0.0
    restart_errors: tuple = (0.0, 0.0, 0.0, None, 0.0, 0.0, 0.0, 0.0, 0.0)


def checked(ball: Ball, state: IntegratorState, settings: CvodeSettings) -> CheckedState:
    """Every field of state checked for ball and the integrator's settings; ValueError names the first bad one."""
    if not isinstance(state, IntegratorState):
        raise ValueError(f"state = {validation.shown(state)} is not allowed: it must be an IntegratorState "
                         "(one of get_state())")
    point = _point(ball, "state", state.t, state.gap, state.h, state.v, state.mode, state.F_ext)
    if point[3] == Mode.FREE and ball.parameters[5] not in (NO_PULL, HUNT_CROSSLEY):
        raise ValueError(f"state mode = {Mode.FREE.value} (FREE) is not allowed for contact = {ball.contact!r} "
                         f"(b = {ball.b!r} N s/m): it is the no-pull law's free sub-mode (with b > 0)")
    t_start = validation.finite("state t_start", state.t_start, "s")
    counts = _counts("state", state)
    if state.zeno_time is not None and not (ball.rigid and point[3] == Mode.CONTACT and counts[2] is not None
                                            and validation.finite("state zeno_time", state.zeno_time, "s") > counts[2]):
        raise ValueError(f"state zeno_time = {state.zeno_time!r} s is not allowed: it is where a rigid ball resting "
                         "on R ends its summed bounces, after its last impact (None otherwise)")
    restart = state.restart
    if restart is None:
        _check_side(ball, settings, "state", point, point, state.h)
        return CheckedState(point, counts, t_start, None, None)
    if not isinstance(restart, RestartPoint):
        raise ValueError(f"state restart = {restart!r} is not allowed: it must be a RestartPoint or None")
    start = _point(ball, "state restart", restart.t, restart.gap, None, restart.v, restart.mode)
    if not (start[0] <= point[0] and start[3] == point[3]):
        raise ValueError(f"state restart at t = {start[0]!r} s in {start[3].name.lower()} is not allowed "
                         f"for a state at t = {point[0]!r} s in {point[3].name.lower()}: it must be of the same "
                         "mode, no later")
    _check_side(ball, settings, "state restart", start[:4] + point[4:], start, ball.R + start[1])
    _check_side(ball, settings, "state", point, start, state.h)
    t_low = validation.finite("state restart t_low", restart.t_low, "s")
    if not abs(t_low) <= math.ulp(start[0]):
        raise ValueError(f"state restart t_low = {t_low!r} s is not allowed: it is the rounding error of t = "
                         f"{start[0]!r} s, at most an ulp of it ({math.ulp(start[0])!r} s)")
    return CheckedState(point, counts, t_start, start[:4], _counts("state restart", restart), t_low,
                        _errors("state restart", restart))


def _errors(name: str, restart: RestartPoint) -> tuple:
    """The error estimate's fields of a restart point, checked."""
    error_x = validation.finite(f"{name} error_x", restart.error_x, "m")
    error_v = validation.finite(f"{name} error_v", restart.error_v, "m/s")
    bound = validation.non_negative(f"{name} error_bound", restart.error_bound, "m")
    scale = validation.non_negative(f"{name} height_scale", restart.height_scale, "m")
    since = None if restart.untrusted_from is None else validation.finite(f"{name} untrusted_from",
                                                                         restart.untrusted_from, "s")
    error_xv = validation.in_closed_range(f"{name} error_xv", restart.error_xv, -1.0, 1.0)
    error2_x = validation.non_negative(f"{name} error2_x", restart.error2_x, "m")
    error2_v = validation.non_negative(f"{name} error2_v", restart.error2_v, "m/s")
    error2_xv = validation.in_closed_range(f"{name} error2_xv", restart.error2_xv, -1.0, 1.0)
    return error_x, error_v, bound, since, scale, error_xv, error2_x, error2_v, error2_xv


def _check_side(ball: Ball, settings: CvodeSettings, name: str, point, start, h) -> None:
    """ValueError if point's mode contradicts its height h [m]: in flight below R, in contact above it.

    Within the margin the phase machine lets CVODE's own steps stray to the other side of R (phases.side_margin,
    of the phase's length from its start, or from the point if larger), which a saved state may show. A state
    beyond it would send the machine on a flight from inside the ground (a division by zero) or a contact
    above it.
    """
    t, x, v, mode, F_ext = point
    load, rtol = load_value(F_ext, ball.m, ball.g), settings.rtol
    atol = 0.0 if settings.atol is None else settings.atol
    length = max(frame(ball.parameters, mode, x, v, load, rtol, atol)[0],
                 frame(ball.parameters, start[3], start[1], start[2], load, rtol, atol)[0])
    margin = side_margin(hop_tolerance(ball, rtol, settings.atol, F_ext), rtol, length)
    if on_wrong_side(mode, x, margin):
        where = "at or above" if mode == Mode.FLIGHT else "at or below"
        raise ValueError(f"{name} h = {h!r} m (h - R = {x!r} m) is not allowed in {mode.name.lower()}: "
                         f"it must be {where} R = {ball.R!r} m (within {margin:.3g} m, CVODE's own margin)")


def _point(ball: Ball, name: str, t, gap, h, v, mode, F_ext=0.0) -> tuple[float, float, float, Mode, float]:
    """(t, x, v, mode, F_ext) of a saved state, each field checked; h None: the gap alone."""
    t = validation.finite(f"{name} t", t, "s")
    v = validation.finite(f"{name} v", v, "m/s")
    F_ext = validation.finite(f"{name} F_ext", F_ext, "N")
    try:
        mode = Mode(mode)
    except ValueError:
        raise ValueError(f"{name} mode = {mode!r} is not allowed: it must be one of "
                         f"{', '.join(f'{m.value} ({m.name})' for m in Mode)}") from None
    if h is None:
        return t, validation.finite(f"{name} gap", gap, "m"), v, mode, F_ext
    h = validation.finite(f"{name} h", h, "m")
    x = h - ball.R
    if gap is not None:
        x = validation.finite(f"{name} gap", gap, "m")
        if not abs((ball.R + x) - h) <= 2.0 * math.ulp(max(abs(h), ball.R)):
            raise ValueError(f"{name} gap = {x!r} m is not allowed with h = {h!r} m: R + gap must be h "
                             f"(R = {ball.R!r} m)")
    return t, x, v, mode, F_ext


def _counts(name: str, saved) -> Counts:
    counts = [saved.impacts, saved.departures, saved.rhs_calls, saved.steps]
    if not all(isinstance(n, numbers.Integral) and not isinstance(n, bool) and n >= 0 for n in counts):
        raise ValueError(f"{name} counts (impacts, departures, rhs_calls, steps) = {counts} are not allowed: "
                         "they must be integers >= 0")
    last_impact = None if saved.last_impact_time is None else validation.finite(
        f"{name} last_impact_time", saved.last_impact_time, "s")
    return int(saved.impacts), int(saved.departures), last_impact, int(saved.rhs_calls), int(saved.steps)
