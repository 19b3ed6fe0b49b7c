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


# The rigid ball on a table s(t) = A sin(w t + p) (Holmes 1982, J. Sound Vib. 84, 173; Luck and Mehta 1993, Phys.
# Rev. E 48, 3988). A period-n orbit leaves the table at the phase phi with the absolute speed u and meets it n
# table periods T = 2 pi / w later at the same phase and height, so u n T - g (n T)^2 / 2 = 0: u = n pi g / w, and
# it lands at -u. The restitution there, u - s' = -e (-u - s') with s' = A w cos(phi), gives u (1 - e) =
# A w cos(phi) (1 + e): cos(phi) = Gamma_n / Gamma. Linearised in (impact time, take-off speed), the map's
# Jacobian has determinant e^2 and trace 1 + e^2 + (1 + e)^2 s''(phi) / g, s'' = -A w^2 sin(phi): stable between
# trace = 1 + e^2 (sin(phi) = 0, Gamma = Gamma_n) and trace = -(1 + e^2) (period doubling, Gamma sin(phi) =
# 2 (1 + e^2) / (1 + e)^2), for sin(phi) > 0.


def table_gamma(amplitude: float, frequency: float, g: float) -> float:
    """Gamma = A w^2 / g, the table's peak acceleration in units of g."""
    return amplitude * (2.0 * math.pi * frequency) ** 2 / g


def table_amplitude(gamma: float, frequency: float, g: float) -> float:
    """The amplitude A [m] of the table at frequency f [Hz] whose Gamma = A w^2 / g is gamma."""
    return gamma * g / (2.0 * math.pi * frequency) ** 2


def period_n_threshold(n: int, e: float) -> float:
    """Gamma_n = n pi (1 - e) / (1 + e): a period-n orbit (one impact every n table periods) exists from it on."""
    return n * math.pi * (1.0 - e) / (1.0 + e)


def period_n_phase(n: int, e: float, gamma: float) -> float:
    """The stable period-n orbit's impact phase phi [rad] in (0, pi/2]: cos(phi) = Gamma_n / Gamma, sin(phi) > 0."""
    return math.acos(period_n_threshold(n, e) / gamma)


def period_n_takeoff_speed(n: int, frequency: float, g: float) -> float:
    """The period-n orbit's absolute take-off speed u = n pi g / w [m/s]."""
    return n * math.pi * g / (2.0 * math.pi * frequency)


def period_doubling_threshold(n: int, e: float) -> float:
    """Gamma_pd = sqrt(Gamma_n^2 + (2 (1 + e^2) / (1 + e)^2)^2): the period-n orbit doubles its period there."""
    return math.hypot(period_n_threshold(n, e), 2.0 * (1.0 + e * e) / (1.0 + e) ** 2)


def ride_end_phase(amplitude: float, frequency: float, a: float) -> float:
    """The phase [rad] where a ride ends: s'' = -A w^2 sin = -a while decreasing, asin(a / (A w^2)) in (0, pi/2).

    a = g - F_ext/m; a ride on a table with A w^2 <= a never ends (a ValueError here).
    """
    return math.asin(a / (amplitude * (2.0 * math.pi * frequency) ** 2))
