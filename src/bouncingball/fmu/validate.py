"""`bouncingball validate`: the FMU through FMPy, side by side with CVODE in-process, SciPy and the exact solution."""

from __future__ import annotations

import math
import shutil
import sys
import time
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..accuracy import Accuracy, accuracy_of, accuracy_of_result, exact_on_grid, impact_counts
from ..capped import FINISHED, Capped, run_capped
from ..contact_laws import LAWS
from ..scenes import Scene, load_scene
from ..solvers import ARTICLE_LABEL
from .variables import fmu_ground_scene, judged_scene, start_values_of

CVODE_LABEL = "CVODE (in-process)"
NAME_WIDTH = 31
SCIPY_CAP = 60.0  # s: the article's explicit method takes many minutes on the stiffest scenes
STAGES = ("exact", "scipy", "cvode", "fmu")  # what `validate --skip` names


@dataclass(frozen=True)
class Row:
    """One run: its accuracy against the exact solution (None: it has no result), wall time [s] and a note."""

    name: str
    accuracy: Accuracy | None
    wall_time: float
    note: str = ""


@dataclass(frozen=True)
class Report:
    scene: Scene
    fmu: Path | None  # None: the FMU stage was skipped
    rows: list[Row]
    impacts_match_at_every_point: bool | None  # None: the FMU stage was skipped
    judge_error: float = 0.0  # the exact solution's own error estimate [m]: a smaller error cannot be told from 0


# The FMI 3.0 FMU's runs beside co-simulation without early return: each is FMPy's simulate_fmu options.
FMI3_RUNS = {
    "FMU 3.0 CS, early return": {"early_return_allowed": True, "use_event_mode": True},
    "FMU 3.0 ME, FMPy CVode 1e-8": {"fmi_type": "ModelExchange", "solver": "CVode", "relative_tolerance": 1e-8},
}
FMI3_NOTES = {"FMU 3.0 CS, early return": "doStep returns at each event; the master's event mode there",
              "FMU 3.0 ME, FMPy CVode 1e-8": "the master integrates; the FMU's event indicator is h - R"}


def run_fmu(fmu: str | Path, scene: Scene, options: dict | None = None, **start_values):
    """The scene through FMPy's simulate_fmu, one communication step per output interval.

    options are more of simulate_fmu's (fmi_type, early_return_allowed, ...). Returns the result, the
    wall time of the simulation [s] and that of loading the FMU [s] before it.
    """
    try:
        from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu
    except ImportError as error:
        from ..extras import install_command

        raise ImportError(f"validate needs FMPy ({error}): {install_command('fmu')}") from None

    values = {**start_values_of(scene), **start_values}
    started = time.perf_counter()
    unzipped = extract(str(fmu))
    try:
        description = read_model_description(unzipped)
        options = dict(options or {})
        instance = instantiate_fmu(unzipped, description, fmi_type=options.get("fmi_type"),
                                   early_return_allowed=options.get("early_return_allowed", False),
                                   event_mode_used=options.get("use_event_mode", False))
        loaded = time.perf_counter()
        result = simulate_fmu(unzipped, model_description=description, fmu_instance=instance,
                              start_values=values, start_time=0.0, stop_time=scene.t_end,
                              output_interval=scene.output_interval, output=["h", "v", "impacts", "contact"],
                              **options)
        finished = time.perf_counter()
        instance.freeInstance()
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)
    return result, finished - loaded, loaded - started


