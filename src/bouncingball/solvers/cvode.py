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

from .. import limits, validation
from ..limits import check_resolvable, resolvable_until
from ..physics import Ball, Mode, gap_acceleration, load_value, rest_margin_value
from . import forcing, sksundae_events
from .dense_output import interpolate, step_state
from .exact import time_to_departure, time_to_impact, velocity_at_departure
from .forcing import ForceTable
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
# Each contact's departure speed comes out ~20 rtol off (CVODE's local errors over its ~50 steps),
# and a ball that keeps its energy keeps those errors: event times drift with the square of the
# number of bounces. Measured with the state scaled to each phase: at 1e-11 an R = 1 um ball of
# 912 events ends 2e-5 of its height scale off; at 1e-12 5e-8, in 8% fewer steps (Adams' order
# rises); the article 1e-10 m.
DEFAULT_RTOL = 1e-12
# No absolute bound by default: CVODE integrates the gap x = h - R scaled to each phase (see
# phase_scales), so rtol is relative to the phase's own size whatever R, the drop height or the
# stiffness. An atol, where given, only tightens that rule.
DEFAULT_ATOL = None
# The contact oscillator is stiff for Adams when it is strongly over-damped (fast and slow rates
# far apart). A high natural frequency alone is not: a bounce must be resolved for accuracy
# anyway, where Adams beats BDF (an undamped k = 1e8 N/m ball over 39 contacts: 1.1e-9 m in 1707
# steps against 5.7e-8 m in 3842), and a rest, where BDF's large steps paid off, is taken in
# closed form.
STIFF_DAMPING_RATIO = 2.0

_CV_ROOT_RETURN = 2
_EPS = 2.0**-52
# A phase whose length scale [m] is below this (a hop or contact of 1e-200 m) is taken on the exact
# flow: its scaled state would leave the range of double precision.
MIN_PHASE_SCALE = 1e-200
# A hop whose apex is within this many rtol of the static deflection above R cannot be told from the
# contact's own error (CVODE controls the contact relative to its amplitude, ~ the deflection near rest).
HOP_RESOLUTION = 10.0
MERGED_HOP_MARGIN = 10.0
SOFT_CONTACT_CAP = 1e3  # a contact's length scale is at most this many max(R, |gap|): see phase_scales
# The value the root function h - R takes at h == R: the mode's own side (see _make_solver).
_OWN_SIDE = 1e-300
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
    """rtol [-], atol [m] (None: no absolute bound), method ("auto", "Adams", "BDF"), max_step [s] (0: none), engine.

    rtol is relative to each phase's own scale (see phase_scales); atol, where given, is an upper
    bound on the absolute error of h and never loosens that rule.

    engine: "sksundae" (scikit-sundae's CVODE with Python callbacks), "compiled" (the same CVODE
    library driven by compiled callbacks and a compiled stepping loop, needs numba) or "auto"
    (compiled where it can run); see choose_engine.
    """

    rtol: float = DEFAULT_RTOL
    atol: float | None = DEFAULT_ATOL
    method: str = "auto"
    max_step: float = 0.0
    engine: str = "auto"

    def __post_init__(self) -> None:
        """Check every setting before the settings exist."""
        object.__setattr__(self, "rtol", validation.in_range("rtol", self.rtol, 0.0, 1.0))
        if self.atol is not None:
            object.__setattr__(self, "atol", validation.positive("atol", self.atol, "m"))
        object.__setattr__(self, "method", validation.choice("method", self.method, METHODS))
        object.__setattr__(self, "max_step", validation.non_negative("max_step", self.max_step, "s"))
        object.__setattr__(self, "engine", validation.choice("engine", self.engine, ENGINES))


