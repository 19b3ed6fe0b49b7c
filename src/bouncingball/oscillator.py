"""The damped linear oscillator in closed form: the linear contact law's exact flow, x'' + 2 sigma x' + w2 x = -g_eff.

Written for floats and arrays alike (the exact solver evaluates a whole grid), with plain-float stand-ins
(``*_value``) that the compiled engine compiles; near cancellation (short times, critical damping) the
Taylor series or an equivalent form keeps the digits. physics.py builds each mode's flow on these.
"""

from __future__ import annotations

import math

import numpy as np


def contact_gap_flow(sigma: float, w2: float, g_eff: float, x0, v0, tau):
    """(x, v) a time tau after (x0, v0) in contact: x'' + 2 sigma x' + w2 x = -g_eff, x = h - R, g_eff = (m g - F)/m.

    x = x0 C + (v0 + sigma x0) S - g_eff P and v = v0 C - (sigma v0 + w2 x0) S - g_eff S, with C, S
    of oscillator_basis and P = integral of S, the response to a unit acceleration (unit_response).
    Written about R, not about the rest height R - d: x = y - d would cancel every digit of x where
    d = g_eff / w2 is far larger than x (a soft contact: 6e120 m against 1e102 m), and R - d would
    round d to ulp(R) where it is far smaller.
    """
    c, s = oscillator_basis(sigma, w2, tau)
    p = unit_response(sigma, w2, tau)
    return x0 * c + (v0 + sigma * x0) * s - g_eff * p, v0 * c - (sigma * v0 + w2 * x0) * s - g_eff * s


# Below this (sigma + w) tau, unit_response sums its Taylor series: the closed forms cancel there.
_SERIES_REACH = 0.5
_SERIES_TERMS = 24  # (0.5)^n / n! < 1e-30 well before
# Over-damped with mu = sqrt(sigma^2 - w2) below this many sigma, unit_response takes (1 - C - sigma S) / w2:
# the expm1 form's two terms agree to ~mu / sigma of their size there, and critical damping in floats
# (b = 2 sqrt(k m), mu ~ 1e-8 sigma) lost half its digits to them. Measured against mpmath from the
# series' end on, either form is within 20 ulps of P for mu / sigma in 0.1 .. 0.5 (the expm1 one 80 ulps
# at 0.1, the other 20 at 0.7).
_NEAR_CRITICAL = 0.3


def unit_response(sigma: float, w2: float, tau):
    """P(tau) [s2]: P'' + 2 sigma P' + w2 P = 1, P(0) = P'(0) = 0; P' is oscillator_basis's S.

    tau^2 / 2 at first. Its closed form 1 - C - sigma S (over w2) cancels for small (sigma + w) tau,
    so there its Taylor series is summed; the clearly over-damped closed form is written with expm1 of
    each rate, which cancels only where the series is used or near critical damping, which takes the
    first form. Floats or arrays.
    """
    if isinstance(tau, float):
        try:
            return unit_response_value(sigma, w2, tau)
        except OverflowError:  # numpy's inf, as for an array
            pass
    tau = np.asarray(tau, dtype=float)
    near = (sigma + math.sqrt(w2)) * np.abs(tau) <= _SERIES_REACH
    out = np.empty_like(tau)
    out[near] = _series_response(sigma, w2, tau[near])
    with np.errstate(over="ignore", invalid="ignore"):
        out[~near] = _closed_response(np, sigma, w2, tau[~near])
    return out


def unit_response_value(sigma: float, w2: float, tau: float) -> float:
    """unit_response of a float tau with the math module (which raises OverflowError where numpy gives inf)."""
    if (sigma + math.sqrt(w2)) * abs(tau) <= _SERIES_REACH:
        return _series_response(sigma, w2, tau)
    return _closed_response(math, sigma, w2, tau)


def _series_response(sigma: float, w2: float, tau):
    # terms t_n = a_n tau^n: t_2 = tau^2 / 2, t_3 = -sigma tau^3 / 3, and from the equation
    # (n + 2)(n + 1) t_{n+2} = -2 sigma tau (n + 1) t_{n+1} - w2 tau^2 t_n
    before, term = 0.5 * tau * tau, -sigma * tau * tau * tau / 3.0
    total = before + term
    for n in range(2, _SERIES_TERMS):
        before, term = term, (-2.0 * sigma * tau * (n + 1) * term - w2 * tau * tau * before) / ((n + 2) * (n + 1))
        total = total + term
    return total


