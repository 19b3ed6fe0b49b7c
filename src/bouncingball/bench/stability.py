"""Stability: every scene with every solver, each run in a capped child process (killed past a time cap)."""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass

import numpy as np

from ..accuracy import Accuracy
from ..capped import FINISHED, run_capped
from ..limits import contact_duration
from ..physics import Ball
from ..scenes import BUILTIN_SCENES, Scene, load_scene, scene_from_mapping
from . import runners
from .runners import ARTICLE, CVODE_AUTO, EXACT, FmuPaths, Run, Solver

_DEFAULT = Ball()


def _extra(description: str, **values) -> dict:
    """A scene's keys, its description formatted from them (and the contact's duration, as {contact})."""
    contact = contact_duration(Ball(**{key: values.get(key, getattr(_DEFAULT, key)) for key in ("m", "k", "b")}))
    return {"description": description.format(**values, contact=contact), **values}


# Extreme scenes beyond the built-in ones: each holds only what differs from the article's defaults.
EXTRA_SCENES = {
    "critical": _extra("critical damping, b = 2 sqrt(k m) = {b:g} N s/m", b=2.0 * math.sqrt(_DEFAULT.k * _DEFAULT.m)),
    "thrown-up": _extra("thrown upwards, v0 = {v0:+g} m/s", v0=5.0),
    "at-surface": _extra("starts exactly at h0 = R, at rest", h0=_DEFAULT.R),
    "k1e14": _extra("k = {k:g} N/m: contacts last {contact:.2g} s", k=1e14),
    "undamped-10000s": _extra("b = {b:g} for {t_end:,.0f} s: energy drift and cost per event", b=0.0, t_end=10_000.0,
                              output_interval=0.01),
}
STIFF_SCENES = ("stiff", "stiff-rest", "tiny-mass", "overdamped")
STIFF_TARGET = 0.1  # CVODE finishes each stiff scene within this wall time [s]
FULL_CAP = 30.0  # [s] per run in the stability matrix (CVODE needs ~15 s for the 10,000 s run)
QUICK_CAP = 2.0
STIFF_REPEATS = 3  # CVODE's runs of each stiff scene, of which the median is shown
COST_CHUNKS = 100  # the cost per event is timed in this many chunks of the run
CSV_FILE = "stability.csv"
FMU_LABEL = "FMU via FMPy"


def extra_scene(name: str) -> Scene:
    return scene_from_mapping(name, EXTRA_SCENES[name])


def all_scenes() -> list[Scene]:
    return [*(load_scene(name) for name in BUILTIN_SCENES), *(extra_scene(name) for name in EXTRA_SCENES)]


@dataclass(frozen=True)
class Case:
    """A scene, a solver and its tolerances (None: the solver's defaults), run `repeats` times in one child."""

    scene: Scene
    solver: Solver
    rtol: float | None = None
    atol: float | None = None
    repeats: int = 1


@dataclass(frozen=True)
class Outcome:
    """status is finished, failed or timed out; wall_time [s] is the median over the case's repeats."""

    case: Case
    status: str
    note: str = ""
    errors: Accuracy | None = None
    wall_time: float = math.nan
    rhs_calls: int | None = None


def stability_solvers(scene: Scene) -> list[Solver]:
    """Every solver; the FMU communicates at the scene's output interval."""
    ours = [runners.cvode(method) for method in ("auto", "Adams", "BDF")] + [runners.CVODE_COMPILED]
    peers = [ARTICLE, *(runners.scipy(method) for method in ("DOP853", "LSODA", "Radau", "BDF"))]
    fmu = Solver(FMU_LABEL, "fmu", comm_step=scene.output_interval)
    return [*ours, EXACT, *peers, fmu]


def stability_cases(scenes: list[Scene]) -> list[Case]:
    """Every solver at CVODE's default tolerances (the article's algorithm as published)."""
    from ..solvers.phase_machine.settings import DEFAULT_RTOL

    cases = []
    for scene in scenes:
        for solver in stability_solvers(scene):
            tolerances = (DEFAULT_RTOL, None) if solver.takes_tolerances else (None, None)
            cases.append(Case(scene, solver, *tolerances))
    return cases


