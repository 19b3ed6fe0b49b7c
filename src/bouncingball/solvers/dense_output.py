"""Dense output between CVODE's internal steps.

Between two step ends the mode is held and its equations are linear with constant coefficients,
so the state at a time inside the step is read off the mode's own flow from the step's start,
plus a linear blend of the mismatch at the step's end:

    y(t) = flow(y0, t - t0) + s (y1 - flow(y0, t1 - t0)),   s = (t - t0) / (t1 - t0).

It matches CVODE's values at both ends. Its error inside the step is bounded by what CVODE
controlled: the error of y0, which the flow never amplifies (the oscillator's energy does not
grow for b >= 0), plus the mismatch, which is CVODE's local error over the step.

A Hermite interpolant built from the derivatives at the step ends does not have that bound: in
contact the derivatives are k/m times a state error, so over a step of many contact periods (the
long steps CVODE takes while the ball rests) it multiplies a tiny state error by (w dt)^2.
"""

from __future__ import annotations

import numpy as np

from ..physics import Ball, Mode


def step_state(ball: Ball, F_ext: float, mode: Mode, start, end, t):
    """The gap x = h - R [m] and v [m/s] at t on the step from start = (t0, x0, v0) to end = (t1, x1, v1) in mode.

    In the gap, which carries the digits of a deflection that h = R + x rounds away. Scalars or
    arrays (one step per element); t0 <= t <= t1. A step of zero length gives its start.
    """
    (t0, x0, v0), (t1, x1, v1) = start, end
    dt = t1 - t0
    x_end, v_end = ball.gap_flow(mode, x0, v0, dt, F_ext)
    tau = t - t0
    if isinstance(dt, float):
        s = tau / dt if dt > 0.0 else 0.0
    else:
        s = tau / np.where(dt > 0.0, dt, np.inf)
    x, v = ball.gap_flow(mode, x0, v0, tau, F_ext)
    return x + s * (x1 - x_end), v + s * (v1 - v_end)


def interpolate(ball: Ball, F_ext: float, ts: np.ndarray, xs: np.ndarray, vs: np.ndarray, modes: np.ndarray,
                t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gap x = h - R and v at the increasing times t from CVODE's step ends (ts, xs, vs) and the mode of each.

    Consecutive points of different modes share their time (an event): that segment has zero
    length and is never used inside a step.
    """
    i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
    j = i + 1
    x = np.empty_like(t)
    v = np.empty_like(t)
    for mode in Mode:
        sel = modes[i] == mode
        if np.any(sel):
            a, b = i[sel], j[sel]
            x[sel], v[sel] = step_state(ball, F_ext, mode, (ts[a], xs[a], vs[a]), (ts[b], xs[b], vs[b]), t[sel])
    return x, v