def _closed_response(xp, sigma: float, w2: float, tau):
    disc = sigma * sigma - w2
    mu = math.sqrt(disc) if disc > 0.0 else 0.0
    if disc <= 0.0 or mu < _NEAR_CRITICAL * sigma:
        # (1 - C - sigma S) / w2: C and sigma S are at most ~1 here (not ~sigma / mu), so the
        # difference is right to ulps of 1 / w2 (and to ~20 ulps of P where the series ends).
        c, s = _oscillator_basis(xp, sigma, w2, tau)
        return (1.0 - c - sigma * s) / w2
    fast = sigma + mu
    slow = w2 / fast
    # (fast (1 - e^{-slow tau}) - slow (1 - e^{-fast tau})) / (2 mu w2)
    return (-fast * xp.expm1(-slow * tau) + slow * xp.expm1(-fast * tau)) / (2.0 * mu * w2)


def oscillator_basis(sigma: float, w2: float, tau):
    """C, S such that y'' + 2 sigma y' + w2 y = 0 gives y = y0 C + (v0 + sigma y0) S, y' = v0 C - (sigma v0 + w2 y0) S.

    C = exp(-sigma tau) cos(omega tau) and S = exp(-sigma tau) sin(omega tau)/omega, continued
    through critical damping (S = tau exp(-sigma tau)) into the over-damped cosh/sinh forms.
    tau a float or an array; a float is evaluated with the math module (a few times faster than
    numpy on one number, which the event searches evaluate hundreds of times per run).
    """
    if isinstance(tau, float):
        try:
            return oscillator_basis_value(sigma, w2, tau)
        except OverflowError:  # numpy's inf, as for an array
            pass
    with np.errstate(over="ignore", invalid="ignore"):
        return _oscillator_basis(np, sigma, w2, tau)


def oscillator_basis_value(sigma: float, w2: float, tau: float) -> tuple[float, float]:
    """oscillator_basis of a float tau with the math module (which raises OverflowError where numpy gives inf)."""
    return _oscillator_basis(math, sigma, w2, tau)


def _oscillator_basis(xp, sigma: float, w2: float, tau):
    disc = sigma * sigma - w2
    if disc < 0.0:
        omega = math.sqrt(-disc)
        decay = xp.exp(-sigma * tau)
        return decay * xp.cos(omega * tau), decay * xp.sin(omega * tau) / omega
    if disc == 0.0:
        decay = xp.exp(-sigma * tau)
        return decay, tau * decay
    mu = math.sqrt(disc)
    slow = xp.exp(-w2 / (sigma + mu) * tau)  # the small root computed without cancellation
    fast = xp.exp(-(sigma + mu) * tau)
    if isinstance(tau, float):  # not `xp is math`, which numba's compiled code takes as False
        if 2.0 * mu * tau < 1.0:
            return 0.5 * (slow + fast), fast * math.expm1(2.0 * mu * tau) / (2.0 * mu)
        return 0.5 * (slow + fast), (slow - fast) / (2.0 * mu)
    near = fast * np.expm1(2.0 * mu * tau) / (2.0 * mu)
    return 0.5 * (slow + fast), np.where(2.0 * mu * tau < 1.0, near, (slow - fast) / (2.0 * mu))


def sine_response(sigma: float, w2: float, forcing: float, w: float, theta):
    """(x, x'): the periodic response to a sinusoidal forcing, x'' + 2 sigma x' + w2 x = forcing sin(theta), theta' = w.

    x = forcing Im(H e^{i theta}), H = 1 / (w2 - w^2 + 2 i sigma w): the steady oscillation any damped motion
    settles to, and with the homogeneous flow (contact_gap_flow) the general solution. theta [rad] a float or an
    array. Undamped resonance (sigma = 0, w2 = w^2) has no periodic response: the caller refuses it
    (sine_response_gain is inf there).
    """
    detuning, friction = w2 - w * w, 2.0 * sigma * w
    size = detuning * detuning + friction * friction
    real, imaginary = detuning / size, -friction / size
    if isinstance(theta, float):
        sin, cos = math.sin(theta), math.cos(theta)
    else:
        sin, cos = np.sin(theta), np.cos(theta)
    return forcing * (real * sin + imaginary * cos), forcing * w * (real * cos - imaginary * sin)


def sine_response_gain(sigma: float, w2: float, w: float) -> float:
    """|H| = 1 / |w2 - w^2 + 2 i sigma w| [s2]: the periodic response's amplitude per unit forcing (inf: resonance)."""
    detuning, friction = w2 - w * w, 2.0 * sigma * w
    size = math.sqrt(detuning * detuning + friction * friction)  # not math.hypot: compiled, libm's differs in ulps
    return 1.0 / size if size > 0.0 else math.inf
