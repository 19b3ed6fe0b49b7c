"""A saved state's checks: every field of an IntegratorState, before BallIntegrator.set_state changes anything.

A ValueError names the first bad field, its value and what it must be.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from .. import validation
from ..contact_laws import has_free_sub_mode, impact_is_instantaneous
from ..equations import load_value
from ..ground import Ground
from ..physics import Ball, Mode
from .phase_machine.phases import frame, on_wrong_side, side_margin
from .phase_machine.settings import CvodeSettings, hop_tolerance
from .state import IntegratorState, RestartPoint
from .vibrating_ground import ground_motion

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


def checked(ball: Ball, state: IntegratorState, settings: CvodeSettings, ground: Ground | None = None) -> CheckedState:
    """Every field of state checked for ball and the integrator's settings; ValueError names the first bad one.

    On a vibrating ground (the integrator's: a state carries none) the state's h and v are the world's, its gap and
    restart point the machine's: the point is taken relative to the ground at its t.
    """
    if not isinstance(state, IntegratorState):
        raise ValueError(f"state = {validation.shown(state)} is not allowed: it must be an IntegratorState "
                         "(one of get_state())")
    point = _point(ball, "state", state.t, state.gap, state.h, state.v, state.mode, state.F_ext, ground)
    if point[3] == Mode.FREE and not has_free_sub_mode(ball.parameters):
        raise ValueError(f"state mode = {Mode.FREE.value} (FREE) is not allowed for contact = {ball.contact!r} "
                         f"(b = {ball.b!r} N s/m): it is the free sub-mode of the linear-no-pull law (with b > 0) "
                         "and of the hunt-crossley law")
    t_start = validation.finite("state t_start", state.t_start, "s")
    counts = _counts("state", state)
    rigid = impact_is_instantaneous(ball.parameters)
    if state.zeno_time is not None and not (rigid and point[3] == Mode.CONTACT and counts[2] is not None
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
    length = max(frame(ball.parameters, mode, x, v, load, rtol, atol, math.inf, 0.0)[0],
                 frame(ball.parameters, start[3], start[1], start[2], load, rtol, atol, math.inf, 0.0)[0])
    margin = side_margin(hop_tolerance(ball, rtol, settings.atol, F_ext), rtol, length)
    if on_wrong_side(mode, x, margin):
        where = "at or above" if mode == Mode.FLIGHT else "at or below"
        raise ValueError(f"{name} h = {h!r} m (h - R = {x!r} m) is not allowed in {mode.name.lower()}: "
                         f"it must be {where} R = {ball.R!r} m (within {margin:.3g} m, CVODE's own margin)")


def _point(ball: Ball, name: str, t, gap, h, v, mode, F_ext=0.0, ground: Ground | None = None
           ) -> tuple[float, float, float, Mode, float]:
    """(t, x, v, mode, F_ext) of a saved state, each field checked; h None: the gap alone (the machine's).

    With h, on a ground that moves: x = h - R - s(t), v - s'(t), the gap (kept to every digit) checked against h.
    """
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
    ground = Ground() if ground is None else ground
    surface = ground_motion(ground, t, 0)
    x = h - ball.R - surface
    if gap is not None:
        x = validation.finite(f"{name} gap", gap, "m")
        if not abs((ball.R + x + surface) - h) <= 2.0 * math.ulp(max(abs(h), ball.R, abs(surface))):
            where = (f", the ground's s(t) = {surface!r} m at t = {t!r} s" if ground.moves else "")
            raise ValueError(f"{name} gap = {x!r} m is not allowed with h = {h!r} m: R + gap{' + s(t)' * ground.moves} "
                             f"must be h (R = {ball.R!r} m{where})")
    return t, x, v - ground_motion(ground, t, 1), mode, F_ext


def _counts(name: str, saved) -> Counts:
    counts = [saved.impacts, saved.departures, saved.rhs_calls, saved.steps]
    if not all(isinstance(n, numbers.Integral) and not isinstance(n, bool) and n >= 0 for n in counts):
        raise ValueError(f"{name} counts (impacts, departures, rhs_calls, steps) = {counts} are not allowed: "
                         "they must be integers >= 0")
    last_impact = None if saved.last_impact_time is None else validation.finite(
        f"{name} last_impact_time", saved.last_impact_time, "s")
    return int(saved.impacts), int(saved.departures), last_impact, int(saved.rhs_calls), int(saved.steps)
