"""`bouncingball validate`: the FMU through FMPy, side by side with CVODE in-process, SciPy and the exact solution."""

from __future__ import annotations

import math
import multiprocessing
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..accuracy import compare, exact_counterpart, impact_count_mismatches, max_height_error
from ..scenes import BALL_KEYS, Scene, load_scene
from ..solvers.result import IMPACT, SimulationResult

SCIPY_CAP = 60.0  # s: the article's explicit method takes many minutes on the stiffest scenes


@dataclass(frozen=True)
class Row:
    """One run: max |h - h_exact| [m], max event time error [s] (None: not observable), events, wall time [s]."""

    name: str
    max_height_error: float
    max_event_time_error: float | None
    events_found: int
    events_exact: int
    wall_time: float
    note: str = ""


@dataclass(frozen=True)
class Report:
    scene: Scene
    fmu: Path
    rows: list[Row]
    impacts_match_at_every_point: bool


def run_fmu(fmu: str | Path, scene: Scene, **start_values):
    """The scene through FMPy's simulate_fmu, one communication step per output interval.

    Returns the result, the wall time of the simulation [s] and that of loading the FMU [s] before it.
    """
    try:
        from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu
    except ImportError as error:
        raise ImportError(f"validate needs FMPy ({error}): pip install 'bouncingball[fmu]'") from None

    values = {key: getattr(scene.ball, key) for key in BALL_KEYS}
    values.update(h=scene.h0, v=scene.v0, F_ext=scene.F_ext, **start_values)
    started = time.perf_counter()
    unzipped = extract(str(fmu))
    try:
        description = read_model_description(unzipped)
        instance = instantiate_fmu(unzipped, description)
        loaded = time.perf_counter()
        result = simulate_fmu(unzipped, model_description=description, fmu_instance=instance,
                              start_values=values, start_time=0.0, stop_time=scene.t_end,
                              output_interval=scene.output_interval, output=["h", "v", "impacts", "contact"])
        finished = time.perf_counter()
        instance.freeInstance()
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)
    return result, finished - loaded, loaded - started


def validate(scene_name: str = "article", fmu: str | Path | None = None,
             progress: Callable[[str], None] = lambda stage: None) -> Report:
    """Run the scene four ways; the FMU is (re)built first if it is missing or older than its sources.

    progress is told each stage as it starts (the SciPy run alone may take up to SCIPY_CAP seconds).
    """
    import fmpy  # noqa: F401  (before any work: without the [fmu] extra, say so now)

    from .build import DEFAULT_OUTPUT, build_fmu, is_stale

    scene = load_scene(scene_name)
    fmu = Path(fmu) if fmu is not None else DEFAULT_OUTPUT
    if fmu == DEFAULT_OUTPUT and is_stale(fmu):
        progress(f"building {fmu}")
        build_fmu(fmu)
    elif not fmu.is_file():
        raise ValueError(f"fmu = {str(fmu)!r} is not allowed: no such file")

    progress("the exact solution")
    exact = scene.simulate("exact")
    n_exact = len(exact.events)
    # SciPy first, in a child process that is killed past the cap (before the FMU starts Python threads).
    progress(f"the article's SciPy algorithm (stopped after {SCIPY_CAP:g} s if it has not finished)")
    runs = {"SciPy (article's RK45)": run_capped(scene, "scipy", SCIPY_CAP)}
    progress("CVODE in this process")
    runs["CVODE (in-process)"] = scene.simulate("cvode")
    rows = []
    progress("the FMU through FMPy")
    result, wall_time, load_time = run_fmu(fmu, scene)
    t = result["time"]
    h_exact, _ = exact_solution_at(scene, t)
    impacts = result["impacts"]
    # Impacts are counted; departures follow from them and the contact flag at both ends.
    contact = result["contact"].astype(int)
    events_found = 2 * int(impacts[-1]) + contact[0] - contact[-1]
    impact_times = np.array([event.time for event in exact.events if event.kind == IMPACT])
    rows.append(Row("FMU (FMPy)", max_height_error(result["h"], h_exact), None, events_found, n_exact,
                    wall_time, f"+ {load_time:.3f} s to load; events seen only at communication points"))
    for label in ("CVODE (in-process)", "SciPy (article's RK45)"):
        run = runs[label]
        if isinstance(run, str):  # SciPy's explicit method fails or crawls on stiff scenes
            rows.append(Row(label, math.nan, math.nan, 0, n_exact, math.nan, run))
            continue
        accuracy = compare(run, exact_counterpart(run, scene.h0, scene.v0))
        rows.append(Row(label, accuracy.max_height_error, accuracy.max_event_time_error, accuracy.events_found,
                        n_exact, run.stats.wall_time))
    rows.append(Row("exact", 0.0, 0.0, n_exact, n_exact, exact.stats.wall_time))
    tie = 1e-9 * np.maximum(1.0, np.abs(t))  # an impact on a communication point, to 1 ns, may count or not
    return Report(scene, fmu, rows, impact_count_mismatches(impact_times, t, impacts, tie).size == 0)


def run_capped(scene: Scene, solver: str, cap: float) -> SimulationResult | str:
    """scene.simulate(solver) in a forked child killed after cap [s]; a string says why it has no result."""
    context = multiprocessing.get_context("fork")
    receiver, sender = context.Pipe(duplex=False)
    process = context.Process(target=_simulate_into, args=(scene, solver, sender), daemon=True)
    process.start()
    try:
        if not receiver.poll(cap):
            return f"killed after {cap:g} s"
        return receiver.recv()
    except EOFError:
        return f"the run ended with exit code {process.exitcode}"
    finally:
        process.kill()
        process.join()


def _simulate_into(scene: Scene, solver: str, sender) -> None:
    try:
        sender.send(scene.simulate(solver))
    except Exception as error:  # the parent reports it in the table
        sender.send(f"failed: {error}")


def exact_solution_at(scene: Scene, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The exact (h, v) of the scene at the times t."""
    from ..solvers.exact import ExactSolution

    solution = ExactSolution(scene.ball, scene.h0, scene.v0, 0.0, float(t[-1]), scene.F_ext)
    return solution.state(t)


def format_report(report: Report) -> str:
    """The table `bouncingball validate` prints."""
    scene = report.scene
    lines = [f"scene {scene.name}: {scene.description}",
             f"FMU {report.fmu}, communication step {scene.output_interval:g} s, 0 to {scene.t_end:g} s",
             f"{'run':24s}{'max |h - h_exact| [m]':>23s}{'event time error [s]':>22s}{'events':>8s}"
             f"{'exact':>7s}{'wall time [s]':>15s}  note"]
    for row in report.rows:
        event_error = "n/a" if row.max_event_time_error is None else f"{row.max_event_time_error:.3e}"
        lines.append(f"{row.name:24s}{row.max_height_error:23.3e}{event_error:>22s}{row.events_found:8d}"
                     f"{row.events_exact:7d}{row.wall_time:15.4f}  {row.note}")
    match = "yes" if report.impacts_match_at_every_point else "NO"
    lines.append(f"FMU impact count equals the exact count at every communication point: {match}")
    return "\n".join(lines)


def validate_command(scene: str = "article", fmu: str | None = None) -> int:
    """`bouncingball validate [SCENE] [--fmu PATH]`."""
    from .build import FmuBuildError

    try:
        report = validate(scene, fmu, progress=lambda stage: print(f"validate: {stage} ...", file=sys.stderr))
    except FmuBuildError as error:
        print(f"bouncingball: cannot build the FMU: {error}", file=sys.stderr)
        return 1
    print(format_report(report))
    return 0
