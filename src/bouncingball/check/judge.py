"""Judge a co-simulation master's result against the exact solution: `bouncingball check` as a Python function.

A master (FMPy, OMSimulator, libcosim, ecos, fmusim, your own) writes a CSV of the FMU's
outputs; check_result() reads it as the master wrote it (see bouncingball.check.result_files),
computes the exact solution at the CSV's own times for the scene and start values the master
was given, and says how far the heights are from it and whether the impacts column counts right::

    from bouncingball.check.judge import check_result

    outcome = check_result("out.csv", "article", {"g": 1.62}, tolerance=1e-6)
    assert outcome.passed, outcome.report()

The run starts at start_time (0 unless given: the FMU's default experiment starts at 0), from the
scene's (h0, v0) with the start values applied; the CSV need not hold that first point (libcosim's
observers start after the first step). Parameters the file carries as columns (libcosim and ecos
write every variable) are taken from it; a start value that contradicts one is bad input. A file
printed with fewer digits than the tolerance needs is judged within its printed resolution. The
FMU's rtol and atol set which hops it may merge into the contact (cvode.merged_hop_limit): an
impact ending such a hop, or one lower than the check's tolerance, may be missing from the count.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import validation
from ..accuracy import event_hops, impact_counts
from ..fmu.variables import (
    GROUND_FIELD_OF_START_VALUE,
    SCENE_FIELD_OF_START_VALUE,
    SCENE_OWN_FIELDS,
    TEXT_START_VALUES,
    VARIABLES,
    ball_fields_of,
    fmu_scene,
    ground_of,
    judged_scene,
    start_values_of,
)
from ..physics import Ball, Mode, without_unread
from ..scenes import BALL_KEYS, Scene, load_scene
from ..solvers.exact import ExactSolution
from ..solvers.forcing import ForceTable
from ..solvers.phase_machine.settings import DEFAULT_RTOL, CvodeSettings, merged_hop_limit
from ..solvers.result import IMPACT
from .input_files import applied_force
from .outcome import CheckResult, MergedHops
from .printed_numbers import Printing
from .result_files import BadResultError, FileParameter, ResultFile, read_result_csv, read_result_file

__all__ = ["DEFAULT_TOLERANCE", "BadResultError", "CheckResult", "MergedHops", "check_result", "read_result_csv",
           "scene_with_start_values"]

DEFAULT_TOLERANCE = 1e-6  # m
IMPACT_TIE = 1e-6  # s: a point this close to an impact may count it or not
START_SLACK = 1e-9  # relative: how far the first row's v and a may be from the start state's before it is said
# The FMU's start values that set up the run, by the scene field each one sets; the others (rtol,
# atol, method, engine) are solver settings, which the exact solution has no use for.
SOLVER_SETTINGS = tuple(v.name for v in VARIABLES if v.causality == "parameter"
                        and v.name not in SCENE_FIELD_OF_START_VALUE and v.name not in GROUND_FIELD_OF_START_VALUE)


def scene_with_start_values(scene: Scene | str | Path = "article",
                            start_values: Mapping[str, float | str] | None = None) -> Scene:
    """The scene a master ran, given the start values it set on the FMU.

    The FMU's parameters m, k, b, R, g, contact_law and the law's (e, v_min, n, alpha) set the ball, the start values
    of h and v the initial state, F_ext (held constant) the external force, and ground_amplitude, ground_frequency
    and ground_phase, where one of them is given, the ground (a sine, or still at 0 where ground_amplitude is 0);
    rtol, atol, method and engine are accepted and ignored (they do not change the exact solution).

    Parameters
    ----------
    scene : Scene, str or pathlib.Path
        A Scene, a built-in scene's name or a .toml file (default: the article's, the FMU's defaults).
    start_values : mapping of str to float or str, optional
        FMU variable name to value, as given to the master (strings are read as numbers).

    Returns
    -------
    Scene
        The scene with the start values applied.

    Raises
    ------
    ValueError
        An unknown scene, a name that is not a settable variable of the FMU, or a value that is
        not allowed (for example m = -1); the message names it.

    Examples
    --------
    >>> scene_with_start_values("article", {"g": "1.62", "h": 1.0}).ball.g
    1.62
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    fmu_scene(scene)
    values = {SCENE_FIELD_OF_START_VALUE.get(name, name): value for name, value in start_values_of(scene).items()}
    ground_given = False
    for name, value in (start_values or {}).items():
        if name in SOLVER_SETTINGS:
            continue
        if name in GROUND_FIELD_OF_START_VALUE:
            values[name], ground_given = _number(name, value), True
            continue
        if name not in SCENE_FIELD_OF_START_VALUE:
            allowed = ", ".join((*SCENE_FIELD_OF_START_VALUE, *GROUND_FIELD_OF_START_VALUE, *SOLVER_SETTINGS))
            raise ValueError(f"start value {name!r} is not allowed: the FMU's settable variables are {allowed}")
        field = SCENE_FIELD_OF_START_VALUE[name]
        if name in TEXT_START_VALUES:
            values[field] = str(value)
            continue
        try:
            values[field] = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"start value {name} = {value!r} is not allowed: it must be a number") from None
    # As the FMU runs them: a parameter the contact law does not read at its default.
    fields = ball_fields_of({name: values[field] for name, field in SCENE_FIELD_OF_START_VALUE.items()})
    ball = Ball(**without_unread(fields)[0])
    ground = ground_of(values) if ground_given else scene.ground  # else the scene's, whatever it is
    return fmu_scene(replace(scene, ball=ball, h0=validation.finite("h", values["h0"], "m"),
                             v0=validation.finite("v", values["v0"], "m/s"),
                             F_ext=validation.finite("F_ext", values["F_ext"], "N"), ground=ground))


