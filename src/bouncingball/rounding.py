"""Arithmetic in plain floats, rounded as Python rounds it, for code that runs interpreted and compiled alike.

product_error is the exact rounding error of a product (Dekker's two-product); hypot_value is
math.hypot as CPython computes it; later is an event's time as a double and its rounding error. All
are plain Python over floats, so numba compiles them to the
same numbers (solvers/engines/jit.py), where compiled code would otherwise call a C library that rounds
differently at times.
"""

from __future__ import annotations

import math

# What interpreted code calls: the C function, a hundred times faster than hypot_value interpreted, and the same
# numbers; the compiled engine binds the name to hypot_value (solvers/engines/compiled.py).
hypot = math.hypot


def product_error(a, b, product):
    """a b - product, exactly, for product = a b rounded (Dekker's two-product; factors within 7e291)."""
    split_a, split_b = 134217729.0 * a, 134217729.0 * b  # 2^27 + 1: each factor in two 26-bit halves
    a_high = split_a - (split_a - a)
    b_high = split_b - (split_b - b)
    a_low, b_low = a - a_high, b - b_high
    return ((a_high * b_high - product) + a_high * b_low + a_low * b_high) + a_low * b_low


def hypot_value(x, y):
    """sqrt(x^2 + y^2) [the unit of x and y], rounded as Python's math.hypot rounds it; plain floats.

    CPython's algorithm for two values (the sum of squares carried in two doubles, then one
    correction of the square root), so that the compiled engine's phase scales are the interpreted
    ones to the bit wherever the result is a normal number: a C library's hypot, which compiled code
    would call, is at times an ulp off, and a scale an ulp off changes CVODE's steps.
    """
    x, y = abs(x), abs(y)
    largest = max(x, y)
    if math.isinf(x) or math.isinf(y):
        return math.inf
    if math.isnan(x) or math.isnan(y):
        return math.nan
    if largest == 0.0:
        return largest
    exponent = math.frexp(largest)[1]
    if exponent < -1023:  # 2^-exponent would overflow: scaled to normal numbers first, as CPython does
        tiny = 2.2250738585072014e-308
        return tiny * hypot_value(x / tiny, y / tiny)
    scale = math.ldexp(1.0, -exponent)
    total, low_products, low_sums = 1.0, 0.0, 0.0
    for value in (x * scale, y * scale):
        square = value * value
        low_products += product_error(value, value, square)
        total, low_sums = total + square, low_sums + ((total - (total + square)) + square)
    h = math.sqrt(total - 1.0 + (low_products + low_sums))
    square = -h * h
    low_products += product_error(-h, h, square)
    total, low_sums = total + square, low_sums + ((total - (total + square)) + square)
    h += (total - 1.0 + (low_products + low_sums)) / (2.0 * h)
    return h / scale


def later(t, t_low, tau):
    """(t + t_low) + tau [s] as a double and its rounding error: the time of an event tau after t.

    t_low is t's own rounding error (0 for a time given exactly). Each event time rounded to the
    nearest double is off by up to half an ulp of t; a ball that repeats the same bounce rounds the
    same way each time, and over 1e5 bounces (t ~ 1e5 s, ulp 1.5e-11 s) the event times drifted by
    4e-7 s. Carried as a double-double (Knuth's two-sum), they do not.
    """
    total = t + tau
    tau_part = total - t
    error = ((t - (total - tau_part)) + (tau - tau_part)) + t_low
    t_event = total + error
    return t_event, error - (t_event - total)