def hop_tolerance(ball: Ball, rtol: float = DEFAULT_RTOL, atol: float | None = DEFAULT_ATOL,
                  F_ext: float = 0.0) -> float:
    """The highest hop [m] above R that CVODE may merge into the contact around it: the tolerance's one hop rule.

    Near rest CVODE controls a contact to rtol times its amplitude, which is then about the static
    deflection d, so a hop rising less than HOP_RESOLUTION rtol d above R cannot be told from that
    error: a contact that cannot lift the ball higher is taken as a rest, and a flight lower than
    that is taken in closed form. An undamped contact never comes to rest (its energy is kept), and
    neither does a lifted one (d <= 0): there the rule is 0, every hop is integrated.
    """
    d = ball.static_deflection(F_ext)
    if ball.b == 0.0 or not d > 0.0:
        return 0.0
    tolerance = HOP_RESOLUTION * rtol * d
    return tolerance if atol is None else min(tolerance, HOP_RESOLUTION * atol)


def merged_hop_limit(ball: Ball, rtol: float = DEFAULT_RTOL, atol: float | None = DEFAULT_ATOL,
                     F_ext: float = 0.0) -> float:
    """The highest hop [m] a CVODE result may lack or add against the exact solution: MERGED_HOP_MARGIN hop_tolerance.

    CVODE decides a rest on its own state, which is off by its tolerance, so a hop a little above
    hop_tolerance may be merged too. The one rule every comparison with the exact solution uses.
    """
    return MERGED_HOP_MARGIN * hop_tolerance(ball, rtol, atol, F_ext)