def check_result(result, scene: Scene | str | Path = "article", start_values: Mapping[str, float | str] | None = None,
                 tolerance: float = DEFAULT_TOLERANCE, start_time: float = 0.0,
                 instance: str | None = None, input_file: str | Path | None = None,
                 step_size: float | None = None) -> CheckResult:
    """Compare a master's result with the exact solution at its own times.

    Parameters
    ----------
    result : str, pathlib.Path, mapping or numpy structured array
        A CSV file (read by bouncingball.check.result_files.read_result_file), or columns by name:
        "time" [s] and "h" [m], and optionally "impacts" (FMPy's simulate_fmu result will do).
    scene : Scene, str or pathlib.Path
        The scene the master ran (default: the article's, which the FMU's defaults are).
    start_values : mapping of str to float or str, optional
        The start values the master set on the FMU (see scene_with_start_values); rtol and atol
        set which hops the FMU may merge into the contact.
    tolerance : float
        The allowed max |h - h_exact| [m] (default 1e-6).
    start_time : float
        When the master started the run [s] (default 0); no time in the result may be earlier.
    instance : str, optional
        The instance of the ball to check, when the file holds several.
    input_file : str or pathlib.Path, optional
        The FMPy input file (``time,F_ext``) the master drove the FMU's F_ext with. F_ext is then held
        over each communication step [t_i, t_i+1) at the value FMPy applies at t_i (its linear
        interpolation of the rows; after a step, two rows at one time, the later value): see
        input_files.fmpy_input_value.
    step_size : float, optional
        The master's communication step [s] with input_file: the communication points are
        start_time + k step_size and the input's step times (FMPy adds those for this FMU, which
        takes variable steps). Without it they are the result's distinct times.

    Where the result has an F_ext column that changes, it is what was applied, as FMPy records it:
    each row holds the F_ext set at the start of the step that ended at its time (FMPy samples after
    doStep), so F_ext over [t_i, t_i+1) is the value in the row at t_i+1. The column is then used
    and input_file is not.

    Returns
    -------
    CheckResult
        Its ``passed`` is the verdict, ``report()`` the text `bouncingball check` prints.

    Raises
    ------
    BadResultError
        The result cannot be read (see read_result_file), starts before start_time, or a start
        value contradicts a parameter column beyond its printed resolution.
    ValueError
        A bad scene, start value, tolerance or start time.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0.0, 0.5, 11)  # in flight: the ball reaches the ground at 0.63 s
    >>> outcome = check_result({"time": t, "h": 2.0 - 0.5 * 9.81 * t**2})
    >>> outcome.passed, outcome.points
    (True, 11)
    """
    tolerance = validation.positive("tolerance", tolerance, "m")
    start_time = validation.finite("start_time", start_time, "s")
    if isinstance(result, str | Path):
        file = read_result_file(result, instance)
    elif instance is not None:
        raise ValueError("instance picks the columns of a file: pass the file, or the instance's columns alone")
    else:
        file = _file_of_columns(result)
    source = file.source
    values = dict(start_values or {})
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    fmu_scene(scene)
    taken, defaults = [], []
    for name, parameter in file.parameters.items():
        where = f"{source}: row {parameter.row}, column {parameter.column!r}"
        if name in values:
            given = _number(name, values[name])
            if not _agree(given, parameter):
                within = f" (beyond its printed resolution, {parameter.resolution:.1g})" if parameter.resolution else ""
                raise BadResultError(f"{where}: {name} = {parameter.value!r} contradicts the start value {name} = "
                                     f"{values[name]}{within}")
        elif not _agree(_setting(scene, name), parameter):  # the scene's value, unless the file shows another
            values[name] = parameter.value
            taken.append(f"{name} = {parameter.value!r} (the scene has {_setting(scene, name)!r})")
        elif _refused(scene, name, parameter.value):  # printed too coarsely to tell from a value the FMU refuses
            if name not in SOLVER_SETTINGS:
                raise BadResultError(f"{where}: {name} is printed as {parameter.value!r}, which the FMU refuses, to a "
                                     f"resolution of {parameter.resolution:.1g}: too few digits to tell the value the "
                                     f"master set; give it with --start-value {name}=VALUE")
            # a solver setting does not change the exact solution: the default it may be printing will do
            defaults.append(f"{name} printed as {parameter.value!r} (refused by the FMU), read as the FMU's default "
                            f"{_setting(scene, name)!r}, within its printed resolution {parameter.resolution:.1g}")
    try:
        scene = scene_with_start_values(scene, values)
        rtol, atol = _solver_settings(values)
    except ValueError as error:
        wrong = next((p for n, p in file.parameters.items() if n not in (start_values or {}) and
                      str(error).startswith(f"{n} = ")), None)
        if wrong is None:
            raise
        raise BadResultError(f"{source}: row {wrong.row}, column {wrong.column!r}: {error} (as printed: give the "
                             f"value the master set with --start-value {wrong.name}=VALUE)") from None
    file_parameters = ", ".join(file.parameters)
    if file_parameters:
        file_parameters += ": " + "; ".join([*(["; ".join(taken) + " taken from it"] if taken else []), *defaults]
                                            or ["as the scene and the FMU's defaults have them"])
    ball = judged_scene(scene, "check").ball
    t, h, t_res, h_res = file.time, file.h, file.time_resolution, file.h_resolution
    if t[0] < start_time - t_res[0]:
        raise BadResultError(f"{source}: its first time, {float(t[0])!r} s, is before the start time {start_time!r} s "
                             "(give the start time the master used)")
    t_last = max(float(np.max(t + t_res)), start_time)
    force, forcing = applied_force(file, scene.F_ext, start_time, float(t[-1]), input_file, step_size)
    solution = ExactSolution(ball, scene.h0, scene.v0, start_time, t_last, force, ground=scene.ground)
    h_exact, v_exact = solution.state(t)
    allowance = tolerance + h_res
    if np.any(t_res > 0.0):  # the time printed to t_res: the ball moves |v| t_res in that time
        speed = np.abs(v_exact)
        for shifted in (np.maximum(t - t_res, start_time), t + t_res):
            speed = np.maximum(speed, np.abs(solution.state(shifted)[1]))
        allowance = allowance + speed * t_res
    error = np.abs(h - h_exact)
    worst, most = int(np.argmax(error)), int(np.argmax(error - allowance))
    events = solution.events
    impact_times = np.array([e.time for e in events if e.kind == IMPACT])
    hops = np.array([hop for e, hop in zip(events, event_hops(solution), strict=True) if e.kind == IMPACT])
    impacts_exact = int(np.searchsorted(impact_times, t[-1], side="right"))
    impacts_found, mismatches, merged = None, (), None
    if file.impacts is not None:
        impacts = file.impacts
        impacts_found = int(impacts[-1])
        limit = max(merged_hop_limit(ball, rtol, atol, f) for f in getattr(force, "values", (force,)))
        counts = impact_counts(impact_times, t, impacts, IMPACT_TIE + t_res, hops <= max(limit, tolerance))
        exact_counts = np.searchsorted(impact_times, t, side="right")
        mismatches = tuple((float(t[i]), int(impacts[i]), int(exact_counts[i])) for i in counts.mismatches)
        by_solver = int(np.count_nonzero(hops[counts.merged] <= limit))
        merged = MergedHops(by_solver, limit, len(counts.merged) - by_solver, tolerance)
    return CheckResult(source, scene, tolerance, start_time, len(t), float(t[0]), float(t[-1]), float(error[worst]),
                       float(t[worst]), float(h[worst]), float(h_exact[worst]), impacts_exact, impacts_found,
                       mismatches, int(np.count_nonzero(error > allowance)), float(t[most]), float(error[most]),
                       float(allowance[most]), str(file.printing), float(np.max(allowance - tolerance)),
                       file.instance, file_parameters, merged,
                       _first_row(file, replace(scene, F_ext=float(ForceTable.of(force).at(start_time))
                                                if forcing else scene.F_ext), tolerance, start_time), forcing,
                       file.F_ext is None and input_file is None,
                       _conditioning(scene, force, start_time, t_last), solution.error_estimate)


