"""Errors of a numerical result against the exact solution on the same grid."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bouncingball.solvers.exact import ExactSolution
from bouncingball.solvers.result import Event, SimulationResult, SolverStats


@dataclass(frozen=True)
class Accuracy:
    """max |h - h_exact| [m], max event time error [s] over the events both found, and the event counts."""

    max_height_error: float
    max_event_time_error: float
    events_found: int
    events_exact: int

    @property
    def events_match(self) -> bool:
        return self.events_found == self.events_exact


def exact_counterpart(result: SimulationResult, h0: float, v0: float) -> SimulationResult:
    """The exact solution on the result's own grid, for the same ball, start state and F_ext."""
    t = result.t
    solution = ExactSolution(result.ball, h0, v0, float(t[0]), float(t[-1]), result.F_ext)
    h, v = solution.state(t)
    return SimulationResult("exact", result.ball, t, h, v, list(solution.events), solution.rest_time,
                            SolverStats(steps=len(solution.phases), events=len(solution.events)), result.F_ext)


def compare(result: SimulationResult, exact: SimulationResult) -> Accuracy:
    """Accuracy of result against exact (both on the same grid)."""
    return Accuracy(max_height_error(result.h, exact.h), max_event_time_error(result.events, exact.events),
                    len(result.events), len(exact.events))


def max_height_error(h: np.ndarray, h_exact: np.ndarray) -> float:
    """max |h - h_exact| [m]; inf where h has gaps (NaN: a run that stopped early)."""
    error = np.abs(np.asarray(h) - h_exact)
    return float("inf") if np.any(np.isnan(error)) else float(np.max(error))


def max_event_time_error(events: list[Event], exact_events: list[Event]) -> float:
    """max |t - t_exact| [s] over the events both lists have, paired in order."""
    return float(max((abs(a.time - b.time) for a, b in zip(events, exact_events, strict=False)), default=0.0))
