"""The compiled engine held against its floor (the same CVODE work in C) and against DOP853 at matched errors.

Timing protocol: interleaved hot calls. Every case runs untimed first (numba's code loaded, the C
library built and bound), then the timed calls go round-robin over the cases, so drift on a shared
machine hits all alike, and no gc.collect() is made before a timed call (one just before a call adds
~0.75 ms to the compiled engine: this measures the call, not the collector). Min and median.

DOP853 is matched to an error by running it: a bisection on log10 rtol over the swept range finds the
loosest rtol whose max height error on the 1 ms grid is <= the target, and that run's settings are
timed; no interpolation between tolerances. The compiled engine is matched the same way.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field

from ..scenes import Scene
from . import runners
from .work_precision import DENSE, Point, Settings

CSV_FILE = "floor.csv"
MATCHED_SOLVERS = (runners.CVODE_COMPILED, runners.scipy("DOP853"))


@dataclass(eq=False)
class Timed(Point):
    """A point on the 1 ms grid with its run's events, the runs it took to find its rtol (the bisection), and for the
    C floor the part of each timed call spent in C [s]."""

    events: list | None = None
    runs: int = 1
    times_in_c: list[float] = field(default_factory=list)

    @property
    def error(self) -> float:
        """The max height error [m] against the exact solution; nan before the run."""
        return self.errors.max_height_error if self.errors else math.nan


def _case(solver: runners.Solver, rtol: float | None) -> Timed:
    return Timed("dense", solver, rtol, DENSE)


@dataclass
class Matched:
    """At a target max height error [m]: the compiled engine and DOP853, each at the rtol reaching it (None: none)."""

    target: float
    cases: dict[str, Timed | None]
    note: str = ""


@dataclass
class FloorStudy:
    """The compiled engine and the C floor at the defaults, whether they did the same work, and the matched cases."""

    compiled: Timed | None
    floor: Timed | None
    same_events: bool
    same_steps: bool
    matched: list[Matched]
    repeats: int
    note: str = ""

    @property
    def ratio(self) -> tuple[float, float]:
        """The compiled engine's time over the floor's time in C: (from min times, from medians)."""
        if self.compiled is None or self.floor is None or not self.floor.times_in_c:
            return math.nan, math.nan
        return (self.compiled.minimum / min(self.floor.times_in_c),
                self.compiled.median / statistics.median(self.floor.times_in_c))


def _run(case: Timed, scene: Scene, record: bool = True, errors=runners.errors_against_exact):
    run = runners.run_solver(case.solver, scene, DENSE, case.rtol, case.atol)
    if record:
        case.status, case.errors = "ok", errors(scene, run)
        case.events, case.steps, case.rhs_calls = run.events, run.steps, run.rhs_calls
    return run


def interleave(cases: list[Timed], scene: Scene, repeats: int, bar) -> None:
    for case in cases:  # warm-up, untimed
        _run(case, scene, record=False)
    for _ in range(repeats):
        for case in cases:
            run = _run(case, scene, record=False)
            case.times.append(run.wall_time)
            if run.wall_time_in_c is not None:
                case.times_in_c.append(run.wall_time_in_c)
        bar.update()


def match(solver: runners.Solver, scene: Scene, target: float, loosest: float, tightest: float,
          steps: int, errors=runners.errors_against_exact) -> Timed | None:
    """The loosest rtol in [tightest, loosest] whose run's max height error is <= target, by bisection in log10 rtol.

    None if even tightest does not reach it; loosest if already it does. Each rtol is run, not interpolated.
    errors(scene, run): the run's Accuracy (against the exact solution unless said otherwise).
    Where the error does not grow with rtol (DOP853's jumps with its event times), the rtol found reaches the
    target and a looser one within the last bisection step does not; a looser one further away may.
    """
    runs = 0

    def at(log_rtol: float) -> Timed:
        nonlocal runs
        runs += 1
        case = _case(solver, 10.0**log_rtol)
        _run(case, scene, errors=errors)
        return case

    bad, good = math.log10(loosest), math.log10(tightest)
    best = at(bad)
    if not best.error <= target:
        best = at(good)
        if not best.error <= target:
            return None
        for _ in range(steps):
            middle = at(0.5 * (bad + good))
            if middle.error <= target:
                good, best = math.log10(middle.rtol), middle
            else:
                bad = math.log10(middle.rtol)
    best.runs = runs
    return best


def measure(scene: Scene, settings: Settings, errors: tuple[float, ...]) -> FloorStudy:
    """The C floor against the compiled engine at the defaults, then the matched cases at each error [m]."""
    from tqdm import tqdm

    from . import c_floor

    matched = []
    for target in errors:
        cases, notes = {}, []
        for solver in MATCHED_SOLVERS:
            try:
                cases[solver.label] = match(solver, scene, target, max(settings.rtols), min(settings.rtols),
                                            settings.bisection_steps)
            except Exception as error:  # a solver that cannot run here (no numba): the page says why
                cases[solver.label] = None
                notes.append(f"{solver.label}: {type(error).__name__}: {error}".splitlines()[0][:200])
                continue
            if cases[solver.label] is None:
                notes.append(f"{solver.label} does not reach it in the swept range")
        matched.append(Matched(target, cases, "; ".join(notes)))
    timed = [case for m in matched for case in m.cases.values() if case is not None]
    reason = c_floor.unavailable_reason()
    if reason is None:
        try:
            runners.run_solver(runners.CVODE_COMPILED, scene, DENSE)
        except ImportError as error:
            reason = f"the compiled engine cannot run here: {error}"
    floors = [_case(runners.CVODE_COMPILED, None), _case(runners.C_FLOOR, None)] if reason is None else []
    for case in floors:
        _run(case, scene)
    with tqdm(total=settings.matched_repeats + settings.floor_repeats, desc="C floor, matched DOP853",
              unit="round") as bar:
        interleave(timed, scene, settings.matched_repeats, bar)
        interleave(floors, scene, settings.floor_repeats if floors else 0, bar)
    if reason is not None:
        return FloorStudy(None, None, False, False, matched, 0, f"the C floor cannot run here: {reason}")
    compiled, floor = floors
    same_events = compiled.events == floor.events
    same_steps = (compiled.steps, compiled.rhs_calls) == (floor.steps, floor.rhs_calls)
    return FloorStudy(compiled, floor, same_events, same_steps, matched, settings.floor_repeats)