def stiff_cases() -> list[Case]:
    """The stiff scenes: CVODE (median of STIFF_REPEATS) and the explicit SciPy methods at their default tolerances."""
    cases = []
    for name in STIFF_SCENES:
        scene = load_scene(name)
        cases += [Case(scene, CVODE_AUTO, repeats=STIFF_REPEATS),
                  Case(scene, runners.CVODE_COMPILED, repeats=STIFF_REPEATS)]
        cases += [Case(scene, ARTICLE), *(Case(scene, runners.scipy(m)) for m in runners.EXPLICIT_SCIPY_METHODS)]
    return cases


def _timed_runs(case: Case, fmus: FmuPaths | None) -> tuple[float, Run]:
    """The case's runs: the median wall time [s] and the last run."""
    times = []
    for _ in range(case.repeats):
        run = runners.run_solver(case.solver, case.scene, case.scene.output_interval, case.rtol, case.atol, fmus)
        times.append(run.wall_time)
    return statistics.median(times), run


def run_case(case: Case, cap: float, fmus: FmuPaths | None = None) -> Outcome:
    """Run case in the capped child process (both engines loaded), killed if its runs take more than cap [s] each."""
    capped = run_capped(_timed_runs, (case, fmus), cap * case.repeats, warm_up=runners.warm_up)
    if capped.status != FINISHED:
        return Outcome(case, capped.status, capped.note)
    wall_time, run = capped.value
    return Outcome(case, FINISHED, errors=runners.errors_against_exact(case.scene, run), wall_time=wall_time,
                   rhs_calls=run.rhs_calls)


def run_cases(cases: list[Case], cap: float, fmus: FmuPaths | None = None, desc: str = "stability") -> list[Outcome]:
    """Each case in the capped child process, one after another, with a progress bar."""
    from tqdm import tqdm

    outcomes = []
    with tqdm(cases, desc=desc, unit="case") as bar:
        for case in bar:
            bar.set_postfix_str(f"{case.scene.name}: {case.solver.label}", refresh=False)
            outcomes.append(run_case(case, cap, fmus))
    return outcomes


@dataclass(frozen=True)
class CostPerEvent:
    """Wall time [s] and events in the first and the last tenth of an undamped run of t_end [s].

    first and last are the least time per event [s] of the tenth's chunks: noise on a shared
    machine only adds time, and one busy moment moved the sum of a tenth by up to 1.6x.
    """

    t_end: float
    events: int
    first_time: float
    first_events: int
    last_time: float
    last_events: int
    first: float
    last: float

    @property
    def ratio(self) -> float:
        return self.last / self.first


def cost_per_event(t_end: float, chunks: int = COST_CHUNKS) -> CostPerEvent:
    """The undamped ball for t_end [s] in one CVODE integrator, timed chunk by chunk (0.01 s output grid)."""
    from tqdm import tqdm

    from ..solvers.cvode import BallIntegrator
    from ..solvers.result import output_grid

    scene = extra_scene("undamped-10000s")
    integrator = BallIntegrator(scene.ball, scene.h0, scene.v0)
    edges = np.linspace(0.0, t_end, chunks + 1)
    times, events = [], []
    for start, end in tqdm(list(zip(edges[:-1], edges[1:], strict=True)), desc="cost per event", unit="chunk"):
        grid = output_grid(float(start), float(end), scene.output_interval)
        started = time.perf_counter()
        found = integrator.integrate_grid(grid)[2]
        times.append(time.perf_counter() - started)
        events.append(len(found))
    tenth = chunks // 10
    per_event = [t / n for t, n in zip(times, events, strict=True)]
    return CostPerEvent(t_end, sum(events), sum(times[:tenth]), sum(events[:tenth]), sum(times[-tenth:]),
                        sum(events[-tenth:]), min(per_event[:tenth]), min(per_event[-tenth:]))
