"""Judge a co-simulation master's result against the exact solution: `bouncingball check` as a Python function.

A master (FMPy, fmusim, libcosim, your own) writes a CSV of the FMU's outputs; check_result()
computes the exact solution at the CSV's own times for the scene and start values the master was
given, and says how far the heights are from it and whether the impacts column counts right::

    from bouncingball.testing import check_result

    outcome = check_result("out.csv", "article", {"g": 1.62}, tolerance=1e-6)
    assert outcome.passed, outcome.report()

The run starts at start_time (0 unless given: the FMU's default experiment starts at 0), from the
scene's (h0, v0) with the start values applied; the CSV need not hold that first point (libcosim's
observers start after the first step); the FMU's solver settings (rtol, atol, method, engine) are accepted
and do not change the exact solution.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from . import validation
from .accuracy import exact_on_grid, impact_count_mismatches
from .fmu.variables import VARIABLES
from .physics import Ball
from .scenes import BALL_KEYS, Scene, load_scene

DEFAULT_TOLERANCE = 1e-6  # m
IMPACT_TIE = 1e-6  # s: a point this close to an impact may count it or not
# The FMU's start values that set up the run, by the scene field each one sets; the others (rtol,
# atol, method, engine) are solver settings, which the exact solution has no use for.
SCENE_FIELD_OF_START_VALUE = {**{key: key for key in BALL_KEYS}, "h": "h0", "v": "v0", "F_ext": "F_ext"}
SOLVER_SETTINGS = tuple(v.name for v in VARIABLES if v.causality == "parameter" and v.name not in BALL_KEYS)


class BadResultError(ValueError):
    """A result that cannot be checked: the message names the file, the row or column, and what is wrong."""


@dataclass(frozen=True)
class CheckResult:
    """The outcome of a check: the worst height error, the impact count, and the verdict.

    Attributes
    ----------
    source : str
        The file checked (or "<columns>" for arrays passed directly).
    scene : Scene
        The scene with the start values applied: the ball and the initial state of the run.
    tolerance : float
        The allowed max |h - h_exact| [m].
    points : int
        Number of points compared.
    start_time : float
        When the run started from the scene's initial state [s].
    t_start, t_end : float
        First and last time in the result [s].
    max_height_error : float
        max |h - h_exact| [m].
    worst_time, worst_h, worst_h_exact : float
        Where that error is: the time [s], the result's height and the exact height [m].
    impacts_exact : int
        The exact number of impacts from start_time to t_end.
    impacts_found : int or None
        The last value of the result's impacts column; None when it has none.
    impact_mismatches : tuple of (time, found, exact)
        The points whose impact count is wrong (the exact count up to that time; empty if none).
    """

    source: str
    scene: Scene
    tolerance: float
    start_time: float
    points: int
    t_start: float
    t_end: float
    max_height_error: float
    worst_time: float
    worst_h: float
    worst_h_exact: float
    impacts_exact: int
    impacts_found: int | None
    impact_mismatches: tuple[tuple[float, int, int], ...]

    @property
    def heights_pass(self) -> bool:
        """True when max |h - h_exact| is within the tolerance."""
        return self.max_height_error <= self.tolerance

    @property
    def passed(self) -> bool:
        """True when the heights are within the tolerance and the impacts column (if any) counts right."""
        return self.heights_pass and not self.impact_mismatches

    @property
    def verdict(self) -> str:
        """PASS or FAIL, with the reason."""
        if self.passed:
            return f"PASS: max |h - h_exact| = {self.max_height_error:.3e} m is within the tolerance " \
                   f"{self.tolerance:g} m" + ("" if self.impacts_found is None else ", impacts counted right")
        reasons = []
        if not self.heights_pass:
            reasons.append(f"max |h - h_exact| = {self.max_height_error:.3e} m at t = {self.worst_time!r} s "
                           f"exceeds the tolerance {self.tolerance:g} m")
        if self.impact_mismatches:
            t, found, exact = self.impact_mismatches[0]
            reasons.append(f"the impacts column is wrong at {len(self.impact_mismatches)} points, first at "
                           f"t = {t!r} s ({found}, exact {exact})")
        return "FAIL: " + "; ".join(reasons)

    def report(self) -> str:
        """The lines `bouncingball check` prints."""
        scene, ball = self.scene, self.scene.ball
        lines = [f"check {self.source} against the exact solution of scene {scene.name}",
                 f"  ball               m = {ball.m:g} kg, k = {ball.k:g} N/m, b = {ball.b:g} N s/m, "
                 f"R = {ball.R:g} m, g = {ball.g:g} m/s2, F_ext = {scene.F_ext:g} N",
                 f"  start              h = {scene.h0:.15g} m, v = {scene.v0:.15g} m/s at t = {self.start_time!r} s",
                 f"  points compared    {self.points} (t = {self.t_start!r} to {self.t_end!r} s)",
                 f"  max |h - h_exact|  {self.max_height_error:.3e} m at t = {self.worst_time!r} s "
                 f"(h = {self.worst_h!r} m, exact {self.worst_h_exact!r} m)"]
        if self.impacts_found is None:
            lines.append(f"  impacts            no impacts column (exact: {self.impacts_exact})")
        elif not self.impact_mismatches:
            lines.append(f"  impacts            {self.impacts_found} at the end, exact {self.impacts_exact}; "
                         "the count is right at every point")
        else:
            lines.append(f"  impacts            {self.impacts_found} at the end, exact {self.impacts_exact}; "
                         f"the count is wrong at {len(self.impact_mismatches)} points:")
            lines += [f"    t = {t!r} s: {found}, exact {exact}" for t, found, exact in self.impact_mismatches[:5]]
        lines.append(f"  verdict            {self.verdict}")
        return "\n".join(lines)


def read_result_csv(path: str | Path) -> dict[str, np.ndarray]:
    """The time, h and (if present) impacts columns of a master's CSV.

    The header names the columns, quoted or not (FMPy writes ``time,h,...``, fmusim
    ``"time","h",...``), in any order; other columns are ignored.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.

    Returns
    -------
    dict of str to numpy.ndarray
        "time" [s] and "h" [m] as floats, and "impacts" as integers when the file has that column.

    Raises
    ------
    BadResultError
        The file cannot be read, has no time or h column, a cell that is not a finite number (or
        not a whole number in impacts), no data row, or times that do not increase. The message
        names the file, the row (its line number) or column, and what is wrong.

    Examples
    --------
    >>> columns = read_result_csv("out.csv")  # doctest: +SKIP
    >>> columns["time"][:2], columns["h"][:2]  # doctest: +SKIP
    (array([0.   , 0.001]), array([2.       , 1.9999951]))
    """
    name = str(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as file:
            reader = csv.reader(file)
            rows = [(reader.line_num, row) for row in reader if any(cell.strip() for cell in row)]
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise BadResultError(f"{name}: cannot be read: {error}") from None
    if not rows:
        raise BadResultError(f"{name}: the file is empty: it needs a header with time and h columns")
    _, header = rows[0]
    header = [cell.strip().strip('"') for cell in header]
    missing = [column for column in ("time", "h") if column not in header]
    if missing:
        raise BadResultError(f"{name}: no {missing[0]!r} column in the header (it has: {', '.join(header)})")
    if len(rows) < 2:
        raise BadResultError(f"{name}: no data rows after the header")
    wanted = [column for column in ("time", "h", "impacts") if column in header]
    columns: dict[str, list[float]] = {column: [] for column in wanted}
    for number, row in rows[1:]:
        for column in wanted:
            index = header.index(column)
            if index >= len(row):
                raise BadResultError(f"{name}: row {number} has no {column!r} cell (it has {len(row)} cells)")
            cell = row[index].strip()
            try:
                value = float(cell)
            except ValueError:
                value = math.nan
            if not math.isfinite(value) or (column == "impacts" and value != int(value)):
                kind = "a whole number" if column == "impacts" else "a finite number"
                raise BadResultError(f"{name}: row {number}, column {column!r}: {cell!r} is not {kind}")
            columns[column].append(value)
    result = {column: np.array(values) for column, values in columns.items()}
    if "impacts" in result:
        result["impacts"] = result["impacts"].astype(np.int64)
    t = result["time"]
    decreasing = np.flatnonzero(np.diff(t) <= 0.0)
    if decreasing.size:
        i = int(decreasing[0]) + 1
        raise BadResultError(f"{name}: row {rows[i + 1][0]}, column 'time': {float(t[i])!r} does not increase "
                             f"(the row before has {float(t[i - 1])!r})")
    return result


def scene_with_start_values(scene: Scene | str | Path = "article",
                            start_values: Mapping[str, float | str] | None = None) -> Scene:
    """The scene a master ran, given the start values it set on the FMU.

    The FMU's parameters m, k, b, R, g set the ball, the start values of h and v the initial
    state, and F_ext (held constant) the external force; rtol, atol, method and engine are accepted and
    ignored (they do not change the exact solution).

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
    values = {key: getattr(scene.ball, key) for key in BALL_KEYS}
    values.update(h0=scene.h0, v0=scene.v0, F_ext=scene.F_ext)
    for name, value in (start_values or {}).items():
        if name in SOLVER_SETTINGS:
            continue
        if name not in SCENE_FIELD_OF_START_VALUE:
            allowed = ", ".join((*SCENE_FIELD_OF_START_VALUE, *SOLVER_SETTINGS))
            raise ValueError(f"start value {name!r} is not allowed: the FMU's settable variables are {allowed}")
        field = SCENE_FIELD_OF_START_VALUE[name]
        try:
            values[field] = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"start value {name} = {value!r} is not allowed: it must be a number") from None
    ball = Ball(**{key: values[key] for key in BALL_KEYS})
    return replace(scene, ball=ball, h0=validation.finite("h", values["h0"], "m"),
                   v0=validation.finite("v", values["v0"], "m/s"),
                   F_ext=validation.finite("F_ext", values["F_ext"], "N"))


