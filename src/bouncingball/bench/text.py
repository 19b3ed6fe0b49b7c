"""Numbers and tables as the benchmark reports print them (markdown)."""

from __future__ import annotations

import math

from ..accuracy import Accuracy


def num(value: float | None, digits: int = 2) -> str:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.{digits}e}"


def ms(seconds: float | None) -> str:
    if seconds is None or math.isnan(seconds):
        return ""
    return f"{seconds * 1e3:.0f}" if seconds >= 0.1 else f"{seconds * 1e3:.3g}"


def rtol_text(rtol: float | None) -> str:
    return "default" if rtol is None else f"{rtol:.0e}"


def events_text(errors: Accuracy | None) -> str:
    if errors is None:
        return ""
    suffix = " impacts" if errors.counted == "impacts" else ""
    return f"{errors.events_found}/{errors.events_exact}{suffix}"


def table(header: list[str], rows: list[list[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(" --- " for _ in header) + "|"]
    return lines + ["| " + " | ".join(row) + " |" for row in rows]


def repr_or_blank(value) -> str:
    return "" if value is None else repr(value)
