"""CSV files: the solution as FMPy writes it (time,h,v) and the event list (time,kind,v)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from .solvers.result import SimulationResult


def write_solution_csv(result: SimulationResult, path: str | Path) -> Path:
    """time,h,v with full double precision, one row per output point."""
    path = Path(path)
    data = np.column_stack((result.t, result.h, result.v))
    np.savetxt(path, data, delimiter=",", header="time,h,v", comments="", fmt="%.17g")
    return path


def write_events_csv(result: SimulationResult, path: str | Path) -> Path:
    """time,kind,v, one row per event."""
    path = Path(path)
    with path.open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["time", "kind", "v"])
        for event in result.events:
            writer.writerow([repr(event.time), event.kind, repr(event.velocity)])
    return path


def read_solution_csv(path: str | Path) -> dict[str, np.ndarray]:
    """The columns of a time,h,v file by name."""
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: np.asarray(data[name]) for name in data.dtype.names}
