"""How many events a drop has, by the mpmath oracle (tests/mpmath_oracle.py): the counts the tests expect.

A test that expects "41 events, 21 impacts" asks here instead of typing the numbers, so the count comes from
an independent truth of the ball the test runs, never from the code under test. Each (ball, run) is computed
once per process (a fraction of a second for the article) and kept.
"""

from __future__ import annotations

from functools import cache
from typing import NamedTuple

from mpmath_oracle import DEPARTURE, IMPACT, Oracle


class Counts(NamedTuple):
    """The events of a run up to its end: kinds in order ("impact", "departure"), and how many of each."""

    kinds: tuple[str, ...]
    impacts: int
    departures: int

    @property
    def events(self) -> int:
        return len(self.kinds)


def oracle_counts(ball, h0: float = 2.0, v0: float = 0.0, t_end: float = 8.0, t_start: float = 0.0,
                  F_ext: float = 0.0) -> Counts:
    """The events in (t_start, t_end] [s] of a linear-law ball (m, k, b, R, g) from (h0 [m], v0 [m/s]) at t_start
    under a constant F_ext [N].

    The defaults are the article's run (a drop from 2 m at rest, 8 s); `oracle_counts(Ball())` is the article.
    """
    if ball.contact != "linear":
        raise ValueError(f"contact = {ball.contact!r}: the oracle solves the linear law only; use another truth")
    return _counts(ball.m, ball.k, ball.b, ball.R, ball.g, h0, v0, t_end, t_start, F_ext)


@cache
def _counts(m, k, b, R, g, h0, v0, t_end, t_start, F_ext) -> Counts:
    kinds = tuple(event.kind for event in Oracle(m, k, b, R, g, h0, v0, t_end, t_start, F_ext).events)
    return Counts(kinds, kinds.count(IMPACT), kinds.count(DEPARTURE))
