"""The two studies `bouncingball bench` runs, from the runs to the files they write."""

from __future__ import annotations

import dataclasses
import sys
import tempfile
from pathlib import Path

from ..scenes import load_scene
from . import c_floor, engine_choice, floor, fmu_steps, runners, stability, work_precision
from .environment import environment
from .pages import write_benchmarks_md, write_stability_md
from .plots import plot_work_precision
from .tables import write_floor_csv, write_stability_csv, write_work_precision_csv
from .targets import MATCHED_ERRORS, Target, all_targets


def step(text: str) -> None:
    """A step of the bench that shows no bar of its own, as a line on stderr."""
    print(f"bench: {text}", file=sys.stderr, flush=True)


def run_benchmark(output_dir: Path, quick: bool = False) -> tuple[list[Path], list[Target]]:
    """The whole `bouncingball bench`: sweep, stiff scenes, cost per event; writes the docs.

    Returns the paths written and the goals held against (the headline).
    """
    settings = work_precision.QUICK if quick else work_precision.FULL
    scene = load_scene("article")
    machine = environment()
    step("loading both CVODE engines (the compiled one from numba's cache, or compiled now: about a minute)")
    scene.simulate("cvode", t_end=1.0, engine="sksundae")  # load scikit-sundae before anything is timed
    try:  # and compile (or load from numba's cache) the compiled engine
        scene.simulate("cvode", t_end=1.0, engine="compiled")
    except ImportError:
        pass  # its rows say why
    step("building the C floor")
    c_floor.unavailable_reason()  # build (or find built) and bind the C floor; where it cannot, its rows say why
    with tempfile.TemporaryDirectory(prefix="bouncingball_bench_") as temp:
        step("building the FMUs (FMI 2.0 and 3.0, and the empty ones; a minute or more)")
        fmus = runners.build_fmus(Path(temp))
        try:  # the FMU's compiled engine too: its first use (seconds) is timed apart, by fmu_steps
            runners.run_solver(runners.fmu(work_precision.DENSE, "compiled"), dataclasses.replace(scene, t_end=0.01),
                               work_precision.DENSE, fmus=fmus, record=False)
        except Exception:  # no numba, no FMU...: its rows say why
            pass
        points = work_precision.make_points(settings)
        work_precision.sweep(scene, points, settings, fmus)
        step("timing the FMU's doStep calls")
        step_costs = fmu_steps.measure(fmus, work_precision.DENSE, scene.t_end, settings.repeats)
    floors = floor.measure(scene, settings, MATCHED_ERRORS)
    stiff = stability.run_cases(stability.stiff_cases(), settings.stiff_cap, desc="stiff scenes")
    per_event = stability.cost_per_event(settings.undamped_t_end)
    step("timing each engine's first use in fresh processes")
    first_use = engine_choice.measure()
    written = [
        write_work_precision_csv(points, output_dir / work_precision.CSV_FILE),
        work_precision.save_h(points, output_dir / work_precision.H_FILE),
        plot_work_precision(points, output_dir / "work_precision.png"),
        write_floor_csv(floors, output_dir / floor.CSV_FILE),
        write_benchmarks_md(points, stiff, per_event, step_costs, settings, quick, machine,
                            output_dir / "benchmarks.md", floors, first_use),
    ]
    return written, all_targets(points, stiff, per_event, floors)


def run_stability_study(output_dir: Path, quick: bool = False) -> list[Path]:
    """`bouncingball bench --stability`: the matrix over all scenes and solvers; writes stability.md and .csv."""
    cap = stability.QUICK_CAP if quick else stability.FULL_CAP
    machine = environment()
    scenes = stability.all_scenes()
    with tempfile.TemporaryDirectory(prefix="bouncingball_bench_") as temp:
        fmus = runners.build_fmus(Path(temp))
        outcomes = stability.run_cases(stability.stability_cases(scenes), cap, fmus)
    return [write_stability_csv(outcomes, output_dir / stability.CSV_FILE),
            write_stability_md(scenes, outcomes, cap, quick, machine, output_dir / "stability.md")]