def _conditioning(scene: Scene, force, start_time: float, t_end: float) -> str:
    """The AccuracyWarning a CVODE run of the scene gives from start_time to t_end [s] under force, or "" (none).

    The exact solution is evaluated in double precision too: where a run's error estimate passes
    the promise, small errors grow faster than any double-precision solution can follow.
    """
    from ..solvers import simulate
    from ..solvers.result import AccuracyWarning

    if not t_end > start_time:
        return ""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", AccuracyWarning)
        try:
            simulate(scene.ball, scene.h0, scene.v0, t_end, (t_end - start_time) / 1000, t_start=start_time,
                     F_ext=force, ground=scene.ground, **({"solver": "exact"} if scene.ground.moves else {}))
        except (ValueError, RuntimeError):  # a run that cannot be made: nothing to say about it
            return ""
    return next((str(w.message) for w in caught if issubclass(w.category, AccuracyWarning)), "")


def _setting(scene: Scene, name: str) -> float:
    """The value a run of scene has for the FMU's parameter name (rtol and atol: the FMU's defaults)."""
    field = SCENE_FIELD_OF_START_VALUE.get(name)
    if field is not None and field not in SCENE_OWN_FIELDS:
        return getattr(scene.ball, field)
    if name in GROUND_FIELD_OF_START_VALUE:
        return getattr(scene.ground, GROUND_FIELD_OF_START_VALUE[name])
    return {"F_ext": scene.F_ext, "rtol": DEFAULT_RTOL, "atol": 0.0}[name]


