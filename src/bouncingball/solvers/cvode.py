"""SUNDIALS CVODE with contact and departure found by root-finding: simulate_cvode, and where each piece lives.

solvers/phase_machine/settings.py holds the settings and the tolerance's hop rule, solvers/engine_selection.py the
choice of engine, solvers/integrator.py the integrator (BallIntegrator) and solvers/phase_machine/phases.py its
decisions; solvers/engines/stepper.py the protocol both engines implement. Their public names are
importable from here too.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import numpy as np

from ..contact_laws import LAWS
from ..ground import Ground
from ..limits import check_cvode_settings, check_resolvable, resolvable_until
from ..physics import Ball, Mode
from . import engine_selection, forcing
from .engine_selection import choose_engine, expected_steps
from .engines.stepper import SolverError
from .forcing import ForceTable
from .integrator import BallIntegrator
from .phase_machine.phases import phase_scales
from .phase_machine.settings import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    ENGINES,
    METHODS,
    CvodeSettings,
    choose_method,
    hop_tolerance,
    merged_hop_limit,
)
from .result import Event, SimulationResult, SolverStats, output_grid
from .state import IntegratorState, RestartPoint

__all__ = ["DEFAULT_ATOL", "DEFAULT_RTOL", "ENGINES", "METHODS", "BallIntegrator", "CvodeSettings",
           "IntegratorState", "RestartPoint", "SolverError", "check_resolvable", "choose_engine", "choose_method",
           "expected_steps", "hop_tolerance", "merged_hop_limit", "phase_scales", "resolvable_until",
           "simulate_cvode"]


def _integrate_pieces(integrator: BallIntegrator, grid: np.ndarray,
                      table: ForceTable) -> tuple[np.ndarray, np.ndarray, list[Event]]:
    """integrate_grid piece by piece of constant F_ext: each piece's grid is its output times and its ends.

    The integrator restarts CVODE where its F_ext changes (the state continuous, the mode held); a
    grid point on a change time is the state there, taken at the end of the piece before.
    """
    constant_pieces = forcing.pieces(table, float(grid[0]), float(grid[-1]))
    h, v = np.empty_like(grid), np.empty_like(grid)
    h[0], v[0] = integrator.h, integrator.v
    events: list[Event] = []
    for start, end, F_ext in constant_pieces:
        integrator.F_ext = F_ext
        inside = (grid > start) & (grid <= end)
        times = np.concatenate(([start], grid[inside]))
        if times[-1] < end:
            times = np.append(times, end)
        h_piece, v_piece, piece_events = integrator.integrate_grid(times)
        count = int(np.count_nonzero(inside))
        h[inside], v[inside] = h_piece[1:1 + count], v_piece[1:1 + count]
        events += piece_events
    return h, v, events


def _steps_for_auto(ball: Ball, h0: float, v0: float, grid: np.ndarray, F_ext: float | ForceTable,
                    settings: CvodeSettings) -> float | None:
    """The run's expected steps where engine "auto" has to weigh them (see choose_engine), else None."""
    if not LAWS[ball.contact].closed_form:  # no exact solution to count its phases by: unknown, as an FMU's
        return None
    if settings.engine != "auto" or (break_even := engine_selection.compiled_break_even()) == 0.0:
        return None
    return engine_selection.expected_steps(ball, h0, v0, float(grid[0]), float(grid[-1]), F_ext, at_most=break_even)


_compiled_engine_ready = False  # its functions compiled (or loaded) in this process: _ready_compiled_engine ran


def _ready_compiled_engine(settings: CvodeSettings) -> None:
    """Compile (or load from numba's disk cache) every compiled function: one bounce of the article's ball."""
    global _compiled_engine_ready
    warm_up = BallIntegrator(Ball(), 2.0, 0.0, 0.0, 0.0, CvodeSettings(rtol=settings.rtol, engine="compiled"))
    try:
        warm_up.integrate_grid(np.array([0.0, 1.0]))
    finally:
        warm_up.close()
    _compiled_engine_ready = True


def simulate_cvode(ball: Ball, h0: float, v0: float, t_end: float, output_interval: float,
                   t_start: float = 0.0, F_ext: float | ForceTable = 0.0, rtol: float = DEFAULT_RTOL,
                   atol: float | None = DEFAULT_ATOL, method: str = "auto", max_step: float = 0.0,
                   engine: str = "auto", progress: Callable[[float], None] | None = None,
                   ground: Ground | None = None) -> SimulationResult:
    """Integrate with CVODE from t_start to t_end and return the solution on the output grid.

    engine: see CvodeSettings; the engine that ran and why are in result.stats, and the time its
    first use in the process took (stats.first_use_time), which stats.wall_time leaves out. F_ext:
    a constant [N] or a forcing.ForceTable, integrated piece by piece of constant force. progress:
    called with the time reached [s] at the start and then at a phase start every PROGRESS_STEPS (20,000)
    CVODE steps or so, for a progress display. ground: see BallIntegrator (a still ground or a sine, every law).
    """
    settings = CvodeSettings(rtol=rtol, atol=atol, method=method, max_step=max_step, engine=engine)
    check_cvode_settings(ball, h0, settings.atol, settings.max_step, t_start, t_end)
    grid = output_grid(t_start, t_end, output_interval)
    table = F_ext if isinstance(F_ext, ForceTable) else None
    moving = ground is not None and ground.moves
    integrator = BallIntegrator(ball, h0, v0, t_start, F_ext if table is None else float(table.at(t_start)),
                                settings, None if moving else _steps_for_auto(ball, h0, v0, grid, F_ext, settings),
                                ground)
    integrator.progress = progress
    try:
        first_use_time = integrator.first_use_time
        if integrator.engine == "compiled" and not _compiled_engine_ready:
            # Its first use (the import, in choose_engine, and the compilation) is not the run's own time.
            started = time.perf_counter()
            _ready_compiled_engine(settings)
            first_use_time += time.perf_counter() - started
        started = time.perf_counter()
        if table is None:
            h, v, events = integrator.integrate_grid(grid)
        else:
            h, v, events = _integrate_pieces(integrator, grid, table)
        wall_time = time.perf_counter() - started
    finally:
        integrator.close()
    if integrator.engine == "sksundae":
        engine_selection.note_sksundae_steps(integrator.steps)
    stats = SolverStats(steps=integrator.steps, rhs_calls=integrator.rhs_calls, events=len(events),
                        wall_time=wall_time, engine=integrator.engine, engine_reason=integrator.engine_reason,
                        first_use_time=first_use_time)
    options = {"rtol": settings.rtol, "atol": settings.atol, "method": settings.method,
               "contact_method": integrator.methods[Mode.CONTACT], "max_step": settings.max_step,
               "engine": settings.engine}
    estimate = integrator.error_estimate
    result = SimulationResult("cvode", ball, grid, h, v, events, integrator.rest_time, stats, F_ext, options, estimate)
    return dataclasses.replace(result, ground=ground) if moving else result
