"""CSV files: the solution as FMPy writes it (time,h,v) and the event list (time,kind,v); atomic_write, through
which every file the package writes goes."""

from __future__ import annotations

import contextlib
import csv
import os
import secrets
from pathlib import Path

import numpy as np

from .solvers.result import SimulationResult


def check_output_path(name: str, path: str | Path) -> Path:
    """path if a file can be written there; else ValueError naming the option, the path and why."""
    path = Path(path)
    folder = path.parent
    if path.is_dir():
        reason = "it is a folder"
    elif not folder.is_dir():
        reason = f"its folder {str(folder)!r} does not exist"
    elif not os.access(folder, os.W_OK):
        reason = f"its folder {str(folder)!r} is not writable"
    else:
        return path
    raise ValueError(f"{name} = {str(path)!r} is not allowed: {reason}")


@contextlib.contextmanager
def atomic_write(path: str | Path):
    """A new file beside path, renamed onto it only once written: no partial file is ever left.

    Every file the package writes goes through here. The file is created as any program creates one,
    mode 0666 less the umask (0644 under umask 022), not mkstemp's 0600, so that CI artifacts and
    shared folders can read it. Write it by name (the yielded path); it is renamed onto path when
    the block ends without an exception, and removed otherwise.
    """
    path = Path(path)
    for _ in range(100):
        temporary = path.with_name(f".{path.name}.{secrets.token_hex(4)}")
        try:  # O_EXCL: a new file of ours, never one that was there; the kernel applies the umask
            os.close(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            break
        except FileExistsError:
            continue
    else:
        raise FileExistsError(f"no free temporary name beside {str(path)!r}")
    try:
        yield temporary
        os.replace(temporary, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.remove(temporary)


def write_solution_csv(result: SimulationResult, path: str | Path) -> Path:
    """time,h,v with full double precision, one row per output point."""
    data = np.column_stack((result.t, result.h, result.v))
    with atomic_write(path) as temporary:
        np.savetxt(temporary, data, delimiter=",", header="time,h,v", comments="", fmt="%.17g")
    return Path(path)


def write_events_csv(result: SimulationResult, path: str | Path) -> Path:
    """time,kind,v, one row per event."""
    with atomic_write(path) as temporary, temporary.open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["time", "kind", "v"])
        for event in result.events:
            writer.writerow([repr(event.time), event.kind, repr(event.velocity)])
    return Path(path)


def read_solution_csv(path: str | Path) -> dict[str, np.ndarray]:
    """The columns of a time,h,v file by name."""
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: np.asarray(data[name]) for name in data.dtype.names}
