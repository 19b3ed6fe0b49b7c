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


def undamped_heights(m: float, k: float, R: float, g: float, h0: float, t):
    """h [m] at the times t [s] (a numpy array) of an undamped ball (b = 0) released at rest from h0 > R [m].

    The motion is periodic from the first impact at t1 = sqrt(2 (h0 - R) / g), with the impact speed
    V = g t1 and period P = 2 V / g + the contact's duration (undamped_event_count). Within a period,
    from an impact: in contact y = x + d = d cos(w s) - (V / w) sin(w s) about the static deflection
    d = m g / k; in flight x = V s - g s^2 / 2 from the departure. P is taken from 40-digit arithmetic
    (mpmath) and split into two doubles, so the phase of t ~ 1e5 s is right to a few ulps of t.
    """
    import mpmath
    import numpy as np

    with mpmath.workdps(40):
        fall = mpmath.sqrt(2 * (mpmath.mpf(h0) - R) / g)
        speed, omega, deflection = g * fall, mpmath.sqrt(mpmath.mpf(k) / m), mpmath.mpf(m) * g / k
        amplitude = mpmath.hypot(deflection, speed / omega)
        contact = (mpmath.pi + 2 * mpmath.asin(deflection / amplitude)) / omega
        period = contact + 2 * speed / g
        parts = [(float(x), float(x - float(x))) for x in (fall, period)]
    (fall_hi, fall_lo), (period_hi, period_lo) = parts
    t = np.asarray(t, dtype=float)
    cycles = np.floor((t - fall_hi) / period_hi)
    # the phase within the period: P_hi split into 26-bit halves (Veltkamp), each times n < 2^27 exact
    split = 134217729.0 * period_hi
    period_top = split - (split - period_hi)
    s = ((t - fall_hi) - cycles * period_top) - cycles * (period_hi - period_top) - (fall_lo + cycles * period_lo)
    speed, omega, deflection, contact = float(speed), float(omega), float(deflection), float(contact)
    in_contact = s < contact
    flight = s - contact
    x = np.where(in_contact, deflection * np.cos(omega * s) - (speed / omega) * np.sin(omega * s) - deflection,
                 speed * flight - 0.5 * g * flight * flight)
    before = t < fall_hi
    x = np.where(before, (h0 - R) - 0.5 * g * t * t, x)
    return R + x
