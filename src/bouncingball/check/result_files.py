"""Masters' result files of the FMU, read as the masters write them.

Each master writes its own CSV dialect, and read_result_file() takes them as they are:

- FMPy: ``"time","h","v",...``, full precision.
- OMSimulator: a quoted header (after an optional ``"sep=,"`` line), every communication point
  written twice and the last one three times, each instance's variables as
  ``model.root.<instance>.<variable>``, values to 12 significant digits.
- libcosim's file observer: ``Time,StepCount,`` then every variable, parameters too, as
  ``name [index type causality]``, each line ending in a comma, values to 6 significant digits.
- ecos: ``iterations, time, <instance>::h[REAL], <instance>::impacts[INT], ...``, 6 decimals.

Column names are matched without regard to case; a prefix naming the instance (``ball::``,
``model.root.ball.``, ``ball.``) and a bracketed suffix (``[REAL]``, ``[5 real output]``) are
understood; columns that are not the FMU's variables (``StepCount``, ``iterations``, another
FMU's) are ignored. A file whose cells show it was printed with fewer digits than a double has
(see printed_numbers.infer_printing) carries its printed resolution, which the check allows for.
"""

from __future__ import annotations

import contextlib
import csv
import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..fmu.variables import VARIABLES
from .printed_numbers import Printed, Printing, infer_printing, parse_number

# The FMU's variables by their lower-case name; the parameters check takes from a file, with F_ext
# (an input: the file's column is taken when it is constant).
VARIABLE_OF = {variable.name.lower(): variable.name for variable in VARIABLES}
PARAMETERS = ("m", "k", "b", "R", "g", "F_ext", "rtol", "atol")
_SUFFIX = re.compile(r"\s*\[[^\[\]]*\]\s*$")  # [REAL], [INT], [5 real output]
_NUMERIC = ("time", "h", "v", "a", "impacts", *PARAMETERS)


class BadResultError(ValueError):
    """A result that cannot be checked: the message names the file, the row or column, and what is wrong."""


def refuse_binary(path: str | Path, wanted: str = "the CSV a master wrote (a time and an h column)") -> None:
    """BadResultError naming what the file is when it is no text (an FMU, a zip archive, a binary file), and wanted.

    A CSV is text: a NUL byte in its first 4 kB, or a zip's signature, says it is something else.
    """
    with open(path, "rb") as file:
        head = file.read(4096)
    if head.startswith(b"PK\x03\x04"):
        kind = "a zip archive"
        with contextlib.suppress(zipfile.BadZipFile, OSError), zipfile.ZipFile(path) as archive:
            if "modelDescription.xml" in archive.namelist():
                kind = "an FMU (a zip archive)"
    elif b"\0" in head:
        kind = "a binary file"
    else:
        return
    raise BadResultError(f"{path}: it is {kind}, not a CSV file: give {wanted}")


def unreadable(error: Exception) -> str:
    """Why a CSV file cannot be read, in words (a text in another encoding than UTF-8 named as such)."""
    if isinstance(error, UnicodeDecodeError):
        return f"it is not UTF-8 text (it holds the byte 0x{error.object[error.start]:02x}): save it as UTF-8"
    return str(error)


@dataclass(frozen=True)
class FileParameter:
    """A parameter the file carries as a column (libcosim and ecos write every variable).

    Attributes
    ----------
    name : str
        The FMU's variable (m, k, b, R, g, F_ext, rtol, atol).
    value : float
        Its value in the file.
    resolution : float
        Its printed resolution (0 in full precision).
    column : str
        The column's name as the file writes it.
    row : int
        The line of the file the value was read from (the first data row).
    """

    name: str
    value: float
    resolution: float
    column: str
    row: int


@dataclass(frozen=True)
class ResultFile:
    """One instance's columns of a master's result file, with what the file says about its own precision.

    Attributes
    ----------
    source : str
        The file.
    instance : str
        The instance's prefix as written ("" when the columns have none).
    columns : dict of str to str
        The FMU variable each column read holds, to its name in the header.
    rows : numpy.ndarray
        The line number of each data row.
    time, h : numpy.ndarray
        The time [s] and height [m] of each row.
    F_ext : numpy.ndarray or None
        The F_ext column [N] where the file has one (an input: it may change; when it does not, it is
        also a parameter).
    impacts, v, a : numpy.ndarray or None
        The impact count, velocity [m/s] and acceleration [m/s2] of each row, where the file has them.
    printing : Printing
        How the file prints its real numbers.
    time_resolution, h_resolution, v_resolution, a_resolution : numpy.ndarray
        The printed resolution of each row's time [s], h [m], v [m/s] and a [m/s2] (0 in full precision).
    parameters : dict of str to FileParameter
        The parameters the file carries as columns.
    """

    source: str
    instance: str
    columns: dict[str, str]
    rows: np.ndarray
    time: np.ndarray
    h: np.ndarray
    impacts: np.ndarray | None
    v: np.ndarray | None
    a: np.ndarray | None
    printing: Printing
    time_resolution: np.ndarray
    h_resolution: np.ndarray
    v_resolution: np.ndarray | None = None
    a_resolution: np.ndarray | None = None
    parameters: dict[str, FileParameter] = field(default_factory=dict)
    F_ext: np.ndarray | None = None


