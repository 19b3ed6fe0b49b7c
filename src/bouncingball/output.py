"""CSV files: the solution as FMPy writes it (time,h,v) and the event list (time,kind,v); atomic_write, through
which every file the package writes goes."""

from __future__ import annotations

import contextlib
import csv
import os
import secrets
from pathlib import Path
from typing import TextIO

import numpy as np

from .solvers.result import SimulationResult

STANDARD_OUTPUT = "-"  # an output path that means stdout


def check_output_path(name: str, path: str | Path, make_folders: bool = False) -> Path:
    """path if a file can be written there; else ValueError naming the option, the path and why.

    Checked as the write will be made: an existing folder on the way that is a file, a folder that
    is missing (unless make_folders: the writer creates it), and a place the kernel refuses a new
    file in (/proc, /sys, a read-only mount) are found by creating, then removing, a temporary file
    in the deepest folder that exists.
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{name} = {str(path)!r} is not allowed: it is a folder")
    existing = next(part for part in path.absolute().parents if part.exists())
    if not existing.is_dir():
        reason = f"{str(existing)!r} is a file, not a folder"
    elif existing != path.absolute().parent and not make_folders:
        reason = f"its folder {str(path.parent)!r} does not exist"
    else:
        try:
            with atomic_write(existing / path.name) as temporary:
                raise _Probed(temporary)  # removed by atomic_write, never renamed onto anything
        except _Probed:
            return path
        except OSError as error:
            reason = f"a file cannot be created in {str(existing)!r} ({error.strerror or error})"
    raise ValueError(f"{name} = {str(path)!r} is not allowed: {reason}")


def check_output_folder(name: str, folder: str | Path) -> Path:
    """folder if it is one, or can be made, and files can be written in it; else ValueError as check_output_path."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"{name} = {str(folder)!r} is not allowed: it is a file, not a folder")
    try:
        check_output_path(name, folder / "probe", make_folders=True)
    except ValueError as error:  # said of the folder, not of the probe's name inside it
        raise ValueError(str(error).replace(repr(str(folder / "probe")), repr(str(folder)), 1)) from None
    return folder


class _Probed(Exception):
    """Raised inside atomic_write by check_output_path: the temporary file was created."""


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


SOLUTION_COLUMNS = ("time", "h", "v")


def write_solution_csv(result: SimulationResult, path: str | Path) -> Path:
    """time,h,v as FMPy's write_csv writes a result: quoted names, each number in its shortest round-trip form."""
    with atomic_write(path) as temporary, temporary.open("w", encoding="utf-8") as file:
        print_solution_csv(result, file)
    return Path(path)


def print_solution_csv(result: SimulationResult, file: TextIO) -> None:
    """The solution CSV of write_solution_csv, written to an open text stream (stdout for --output -)."""
    file.write(",".join(f'"{name}"' for name in SOLUTION_COLUMNS) + "\n")
    # repr of a float is the shortest text that reads back as the same double (0.298, not 0.29799999999999999).
    file.writelines(f"{t!r},{h!r},{v!r}\n" for t, h, v in zip(result.t.tolist(), result.h.tolist(),
                                                                 result.v.tolist(), strict=True))


def write_events_csv(result: SimulationResult, path: str | Path) -> Path:
    """time,kind,v, one row per event."""
    with atomic_write(path) as temporary, temporary.open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["time", "kind", "v"])
        for event in result.events:
            writer.writerow([repr(event.time), event.kind, repr(event.velocity)])
    return Path(path)


def read_solution_csv(path: str | Path) -> dict[str, np.ndarray]:
    """The columns of a time,h,v file by name (the names quoted, as FMPy writes them, or not)."""
    data = np.genfromtxt(path, delimiter=",", names=True, deletechars='"')
    return {name: np.asarray(data[name]) for name in data.dtype.names}