def _solver_settings(values: Mapping[str, float | str]) -> tuple[float, float | None]:
    """(rtol, atol [m] or None) the FMU runs with for these start values; ValueError names a refused one.

    CvodeSettings checks them, as the FMU does: the same ranges (rtol in [1e-15, 1], atol 0 for none).
    """
    settings = CvodeSettings(rtol=_number("rtol", values.get("rtol", DEFAULT_RTOL)),
                             atol=_number("atol", values.get("atol", 0.0)))
    return settings.rtol, settings.atol


def _refused(scene: Scene, name: str, value: float) -> bool:
    """Whether the FMU refuses value for its parameter name in scene."""
    try:
        _solver_settings({name: value}) if name in SOLVER_SETTINGS else scene_with_start_values(scene, {name: value})
    except ValueError:
        return True
    return False


def _agree(value: float, parameter: FileParameter) -> bool:
    """True when value is the parameter's printed value, to its printed resolution."""
    return abs(value - parameter.value) <= parameter.resolution + math.ulp(max(abs(value), abs(parameter.value)))


def _number(name: str, value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"start value {name} = {value!r} is not allowed: it must be a number") from None


def _first_row(file: ResultFile, scene: Scene, tolerance: float, start_time: float) -> tuple[str, ...]:
    """How the file's first row, when it is the start, disagrees with the scene: each with the start value that fits."""
    if abs(file.time[0] - start_time) > file.time_resolution[0]:
        return ()  # the file starts later (libcosim's observers): its first row is not the start state
    ball, F_ext = scene.ball, scene.F_ext
    notes = []
    h0 = float(file.h[0])
    if abs(h0 - scene.h0) > tolerance + file.h_resolution[0]:
        notes.append(f"h = {h0!r} m where the scene starts at {scene.h0!r} m (--start-value h={h0!r} would match it)")
    v0 = scene.v0 if file.v is None else float(file.v[0])
    if file.v is not None and abs(v0 - scene.v0) > file.v_resolution[0] + START_SLACK * max(1.0, abs(scene.v0)):
        notes.append(f"v = {v0!r} m/s where the scene starts at {scene.v0!r} m/s (--start-value v={v0!r} would "
                     "match it)")
    if file.a is not None:  # at the file's own start state, a tells the ball's parameters apart
        mode = ball.initial_mode(h0, v0, F_ext)
        expected = ball.acceleration(h0, v0, mode, F_ext)
        a0 = float(file.a[0])
        if abs(a0 - expected) > file.a_resolution[0] + START_SLACK * max(1.0, abs(expected)):
            g = F_ext / ball.m - a0
            if "g" in file.parameters and (mode == Mode.FLIGHT or set(BALL_KEYS) <= set(file.parameters)):
                fits = "the file's own parameter columns do not give the run it holds"
            elif mode == Mode.FLIGHT and g >= 0.0:
                fits = f"--start-value g={g!r} would match it"
            else:
                fits = "one of m, k, b, R, g, F_ext differs"
            notes.append(f"a = {a0!r} m/s2 where the scene's ball has {expected!r} m/s2 there ({fits})")
    return tuple(notes)


def _file_of_columns(result) -> ResultFile:
    names = result.dtype.names if hasattr(result, "dtype") else tuple(result)
    missing = [column for column in ("time", "h") if column not in names]
    if missing:
        raise BadResultError(f"the result has no {missing[0]!r} column (it has: {', '.join(names)})")
    t, h = np.asarray(result["time"], dtype=float), np.asarray(result["h"], dtype=float)
    if t.size == 0 or t.shape != h.shape or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0.0):
        raise BadResultError("the result's time column must be non-empty, finite, non-decreasing and as long as h")
    if not np.all(np.isfinite(h)):
        raise BadResultError("the result's h column has a value that is not a finite number")
    impacts = np.asarray(result["impacts"], dtype=np.int64) if "impacts" in names else None
    zero = np.zeros_like(t)
    return ResultFile("<columns>", "", {"time": "time", "h": "h"}, np.arange(2, t.size + 2), t, h, impacts, None,
                      None, Printing("full"), zero, zero)
