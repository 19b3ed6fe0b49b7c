"""Work-precision on the article scene: every solver over a sweep of tolerances, timed side by side in one process.

Each point runs once as a warm-up (its errors against the exact solution come from that run), then
`repeats` more times; the repeats go round-robin over all points, so drift on a shared machine hits
every solver alike. Time is the median (and min) wall time of the repeats.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..accuracy import Accuracy
from ..output import atomic_write
from ..scenes import Scene
from ..solvers.result import DEFAULT_OUTPUT_INTERVAL
from . import runners
from .runners import ARTICLE, EXACT, EXACT_EVALUATION, FmuPaths, Run, Solver

DENSE = DEFAULT_OUTPUT_INTERVAL  # the article's 1 ms output grid [s]
SPARSE = 0.1  # a sparse grid, where output overhead does not dominate [s]
ATOL_PER_RTOL = 1e-3  # atol = 1e-3 * rtol
SAVED_RTOL = 1e-6  # on the dense grid, h is saved for the tolerance nearest this one (all points on the sparse grid)
H_FILE = "work_precision_h.npz"
CSV_FILE = "work_precision.csv"


@dataclass(frozen=True)
class Settings:
    """How big a run is: tolerances, timed repeats, the per-run time budget [s] past which a solver's tighter
    tolerances are skipped, FMU communication steps [s], the undamped run's length [s] and the stiff cases' cap [s];
    for bench/floor.py the interleaved calls timed against the C floor and at matched errors, and the bisection's
    steps."""

    rtols: tuple[float, ...]
    repeats: int
    budget: float
    comm_steps: tuple[float, ...] = (1e-3, 1e-2)
    undamped_t_end: float = 10_000.0
    stiff_cap: float = 5.0
    floor_repeats: int = 400
    matched_repeats: int = 20
    bisection_steps: int = 8


FULL = Settings(rtols=tuple(10.0**-k for k in range(3, 13)), repeats=5, budget=2.0)
QUICK = Settings(rtols=(1e-3, 1e-6, 1e-9, 1e-12), repeats=2, budget=0.3, undamped_t_end=1000.0, stiff_cap=0.5,
                 floor_repeats=10, matched_repeats=2, bisection_steps=2)


@dataclass(eq=False)
class Point:
    """One solver at one tolerance on one grid; status ok, failed or skipped."""

    section: str  # "dense" or "sparse"
    solver: Solver
    rtol: float | None
    grid: float  # the output interval of the run [s] (the FMU: its communication step)
    status: str = "pending"
    note: str = ""
    errors: Accuracy | None = None
    rhs_calls: int | None = None
    steps: int = 0
    times: list[float] = field(default_factory=list)
    h: np.ndarray | None = None  # kept for the points whose h values are saved

    @property
    def atol(self) -> float | None:
        return None if self.rtol is None else ATOL_PER_RTOL * self.rtol

    @property
    def median(self) -> float:
        return statistics.median(self.times) if self.times else math.nan

    @property
    def minimum(self) -> float:
        return min(self.times) if self.times else math.nan

    @property
    def key(self) -> str:
        """Names the point in the saved h values."""
        return f"{self.section}|{self.solver.label}|{'default' if self.rtol is None else f'{self.rtol:.0e}'}"


def solvers(section: str, settings: Settings) -> list[Solver]:
    """The solvers of a section, in the order of the tables."""
    ours = [runners.cvode(method) for method in ("Adams", "BDF", "auto")] + [runners.CVODE_COMPILED, runners.C_FLOOR]
    fmus = ([runners.fmu(step, engine) for engine in ("sksundae", "compiled") for step in settings.comm_steps]
            if section == "dense" else [])
    floors = [runners.empty_slave(step) for step in settings.comm_steps] if section == "dense" else []
    peers = [ARTICLE, *(runners.scipy(method) for method in runners.SCIPY_METHODS)]
    evaluation = [EXACT_EVALUATION] if section == "dense" else []
    return [*ours, *fmus, *floors, *peers, EXACT, *evaluation]


def make_points(settings: Settings) -> list[Point]:
    points = []
    for section, grid in (("dense", DENSE), ("sparse", SPARSE)):
        for solver in solvers(section, settings):
            rtols = settings.rtols if solver.takes_tolerances else (None,)
            points += [Point(section, solver, rtol, solver.comm_step or grid) for rtol in rtols]
    return points


def sweep(scene: Scene, points: list[Point], settings: Settings, fmus: FmuPaths) -> None:
    """Warm-up (and errors) for every point, then the timed repeats round-robin; fills in the points."""
    from tqdm import tqdm

    over_budget: dict[tuple[str, str], str] = {}
    with tqdm(total=len(points) * (1 + settings.repeats), desc="work-precision", unit="run") as bar:
        for point in points:  # each solver from loose to tight tolerances
            bar.set_postfix_str(f"{point.solver.label} {point.rtol or ''}", refresh=False)
            group = (point.section, point.solver.label)
            if group in over_budget:
                point.status, point.note = "skipped", over_budget[group]
                bar.total -= 1 + settings.repeats
                bar.refresh()
                continue
            try:
                run = runners.run_solver(point.solver, scene, point.grid, point.rtol, point.atol, fmus)
            except Exception as error:  # a solver that fails is a result too
                point.status, point.note = "failed", f"{type(error).__name__}: {error}".splitlines()[0][:200]
                bar.total -= settings.repeats
                bar.update()
                continue
            _record(point, scene, run)
            if run.wall_time > settings.budget and point.solver.takes_tolerances:
                over_budget[group] = (f"skipped: rtol {point.rtol:.0e} took {run.wall_time:.2f} s "
                                      f"> budget {settings.budget:g} s")
            bar.update()
        ok = [point for point in points if point.status == "ok"]
        # chosen among the points that ran: under load the budget may skip the one nearest SAVED_RTOL
        saved = {id(point) for point in _points_to_save(ok)}
        for point in ok:
            if id(point) not in saved:
                point.h = None
        for _ in range(settings.repeats):
            for point in ok:
                bar.set_postfix_str(f"{point.solver.label} {point.rtol or ''}", refresh=False)
                point.times.append(runners.run_solver(point.solver, scene, point.grid, point.rtol, point.atol,
                                                      fmus, record=False).wall_time)
                bar.update()


def _record(point: Point, scene: Scene, run: Run) -> None:
    point.status = "ok"
    point.rhs_calls, point.steps = run.rhs_calls, run.steps
    if run.h is not None:
        point.errors = runners.errors_against_exact(scene, run)
        point.h = np.asarray(run.h, dtype=float)


def _points_to_save(points: list[Point]) -> list[Point]:
    """Of points: every one on the sparse grid; on the dense grid one per solver, the tolerance nearest SAVED_RTOL."""
    chosen = [point for point in points if point.section == "sparse"]
    groups: dict[str, list[Point]] = {}
    for point in points:
        if point.section == "dense":
            groups.setdefault(point.solver.label, []).append(point)
    for group in groups.values():
        chosen.append(min(group, key=lambda p: 0.0 if p.rtol is None else abs(math.log10(p.rtol / SAVED_RTOL))))
    return chosen


def by_solver(points: list[Point], section: str) -> dict[str, list[Point]]:
    """The points of one section (dense or sparse grid), grouped by solver label in the order they come."""
    groups: dict[str, list[Point]] = {}
    for point in points:
        if point.section == section:
            groups.setdefault(point.solver.label, []).append(point)
    return groups


def time_at_error(points: list[Point], target: float, statistic: str = "median") -> tuple[float | None, bool]:
    """Time [s] (the median, or with statistic="minimum" the min) at which a solver's height error reaches
    target, interpolated log-log between tolerances.

    Returns (time, upper_bound): upper_bound is True when already the loosest tolerance beats target
    (its time is then an upper bound); time is None if no tolerance reached target.
    """
    ordered = sorted((p for p in points if p.status == "ok" and p.errors), key=lambda p: -(p.rtol or 0.0))
    previous = None
    for point in ordered:
        error = point.errors.max_height_error
        if error <= target:
            if previous is None or error <= 0.0:
                return getattr(point, statistic), previous is None
            e0, e1 = math.log(previous.errors.max_height_error), math.log(error)
            t0, t1 = math.log(getattr(previous, statistic)), math.log(getattr(point, statistic))
            return math.exp(t0 + (math.log(target) - e0) / (e1 - e0) * (t1 - t0)), False
        previous = point
    return None, False


def save_h(points: list[Point], path: Path) -> Path:
    """The h values of the saved points, keyed by Point.key, so that errors can be recomputed."""
    with atomic_write(path) as temporary, temporary.open("wb") as file:  # a file: savez adds no .npz to it
        np.savez_compressed(file, **{point.key: point.h for point in points if point.h is not None})
    return path