def validate(scene_name: str = "article", fmu: str | Path | None = None,
             progress: Callable[[str], None] = lambda stage: None, skip: Sequence[str] = (),
             time_cap: float = SCIPY_CAP, fmi_version: int = 2) -> Report:
    """Run the scene four ways (six for FMI 3.0: FMI3_RUNS too); the FMU is (re)built first if it is stale.

    progress is told each stage as it starts (the SciPy run alone may take up to time_cap seconds).
    skip names stages of STAGES not to run; the exact solution, which judges the others, is still
    computed when "exact" is skipped (its own row is left out). Every input, the FMU file included,
    is checked before any stage runs.
    """
    from .. import validation
    from .build import DEFAULT_OUTPUTS, build_fmu, is_stale

    if fmi_version not in DEFAULT_OUTPUTS:
        raise ValueError(f"fmi_version = {fmi_version!r} is not allowed: it must be 2 or 3")
    skip = {validation.choice("--skip", stage, STAGES) for stage in skip}
    time_cap = validation.positive("--time-cap", time_cap, "s")
    scene = fmu_ground_scene(judged_scene(load_scene(scene_name), "validate"))
    if not LAWS[scene.ball.contact].article_algorithm and "scipy" not in skip:
        skip.add("scipy")
        progress("the article's SciPy algorithm is not run: it models the linear contact law, not "
                 f"{scene.ball.contact}")
    if scene.ground.moves and "scipy" not in skip:
        skip.add("scipy")
        progress("the article's SciPy algorithm is not run: it models a still ground, not a vibrating one")
    default = DEFAULT_OUTPUTS[fmi_version]
    fmu = Path(fmu) if fmu is not None else default
    if "fmu" not in skip:
        import fmpy  # noqa: F401  (before any work: without the [fmu] extra, say so now)

        if fmu == default and is_stale(fmu):
            progress(f"building {fmu}")
            build_fmu(None, fmi_version, lambda step: progress(f"building {fmu}: {step}"))  # its folder is made
        else:
            check_fmu_file(fmu)

    progress("the exact solution")
    exact = scene.simulate("exact")
    runs = {}
    if "scipy" not in skip:  # in a child process killed past the cap (before the FMU starts Python threads)
        progress(f"the article's SciPy algorithm (stopped after {time_cap:g} s if it has not finished)")
        runs[ARTICLE_LABEL] = run_capped(scene.simulate, ("scipy",), time_cap)
    if "cvode" not in skip:
        progress("CVODE in this process")
        runs[CVODE_LABEL] = Capped(FINISHED, scene.simulate("cvode"))
    rows, impacts_match = [], None
    if "fmu" not in skip:
        progress("the FMU through FMPy")
        result, wall_time, load_time = run_fmu(fmu, scene)
        others = "" if LAWS[scene.ball.contact].crossings_only else \
            "; impacts counted, the law's other events are not among the FMU's outputs"
        rows.append(Row("FMU (FMPy)" if fmi_version == 2 else "FMU 3.0 CS (FMPy)", _fmu_accuracy(result, scene),
                        wall_time, f"+ {load_time:.3f} s to load; events seen only at communication points{others}"))
        impacts_match = _impacts_match(result, scene)
        for label, options in FMI3_RUNS.items() if fmi_version == 3 else ():
            progress(f"the FMU through FMPy: {label}")
            other, other_time, _ = run_fmu(fmu, scene, options)
            note = FMI3_NOTES[label].replace("h - R", "h - R - s(t)") if scene.ground.moves else FMI3_NOTES[label]
            rows.append(Row(label, _fmu_accuracy(other, scene), other_time, note))
    for label in (CVODE_LABEL, ARTICLE_LABEL):
        capped = runs.get(label)
        if capped is None:
            continue
        if capped.status != FINISHED:  # SciPy's explicit method fails or crawls on stiff scenes
            rows.append(Row(label, None, math.nan, f"{capped.status}: {capped.note}"))
            continue
        run = capped.value
        rows.append(Row(label, accuracy_of_result(run, scene.h0, scene.v0)[0], run.stats.wall_time))
    if "exact" not in skip:
        rows.append(Row("exact", accuracy_of_result(exact, scene.h0, scene.v0)[0], exact.stats.wall_time))
    return Report(scene, None if "fmu" in skip else fmu, rows, impacts_match, exact.error_estimate)


def _fmu_accuracy(result, scene: Scene) -> Accuracy:
    """The FMU's result against the exact solution at its own times (early return adds the events' times)."""
    at_points = exact_on_grid(result["time"], scene.ball, scene.h0, scene.v0, scene.F_ext, t_start=0.0,
                              ground=scene.ground)
    impacts, contact = int(result["impacts"][-1]), result["contact"].astype(int)
    if not LAWS[scene.ball.contact].crossings_only:  # a rigid ball's rest, a no-pull release: not in its outputs
        return accuracy_of(at_points, result["h"], impacts=impacts)
    # The FMU counts impacts; its departures follow from them and the contact flag at both ends.
    return accuracy_of(at_points, result["h"], events_found=2 * impacts + contact[0] - contact[-1])