def check_result(result, scene: Scene | str | Path = "article", start_values: Mapping[str, float | str] | None = None,
                 tolerance: float = DEFAULT_TOLERANCE, start_time: float = 0.0) -> CheckResult:
    """Compare a master's result with the exact solution at its own times.

    Parameters
    ----------
    result : str, pathlib.Path, mapping or numpy structured array
        A CSV file (read by read_result_csv), or columns by name: "time" [s] and "h" [m], and
        optionally "impacts" (FMPy's simulate_fmu result will do).
    scene : Scene, str or pathlib.Path
        The scene the master ran (default: the article's, which the FMU's defaults are).
    start_values : mapping of str to float or str, optional
        The start values the master set on the FMU (see scene_with_start_values).
    tolerance : float
        The allowed max |h - h_exact| [m] (default 1e-6).
    start_time : float
        When the master started the run [s] (default 0); no time in the result may be earlier.

    Returns
    -------
    CheckResult
        Its ``passed`` is the verdict, ``report()`` the text `bouncingball check` prints.

    Raises
    ------
    BadResultError
        The result cannot be read (see read_result_csv).
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
    scene = scene_with_start_values(scene, start_values)
    if isinstance(result, str | Path):
        source, columns = str(result), read_result_csv(result)
    else:
        source, columns = "<columns>", _columns_of(result)
    t, h = columns["time"], columns["h"]
    if t[0] < start_time:
        raise BadResultError(f"{source}: its first time, {float(t[0])!r} s, is before the start time {start_time!r} s "
                             "(give the start time the master used)")
    exact = exact_on_grid(t, scene.ball, scene.h0, scene.v0, scene.F_ext, t_start=start_time)
    error = np.abs(h - exact.h)
    worst = int(np.argmax(error))
    impact_times = exact.impact_times
    impacts_found, mismatches = None, ()
    if "impacts" in columns:
        impacts = columns["impacts"]
        impacts_found = int(impacts[-1])
        mismatches = tuple((float(t[i]), int(impacts[i]), int(exact.impacts[i]))
                           for i in impact_count_mismatches(impact_times, t, impacts, IMPACT_TIE))
    return CheckResult(source, scene, tolerance, start_time, len(t), float(t[0]), float(t[-1]), float(error[worst]),
                       float(t[worst]), float(h[worst]), float(exact.h[worst]), len(impact_times), impacts_found,
                       mismatches)


def _columns_of(result) -> dict[str, np.ndarray]:
    names = result.dtype.names if hasattr(result, "dtype") else tuple(result)
    missing = [column for column in ("time", "h") if column not in names]
    if missing:
        raise BadResultError(f"the result has no {missing[0]!r} column (it has: {', '.join(names)})")
    columns = {"time": np.asarray(result["time"], dtype=float), "h": np.asarray(result["h"], dtype=float)}
    if "impacts" in names:
        columns["impacts"] = np.asarray(result["impacts"], dtype=np.int64)
    t = columns["time"]
    if t.size == 0 or t.shape != columns["h"].shape or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
        raise BadResultError("the result's time column must be non-empty, finite, increasing and as long as h")
    if not np.all(np.isfinite(columns["h"])):
        raise BadResultError("the result's h column has a value that is not a finite number")
    return columns
