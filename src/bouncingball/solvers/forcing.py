"""A piecewise-constant external force: F_ext held at values[i] over [times[i], times[i+1]).

Every solver takes F_ext as a constant or as a ForceTable, and runs a table piece by piece:
the state is continuous at each change time and the mode is held there; within a piece F_ext is
constant, so each solver's constant-force machinery (the exact flows, CVODE's restart) applies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import validation


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
            Not a pair, lengths that differ, no value, an entry that is not a finite number, or
            times that do not increase strictly.
        """
        if isinstance(table, ForceTable):
            return table
        try:
            times, values = table
            times, values = list(times), list(values)
        except (TypeError, ValueError):
            raise ValueError(f"{name} = {table!r} is not allowed: it must be a number [N] or a table "
                             "(times [s], values [N])") from None
        if len(times) != len(values):
            raise ValueError(f"{name} table is not allowed: {len(times)} times but {len(values)} values "
                             "(they must be as many)")
        if not values:
            raise ValueError(f"{name} table is not allowed: it has no value (it needs at least one)")
        times = [validation.finite(f"{name} times[{i}]", t, "s") for i, t in enumerate(times)]
        values = [validation.finite(f"{name} values[{i}]", f, "N") for i, f in enumerate(values)]
        for i in range(1, len(times)):
            if not times[i] > times[i - 1]:
                raise ValueError(f"{name} times[{i}] = {times[i]!r} s is not allowed: the times must increase "
                                 f"strictly (times[{i - 1}] = {times[i - 1]!r} s)")
        return cls(tuple(times), tuple(values))

    def at(self, t):
        """The force [N] at the times t [s] (arrays allowed)."""
        index = np.searchsorted(np.asarray(self.times), t, side="right") - 1
        return np.asarray(self.values)[np.clip(index, 0, len(self.values) - 1)]

    def pieces(self, t_start: float, t_end: float) -> list[tuple[float, float, float]]:
        """(start [s], end [s], force [N]) of each piece of constant force from t_start to t_end, in order.

        Consecutive entries with the same value are one piece.
        """
        pieces: list[tuple[float, float, float]] = []
        start, force = t_start, float(self.at(t_start))
        for t, value in zip(self.times, self.values, strict=True):
            if t <= t_start:
                continue
            if t >= t_end:
                break
            if value != force:
                pieces.append((start, t, force))
                start, force = t, value
        pieces.append((start, t_end, force))
        return pieces

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