@dataclass(frozen=True)
class _Column:
    index: int
    raw: str  # as written
    prefix: str  # the instance part, as written
    variable: str  # the FMU's variable name, or the name as written when it is none


def _split(raw: str) -> tuple[str, str]:
    """(instance prefix, variable) of a header cell: ball::h[REAL], model.root.ball.h, h [5 real output]."""
    name = _SUFFIX.sub("", raw).strip()
    for separator in ("::", "."):
        if separator in name:
            prefix, variable = name.rsplit(separator, 1)
            return prefix, variable
    return "", name


def _short(prefix: str) -> str:
    """The instance's own name: the last part of model.root.ball."""
    return re.split(r"::|\.", prefix)[-1]


def read_result_file(path: str | Path, instance: str | None = None) -> ResultFile:
    """One instance's time, h, impacts, v, a and parameter columns of a master's CSV, as the master wrote it.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.
    instance : str, optional
        Which instance of the ball to read when the file holds several: its name (``ball``) or
        its whole prefix (``model.root.ball``). Needed when there are several, refused when the
        columns name none.

    Returns
    -------
    ResultFile
        The columns read and their printed resolution.

    Raises
    ------
    BadResultError
        The file cannot be read or is not a result: no time or h column, a duplicated column,
        several instances and none picked (the message names them), a row with more cells than
        the header or without a cell it needs, a cell that is not a finite decimal number (``1_0``
        is not 10) or not a whole number in impacts, time going back, a parameter that changes,
        or no data row. The message names the file, the row (its line number), the column and
        the value.

    Examples
    --------
    >>> result = read_result_file("libcosim.csv")  # doctest: +SKIP
    >>> str(result.printing), result.parameters["g"].value  # doctest: +SKIP
    ('6 significant digits', 9.81)
    """
    name = str(path)
    try:
        refuse_binary(path)
        with open(path, newline="", encoding="utf-8-sig") as file:
            reader = csv.reader(file, skipinitialspace=True)
            lines = [(reader.line_num, row) for row in reader if any(cell.strip() for cell in row)]
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise BadResultError(f"{name}: cannot be read: {unreadable(error)}") from None
    if lines and len(lines[0][1]) == 1 and lines[0][1][0].strip().lower().startswith("sep="):
        separator = lines[0][1][0].strip()[4:]
        if separator != ",":
            raise BadResultError(f"{name}: row {lines[0][0]} says the separator is {separator!r}: only ',' is read")
        lines = lines[1:]  # OMSimulator's "sep=," line, for spreadsheets
    if not lines:
        raise BadResultError(f"{name}: the file is empty: it needs a header with time and h columns")
    header_line, header = lines[0]
    header = [cell.strip() for cell in header]
    width = len(header)
    while header and not header[-1]:  # libcosim ends every line with a comma
        header.pop()
    columns = _header_columns(name, header_line, header)
    time = next((c for c in columns if not c.prefix and c.variable == "time"), None)
    if time is None:
        raise BadResultError(f"{name}: no 'time' column in the header (it has: {', '.join(header)})")
    chosen = _instance_columns(name, columns, instance, header)
    if len(lines) < 2:
        raise BadResultError(f"{name}: no data rows after the header")
    wanted = {"time": time, **{c.variable: c for c in chosen if c.variable in _NUMERIC}}
    cells: dict[str, list[Printed]] = {variable: [] for variable in wanted}
    for number, row in lines[1:]:
        if len(row) > width and any(cell.strip() for cell in row[width:]):
            extra = next(i for i in range(width, len(row)) if row[i].strip())
            raise BadResultError(f"{name}: row {number} has {len(row)} cells, the header {len(header)}: cell "
                                 f"{extra + 1} ({row[extra].strip()!r}) has no column")
        for variable, column in wanted.items():
            if column.index >= len(row):
                raise BadResultError(f"{name}: row {number} has no {column.raw!r} cell (it has {len(row)} cells)")
            cell = row[column.index].strip()
            printed = parse_number(cell)
            if printed is None:
                raise BadResultError(f"{name}: row {number}, column {column.raw!r}: {cell!r} is not a finite number")
            if variable == "impacts" and (printed.value != int(printed.value) or printed.value < 0):
                raise BadResultError(f"{name}: row {number}, column {column.raw!r}: {cell!r} is not a whole number "
                                     ">= 0")
            cells[variable].append(printed)
    rows = np.array([number for number, _ in lines[1:]])
    printing = time_printing = infer_printing(cells["time"], cells["h"])
    if printing.full:  # ecos prints its time as it comes (0.01) and every variable to 6 decimals (1.999510)
        variables_printing = infer_printing([], cells["h"])
        if not variables_printing.full:
            printing, time_printing = variables_printing, infer_printing(cells["time"], [])

    def values(variable: str) -> np.ndarray | None:
        return np.array([c.value for c in cells[variable]]) if variable in cells else None

    def resolution(variable: str) -> np.ndarray | None:
        format = time_printing if variable == "time" else printing
        return np.array([format.resolution(c) for c in cells[variable]]) if variable in cells else None

    t = values("time")
    back = np.flatnonzero(np.diff(t) < 0.0)
    if back.size:
        i = int(back[0]) + 1
        raise BadResultError(f"{name}: row {rows[i]}, column {time.raw!r}: {cells['time'][i].text} goes back in time "
                             f"(the row before has {cells['time'][i - 1].text})")
    parameters = {}
    for variable in PARAMETERS:
        if variable in cells:
            first = cells[variable][0]
            if variable == "F_ext" and any(printed.value != first.value for printed in cells[variable]):
                continue  # an input that changed: the run's forcing, read from the F_ext column by the check
            for number, printed in zip(rows, cells[variable], strict=True):
                if printed.value != first.value:
                    raise BadResultError(f"{name}: row {number}, column {wanted[variable].raw!r}: {printed.text} "
                                         f"differs from {first.text} in row {rows[0]}: check takes {variable} "
                                         "as constant through the run")
            parameters[variable] = FileParameter(variable, first.value, printing.resolution(first),
                                                 wanted[variable].raw, int(rows[0]))
    impacts = values("impacts")
    return ResultFile(name, chosen[0].prefix if chosen else "", {v: c.raw for v, c in wanted.items()}, rows, t,
                      values("h"), None if impacts is None else impacts.astype(np.int64), values("v"), values("a"),
                      printing, resolution("time"), resolution("h"), resolution("v"), resolution("a"), parameters,
                      values("F_ext"))


