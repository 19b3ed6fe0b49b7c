"""The F_ext a master applied: FMPy's input file, read and applied as FMPy does, or the result's own F_ext column.

`bouncingball check --input-file` (testing.check_result's input_file) rebuilds the run's forcing
with these, as a ForceTable the exact solution takes.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from .. import validation
from ..solvers.forcing import ForceTable
from .printed_numbers import parse_number
from .result_files import BadResultError, ResultFile, refuse_binary, unreadable


def read_input_file(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """The time and F_ext columns of an FMPy input file (``time,F_ext``; a step is two rows at the same time).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file: a header whose first column is the time, with an F_ext column.

    Returns
    -------
    times, values : numpy.ndarray
        The rows' times [s] (non-decreasing) and F_ext [N].

    Raises
    ------
    BadResultError
        The file cannot be read, has no time first or no F_ext column, no data row, a cell that is
        not a finite number, or a time going back; the message names the file, the row, the column
        and the value.
    """
    name = str(path)
    try:
        refuse_binary(path, "FMPy's input file (a CSV: time,F_ext)")
        with open(path, newline="", encoding="utf-8-sig") as file:
            lines = [(number, row) for number, row in enumerate(csv.reader(file, skipinitialspace=True), 1)
                     if any(cell.strip() for cell in row)]
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise BadResultError(f"{name}: cannot be read: {unreadable(error)}") from None
    if not lines:
        raise BadResultError(f"{name}: the input file is empty: it needs a header time,F_ext")
    header = [cell.strip() for cell in lines[0][1]]
    if header[0].lower() != "time":
        raise BadResultError(f"{name}: row {lines[0][0]}: the first column is {header[0]!r}: FMPy's input file "
                             "starts with the time")
    force = next((i for i, cell in enumerate(header) if cell.lower() == "f_ext"), None)
    if force is None:
        raise BadResultError(f"{name}: no 'F_ext' column in the header (it has: {', '.join(header)})")
    if len(lines) < 2:
        raise BadResultError(f"{name}: no data rows after the header")
    times, values = [], []
    for number, row in lines[1:]:
        for index, into in ((0, times), (force, values)):
            cell = row[index].strip() if index < len(row) else ""
            printed = parse_number(cell)
            if printed is None:
                raise BadResultError(f"{name}: row {number}, column {header[index]!r}: {cell!r} is not a finite "
                                     "number")
            into.append(printed.value)
        if len(times) > 1 and times[-1] < times[-2]:
            raise BadResultError(f"{name}: row {number}, column {header[0]!r}: {times[-1]!r} goes back in time "
                                 f"(the row before has {times[-2]!r})")
    return np.array(times), np.array(values)


def fmpy_input_value(times: np.ndarray, values: np.ndarray, t: float) -> float:
    """The F_ext FMPy applies at the communication point t before the step from it (its Input.apply, after_event).

    Before the first row the first value, after the last the last; at a time that several rows
    share (math.isclose), the value of the last of them; else the linear interpolation of the rows
    either side.
    """
    if times.size < 2:
        return float(values[0])
    i = int(np.searchsorted(times, t))
    if i == 0:
        return float(values[0])
    if i == times.size:
        return float(values[-1])
    if math.isclose(t, times[i]) and i < times.size - 1 and math.isclose(times[i], times[i + 1]):
        while i < times.size - 1 and math.isclose(times[i], times[i + 1]):
            i += 1
        return float(values[i])
    w0 = (times[i] - t) / (times[i] - times[i - 1])
    return float(w0 * values[i - 1] + (1.0 - w0) * values[i])


def applied_force(file: ResultFile, constant: float, start_time: float, t_end: float, input_file: str | Path | None,
                  step_size: float | None) -> tuple[float | ForceTable, str]:
    """F_ext over a master's run, and where it came from.

    Parameters
    ----------
    file : ResultFile
        The master's result; a changing F_ext column in it is what was applied (the row at t_i+1
        holds the value applied over [t_i, t_i+1), as FMPy samples after doStep).
    constant : float
        The scene's F_ext [N], for a run without either.
    start_time, t_end : float
        The run's start and its last time [s].
    input_file : str or pathlib.Path or None
        FMPy's input file, applied at each communication point as fmpy_input_value says.
    step_size : float or None
        The master's communication step [s] with input_file (None: the result's own times).

    Returns
    -------
    force : float or ForceTable
        The constant with "", or a ForceTable, held over each communication step.
    whence : str
        Where a ForceTable came from, for the report.

    Raises
    ------
    ValueError
        step_size without input_file, or a step_size that is not positive.
    BadResultError
        The input file cannot be read (see read_input_file).
    """
    if file.F_ext is not None and "F_ext" not in file.parameters:  # the column changes: what was applied
        times, first = np.unique(file.time, return_index=True)
        forces = file.F_ext[first]
        if times[0] > start_time:
            times, forces = np.concatenate(([start_time], times)), np.concatenate(([forces[0]], forces))
        table = ForceTable.of((times[:-1], forces[1:]) if times.size > 1 else ([start_time], forces))
        return table, f"from the file's {file.columns['F_ext']!r} column ({len(table.values)} steps; the row at " \
                      "t_i+1 holds the value applied over [t_i, t_i+1))"
    if input_file is None:
        if step_size is not None:
            raise ValueError("step_size names the communication points of an input file: give input_file too")
        return constant, ""
    input_times, input_values = read_input_file(input_file)
    if step_size is None:
        points = np.unique(np.concatenate(([start_time], file.time)))
        points = points[points >= start_time]
        whence = "the result's times"
    else:
        step_size = validation.positive("step_size", step_size, "s")
        count = math.floor((t_end - start_time) / step_size * (1.0 + 1e-9))
        regular = start_time + step_size * np.arange(count + 1)
        events = input_times[:-1][np.diff(input_times) == 0.0]
        points = np.unique(np.concatenate((regular, events[(events > start_time) & (events < t_end)])))
        whence = f"every {step_size!r} s and at the input's steps"
    values = [fmpy_input_value(input_times, input_values, float(p)) for p in points]
    return ForceTable.of((points, values)), f"from {input_file} as FMPy applies it at each communication " \
                                            f"point ({whence}), held over the step"
