"""The benchmarks' raw numbers as CSV: every work-precision point and every stability run, full precision."""

from __future__ import annotations

import csv
from pathlib import Path

from ..accuracy import Accuracy
from ..output import atomic_write
from .floor import FloorStudy
from .runners import Solver
from .stability import Outcome
from .text import repr_or_blank
from .work_precision import Point

WORK_PRECISION_COLUMNS = ("section", "solver", "kind", "method", "rtol", "atol", "output_interval", "status", "note",
                          "max_height_error", "max_event_time_error", "events_found", "events_exact", "counted",
                          "rhs_calls", "steps", "median_time", "min_time", "repeats", "times", "h_key")


def write_work_precision_csv(points: list[Point], path: Path) -> Path:
    """One row per point, full precision; times are every timed repeat [s]; h_key names the saved h values."""
    with atomic_write(path) as temporary, open(temporary, "w", newline="", encoding="utf-8") as file:
        writer = csv.writer(file)
        writer.writerow(WORK_PRECISION_COLUMNS)
        for p in points:
            e = p.errors
            writer.writerow([
                p.section, p.solver.label, p.solver.kind, p.solver.method, repr_or_blank(p.rtol),
                repr_or_blank(p.atol), repr(p.grid), p.status, p.note, repr_or_blank(e and e.max_height_error),
                repr_or_blank(e and e.max_event_time_error),
                repr_or_blank(e and e.events_found), repr_or_blank(e and e.events_exact), e.counted if e else "",
                repr_or_blank(p.rhs_calls), p.steps, repr_or_blank(p.median if p.times else None),
                repr_or_blank(p.minimum if p.times else None), len(p.times), ";".join(repr(t) for t in p.times),
                p.key if p.h is not None else ""])
    return path


FLOOR_COLUMNS = ("case", "target_error", "solver", "rtol", "atol", "max_height_error", "steps", "rhs_calls",
                 "runs_to_find_rtol", "median_time", "min_time", "repeats", "times")


def write_floor_csv(study: FloorStudy, path: Path) -> Path:
    """bench/floor.py's cases, one row each: against the C floor at the defaults, then matched; every call [s]."""
    cases = [("defaults", None, case) for case in (study.compiled, study.floor) if case is not None]
    cases += [("matched", m.target, case) for m in study.matched for case in m.cases.values() if case is not None]
    with atomic_write(path) as temporary, open(temporary, "w", newline="", encoding="utf-8") as file:
        writer = csv.writer(file)
        writer.writerow(FLOOR_COLUMNS)
        for name, target, c in cases:
            writer.writerow([name, repr_or_blank(target), c.solver.label, repr_or_blank(c.rtol), repr_or_blank(c.atol),
                             repr(c.error), c.steps, repr_or_blank(c.rhs_calls), c.runs, repr(c.median),
                             repr(c.minimum), len(c.times), ";".join(repr(t) for t in c.times)])
    return path


def read_work_precision_csv(path: Path) -> list[Point]:
    """The points write_work_precision_csv wrote (without their h values), to redraw the plot from them."""
    def number(text: str, kind=float):
        return None if text == "" else kind(text)

    points = []
    with open(path, newline="", encoding="utf-8") as file:
        for row in csv.DictReader(file):
            kind = row["kind"]
            grid = float(row["output_interval"])
            engine = "compiled" if "(compiled)" in row["solver"] else "sksundae" if kind in ("cvode", "fmu") else ""
            solver = Solver(row["solver"], kind, row["method"], grid if kind in ("fmu", "empty") else 0.0, engine)
            errors = None
            if row["max_height_error"]:
                errors = Accuracy(float(row["max_height_error"]), float(row["max_event_time_error"] or "nan"),
                                  number(row["events_found"], int), number(row["events_exact"], int), row["counted"])
            times = [float(t) for t in row["times"].split(";") if t]
            points.append(Point(row["section"], solver, number(row["rtol"]), grid, row["status"], row["note"], errors,
                                number(row["rhs_calls"], int), int(row["steps"] or 0), times))
    return points


STABILITY_COLUMNS = ("scene", "solver", "kind", "method", "rtol", "atol", "status", "note", "max_height_error",
                     "max_event_time_error", "events_found", "events_exact", "counted", "energy_drift", "wall_time",
                     "rhs_calls")


def write_stability_csv(outcomes: list[Outcome], path: Path) -> Path:
    with atomic_write(path) as temporary, open(temporary, "w", newline="", encoding="utf-8") as file:
        writer = csv.writer(file)
        writer.writerow(STABILITY_COLUMNS)
        for o in outcomes:
            e, c = o.errors, o.case
            writer.writerow([c.scene.name, c.solver.label, c.solver.kind, c.solver.method, repr_or_blank(c.rtol),
                             repr_or_blank(c.atol), o.status, o.note, repr_or_blank(e and e.max_height_error),
                             repr_or_blank(e and e.max_event_time_error), repr_or_blank(e and e.events_found),
                             repr_or_blank(e and e.events_exact), e.counted if e else "",
                             repr_or_blank(e and e.energy_drift),
                             repr_or_blank(o.wall_time), repr_or_blank(o.rhs_calls)])
    return path
