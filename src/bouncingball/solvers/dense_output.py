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

step_state and fill_grid take plain floats and arrays: the compiled engine compiles them (a grid
filled in one compiled pass), the scikit-sundae engine fills its grid with interpolate, in numpy.
"""

from __future__ import annotations

import numpy as np

from ..codes import CONTACT
from ..contact_laws import HUNT_CROSSLEY, hunt_crossley_acceleration, hunt_crossley_partials, law_flow_value


def step_state(parameters, load, mode, t0, x0, v0, t1, x1, v1, t):
    """The gap x = h - R [m] and v [m/s] at t on the step from (t0, x0, v0) to (t1, x1, v1) in mode.

    parameters: Ball.parameters; load: m g - F_ext [N]. In the gap, which carries the
    digits of a deflection that h = R + x rounds away. Floats, or arrays with one step per element;
    t0 <= t <= t1. A step of zero length gives its start. A Hunt-Crossley contact (no closed form) is
    read off hunt_crossley_state's quintic Hermite interpolant, floats only.
    """
    if mode == CONTACT and parameters.law == HUNT_CROSSLEY:
        return hunt_crossley_state(parameters, load, t0, x0, v0, t1, x1, v1, t)
    dt, dx, dv = step_mismatch(parameters, load, mode, t0, x0, v0, t1, x1, v1)
    return blended_state(parameters, load, mode, t0, x0, v0, dt, dx, dv, t)


def hunt_crossley_state(parameters, load, t0, x0, v0, t1, x1, v1, t):
    """(x [m], v [m/s]) at t in a Hunt-Crossley contact's step: the quintic Hermite interpolant of its ends.

    x from (x, v, a) at both ends, v from (v, a, da/dt), with the contact's own equation for a and its
    partials for da/dt = a_x v + a_v a: sixth order, so its error inside a step (~h^6 y^(6) / 46080)
    stays below what CVODE controlled over it. Floats.
    """
    m, k, n, alpha = parameters.m, parameters.k, parameters.n, parameters.alpha
    h = t1 - t0
    if not h > 0.0:
        return x0, v0
    s = (t - t0) / h
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    s5 = s4 * s
    b0 = 1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5
    b1 = h * (s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5)
    b2 = 0.5 * h * h * (s2 - 3.0 * s3 + 3.0 * s4 - s5)
    b3 = 10.0 * s3 - 15.0 * s4 + 6.0 * s5
    b4 = h * (-4.0 * s3 + 7.0 * s4 - 3.0 * s5)
    b5 = 0.5 * h * h * (s3 - 2.0 * s4 + s5)
    a0 = hunt_crossley_acceleration(x0, v0, load, m, k, n, alpha)
    a1 = hunt_crossley_acceleration(x1, v1, load, m, k, n, alpha)
    ax0, av0 = hunt_crossley_partials(x0, v0, load, m, k, n, alpha)
    ax1, av1 = hunt_crossley_partials(x1, v1, load, m, k, n, alpha)
    j0, j1 = ax0 * v0 + av0 * a0, ax1 * v1 + av1 * a1
    x = b0 * x0 + b1 * v0 + b2 * a0 + b3 * x1 + b4 * v1 + b5 * a1
    v = b0 * v0 + b1 * a0 + b2 * j0 + b3 * v1 + b4 * a1 + b5 * j1
    return x, v


def step_mismatch(parameters, load, mode, t0, x0, v0, t1, x1, v1):
    """(dt, dx, dv): the step's length [s], and how far its end lies from the mode's flow from its start [m, m/s]."""
    dt = t1 - t0
    x_end, v_end = law_flow_value(parameters, mode, x0, v0, dt, load)
    return dt, x1 - x_end, v1 - v_end


def blended_state(parameters, load, mode, t0, x0, v0, dt, dx, dv, t):
    """The flow from the step's start at t, plus the share (t - t0) / dt of its end's mismatch (step_mismatch)."""
    tau = t - t0
    if isinstance(dt, float):
        s = tau / dt if dt > 0.0 else 0.0
    else:
        s = tau / np.where(dt > 0.0, dt, np.inf)
    x, v = law_flow_value(parameters, mode, x0, v0, tau, load)
    return x + s * dx, v + s * dv


def interpolate(parameters, load: float, points: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gap x = h - R and v at the increasing times t from CVODE's step ends, points rows (t, x, v, mode).

    Consecutive points of different modes share their time (an event): that segment has zero
    length and is never used inside a step.
    """
    ts, xs, vs, modes = points[:, 0], points[:, 1], points[:, 2], points[:, 3]
    i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
    j = i + 1
    x = np.empty_like(t)
    v = np.empty_like(t)
    for mode in (0, 1, 2):  # 2: the no-pull law's free sub-mode
        sel = modes[i] == mode
        if mode == CONTACT and parameters.law == HUNT_CROSSLEY:  # floats only (its interpolant)
            for p in np.flatnonzero(sel):
                a, b = i[p], j[p]
                x[p], v[p] = hunt_crossley_state(parameters, load, ts[a], xs[a], vs[a], ts[b], xs[b], vs[b], t[p])
            continue
        if np.any(sel):
            a, b = i[sel], j[sel]
            x[sel], v[sel] = step_state(parameters, load, mode, ts[a], xs[a], vs[a], ts[b], xs[b], vs[b], t[sel])
    return x, v


def fill_grid(parameters, load, points, n_points, t, x, v):
    """interpolate, one grid time after the other (x and v filled in place): the compiled engine's grid fill.

    Each step's mismatch is computed once, for all the grid times inside it.
    """
    i, step = 0, -1
    mode, t0, x0, v0, dt, dx, dv = 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for n in range(t.shape[0]):
        while i < n_points - 2 and points[i + 1, 0] <= t[n]:
            i += 1
        if i != step:
            step, mode, t0, x0, v0 = i, int(points[i, 3]), points[i, 0], points[i, 1], points[i, 2]
            dt, dx, dv = step_mismatch(parameters, load, mode, t0, x0, v0, points[i + 1, 0], points[i + 1, 1],
                                       points[i + 1, 2])
        if mode == CONTACT and parameters.law == HUNT_CROSSLEY:
            x[n], v[n] = hunt_crossley_state(parameters, load, t0, x0, v0, points[i + 1, 0], points[i + 1, 1],
                                             points[i + 1, 2], t[n])
        else:
            x[n], v[n] = blended_state(parameters, load, mode, t0, x0, v0, dt, dx, dv, t[n])
