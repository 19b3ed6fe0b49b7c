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

from ...codes import CONTACT, FLIGHT, FREE
from ...contact_laws import law_flow_at, law_flow_value, law_interpolant, own_interpolant


def step_state(parameters, load, mode, t0, x0, v0, t1, x1, v1, t):
    """The gap x = h - R [m] and v [m/s] at t on the step from (t0, x0, v0) to (t1, x1, v1) in mode.

    parameters: Ball.parameters; load: m g - F_ext [N]. In the gap, which carries the
    digits of a deflection that h = R + x rounds away. Floats, or arrays with one step per element;
    t0 <= t <= t1. A step of zero length gives its start. A mode with no closed form (a Hunt-Crossley contact) is
    read off its law's own interpolant (contact_laws.law_interpolant), floats only; so is a step on a vibrating ground.
    """
    if own_interpolant(parameters, mode):
        return law_interpolant(parameters, load, mode, t0, x0, v0, t1, x1, v1, t)
    if parameters.ground_amplitude != 0.0:
        return ground_step_state(parameters, load, mode, t0, x0, v0, t1, x1, v1, t)
    dt, dx, dv = step_mismatch(parameters, load, mode, t0, x0, v0, t1, x1, v1)
    return blended_state(parameters, load, mode, t0, x0, v0, dt, dx, dv, t)


def ground_step_state(parameters, load, mode, t0, x0, v0, t1, x1, v1, t):
    """step_state on a vibrating ground (floats): its forced flow (contact_laws.law_flow_at) blended the same way.

    Apart from the still ground's functions, which a grid's every point calls: their code stays as small.
    """
    x_end, v_end = law_flow_at(parameters, mode, x0, v0, t0, t1 - t0, load)
    x, v = law_flow_at(parameters, mode, x0, v0, t0, t - t0, load)
    s = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
    return x + s * (x1 - x_end), v + s * (v1 - v_end)


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
    for mode in (FLIGHT, CONTACT, FREE):
        sel = modes[i] == mode
        if own_interpolant(parameters, mode):  # floats only
            for p in np.flatnonzero(sel):
                a, b = i[p], j[p]
                x[p], v[p] = law_interpolant(parameters, load, mode, ts[a], xs[a], vs[a], ts[b], xs[b], vs[b], t[p])
            continue
        if np.any(sel):
            a, b = i[sel], j[sel]
            x[sel], v[sel] = step_state(parameters, load, mode, ts[a], xs[a], vs[a], ts[b], xs[b], vs[b], t[sel])
    return x, v


def fill_grid(parameters, load, points, n_points, t, x, v):
    """interpolate, one grid time after the other (x and v filled in place): the compiled engine's grid fill.

    Each step's mismatch is computed once, for all the grid times inside it.
    """
    i, step, moving, own, blended = 0, -1, parameters.ground_amplitude != 0.0, False, True
    mode, t0, x0, v0, dt, dx, dv = 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for n in range(t.shape[0]):
        while i < n_points - 2 and points[i + 1, 0] <= t[n]:
            i += 1
        if i != step:  # what the step's points are read off, decided once per step
            step, mode, t0, x0, v0 = i, int(points[i, 3]), points[i, 0], points[i, 1], points[i, 2]
            dt, dx, dv = step_mismatch(parameters, load, mode, t0, x0, v0, points[i + 1, 0], points[i + 1, 1],
                                       points[i + 1, 2])
            own = own_interpolant(parameters, mode)
            blended = not (moving or own)
        if blended:
            x[n], v[n] = blended_state(parameters, load, mode, t0, x0, v0, dt, dx, dv, t[n])
        elif own:
            x[n], v[n] = law_interpolant(parameters, load, mode, t0, x0, v0, points[i + 1, 0], points[i + 1, 1],
                                         points[i + 1, 2], t[n])
        else:
            x[n], v[n] = ground_step_state(parameters, load, mode, t0, x0, v0, points[i + 1, 0], points[i + 1, 1],
                                           points[i + 1, 2], t[n])
