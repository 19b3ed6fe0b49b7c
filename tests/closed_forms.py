"""Numbers the tests expect, computed here from the physics by hand, independently of the solvers."""

from __future__ import annotations

import math


def first_impact_time(h0: float, R: float, g: float) -> float:
    """Time [s] for a ball released at rest from h0 [m] to fall to contact (h = R)."""
    return math.sqrt(2.0 * (h0 - R) / g)


def undamped_event_count(m: float, k: float, R: float, g: float, h0: float, t_end: float) -> int:
    """Impacts and departures up to t_end [s] of an undamped ball (b = 0) released at rest from h0 [m].

    The bounces are periodic: each flight lasts 2 sqrt(2 (h0 - R) / g); each contact is the part of
    an oscillation x = A cos(w t + phi) about the static deflection d = m g / k spent below x = d,
    which lasts (pi + 2 asin(d / A)) / w, with w = sqrt(k / m) and A = sqrt(d^2 + (V / w)^2) for the
    impact speed V = sqrt(2 g (h0 - R)).
    """
    fall = first_impact_time(h0, R, g)
    flight = 2.0 * fall
    omega = math.sqrt(k / m)
    deflection = m * g / k
    speed = g * fall
    amplitude = math.hypot(deflection, speed / omega)
    contact = (math.pi + 2.0 * math.asin(deflection / amplitude)) / omega
    if t_end < fall:
        return 0
    cycles, remainder = divmod(t_end - fall, contact + flight)  # each cycle: impact ... departure ... impact
    return 1 + 2 * int(cycles) + (1 if remainder >= contact else 0)
