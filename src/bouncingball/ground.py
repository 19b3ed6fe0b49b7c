"""The ground under the ball: still (at a height), a sinusoidally vibrating table, or positions from a table.

h stays the height of the ball's centre in the world frame; the ball touches the ground where its gap
h - R - s(t) is 0, s(t) the ground's height [m]. A still ground at height 0 is the model without a ground.

Besides its motion (position, velocity, acceleration), the ground answers the two questions a rigid ball
asks of it: where a flight's gap first reaches 0 (`first_touch`: a guaranteed first root, never a grazing
impact stepped over) and where a ball riding it is thrown off (`ride_end`: where its acceleration falls below
-(g - F_ext / m)).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from . import validation
from .equations import sine_ride_end

_EPS = 2.0**-52
MAX_TABLE_ENTRIES = validation.MAX_TABLE_ENTRIES
# The search for a flight's first touch gives up (RuntimeError, saying where) after this many certified steps
# rather than loop for ever: a safeguard; the grazing family's flights (tests/table_scenes.py) take at most 12.
MAX_TOUCH_STEPS = 100_000
# A bound whose root is computed in floats is stepped to just short of it: what numpy's root may overshoot.
_SHORT_OF_ROOT = 1.0 - 1e-9
# A sine's ranges in double precision (the FMU's ground_* too): its bound A w^4 neither underflows nor overflows, and
# sin(w t + phase) keeps the digits a short step needs (a phase of 1e13 rad put a free fall 4e-6 m off).
SINE_AMPLITUDE_RANGE = (1e-100, 1e100)  # m (0: a still ground)
SINE_FREQUENCY_RANGE = (1e-6, 1e6)  # Hz
SINE_PHASE_RANGE = (-1e4, 1e4)  # rad: a larger phase, reduced modulo 2 pi, is the same table
SINE_RANGE_WHY = "the range double precision resolves"


def checked_sine(amplitude, frequency, phase, names=("ground amplitude", "ground frequency", "ground phase")):
    """(amplitude [m], frequency [Hz], phase [rad]) as floats, each in its SINE_*_RANGE; else ValueError by names."""
    ranges = (SINE_AMPLITUDE_RANGE, SINE_FREQUENCY_RANGE, SINE_PHASE_RANGE)
    return tuple(validation.in_closed_range(name, value, *bounds, unit, why=SINE_RANGE_WHY) for name, value, bounds,
                 unit in zip(names, (amplitude, frequency, phase), ranges, ("m", "Hz", "rad"), strict=True))


@dataclass(frozen=True)
class Ground:
    """The ground's height s(t) [m] under the ball: still, a sine, or a cubic spline through a table.

    Make one with `Ground.still`, `Ground.sine` or `Ground.table`.

    Attributes
    ----------
    kind : {"still", "sine", "table"}
        How it moves.
    height : float
        A still ground's height [m].
    amplitude, frequency, phase : float
        A sine's s(t) = amplitude sin(2 pi frequency t + phase) [m, Hz, rad].
    times, positions : tuple of float
        A table's points (t [s], s [m]).
    """

    kind: str = "still"
    height: float = 0.0
    amplitude: float = 0.0
    frequency: float = 0.0
    phase: float = 0.0
    times: tuple[float, ...] = ()
    positions: tuple[float, ...] = ()
    _spline: object = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        """A Ground made other than by its three constructors is checked as they check theirs."""
        kind = validation.choice("ground kind", self.kind, ("still", "sine", "table"))
        if kind == "sine":
            checked_sine(self.amplitude, self.frequency, self.phase)
        if kind == "table" and self._spline is None:
            raise ValueError("ground kind = 'table' is not allowed without its spline: make it with Ground.table(t, s)")
        if kind == "still":
            validation.finite("ground height", self.height, "m")

    @classmethod
    def still(cls, height: float = 0.0) -> Ground:
        """A ground at rest at height [m] (0: the ground of a Ball alone)."""
        return cls("still", height=validation.finite("ground height", height, "m"))

    @classmethod
    def sine(cls, amplitude: float, frequency: float, phase: float = 0.0) -> Ground:
        """A table vibrating as s(t) = amplitude sin(2 pi frequency t + phase).

        Parameters
        ----------
        amplitude : float
            [m], 0 (a still ground at 0) or in [1e-100, 1e100].
        frequency : float
            [Hz], in [1e-6, 1e6].
        phase : float, optional
            [rad], in [-1e4, 1e4] (reduce a larger one modulo 2 pi).
        """
        if validation.non_negative("ground amplitude", amplitude, "m") == 0.0:
            validation.positive("ground frequency", frequency, "Hz")
            validation.finite("ground phase", phase, "rad")
            return cls.still()
        amplitude, frequency, phase = checked_sine(amplitude, frequency, phase)
        return cls("sine", amplitude=amplitude, frequency=frequency, phase=phase)

    @classmethod
    def table(cls, t, s) -> Ground:
        """The ground through the points (t [s], s [m]), a C2 cubic spline (scipy's, not-a-knot ends).

        The ride's end and an impact's saltation need s'', so the positions are not joined by lines. A run
        must stay within [t[0], t[-1]]: past the table's ends the ground is not known, and such a run is
        refused before it starts.

        Parameters
        ----------
        t : sequence of float
            Times [s], at least 4, strictly increasing.
        s : sequence of float
            The ground's height [m] at each time.
        """
        times = _entries("ground table times", t, "s")
        positions = _entries("ground table positions", s, "m")
        if len(times) != len(positions):
            raise ValueError(f"ground table is not allowed: {len(times)} times but {len(positions)} positions "
                             "(they must be as many)")
        if not 4 <= len(times) <= MAX_TABLE_ENTRIES:
            raise ValueError(f"ground table of {len(times)} points is not allowed: it must have from 4 to "
                             f"{MAX_TABLE_ENTRIES:.0e} (a cubic spline through them)")
        later = times[1:] > times[:-1]
        if not later.all():
            i = int(np.flatnonzero(~later)[0]) + 1
            raise ValueError(f"ground table times[{i}] = {float(times[i])!r} s is not allowed: the times must "
                             f"increase strictly (times[{i - 1}] = {float(times[i - 1])!r} s)")
        from scipy.interpolate import CubicSpline  # scikit-sundae's dependency: no extra

        return cls("table", times=tuple(times.tolist()), positions=tuple(positions.tolist()),
                   _spline=CubicSpline(times, positions))

    # --- its motion ------------------------------------------------------------------------------------------
    @property
    def moves(self) -> bool:
        """Whether the ground moves (a sine or a table)."""
        return self.kind != "still"

    @property
    def omega(self) -> float:
        """A sine's angular frequency 2 pi frequency [rad/s]."""
        return 2.0 * math.pi * self.frequency

    def derivative(self, t, order: int):
        """The order-th time derivative of s at the times t [s] (0: the height [m]; arrays allowed)."""
        if self.kind == "still":
            value = self.height if order == 0 else 0.0
            return value if np.ndim(t) == 0 else np.full(np.shape(t), value)
        if self.kind == "sine":
            w = self.omega
            if type(t) is float:  # the searches' scalars: math, not numpy's array machinery (5x faster)
                return self.amplitude * w**order * math.sin(w * t + self.phase + 0.5 * math.pi * order)
            angle = w * np.asarray(t, dtype=float) + self.phase + 0.5 * math.pi * order
            value = self.amplitude * w**order * np.sin(angle)
            return float(value) if np.ndim(t) == 0 else value
        value = self._spline(t, order) if order <= 3 else 0.0 * np.asarray(t, dtype=float)
        return float(value) if np.ndim(t) == 0 else np.asarray(value)

    def position(self, t):
        """s(t) [m]."""
        return self.derivative(t, 0)

    def velocity(self, t):
        """s'(t) [m/s]."""
        return self.derivative(t, 1)

    def acceleration(self, t):
        """s''(t) [m/s2]."""
        return self.derivative(t, 2)

    def rise(self, t0: float, tau: float) -> float:
        """s(t0 + tau) - s(t0) [m], without the cancellation of the difference of two heights for a short tau."""
        if self.kind == "sine":
            w = self.omega
            return 2.0 * self.amplitude * math.cos(w * (t0 + 0.5 * tau) + self.phase) * math.sin(0.5 * w * tau)
        return float(self.position(t0 + tau)) - float(self.position(t0))

    @functools.cached_property
    def _knots(self) -> np.ndarray:
        """A table's times as an array, made once."""
        return np.asarray(self.times, dtype=float)

    @functools.cached_property
    def _position_array(self) -> np.ndarray:
        return np.asarray(self.positions, dtype=float)

    @functools.cached_property
    def _largest_position(self) -> float:
        return max((abs(p) for p in self.positions), default=abs(self.height))

    @property
    def acceleration_bound(self) -> float:
        """The largest |s''| [m/s2] anywhere (a spline's s'' is linear between its points)."""
        if self.kind == "sine":
            return self.amplitude * self.omega**2
        if self.kind == "table":
            return float(np.max(np.abs(self._spline(self._knots, 2))))
        return 0.0

    def describe(self) -> str:
        """One line saying what the ground does."""
        if self.kind == "still":
            return f"still ground at {self.height:g} m"
        if self.kind == "sine":
            return (f"ground s(t) = {self.amplitude:g} m sin(2 pi {self.frequency:g} Hz t + {self.phase:g} rad)")
        return f"ground through {len(self.times)} points from {self.times[0]:g} s to {self.times[-1]:g} s"

    def check_covers(self, t_start: float, t_end: float) -> None:
        """ValueError before a run from t_start to t_end [s] that leaves a table's times."""
        if self.kind == "table" and not self.times[0] <= t_start <= t_end <= self.times[-1]:
            raise ValueError(f"ground table from {self.times[0]!r} s to {self.times[-1]!r} s is not allowed for a "
                             f"run from {t_start!r} s to {t_end!r} s: it must cover the run (past its ends the "
                             "ground is not known); extend the table or shorten the run")

    # --- what a rigid ball asks of it ------------------------------------------------------------------------
    def ride_end(self, t: float, a: float) -> float:
        """The first time >= t [s] at which s'' < -a: where a ball riding the ground under a = g - F_ext/m leaves.

        t itself where s''(t) < -a already; inf where it never does.
        """
        if self.kind == "still":
            return t if a < 0.0 else math.inf
        if self.kind == "sine":
            return sine_ride_end(self.amplitude, self.omega, self.phase, t, a)
        return _table_ride_end(self, t, a)

    def touch_rounding(self, t0: float, x0: float, v0: float, a: float, tau: float) -> float:
        """The rounding [m] of a flight's gap to the ground tau [s] after t0, as first_touch computes it.

        16 ulps of the terms it sums: the flight's (|x0| + |v0| tau + |a| tau^2 / 2) and the ground's rise,
        whose angle w t + p carries an ulp of itself.
        """
        spread = abs(x0) + abs(v0) * tau + 0.5 * abs(a) * tau * tau
        if self.kind == "sine":
            t = t0 + tau
            spread += self.amplitude * (1.0 + abs(self.omega * t + self.phase) * min(self.omega * tau, 2.0))
        elif self.kind == "table":
            spread += self._largest_position
        return 16.0 * _EPS * spread


def _table_ride_end(ground: Ground, t: float, a: float) -> float:
    """The first time >= t [s] at which a table ground's s'' < -a: on its spline s'' is linear between knots."""
    times = ground._knots
    if float(ground.acceleration(t)) < -a:
        return t
    i = max(int(np.searchsorted(times, t, side="right")) - 1, 0)
    knots = np.concatenate(([t], times[i + 1:]))
    second = np.asarray(ground._spline(knots, 2)) + a  # linear between knots
    below = np.flatnonzero(second[1:] < 0.0)
    if len(below) == 0:
        return math.inf
    j = int(below[0])
    t0, t1, y0, y1 = knots[j], knots[j + 1], second[j], second[j + 1]
    return float(min(max(t0 + (t1 - t0) * y0 / (y0 - y1), t0), t1))


def first_touch(ground: Ground, t0: float, x0: float, v0: float, a: float, horizon: float,
                on_ground: bool = False) -> float:
    """tau [s]: the first time after t0 at which a flight reaches the ground; inf if not within horizon [s].

    The flight's height above R is x0 + v0 tau - a tau^2 / 2 (x0 [m], v0 [m/s], a [m/s2]), its gap that less
    s(t0 + tau); on_ground: it starts on the ground (a rebound, a ride's end), its gap 0 there exactly. Certified:
    each step goes to the first root of a lower bound of the gap (_safe_step; a spline's gap is a cubic per piece,
    taken exactly), so the steps converge on the first root from before it and no graze is stepped over; a gap
    within its rounding of 0 is a touch.
    """
    gap0 = 0.0 if on_ground else x0 - float(ground.position(t0))
    tau, steps = 0.0, 0
    rate_bound = ground.amplitude * ground.omega**4 if ground.kind == "sine" else 0.0
    while tau <= horizon:
        gap, slope, curve, jerk, rounding = _gap_terms(ground, t0, gap0, v0, a, tau)
        # on the ground within its rounding: a touch, but not the start a flight leaves from
        if gap <= rounding and (tau > 0.0 or (slope < 0.0 and not on_ground)):
            return tau
        steps += 1
        if steps > MAX_TOUCH_STEPS:
            raise RuntimeError(f"the search for the flight's touch from t = {t0!r} s made {steps} steps: "
                               "neither a touch nor a way past one")
        if tau == 0.0 and on_ground and slope == 0.0:  # a lift-off with the ground: its gap's curvature is >= 0
            curve = max(curve, 0.0)  # (0 at a ride's end, but for the rounding of s'' there)
        step = _safe_step(ground, t0 + tau, max(gap, 0.0), slope, curve, jerk, rate_bound, abs(a))
        if not step > 0.0:
            return tau
        tau += step
        if ground.kind == "table":  # past the pieces the gap is certified positive on, in one numpy pass
            tau = _certified_pieces_end(ground, t0, gap0, v0, a, tau, horizon)
    return math.inf


def _gap_terms(ground, t0, gap0, v0, a, tau):
    """(gap, its first three derivatives, rounding) of the flight tau after t0; rounding: the gap's own [m]."""
    t = t0 + tau
    gap = gap0 + tau * (v0 - 0.5 * a * tau) - ground.rise(t0, tau)
    slope = v0 - a * tau - float(ground.velocity(t))
    curve = -a - float(ground.acceleration(t))
    jerk = -float(ground.derivative(t, 3))
    return gap, slope, curve, jerk, ground.touch_rounding(t0, gap0, v0, a, tau)


def _safe_step(ground, t, gap, slope, curve, jerk, rate_bound, pull):
    """The first root of a lower bound of the gap from t: a step it cannot vanish within.

    First the quadratic bound gap + gap' d - M d^2 / 2, M = pull + A w^2 >= |gap''| (in closed form); where its
    step is short (a graze, the cubic start after a ride) the quartic one, which knows the second and third
    derivatives. Each bounds the gap below, so the longer of the two steps is as safe.
    """
    if ground.kind == "table":
        return _table_step(ground, t, gap, slope, curve, jerk)
    bound = pull + ground.acceleration_bound
    root = math.sqrt(slope * slope + 2.0 * bound * gap)
    quadratic = (slope + root) / bound if slope >= 0.0 else 2.0 * gap / (root - slope) if root > slope else 0.0
    if quadratic * ground.omega > 1e-2:
        return _SHORT_OF_ROOT * quadratic
    coefficients = [-rate_bound / 24.0, jerk / 6.0, curve / 2.0, slope, gap]
    return _SHORT_OF_ROOT * max(quadratic, _first_positive_root(coefficients))


def _table_step(ground, t, gap, slope, curve, jerk):
    """To the next knot, or to the exact cubic's first root before it (a spline's gap is a cubic per piece)."""
    times = ground._knots
    i = int(np.searchsorted(times, t, side="right"))
    if i >= len(times):
        return math.inf
    piece = times[i] - t
    root = _first_positive_root([jerk / 6.0, curve / 2.0, slope, gap])
    return min(piece, _SHORT_OF_ROOT * root) if root < piece else piece


def _certified_pieces_end(ground, t0, gap0, v0, a, tau, horizon, chunk=512):
    """tau, or, where t0 + tau is a knot, the start of the first piece on from it whose gap may vanish.

    On a piece of length h whose |gap''| <= M (s'' is linear on it: M at an end), the gap is at least the
    smaller of its ends' less M h^2 / 8; a piece where that is above the gap's rounding has no root.
    """
    knots, spline = ground._knots, ground._spline
    i = int(np.searchsorted(knots, t0 + tau, side="left"))
    if i >= len(knots) - 1 or knots[i] - (t0 + tau) > 4.0 * _EPS * abs(knots[i]):
        return tau
    start = float(ground.position(t0))
    while i < len(knots) - 1 and knots[i] - t0 < horizon:
        j = min(i + chunk, len(knots) - 1)
        times = knots[i:j + 1] - t0
        gap = gap0 + times * (v0 - 0.5 * a * times) - (ground._position_array[i:j + 1] - start)
        length = np.diff(times)
        left = a + 2.0 * spline.c[1, i:j]
        right = left + 6.0 * spline.c[0, i:j] * length
        pull = np.maximum(np.abs(left), np.abs(right))
        rounding = 16.0 * _EPS * (abs(gap0) + abs(v0) * times[1:] + 0.5 * abs(a) * times[1:] ** 2
                                  + ground._largest_position)
        uncertain = np.flatnonzero(np.minimum(gap[:-1], gap[1:]) - pull * length**2 / 8.0 <= rounding)
        if len(uncertain):
            return float(times[uncertain[0]])
        i = j
    return float(knots[i] - t0)


def _first_positive_root(coefficients) -> float:
    """The smallest positive real root of the polynomial (highest power first); inf if none."""
    coefficients = np.asarray(coefficients, dtype=float)
    leading = np.flatnonzero(coefficients)
    coefficients = coefficients[leading[0]:] if len(leading) else coefficients[:0]
    if len(coefficients) <= 1:
        return math.inf
    if coefficients[-1] == 0.0:  # a root at 0: the one after it
        return _first_positive_root(coefficients[:-1])
    roots = np.roots(coefficients)
    real = roots.real[(np.abs(roots.imag) <= 1e-9 * np.abs(roots)) & (roots.real > 0.0)]
    return float(real.min()) if len(real) else math.inf


def _entries(name: str, values, unit: str) -> np.ndarray:
    """values as a 1-d float array of finite numbers (validation.finite_entries); ValueError if not a sequence."""
    try:
        values = values if isinstance(values, np.ndarray) and values.ndim == 1 else list(values)
    except TypeError:
        raise ValueError(f"{name} = {validation.shown(values)} is not allowed: it must be a sequence of "
                         f"numbers [{unit}]") from None
    return validation.finite_entries(name, values, unit)


def as_ground(ground) -> Ground:
    """ground as a Ground (None: a still ground at 0); ValueError naming the field otherwise."""
    if ground is None:
        return Ground.still()
    if not isinstance(ground, Ground):
        raise ValueError(f"ground = {ground!r} is not allowed: it must be a bouncingball.Ground (Ground.still, "
                         "Ground.sine or Ground.table)")
    return ground


__all__ = ["Ground", "as_ground", "first_touch"]
