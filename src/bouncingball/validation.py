"""Input checks that raise a ValueError naming the field, its value and what is allowed."""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable

import numpy as np

# A table's entries (F_ext's, the ground's) are checked in numpy, in linear time, and kept twice, as tuples and
# arrays: 1e6 of them take 0.8 s before the run on a loaded 2-core machine (a scene check per distinct value took
# 40 s), 1e7 4 to 8 s (mostly making the tuples) and 0.5 GB.
MAX_TABLE_ENTRIES = 1_000_000


def _as_float(name: str, value: object) -> float:
    if type(value) is float:  # most values: no isinstance against the numbers ABCs (slow), nothing to convert
        return value
    # bool is an int to Python and TOML's true would pass as 1; text ("1e4" in quotes) is not a number either.
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} = {shown(value)} is not allowed: it must be a number")
    try:
        return float(value)
    except OverflowError:  # an int beyond 1.8e308 (10**400): infinite, refused with the field's own range
        return math.inf if value > 0 else -math.inf


def shown(value: object) -> str:
    """value as a message prints it: its repr, an int of more than 30 digits as its power of ten (10**400: 1e+400).

    The repr of such an int is hundreds of digits, and beyond 4300 Python refuses to write it.
    """
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**30:
        return f"{'-' if value < 0 else ''}{10.0 ** (math.log10(abs(value)) % 1.0):.3g}e+{int(math.log10(abs(value)))}"
    return repr(value)


def positive(name: str, value: object, unit: str = "") -> float:
    """Return value as a float if it is finite and > 0."""
    x = _as_float(name, value)
    if not (math.isfinite(x) and x > 0.0):
        raise ValueError(f"{name} = {shown(value)}{_unit(unit)} is not allowed: it must be finite and > 0")
    return x


def non_negative(name: str, value: object, unit: str = "") -> float:
    """Return value as a float if it is finite and >= 0."""
    x = _as_float(name, value)
    if not (math.isfinite(x) and x >= 0.0):
        raise ValueError(f"{name} = {shown(value)}{_unit(unit)} is not allowed: it must be finite and >= 0")
    return x


def finite(name: str, value: object, unit: str = "") -> float:
    """Return value as a float if it is finite (not NaN, not infinite)."""
    x = _as_float(name, value)
    if not math.isfinite(x):
        raise ValueError(f"{name} = {shown(value)}{_unit(unit)} is not allowed: it must be a finite number")
    return x


def in_range(name: str, value: object, low: float, high: float, unit: str = "") -> float:
    """Return value as a float if low < value <= high."""
    x = _as_float(name, value)
    if not (math.isfinite(x) and low < x <= high):
        raise ValueError(f"{name} = {shown(value)}{_unit(unit)} is not allowed: it must be in "
                         f"({exact(low)}, {exact(high)}]")
    return x


def zero_or_at_least(name: str, value: object, low: float, unit: str = "", why: str = "") -> float:
    """Return value as a float if it is 0 (none) or finite and >= low; why, if given, ends the message in brackets."""
    x = _as_float(name, value)
    if not (x == 0.0 or (math.isfinite(x) and x >= low)):
        raise ValueError(f"{name} = {shown(value)}{_unit(unit)} is not allowed: it must be 0 (none) or "
                         f"finite and >= {exact(low)}{_unit(unit)}" + (f" ({why})" if why else ""))
    return x


def in_closed_range(name: str, value: object, low: float, high: float, unit: str = "", why: str = "") -> float:
    """Return value as a float if low <= value <= high; why, if given, ends the message in brackets."""
    x = _as_float(name, value)
    if not (math.isfinite(x) and low <= x <= high):
        raise ValueError(f"{name} = {shown(value)}{_unit(unit)} is not allowed: it must be in "
                         f"[{exact(low)}, {exact(high)}]" + (f" ({why})" if why else ""))
    return x


def finite_entries(name: str, entries: list | np.ndarray, unit: str) -> np.ndarray:
    """entries as an array of floats, each a finite number; ValueError naming the first that is not (name[i]).

    In numpy, in linear time: a table of 1e7 entries takes a fraction of a second. A float array or a list of
    floats converts as it is; anything else is checked entry by entry, so that text or a bool is named.
    """
    if isinstance(entries, np.ndarray) and entries.dtype.kind in "fiu":
        array = entries.astype(float)
    elif all(type(entry) is float for entry in entries):
        array = np.array(entries, dtype=float)
    else:
        array = np.array([finite(f"{name}[{i}]", entry, unit) for i, entry in enumerate(entries)], dtype=float)
    allowed = np.isfinite(array)
    if not allowed.all():
        i = int(np.flatnonzero(~allowed)[0])
        finite(f"{name}[{i}]", float(array[i]), unit)
    return array


def exact(x: float) -> str:
    """x in the shortest text that reads back as the same double, without a trailing ".0" (8, 0.1, 1e-12).

    Bounds in messages are printed so: a bound rounded to fewer digits could make a refused value
    look inside the range.

    Examples
    --------
    >>> exact(8.0), exact(0.1 + 0.2), exact(1e-12)
    ('8', '0.30000000000000004', '1e-12')
    """
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text


def choice(name: str, value: object, allowed: Iterable[str]) -> str:
    """Return value if it is one of allowed (compared case-insensitively), spelled as in allowed."""
    allowed = list(allowed)
    for option in allowed:
        if isinstance(value, str) and value.lower() == option.lower():
            return option
    raise ValueError(f"{name} = {shown(value)} is not allowed: it must be one of {', '.join(allowed)}")


def _unit(unit: str) -> str:
    return f" {unit}" if unit else ""
