"""The reference article's algorithm: solve_ivp with one terminal event per phase and a restart at each."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from .. import validation
from ..contact_laws import LAWS
from ..physics import Ball, Mode, clipped_contact_mode
from . import forcing
from .article import ARTICLE_ATOL, ARTICLE_MAX_STEP, ARTICLE_METHOD, ARTICLE_RTOL
from .forcing import ForceTable
from .result import DEPARTURE, IMPACT, Event, SimulationResult, SolverStats, output_grid

METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")
IMPLICIT = ("Radau", "BDF", "LSODA")


def simulate_scipy(ball: Ball, h0: float, v0: float, t_end: float, output_interval: float,
                   t_start: float = 0.0, F_ext: float | ForceTable = 0.0, method: str = ARTICLE_METHOD,
                   rtol: float = ARTICLE_RTOL, atol: float = ARTICLE_ATOL, max_step: float = ARTICLE_MAX_STEP,
                   max_events: int = 100_000, progress: Callable[[float], None] | None = None) -> SimulationResult:
    """Integrate as the article does; defaults are the article's (RK45, max_step 0.01, SciPy's tolerances).

    max_step = 0 means unbounded. F_ext: a constant [N] or a forcing.ForceTable, integrated piece by
    piece of constant force (solve_ivp restarts at each change, the state continuous, the mode held).
    A run that reports more than max_events events stops there
    (explicit methods chatter through false events on stiff scenes). progress: called with the time
    reached [s] at each restart, for a progress display. The linear and Hunt-Crossley contact laws (ValueError
    else): the contact's right-hand side is Ball.acceleration, which clips the Hunt-Crossley force at 0 (its
    free sub-mode is the same phase here, ended by the same crossing of R); the implicit methods take the
    linear law's constant Jacobian, and estimate the Hunt-Crossley one by finite differences.

    Raises RuntimeError where solve_ivp fails, or where one of its steps ends on the wrong side of R
    for the phase by more than atol + rtol R (a bounce stepped over unseen: the results would be wrong
    from there on).
    """
    method, rtol, atol, max_step = _checked(ball, method, rtol, atol, max_step)
    grid = output_grid(t_start, t_end, output_interval)
    h_out = np.full_like(grid, np.nan)
    v_out = np.full_like(grid, np.nan)
    events: list[Event] = []
    stats = SolverStats()
    started = time.perf_counter()

    t, y = t_start, np.array([h0, v0], dtype=float)
    mode = clipped_contact_mode(ball, ball.initial_mode(h0, v0, F_ext))
    h_out[0], v_out[0] = y
    filled = 1
    last_impact = t_start if mode == Mode.CONTACT else None
    constant_pieces = forcing.pieces(F_ext, t_start, t_end)
    while t < t_end and len(events) < max_events:
        if progress is not None:
            progress(t)
        # the piece of constant force t lies in: solve_ivp stops at its end, and restarts with the next value
        _, t_stop, force = next(p for p in reversed(constant_pieces) if p[0] <= t)
        sol = _solve_phase(ball, mode, force, t, t_stop, y, method, rtol, atol, max_step)
        stats.steps += len(sol.t) - 1
        stats.rhs_calls += sol.nfev
        if sol.status == -1:
            raise RuntimeError(f"solve_ivp ({method}) failed at t = {sol.t[-1]!r} s: {sol.message}")
        _refuse_a_crossing_stepped_over(ball, mode, sol, atol + rtol * ball.R, method)
        t_reached = float(sol.t[-1])
        stop = np.searchsorted(grid, t_reached, side="right")
        if stop > filled:
            h_out[filled:stop], v_out[filled:stop] = sol.sol(grid[filled:stop])
            filled = stop
        t, y = t_reached, sol.y[:, -1]
        if sol.status == 1:
            kind = IMPACT if mode == Mode.FLIGHT else DEPARTURE
            events.append(Event(t, kind, float(y[1])))
            mode = Mode.CONTACT if mode == Mode.FLIGHT else Mode.FLIGHT
            if mode == Mode.CONTACT:
                last_impact = t
    stats.events = len(events)
    stats.wall_time = time.perf_counter() - started
    rest_time = None
    if mode == Mode.CONTACT and LAWS[ball.contact].closed_form and ball.contact_is_permanent(y[0], y[1],
                                                                                      constant_pieces[-1][2]):
        rest_time = last_impact
    options = {"method": method, "rtol": rtol, "atol": atol, "max_step": max_step}
    return SimulationResult("scipy", ball, grid, h_out, v_out, events, rest_time, stats, F_ext, options)


def _checked(ball: Ball, method: str, rtol: float, atol: float, max_step: float) -> tuple[str, float, float, float]:
    """(method, rtol, atol, max_step) checked; ValueError naming the one out of range, or the law the article's
    algorithm cannot run (its terminal events switch between flight and contact)."""
    if not LAWS[ball.contact].article_algorithm:
        runs = ", ".join(name for name, law in LAWS.items() if law.article_algorithm)
        raise ValueError(f"solver = 'scipy' is not allowed with contact = {ball.contact!r}: the reference "
                         f"article's algorithm models a contact whose force is a function of the state ({runs}); "
                         + ("use cvode or exact" if LAWS[ball.contact].closed_form else "use cvode"))
    return (validation.choice("method", method, METHODS), validation.in_range("rtol", rtol, 0.0, 1.0),
            validation.positive("atol", atol), validation.non_negative("max_step", max_step, "s"))


def _solve_phase(ball: Ball, mode: Mode, force: float, t: float, t_stop: float, y: np.ndarray, method: str,
                 rtol: float, atol: float, max_step: float):
    """solve_ivp over one phase in mode under force [N], from (t, y) to its terminal crossing of R or to t_stop."""

    def rhs(_t, state):
        return [state[1], ball.acceleration(state[0], state[1], mode, force)]

    def crossing(_t, state):
        return state[0] - ball.R

    crossing.terminal = True
    crossing.direction = -1.0 if mode == Mode.FLIGHT else 1.0
    jacobian = ball.jacobian(mode)

    def jac(_t, _state):  # a callable: LSODA cannot take a constant array
        return jacobian

    return solve_ivp(rhs, (t, t_stop), y, method=method, rtol=rtol, atol=atol, max_step=max_step or np.inf,
                     events=crossing, dense_output=True,
                     **({"jac": jac} if method in IMPLICIT and LAWS[ball.contact].closed_form else {}))


def _refuse_a_crossing_stepped_over(ball: Ball, mode: Mode, sol, slack: float, method: str) -> None:
    """Raise RuntimeError where a step of sol ended inside its phase on the wrong side of R, by more than slack [m].

    solve_ivp sees a terminal event where the event function changes sign between two steps. After a
    departure located a rounding below R, a hop shorter than one step ends below R with no change of
    sign: the ball then falls through the ground in flight (DOP853 at rtol 1e-12, Hunt-Crossley,
    k = 1e6 N/m^1.5, alpha = 0.32 s/m: 140 m below it at 8 s), every status success. A missed departure
    leaves the ball above R in contact, pulled back by the contact law. Either result is wrong from
    there on, so the run stops with the reason instead.
    """
    # The steps' ends between the phase's start and its event: those two are located on R only to within |v| ulp(t),
    # which passes any slack on a long run (b = 0, 150 s, atol 1e-15: 7.5e-14 m at 66 s, with every event right).
    inside = slice(1, -1) if sol.status == 1 else slice(1, None)
    heights = sol.y[0, inside]
    gap = (heights - ball.R) if mode == Mode.FLIGHT else (ball.R - heights)
    wrong = np.flatnonzero(gap < -slack)
    if wrong.size:
        i = wrong[0] + 1
        where, crossing = ("below", "an impact") if mode == Mode.FLIGHT else ("above", "a departure")
        raise RuntimeError(f"solve_ivp ({method}) stepped over {crossing} unseen: at t = {float(sol.t[i])!r} s the "
                           f"ball's centre is at h = {float(sol.y[0, i])!r} m, {where} R = {ball.R!r} m in "
                           f"{mode.name.lower()} (a bounce shorter than one of its steps, begun a rounding on the "
                           "wrong side of R), so its results from there on would be wrong; solver = 'cvode' "
                           "locates every crossing")
