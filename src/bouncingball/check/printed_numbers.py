"""Numbers as a master printed them: each cell's value and digits, and the format a file prints its numbers with.

A master prints its result file to full precision (FMPy), to a number of significant digits
(libcosim's 6, OMSimulator's 12) or to a number of decimals (ecos's 6); a check of such a file
allows each number its printed resolution (Printing.resolution). bouncingball.check.result_files reads
the files with these.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

FULL_PRECISION_DIGITS = 15  # a column printed to this many significant digits or more is read as exact
_NUMBER = re.compile(r"([+-]?)(\d*)(?:\.(\d*))?(?:[eE]([+-]?\d+))?")


@dataclass(frozen=True)
class Printed:
    """A number as a master printed it: its value, and its digits.

    Attributes
    ----------
    text : str
        The cell as written.
    value : float
        Its value.
    digits : int
        Significant digits written (0 for a zero).
    last : int
        Decimal exponent of the last digit written (-6 for 1.000000).
    exponent : bool
        Written with an exponent (1e-05).
    """

    text: str
    value: float
    digits: int
    last: int
    exponent: bool

    @property
    def decimals(self) -> int:
        """Digits after the decimal point, as written."""
        return -self.last


def parse_number(text: str) -> Printed | None:
    """A cell read as a decimal number, or None if it is not one.

    Stricter than float(): ``1_0``, ``inf``, ``nan``, ``0x10`` and an empty cell are not numbers.

    Parameters
    ----------
    text : str
        The cell, surrounding spaces removed.

    Returns
    -------
    Printed or None
        The value and how many digits it was written with; None for anything else.

    Examples
    --------
    >>> parse_number("1.99995").digits, parse_number("1.99995").last
    (6, -5)
    >>> parse_number("1_0") is None
    True
    """
    match = _NUMBER.fullmatch(text)
    if match is None:
        return None
    _, whole, fraction, exponent = match.groups()
    if not whole and not fraction:
        return None
    fraction = fraction or ""
    digits = (whole + fraction).lstrip("0")
    last = int(exponent or 0) - len(fraction)
    value = float(text)
    return Printed(text, value, len(digits), last, exponent is not None) if math.isfinite(value) else None


@dataclass(frozen=True)
class Printing:
    """How a file prints its real numbers: to a number of significant digits, to a number of decimals, or in full.

    Attributes
    ----------
    kind : str
        "full" (every digit a double needs, or near it), "significant" or "decimals".
    digits : int
        The significant digits or the decimals.
    """

    kind: str
    digits: int = 0

    @property
    def full(self) -> bool:
        """True when the file prints numbers to a double's precision: nothing is lost."""
        return self.kind == "full"

    def resolution(self, number: Printed) -> float:
        """Half a unit in the last place the format prints for this number [its unit]; 0 in full precision."""
        if self.full:
            return 0.0
        if self.kind == "decimals":
            return 0.5 * 10.0 ** -self.digits
        if number.digits == 0:  # a zero printed to significant digits is a zero
            return 0.0
        first = number.last + number.digits - 1  # exponent of the first significant digit
        return 0.5 * 10.0 ** (first - self.digits + 1)

    def __str__(self) -> str:
        if self.full:
            return "full precision"
        return f"{self.digits} significant digits" if self.kind == "significant" else f"{self.digits} decimals"


def infer_printing(time: list[Printed], h: list[Printed]) -> Printing:
    """The format a file's real numbers were printed with, from its time and h cells.

    A file is read as full precision unless its cells show otherwise, since a short cell may be
    a rounded one or an exact short decimal (2 - 4.905 t^2 at t = 0.1 s is 1.95095):

    - every cell with the same number of decimals D, no exponent, and some cell with a trailing
      zero that only a fixed format writes (2.000000): D decimals (ecos's 6);
    - at most S < 15 significant digits in every cell, and S of them in at least half of ten or
      more nonzero heights: S significant digits, %g-like, which drops trailing zeros
      (libcosim's 6, OMSimulator's 12);
    - anything else (FMPy's shortest round-trip digits, a short file): full precision.

    Parameters
    ----------
    time, h : list of Printed
        The cells of the time and h columns.

    Returns
    -------
    Printing
        The format.

    Examples
    --------
    >>> cells = [parse_number(x) for x in ("0.001000", "1.999995", "2.000000")]
    >>> str(infer_printing(cells[:1], cells[1:]))
    '6 decimals'
    >>> h = [parse_number(f"{2 - 0.01 * i**0.5:g}") for i in range(1, 21)]
    >>> str(infer_printing([parse_number("0.001")], h)), str(infer_printing([], h[:2]))
    ('6 significant digits', 'full precision')
    """
    cells = time + h
    if not cells:
        return Printing("full")
    most = max(c.digits for c in cells)
    decimals = {c.decimals for c in cells}
    padded = any(c.decimals >= 2 and c.text.rstrip().endswith("0") for c in cells)
    if len(decimals) == 1 and padded and not any(c.exponent for c in cells) and most < FULL_PRECISION_DIGITS:
        return Printing("decimals", decimals.pop())
    heights = [c for c in h if c.digits]
    if most < FULL_PRECISION_DIGITS and len(heights) >= 10 and \
            2 * sum(c.digits == most for c in heights) >= len(heights):
        return Printing("significant", most)
    return Printing("full")
