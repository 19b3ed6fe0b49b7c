"""The one place that reaches into scikit-sundae's private event bookkeeping.

scikit-sundae (checked on 1.2.0) records every root CVODE returns on the events function object
(`_i`: CVodeGetRootInfo per root, `_t`, `_y`, and the terminal counters `_i_cnt`) and never resets
them: `t_events` is cumulative across re-initialisations, and `step()` rebuilds that history on
each call, so each call gets slower as roots accumulate (from ~12 us to ~1.3 ms per call after
3000 roots). It has no public call to clear the history or to ask which root function fired, so
we read and clear it here, after each root. tests/test_cvode.py checks these fields still exist.
"""

from __future__ import annotations

CHECKED_VERSIONS = ("1.2.0",)


def roots_found(event_function) -> list[int]:
    """CVodeGetRootInfo of the last root return: per root function, 0 or the crossing's sign."""
    return [int(i) for i in event_function._i[-1]] if event_function._i else []


def clear(event_function) -> None:
    """Forget every recorded root, so terminal counters and the history start afresh."""
    event_function._i.clear()
    event_function._t.clear()
    event_function._y.clear()
    event_function._i_cnt[:] = 0