def _impacts_match(result, scene: Scene) -> bool:
    """Whether the FMU's impact count equals the exact one at every communication point."""
    at_points = exact_on_grid(result["time"], scene.ball, scene.h0, scene.v0, scene.F_ext, t_start=0.0,
                              ground=scene.ground)
    t = at_points.t
    tie = 1e-9 * np.maximum(1.0, np.abs(t))  # an impact on a communication point, to 1 ns, may count or not
    return impact_counts(at_points.impact_times, t, result["impacts"], tie).mismatches.size == 0


def check_fmu_file(fmu: Path) -> None:
    """ValueError naming fmu unless it is a zip archive with a modelDescription.xml, as every FMU is."""
    if not fmu.is_file():
        reason = "it is a folder" if fmu.is_dir() else "no such file"
        raise ValueError(f"--fmu = {str(fmu)!r} is not allowed: {reason}")
    if not zipfile.is_zipfile(fmu):
        raise ValueError(f"--fmu = {str(fmu)!r} is not allowed: it is not an FMU (not a zip archive)")
    with zipfile.ZipFile(fmu) as archive:
        if "modelDescription.xml" not in archive.namelist():
            raise ValueError(f"--fmu = {str(fmu)!r} is not allowed: it is not an FMU (no modelDescription.xml)")


def format_report(report: Report) -> str:
    """The table `bouncingball validate` prints."""
    scene = report.scene
    lines = [f"scene {scene.name}: {scene.description}",
             (f"FMU {report.fmu}, communication step" if report.fmu else "FMU skipped; output every")
             + f" {scene.output_interval:g} s, 0 to {scene.t_end:g} s",
             f"{'run':{NAME_WIDTH}s}{'max |h - h_exact| [m]':>23s}{'event time error [s]':>22s}{'events':>8s}"
             f"{'exact':>7s}{'wall time [s]':>15s}  note"]
    for row in report.rows:
        a = row.accuracy
        if a is None:
            lines.append(f"{row.name:{NAME_WIDTH}s}{'-':>23s}{'-':>22s}{'-':>8s}{'-':>7s}{'-':>15s}  {row.note}")
            continue
        event_error = "n/a" if math.isnan(a.max_event_time_error) else f"{a.max_event_time_error:.3e}"
        lines.append(f"{row.name:{NAME_WIDTH}s}{a.max_height_error:23.3e}{event_error:>22s}{a.events_found:8d}"
                     f"{a.events_exact:7d}{row.wall_time:15.4f}  {row.note}")
    if report.impacts_match_at_every_point is not None:
        match = "yes" if report.impacts_match_at_every_point else "NO"
        lines.append(f"FMU impact count equals the exact count at every communication point: {match}")
    undecided = [row.name for row in report.rows if row.accuracy is not None and row.name != "exact"
                 and row.accuracy.max_height_error <= report.judge_error]
    if undecided:  # the judge's own error estimate is above theirs: it cannot tell them from exact
        lines.append(f"the exact solution's own error estimate (its rounding, carried) is {report.judge_error:.3e} m: "
                     f"the judge cannot decide below it, and {', '.join(undecided)} are within it")
    return "\n".join(lines)


def validate_command(scene: str = "article", fmu: str | None = None, skip: Sequence[str] = (),
                     time_cap: float = SCIPY_CAP, fmi_version: int = 2) -> int:
    """`bouncingball validate [SCENE] [--fmu PATH] [--skip STAGE ...] [--time-cap S] [--fmi-version 2|3]`."""
    from .build import FmuBuildError

    try:
        report = validate(scene, fmu, lambda stage: print(f"validate: {stage} ...", file=sys.stderr), skip, time_cap,
                          fmi_version)
    except FmuBuildError as error:
        print(f"bouncingball: cannot build the FMU: {error}", file=sys.stderr)
        return 1
    print(format_report(report))
    return 0