def phase_scales(ball: Ball, mode: Mode, x: float, v: float, F_ext: float = 0.0) -> tuple[float, float]:
    """The length [m] and speed [m/s] a phase from the gap x = h - R [m] and v [m/s] is integrated relative to.

    In flight the apex above R and the speed at impact; in contact the amplitude of the
    oscillation about the rest height (at most SOFT_CONTACT_CAP max(R, |x|)) and its largest speed.
    CVODE integrates x / length and v / speed, so its error is rtol times the phase's own size: a
    1.6e-9 m hop or a contact deflecting the ball by 1e-9 R after a 100 m fall are resolved as well
    as the article's bounce.
    A flight that never comes down is scaled by its height (at least R).
    """
    if mode == Mode.FLIGHT:
        g_eff = ball.effective_gravity(F_ext)
        if g_eff > 0.0:
            length = max(x, 0.0) + 0.5 * (max(v, 0.0) / math.sqrt(g_eff)) ** 2
            return length, math.sqrt(2.0 * g_eff * length)
        length = max(abs(x), ball.R)
        return length, max(abs(v), math.sqrt(2.0 * abs(g_eff) * length), length)
    w = ball.natural_frequency
    amplitude = math.hypot(x + ball.static_deflection(F_ext), v / w)
    # Never far beyond the scene's own scale: a contact so soft that its amplitude dwarfs R (k/m = 7e-12
    # 1/s2, 6e120 m against R = 3e97 m) is left long before it gets there, and rtol times the amplitude
    # was 4e-6 of the ball's whole motion. (A cap at max(R, |x|) itself cost an R = 1 um ball, whose
    # contact swings 1.3 R, 17 times its accuracy.)
    length = min(amplitude, SOFT_CONTACT_CAP * max(ball.R, abs(x)))
    return length, w * length


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
    gap: float | None = None  # h - R [m] to every digit (h rounds a deflection to ulp(R)); None: h - R


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
        limits.check_scene(ball, h0, v0, F_ext, t0)
        self.resolvable_until = resolvable_until(ball)
        check_resolvable(ball, t0)
        self._logs = {mode: SundialsLog() for mode in Mode}
        self._cvode_called = False
        self.engine, self.engine_reason = choose_engine(self.settings.engine)
        self._solvers: dict[Mode, CVODE] = {}
        self._event_functions = {}
        # The phase's frame: CVODE's time is t - origin, its state (x / length, v / speed); see _start_frame.
        self._frames = {mode: [0.0, 1.0, 1.0, 0.0] for mode in Mode}  # origin, length, speed, hop tolerance
        for mode in Mode:
            make = self._make_compiled_solver if self.engine == "compiled" else self._make_solver
            self._solvers[mode], self._event_functions[mode] = make(mode)
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

    def _make_compiled_solver(self, mode: Mode):
        """The same CVODE set-up as _make_solver, with the callbacks compiled from physics.py."""
        from .compiled import PhaseSolver

        s = self.settings
        solver = PhaseSolver(self.ball, mode, self.methods[mode], s.rtol, s.max_step, _MAX_STEPS_PER_CALL,
                             self._own_side(mode), self._root_directions(mode), MAX_STEPS_PER_PHASE)
        return solver, None

    def _make_solver(self, mode: Mode):
        ball = self.ball
        m, k, b = ball.m, ball.k, ball.b
        w2, damping = k / m, b / m
        own_side = self._own_side(mode)
        contact = mode == Mode.CONTACT
        frame = self._frames[mode]

        # CVODE integrates x / length and v / speed (the frame's scales), in time from the frame's origin.
        def rhs(t, y, yp):
            _, length, speed, _ = frame
            yp[0] = (speed / length) * y[1]
            yp[1] = gap_acceleration(length * y[0], speed * y[1], mode, self._load, m, k, b) / speed

        def jac(t, y, yp, JJ):
            _, length, speed, _ = frame
            JJ[0, 0], JJ[0, 1] = 0.0, speed / length
            JJ[1, 0], JJ[1, 1] = (-w2 * length / speed, -damping) if contact else (0.0, 0.0)

        def event(t, y, out):
            _, length, speed, hop = frame
            out[0] = y[0] if y[0] != 0.0 else own_side
            # Under zero net gravity v never changes in flight: a root function identically 0 would
            # only make CVODE warn.
            out[1] = y[1] if contact or self._load != 0.0 else 1.0
            d = self._load / k  # ball.static_deflection, from the load kept for the phase (as the compiled roots)
            out[2] = rest_margin_value(length * y[0], speed * y[1], d, hop, w2) if contact and d > 0.0 else -1.0
            # CVODE evaluates the root functions once per step (and a few times per root found)
            self._phase_evaluations += 1
            if self._phase_evaluations > MAX_STEPS_PER_PHASE:
                raise self._too_many_steps(mode, t)

        event.terminal = [True, False, True]
        event.direction = self._root_directions(mode)
        s = self.settings
        # The scaled state is of order 1: atol = rtol asks for rtol times the phase's scale.
        solver = CVODE(rhs, method=self.methods[mode], rtol=s.rtol, atol=s.rtol, max_step=s.max_step,
                       eventsfn=event, num_events=3, jacfn=jac, max_num_steps=_MAX_STEPS_PER_CALL)
        return solver, event

    def _start_frame(self) -> tuple[float, float, float]:
        """Fix the current phase's frame at the current state; (origin [s], length [m], speed [m/s]).

        Scales from phase_scales, capped so that rtol length <= atol where atol is given.
        """
        s, mode = self.settings, self._mode
        length, speed = phase_scales(self.ball, mode, self._x, self._v, self._F_ext)
        if s.atol is not None and s.rtol * length > s.atol:
            speed *= s.atol / (s.rtol * length)
            length = s.atol / s.rtol
        hop = self.hop_tolerance
        self._frames[mode][:] = self._t, length, speed, hop
        if self.engine == "compiled":
            self._solvers[mode].set_frame(length, speed, hop)
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
            self._reinit_needed()
            self._F_ext = value
            self._sync_F_ext()

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

        A restored snapshot restarts CVODE there, so it continues within the tolerance of the
        original run, not bit for bit (CVODE's step history is not part of the snapshot).
        """
        return IntegratorState(t=self._t, h=self.h, v=self._v, mode=self._mode, F_ext=self._F_ext,
                               impacts=self._impacts, departures=self._departures,
                               last_impact_time=self._last_impact_time, t_start=self._t_start,
                               rhs_calls=self.rhs_calls, steps=self._steps, gap=self._x)

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
        x = h - self.ball.R
        if state.gap is not None:
            x = validation.finite("state gap", state.gap, "m")
            if not abs((self.ball.R + x) - h) <= 2.0 * math.ulp(max(abs(h), self.ball.R)):
                raise ValueError(f"state gap = {x!r} m is not allowed with h = {h!r} m: R + gap must be h "
                                 f"(R = {self.ball.R!r} m)")
        check_resolvable(self.ball, t)
        self._t, self._x, self._v, self._mode, self._F_ext = t, x, v, mode, F_ext
        self._impacts, self._departures = int(state.impacts), int(state.departures)
        self._last_impact_time, self._t_start = last_impact, t_start
        self._rhs_calls, self._steps = int(state.rhs_calls), int(state.steps)
        self._nfev_since_init = 0
        self._sync_F_ext()
        self._reinit_needed()

    def _sync_F_ext(self) -> None:
        """The load m g - F_ext for the right-hand side; the compiled callbacks read both from their parameters."""
        self._load = load_value(self._F_ext, self.ball.m, self.ball.g)
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
        _, length, speed = self._start_frame()
        with self._logs[self._mode].capturing():
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
                    x, v = step_state(self.ball, self._F_ext, mode, start, end, t_target)
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
                self._t, self._x, self._v = t_target, *self._rest_state(t_target)
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
            origin, length, speed, _ = self._frames[self._mode]
            tau_before = self._step_start[0] - origin
            result = solver.step(tau_before + _STEP_HORIZON, method="onestep")
            self._cvode_called = True
            self._check(result)
            self._nfev_since_init = result.nfev
            tau, x, v = float(result.t), length * float(result.y[0]), speed * float(result.y[1])
            end = (origin + tau, x, v)
            if result.status == _CV_ROOT_RETURN:
                roots = self._roots_found(self._mode)
                if roots[0]:
                    tau, v = self._polish_event(tau_before, (tau, x, v))
                    end = self._event_pending = (origin + tau, 0.0, v)
                elif roots[2]:
                    self._rest_from = end
                self._clear_roots(self._mode)
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
        t_end = grid[-1]
        check_resolvable(self.ball, t_end)
        times, gaps, velocities, modes = [], [], [], []
        events: list[Event] = []

        def record(ts, xs, vs, mode: Mode) -> None:
            """Keep a piece of trajectory in one mode (gaps x = h - R), and move to its last point."""
            times.append(ts)
            gaps.append(xs)
            velocities.append(vs)
            modes.append(np.full(len(ts), int(mode)))
            self._t, self._x, self._v = float(ts[-1]), float(xs[-1]), float(vs[-1])

        def record_to(end: tuple[float, float, float], mode: Mode) -> None:
            """A piece from here to end = (t, x, v) on the mode's exact flow."""
            record(np.array([self._t, end[0]]), np.array([self._x, end[1]]), np.array([self._v, end[2]]), mode)

        record(np.array([self._t]), np.array([self._x]), np.array([self._v]), self._mode)
        self._reinit_needed()
        resting = False  # set when CVODE stops at the start of a rest
        while self._t < t_end and not self._close_enough(t_end):
            mode = self._mode
            if resting or self._at_rest():
                self._rest_from = (self._t, self._x, self._v)
                record_to((t_end, *self._rest_state(t_end)), mode)
                break
            event = self._event_in_closed_form()
            if event is not None:
                reached = event[0] <= t_end
                if not reached:
                    x_end, v_end = self.ball.gap_flow(mode, self._x, self._v, t_end - self._t, self._F_ext)
                    event = (t_end, float(x_end), float(v_end))
                record_to(event, mode)
                if reached:
                    events.append(self._switch_mode())
                continue
            self._clear_roots(mode)
            origin, length, speed = self._start_frame()
            with self._logs[mode].capturing():
                result = self._solvers[mode].solve(np.array([0.0, t_end - origin]),
                                                   np.array([self._x / length, self._v / speed]))
            self._cvode_called = True
            self._check(result)
            taus, xs, vs = result.t.copy(), length * result.y[:, 0], speed * result.y[:, 1]
            xs[0], vs[0] = self._x, self._v  # the phase's start as it was, not scaled and back
            roots = self._roots_found(mode) if result.status == _CV_ROOT_RETURN else [0, 0, 0]
            root, resting = bool(roots[0]), bool(roots[2])
            if root:
                tau_before = float(taus[-2])
                taus[-1], vs[-1] = self._polish_event(tau_before, (float(taus[-1]), float(xs[-1]), float(vs[-1])))
                xs[-1] = 0.0
                self._check_step_ends(origin + tau_before, xs[:-1])
            else:
                self._check_step_ends(origin + float(taus[-1]), xs)
            self._clear_roots(mode)
            ts = origin + taus
            if not (root or resting):  # CVODE stopped at t_end - origin, which may round off t_end
                ts[-1] = t_end
            # A phase's first point is the previous phase's last: one copy per mode, so that no
            # dense-output segment straddles the switch.
            record(ts, xs, vs, mode)
            self._steps += len(ts) - 1
            self._rhs_calls += int(result.nfev)
            if root:
                events.append(self._switch_mode())
        if self._t > times[-1][-1]:  # finished by a Taylor step within a few ulps of t_end
            record(np.array([self._t]), np.array([self._x]), np.array([self._v]), self._mode)
        x_out, v_out = interpolate(self.ball, self._F_ext, np.concatenate(times), np.concatenate(gaps),
                                   np.concatenate(velocities), np.concatenate(modes), grid)
        return self.ball.R + x_out, v_out, events

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
        reaches R; so it does for a contact CVODE cannot resolve (_contact_unresolved).
        """
        if self._mode != Mode.CONTACT:
            return False
        ball, d = self.ball, self.ball.static_deflection(self._F_ext)
        if d > 0.0 and rest_margin_value(self._x, self._v, d, self.hop_tolerance, ball.k / ball.m) > 0.0:
            return True  # Ball.contact_is_permanent, in the gap
        undecided = ball.damping_ratio >= 1.0 or d <= 0.0 or self._contact_unresolved()
        return undecided and math.isinf(time_to_departure(ball, self._x, self._v, self._F_ext))

    def _rest_state(self, t: float) -> tuple[float, float]:
        """The gap x = h - R [m] and v [m/s] at t on a rest, on the contact's exact flow from where the rest began.

        Once at rest the ball's motion is the linear oscillator decaying to the rest height,
        which CVODE would only add its error to: where k/m ulp(R) is comparable to g, h cannot
        even represent the rest height, and the quantised spring force keeps CVODE's steps tiny.
        """
        t0, x0, v0 = self._rest_from
        x, v = self.ball.gap_flow(Mode.CONTACT, x0, v0, t - t0, self._F_ext)
        return float(x), float(v)

    def _contact_unresolved(self) -> bool:
        """In a contact CVODE cannot decide: smaller than MIN_PHASE_SCALE, or resting too close to R.

        Below MIN_PHASE_SCALE its scaled state would not be representable. A rest height closer to R
        than CVODE resolves (HOP_RESOLUTION rtol the contact's amplitude) makes CVODE's x cross 0 or not
        by its own error: a ball creeping to a rest height 1e-23 m below R (F_ext within 2e-16 N of its
        weight), integrated to 5e-19 m, left the ground and came back.
        """
        length, speed = phase_scales(self.ball, Mode.CONTACT, self._x, self._v, self._F_ext)
        if not (length >= MIN_PHASE_SCALE and speed > 0.0):
            return True
        return abs(self.ball.static_deflection(self._F_ext)) < HOP_RESOLUTION * self.settings.rtol * length

    def _event_in_closed_form(self) -> tuple[float, float, float] | None:
        """The event (t, x = 0, v) ending the current phase if CVODE is not to integrate it, else None.

        A flight whose apex stays within hop_tolerance of R (a hop merged into the contacts around it
        would be as right) or below MIN_PHASE_SCALE. A contact CVODE cannot resolve
        (_contact_unresolved) that ends. A contact that cannot hold the ball (F_ext lifts more than its
        weight: the rest height is above R), which always ends, but may creep towards a rest height
        closer to R than CVODE resolves, where h never visibly crosses R (a weightless ball lifted by
        1e-6 N stayed at R instead of flying 4.5e-6 m in 3 s). Each mode's flow is exact, so such a
        phase is taken in closed form: events of the right kind at the right times.
        """
        ball, x, v = self.ball, self._x, self._v
        if self._mode == Mode.CONTACT:
            if not (ball.static_deflection(self._F_ext) < 0.0 or self._contact_unresolved()):
                return None
            tau = time_to_departure(ball, x, v, self._F_ext)
            if math.isinf(tau):
                return None
            return self._t + tau, 0.0, velocity_at_departure(ball, x, v, tau, self._F_ext)
        if x < 0.0:
            return None
        g_eff = ball.effective_gravity(self._F_ext)
        if not g_eff > 0.0:
            return None
        apex, _ = phase_scales(ball, Mode.FLIGHT, x, v, self._F_ext)
        if not apex < max(self.hop_tolerance, MIN_PHASE_SCALE):
            return None
        tau, v_impact = time_to_impact(x, v, g_eff)
        return self._t + tau, 0.0, v_impact

    def _polish_event(self, tau_before: float, root: tuple[float, float, float]) -> tuple[float, float]:
        """The crossing of x = 0 that CVODE located at root = (tau, x, v) in the phase's frame: (tau, v) there.

        CVODE locates a root to ~100 ulps of its time, on its own trajectory, which is off the true
        one by its tolerance: a long fall leaves x off by ~rtol times the drop height where CVODE
        says 0. The next phase starts at x = 0 exactly; its start time and speed come from Newton
        on the mode's exact flow from the root, however large the correction (a 1e-11 m error of
        the fall against a contact deflecting the ball by 6e-9 m: a departure 9e-6 too fast when
        the root was kept). At a departure the damper's force also jumps the acceleration by b v /
        m, so a time error becomes a velocity error. A correction that does not converge, or that
        would go back past the step's start, keeps CVODE's root (a grazing root, v ~ 0). An impact
        never leaves upwards, a departure never downwards.
        """
        ball, mode, F_ext = self.ball, self._mode, self._F_ext
        tau_root, x_root, v_root = root
        length = self._frames[mode][1]
        tau, x, v = 0.0, x_root, v_root
        for _ in range(8):
            if x == 0.0 or v == 0.0:
                break
            correction = x / v
            tau -= correction
            x, v = ball.gap_flow(mode, x_root, v_root, tau, F_ext)
            if abs(correction) <= 2.0 * _EPS * abs(tau_root + tau):
                break
        if abs(x) <= 16.0 * _EPS * length and tau_root + tau >= tau_before:
            tau_root, v_root = tau_root + tau, float(v)
        return tau_root, (min(v_root, 0.0) if mode == Mode.FLIGHT else max(v_root, 0.0))

    def _check_side(self, t: float, x: float) -> None:
        """A step end (gap x [m] at t) must lie on the mode's side of R: else CVODE stepped over an event unseen."""
        flight = self._mode == Mode.FLIGHT
        margin = max(self.hop_tolerance, HOP_RESOLUTION * self.settings.rtol * self._frames[self._mode][1])
        if (x < -margin) if flight else (x > margin):
            R = self.ball.R
            raise SolverError(f"CVODE stepped over an {'impact' if flight else 'departure'} unseen near "
                              f"t = {t!r} s (h = {R + x!r} m, R = {R!r} m); "
                              "the result would be wrong: tighten rtol/atol or set max_step")

    def _check_step_ends(self, t: float, gaps: np.ndarray) -> None:
        """_check_side for a phase's step ends up to t: only the extreme on the side an unseen event would leave."""
        self._check_side(t, float(gaps.min() if self._mode == Mode.FLIGHT else gaps.max()))

    def _close_enough(self, t_target: float) -> bool:
        """Within a few ulps of t_target CVODE refuses to step (CV_TOO_CLOSE): finish by Taylor."""
        dt = t_target - self._t
        if dt > 32.0 * math.ulp(max(abs(t_target), abs(self._t), 1e-300)):
            return False
        a = self.acceleration
        self._t, self._x, self._v = t_target, self._x + dt * (self._v + 0.5 * dt * a), self._v + dt * a
        return True

    def _check(self, result) -> None:
        if result.status < 0 and self.engine == "compiled" and self._solvers[self._mode].exceeded:
            raise self._too_many_steps(self._mode, float(np.atleast_1d(result.t)[-1]))
        if result.status < 0:
            t = float(np.atleast_1d(result.t)[-1])
            raise SolverError(f"CVODE failed at t = {t!r} s ({self._mode.name.lower()}, "
                              f"h = {self.h!r} m, v = {self._v!r} m/s): {result.message}")

    def _switch_mode(self) -> Event:
        self._reinit_needed()
        if self._mode == Mode.FLIGHT:
            self._mode, self._impacts, self._last_impact_time = Mode.CONTACT, self._impacts + 1, self._t
            return Event(self._t, IMPACT, self._v)
        self._mode, self._departures = Mode.FLIGHT, self._departures + 1
        return Event(self._t, DEPARTURE, self._v)


def _integrate_pieces(ball: Ball, h0: float, v0: float, grid: np.ndarray, table: ForceTable,
                      settings: CvodeSettings) -> tuple[BallIntegrator, np.ndarray, np.ndarray, list[Event]]:
    """integrate_grid piece by piece of constant F_ext: each piece's grid is its output times and its ends.

    The integrator restarts CVODE where its F_ext changes (the state continuous, the mode held); a
    grid point on a change time is the state there, taken at the end of the piece before.
    """
    constant_pieces = forcing.pieces(table, float(grid[0]), float(grid[-1]))
    integrator = BallIntegrator(ball, h0, v0, float(grid[0]), constant_pieces[0][2], settings)
    h, v = np.empty_like(grid), np.empty_like(grid)
    h[0], v[0] = integrator.h, integrator.v
    events: list[Event] = []
    for start, end, F_ext in constant_pieces:
        integrator.F_ext = F_ext
        inside = (grid > start) & (grid <= end)
        times = np.concatenate(([start], grid[inside]))
        if times[-1] < end:
            times = np.append(times, end)
        h_piece, v_piece, piece_events = integrator.integrate_grid(times)
        count = int(np.count_nonzero(inside))
        h[inside], v[inside] = h_piece[1:1 + count], v_piece[1:1 + count]
        events += piece_events
    return integrator, h, v, events


def simulate_cvode(ball: Ball, h0: float, v0: float, t_end: float, output_interval: float,
                   t_start: float = 0.0, F_ext: float | ForceTable = 0.0, rtol: float = DEFAULT_RTOL,
                   atol: float | None = DEFAULT_ATOL, method: str = "auto", max_step: float = 0.0,
                   engine: str = "auto") -> SimulationResult:
    """Integrate with CVODE from t_start to t_end and return the solution on the output grid.

    engine: see CvodeSettings; the engine that ran and why are in result.stats. F_ext: a constant [N]
    or a forcing.ForceTable, integrated piece by piece of constant force.
    """
    settings = CvodeSettings(rtol=rtol, atol=atol, method=method, max_step=max_step, engine=engine)
    grid = output_grid(t_start, t_end, output_interval)
    started = time.perf_counter()
    if isinstance(F_ext, ForceTable):
        integrator, h, v, events = _integrate_pieces(ball, h0, v0, grid, F_ext, settings)
    else:
        integrator = BallIntegrator(ball, h0, v0, t_start, F_ext, settings)
        h, v, events = integrator.integrate_grid(grid)
    wall_time = time.perf_counter() - started
    stats = SolverStats(steps=integrator.steps, rhs_calls=integrator.rhs_calls, events=len(events),
                        wall_time=wall_time, engine=integrator.engine, engine_reason=integrator.engine_reason)
    options = {"rtol": settings.rtol, "atol": settings.atol, "method": settings.method,
               "contact_method": integrator.methods[Mode.CONTACT], "max_step": settings.max_step,
               "engine": settings.engine}
    return SimulationResult("cvode", ball, grid, h, v, events, integrator.rest_time, stats, F_ext, options)