def read_result_csv(path: str | Path, instance: str | None = None) -> dict[str, np.ndarray]:
    """The time, h and (if present) impacts columns of a master's CSV, read as the master wrote it.

    See read_result_file for the dialects read (FMPy, OMSimulator,
    libcosim, ecos) and what is bad input.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.
    instance : str, optional
        The instance of the ball to read when the file holds several.

    Returns
    -------
    dict of str to numpy.ndarray
        "time" [s] and "h" [m] as floats, and "impacts" as integers when the file has that column.

    Raises
    ------
    BadResultError
        The file cannot be read or is not a result; the message names the file, the row (its
        line number), the column and the value.

    Examples
    --------
    >>> columns = read_result_csv("out.csv")  # doctest: +SKIP
    >>> columns["time"][:2], columns["h"][:2]  # doctest: +SKIP
    (array([0.   , 0.001]), array([2.       , 1.9999951]))
    """
    result = read_result_file(path, instance)
    columns = {"time": result.time, "h": result.h}
    if result.impacts is not None:
        columns["impacts"] = result.impacts
    return columns


def _header_columns(name: str, line: int, header: list[str]) -> list[_Column]:
    """The header's named columns; a duplicated one (the same after case and suffix are set aside) is bad input."""
    columns, seen = [], {}
    for index, raw in enumerate(header):
        if not raw:
            continue
        prefix, variable = _split(raw)
        variable = "time" if variable.lower() == "time" else VARIABLE_OF.get(variable.lower(), variable)
        key = (prefix.lower(), variable.lower())
        if key in seen:
            raise BadResultError(f"{name}: row {line}, column {index + 1}: {raw!r} duplicates column "
                                 f"{seen[key] + 1} ({header[seen[key]]!r})")
        seen[key] = index
        columns.append(_Column(index, raw, prefix, variable))
    return columns


def _instance_columns(name: str, columns: list[_Column], instance: str | None, header: list[str]) -> list[_Column]:
    """The columns of the instance of the ball to check: the one there is, or the one asked for."""
    prefixes = list(dict.fromkeys(c.prefix for c in columns if c.variable == "h"))
    if not prefixes:
        raise BadResultError(f"{name}: no 'h' column in the header (it has: {', '.join(header)})")
    shown = ", ".join(p or "(no prefix)" for p in prefixes)
    if instance is None:
        if len(prefixes) > 1:
            raise BadResultError(f"{name}: the file holds several instances of the ball ({shown}): pick one with "
                                 "--instance NAME")
        prefix = prefixes[0]
    else:
        if prefixes == [""]:
            raise BadResultError(f"{name}: --instance {instance!r}: the file's columns name no instance")
        matches = [p for p in prefixes if instance.lower() in (p.lower(), _short(p).lower())]
        if len(matches) != 1:
            why = "names several" if matches else "is none"
            raise BadResultError(f"{name}: --instance {instance!r} {why} of the file's instances of the ball ({shown})")
        prefix = matches[0]
    return [c for c in columns if c.prefix.lower() == prefix.lower() and c.variable in VARIABLE_OF.values()]
