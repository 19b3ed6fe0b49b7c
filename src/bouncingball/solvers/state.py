"""An integrator's saved state (IntegratorState, with the RestartPoint it came from) and its checks.

BallIntegrator.get_state takes one; set_state checks every field here before it changes anything.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from .. import validation
from ..physics import Ball, Mode


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

    def __post_init__(self) -> None:
        """Take the restart point from a dict of its fields (a deserialized state); TypeError names a bad one."""
        if isinstance(self.restart, dict):
            object.__setattr__(self, "restart", RestartPoint(**self.restart))


Counts = tuple[int, int, float | None, int, int]  # impacts, departures, last impact time [s], RHS calls, steps


@dataclass(frozen=True)
class CheckedState:
    """A saved state's fields, checked: point (t, x, v, mode, F_ext), counts and t_start; the restart's too."""

    point: tuple[float, float, float, Mode, float]
    counts: Counts
    t_start: float
    restart_point: tuple[float, float, float, Mode] | None
    restart_counts: Counts | None


def checked(ball: Ball, state: IntegratorState) -> CheckedState:
    """Every field of state checked for ball; ValueError names the first bad one."""
    point = _point(ball, "state", state.t, state.gap, state.h, state.v, state.mode, state.F_ext)
    t_start = validation.finite("state t_start", state.t_start, "s")
    counts = _counts("state", state)
    restart = state.restart
    if restart is None:
        return CheckedState(point, counts, t_start, None, None)
    if not isinstance(restart, RestartPoint):
        raise ValueError(f"state restart = {restart!r} is not allowed: it must be a RestartPoint or None")
    start = _point(ball, "state restart", restart.t, restart.gap, None, restart.v, restart.mode)
    if not (start[0] <= point[0] and start[3] == point[3]):
        raise ValueError(f"state restart at t = {start[0]!r} s in {start[3].name.lower()} is not allowed "
                         f"for a state at t = {point[0]!r} s in {point[3].name.lower()}: it must be of the same "
                         "mode, no later")
    return CheckedState(point, counts, t_start, start[:4], _counts("state restart", restart))


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
