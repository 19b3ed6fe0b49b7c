"""The ball's equations as functions of plain floats: accelerations, load, deflection, rest margin and flow.

Each mode's acceleration, the load, the static deflection, the rest margin and the exact flow of the
linear law's modes. physics.Ball's methods call them, and the compiled CVODE engine compiles these same
functions, so the physics has one definition (solvers/engines/jit.py's rules); contact_laws/ builds each law's
on them.
"""

from __future__ import annotations

from .codes import CONTACT
from .oscillator import contact_gap_flow
from .rounding import product_error


# The equations as functions of plain floats: Ball's methods call them, and the compiled CVODE
# engine compiles these same functions, so the physics has one definition.
def gap_acceleration(x, v, mode, load, m, k, b):
    """dv/dt [m/s2] in mode at the gap x = h - R [m]; load = load_value(F_ext, m, g) [N], the same for a whole phase.

    k x, not k h - k R: x is exact near R, whereas the two products of a stiff ball (k = 1e12)
    would bury its deflection in their round-off. The load, not g - F_ext/m, which rounds
    differently: a ball creeping to a rest height of exactly R felt a residual 2e-15 m/s2.
    """
    if mode != CONTACT:  # flight, or free below R under the no-pull law
        return -load / m
    return (-b * v - k * x - load) / m


def effective_gravity_value(F_ext, m, g):
    """(m g - F_ext)/m [m/s2]; see Ball.effective_gravity and load_value."""
    return load_value(F_ext, m, g) / m


def static_deflection_value(F_ext, m, k, g):
    """(m g - F_ext)/k [m]; see Ball.static_deflection and load_value."""
    return load_value(F_ext, m, g) / k


def load_value(F_ext, m, g):
    """m g - F_ext [N], the net load on the spring, with the product m g exact (Dekker's two-product).

    Its sign decides whether a contact can hold the ball. m g rounded first can land on F_ext when
    F_ext exceeds the weight by an ulp: the load came out 0, and a ball that truly rises 3.6e-16 m
    above R and leaves after 42 s was declared at rest (found by the near-critical property).
    """
    product = m * g
    if not (abs(134217729.0 * m) < 1e300 and abs(134217729.0 * g) < 1e300 and abs(product) < 1e300):
        return product - F_ext
    return (product - F_ext) + product_error(m, g, product)


def rest_margin_value(x, v, d, hop_tolerance, w2):
    """w2 d (d + 2 hop_tolerance) - (v^2 + w2 y^2) [m2/s2] at the gap x = h - R, d the static deflection.

    y = x + d is the deflection from the rest height; the d^2 terms cancel in closed form, as
    w2 (2 d hop_tolerance - x (x + 2 d)) - v^2, which keeps x's digits where d is far larger (a soft
    contact) and d's where it is far smaller than R (no R - d). See Ball.rest_margin.
    """
    return w2 * (2.0 * d * hop_tolerance - x * (x + 2.0 * d)) - v * v


def gap_flow_value(mode, x0, v0, tau, load, m, k, b):
    """The exact (x [m], v [m/s]) a time tau [s] after (x0, v0) in mode; load = load_value(F_ext, m, g) [N].

    See Ball.gap_flow. Floats or arrays; compiled by the compiled engine. Mode 2 (free below R under the
    no-pull law) is the flight's parabola.
    """
    g_eff = load / m
    if mode != CONTACT:
        return x0 + tau * (v0 - 0.5 * g_eff * tau), v0 - g_eff * tau
    return contact_gap_flow(b / (2.0 * m), k / m, g_eff, x0, v0, tau)
