"""A piecewise-constant external force: F_ext held at values[i] over [times[i], times[i+1]).

Every solver takes F_ext as a constant or as a ForceTable, and runs a table piece by piece:
the state is continuous at each change time and the mode is held there; within a piece F_ext is
constant, so each solver's constant-force machinery (the exact flows, CVODE's restart) applies.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .. import validation

MAX_TABLE_ENTRIES = validation.MAX_TABLE_ENTRIES


@dataclass(frozen=True)
class ForceTable:
    """F_ext [N] held at values[i] over [times[i], times[i+1]); values[0] before times[0], values[-1] after the last.

    Attributes
    ----------
    times : tuple of float
        The change times [s], strictly increasing.
    values : tuple of float
        The force [N] from each time on.

    Examples
    --------
    >>> table = ForceTable.of(([0.0, 1.0], [0.0, 20.0]))
    >>> float(table.at(0.5)), float(table.at(1.0))
    (0.0, 20.0)
    """

    times: tuple[float, ...]
    values: tuple[float, ...]

    @classmethod
    def of(cls, table, name: str = "F_ext") -> ForceTable:
        """A ForceTable from (times, values), validated; the error names the field and the entry.

        Parameters
        ----------
        table : ForceTable or pair of sequences
            (times [s], values [N]).
        name : str, optional
            The field's name in error messages.

        Returns
        -------
        ForceTable

        Raises
        ------
        ValueError
            Not a pair, lengths that differ, no value, more than MAX_TABLE_ENTRIES entries, an entry that is not
            a finite number, or times that do not increase strictly.
        """
        if isinstance(table, ForceTable):
            return table
        try:
            times, values = table
            times, values = (entries if isinstance(entries, np.ndarray) and entries.ndim == 1 else list(entries)
                             for entries in (times, values))
        except (TypeError, ValueError):
            raise ValueError(f"{name} = {table!r} is not allowed: it must be a number [N] or a table "
                             "(times [s], values [N])") from None
        if len(times) != len(values):
            raise ValueError(f"{name} table is not allowed: {len(times)} times but {len(values)} values "
                             "(they must be as many)")
        if len(values) == 0:
            raise ValueError(f"{name} table is not allowed: it has no value (it needs at least one)")
        if len(values) > MAX_TABLE_ENTRIES:
            raise ValueError(f"{name} table of {len(values)} entries is not allowed: it must have at most "
                             f"{MAX_TABLE_ENTRIES:.0e} (each is checked before the run, up to a second for the most, "
                             "and each change of force inside the run restarts the integrator); resample it "
                             "coarser, or split the run into shorter ones (t_start, and the state at the end of "
                             "the one before)")
        times = validation.finite_entries(f"{name} times", times, "s")
        values = validation.finite_entries(f"{name} values", values, "N")
        later = times[1:] > times[:-1]
        if not later.all():
            i = int(np.flatnonzero(~later)[0]) + 1
            raise ValueError(f"{name} times[{i}] = {float(times[i])!r} s is not allowed: the times must increase "
                             f"strictly (times[{i - 1}] = {float(times[i - 1])!r} s)")
        table = cls(tuple(times.tolist()), tuple(values.tolist()))
        table.__dict__["arrays"] = times, values  # arrays' cached value, as checked: not made again from the tuples
        return table

    @functools.cached_property
    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(times, values) as arrays, made once: a table may hold millions of entries."""
        return np.asarray(self.times, dtype=float), np.asarray(self.values, dtype=float)

    def at(self, t):
        """The force [N] at the times t [s] (arrays allowed)."""
        times, values = self.arrays
        index = np.searchsorted(times, t, side="right") - 1
        return values[np.clip(index, 0, len(values) - 1)]

    def pieces(self, t_start: float, t_end: float) -> list[tuple[float, float, float]]:
        """(start [s], end [s], force [N]) of each piece of constant force from t_start to t_end, in order.

        Consecutive entries with the same value are one piece.
        """
        times, values = self.arrays
        inside = slice(np.searchsorted(times, t_start, side="right"), np.searchsorted(times, t_end, side="left"))
        force = float(self.at(t_start))
        changes = values[inside] != np.concatenate(([force], values[inside][:-1]))
        starts = [t_start, *times[inside][changes].tolist()]
        forces = [force, *values[inside][changes].tolist()]
        return list(zip(starts, [*starts[1:], t_end], forces, strict=True))

    @property
    def largest(self) -> float:
        """The value of largest magnitude [N] (for the scene's range checks)."""
        return max(self.values, key=abs)


def as_force(F_ext, name: str = "F_ext") -> float | ForceTable:
    """F_ext as a float (a constant) or a validated ForceTable; ValueError naming the field otherwise."""
    if isinstance(F_ext, ForceTable):
        return F_ext
    if isinstance(F_ext, tuple | list) or (isinstance(F_ext, np.ndarray) and F_ext.ndim > 0):
        return ForceTable.of(F_ext, name)
    return validation.finite(name, F_ext, "N")


def pieces(F_ext: float | ForceTable, t_start: float, t_end: float = math.inf) -> list[tuple[float, float, float]]:
    """(start, end, force) of each piece of constant force: a constant gives one piece."""
    if isinstance(F_ext, ForceTable):
        return F_ext.pieces(t_start, t_end)
    return [(t_start, t_end, F_ext)]
