"""Errors of a numerical result against the exact solution on the same grid.

The one way every user (run, check, validate, the bench, the sweep, the tests) compares: the exact
solution sampled on the result's own times (exact_on_grid), and the one record of the comparison
(Accuracy, built by accuracy_of).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .ground import Ground
from .physics import Ball, Mode
from .solvers.exact import ExactSolution
from .solvers.forcing import ForceTable
from .solvers.result import DEPARTURE, IMPACT, Event, SimulationResult, SolverStats


@dataclass(frozen=True)
class ExactOnGrid:
    """The exact solution sampled at the times t [s]: h [m], v [m/s] and the impacts up to each time."""

    solution: ExactSolution
    t: np.ndarray
    h: np.ndarray
    v: np.ndarray
    impacts: np.ndarray

    @property
    def impact_times(self) -> np.ndarray:
        """The exact impact times [s] up to the last sample time."""
        return np.array([event.time for event in self.solution.events if event.kind == IMPACT])

    def result(self) -> SimulationResult:
        """The same samples as a SimulationResult of the "exact" solver (to draw or print beside a run)."""
        solution = self.solution
        stats = SolverStats(steps=len(solution.phases), events=len(solution.events))
        return SimulationResult("exact", solution.ball, self.t, self.h, self.v, list(solution.events),
                                solution.rest_time, stats, solution.F_ext, ground=solution.ground)


def exact_on_grid(t, ball: Ball, h0: float, v0: float, F_ext: float | ForceTable = 0.0,
                  t_start: float | None = None, ground: Ground | None = None) -> ExactOnGrid:
    """The exact solution from (h0 [m], v0 [m/s]) at t_start (default: t[0]) sampled at the times t [s].

    Parameters
    ----------
    t : array_like
        Increasing sample times [s], all >= t_start.
    ball : Ball
        The ball.
    h0, v0 : float
        Height [m] and velocity [m/s] at t_start.
    F_ext : float or ForceTable, optional
        External force [N], positive upwards: a constant or piecewise constant.
    t_start : float, optional
        Time [s] of the start state; t[0] if not given.
    ground : Ground, optional
        The ground under the ball (still at 0 by default).

    Returns
    -------
    ExactOnGrid
        The solution, and h, v and the number of impacts up to (and at) each time.
    """
    t = np.asarray(t, dtype=float)
    solution = ExactSolution(ball, h0, v0, float(t[0]) if t_start is None else t_start, float(t[-1]), F_ext,
                             ground=ground)
    h, v = solution.state(t)
    impact_times = [event.time for event in solution.events if event.kind == IMPACT]
    return ExactOnGrid(solution, t, h, v, np.searchsorted(impact_times, t, side="right"))


@dataclass(frozen=True)
class Accuracy:
    """How a result compares with the exact solution on the result's own grid.

    max |h - h_exact| [m]; the max event time error [s] over the events both found (nan when the
    events are not observable, as through an FMU that counts impacts); the events (or impacts,
    see `counted`) found and in the exact solution; and the relative energy drift
    max |E - E0| / |E0| (nan without v).
    """

    max_height_error: float
    max_event_time_error: float
    events_found: int
    events_exact: int
    counted: str = "events"  # or "impacts"
    energy_drift: float = math.nan

    @property
    def events_match(self) -> bool:
        """True if the result found as many events (or impacts) as the exact solution."""
        return self.events_found == self.events_exact


def accuracy_of(exact: ExactOnGrid, h, *, events: list[Event] | None = None, impacts: int | None = None,
                events_found: int | None = None, v=None) -> Accuracy:
    """Compare a result on exact's grid with it: by its events if given, else by its event or impact count.

    Parameters
    ----------
    exact : ExactOnGrid
        The exact solution on the result's grid.
    h : array_like
        The result's heights [m] on that grid (NaN where it has none: the error is then inf).
    events : list of Event, optional
        The result's events; compared in order with the exact ones.
    impacts : int, optional
        The result's impact count, when its events are not observable.
    events_found : int, optional
        The result's event count, when their times are not observable (an FMU's impacts and its
        contact flag at both ends).
    v : array_like, optional
        The result's velocities [m/s], for the energy drift.
    """
    if events is not None:
        event_error = max_event_time_error(events, exact.solution.events)
        found, expected, counted = len(events), len(exact.solution.events), "events"
    elif events_found is not None:
        event_error = math.nan
        found, expected, counted = events_found, len(exact.solution.events), "events"
    else:
        event_error = math.nan
        found, expected, counted = impacts, int(exact.impacts[-1]), "impacts"
    drift = math.nan
    if v is not None:
        energy = exact.solution.ball.energy(np.asarray(h), np.asarray(v), exact.solution.F_ext)
        drift = float(np.max(np.abs(energy - energy[0])) / abs(energy[0]))
    return Accuracy(max_height_error(h, exact.h), event_error, found, expected, counted, drift)


def accuracy_of_result(result: SimulationResult, h0: float, v0: float) -> tuple[Accuracy, ExactOnGrid]:
    """A result against the exact solution from (h0 [m], v0 [m/s]) on its own grid: the record, and that solution."""
    exact = exact_on_grid(result.t, result.ball, h0, v0, result.F_ext, ground=result.ground)
    return accuracy_of(exact, result.h, events=result.events), exact


def max_height_error(h: np.ndarray, h_exact: np.ndarray) -> float:
    """max |h - h_exact| [m]; inf where h has gaps (NaN: a run that stopped early)."""
    error = np.abs(np.asarray(h) - h_exact)
    return float("inf") if np.any(np.isnan(error)) else float(np.max(error))


def max_event_time_error(events: list[Event], exact_events: list[Event]) -> float:
    """max |t - t_exact| [s] over the events both lists have, paired in order."""
    return float(max((abs(a.time - b.time) for a, b in zip(events, exact_events, strict=False)), default=0.0))


@dataclass(frozen=True)
class ImpactCounts:
    """An impacts column against the exact impacts: the points it is wrong at and the impacts it merged.

    Attributes
    ----------
    mismatches : numpy.ndarray
        Indices of the points whose count is wrong, increasing.
    merged : numpy.ndarray
        Indices (into the exact impact times) of the mergeable impacts the column lacks, increasing.
    """

    mismatches: np.ndarray
    merged: np.ndarray


def impact_counts(impact_times: np.ndarray, t: np.ndarray, impacts: np.ndarray, tie=0.0,
                  mergeable: np.ndarray | None = None) -> ImpactCounts:
    """Match an impacts column with the exact impacts, letting mergeable ones be missing.

    A result that merges a hop into the contact around it lacks that hop's impact from then on.
    The points are taken in order: at each, the exact impacts before t - tie that no earlier
    point accounted for must be counted now or merged (only a mergeable one may be), and those
    within tie of t may be counted now or later. A count that is too high, too low, or lower than
    the count before it is wrong at that point; the points after it are judged as if it had been
    right, so a count that stays one short is wrong at every point from there on.

    Parameters
    ----------
    impact_times : numpy.ndarray
        The exact impact times [s], increasing.
    t : numpy.ndarray
        The times of the points [s], non-decreasing.
    impacts : numpy.ndarray
        The impact count reported at each point.
    tie : float or numpy.ndarray
        How close [s] to an impact a point may count it either way (one value, or one per point).
    mergeable : numpy.ndarray of bool, optional
        One per exact impact: True where it may be missing (default: none may).

    Returns
    -------
    ImpactCounts
        The points whose count is wrong, and which exact impacts the column lacks (of the
        mergeable ones a shortfall could stand for, the latest).

    Examples
    --------
    >>> impact_counts(np.array([0.5]), np.array([0.0, 1.0]), np.array([0, 0])).mismatches
    array([1])
    >>> counts = impact_counts(np.array([0.5, 1.5]), np.array([0.0, 1.0, 2.0]), np.array([0, 0, 1]),
    ...                        mergeable=np.array([True, False]))
    >>> counts.mismatches, counts.merged
    (array([], dtype=int64), array([0]))
    """
    impact_times = np.asarray(impact_times, dtype=float)
    t = np.asarray(t, dtype=float)
    impacts = np.asarray(impacts).astype(np.int64)
    mergeable = np.zeros(len(impact_times), bool) if mergeable is None else np.asarray(mergeable, bool)
    before = np.searchsorted(impact_times, t - tie, side="left")  # these must be accounted for by now
    up_to = np.searchsorted(impact_times, t + tie, side="right")  # these may be counted by now
    wrong = np.zeros(len(t), bool)
    # A point like the one before it (same impacts due, same count) gets the same verdict: only the others are walked.
    changed = np.ones(len(t), bool)
    changed[1:] = (np.diff(before) != 0) | (np.diff(up_to) != 0) | (np.diff(impacts) != 0)
    merged: list[int] = []
    p = counted = 0  # the exact impacts before p are accounted for: counted of them counted, the others merged
    for i in np.flatnonzero(changed):
        due = np.arange(p, max(p, before[i]))  # must be counted now or merged
        optional = max(up_to[i] - max(p, before[i]), 0)  # may be counted now or later
        must = int(np.count_nonzero(~mergeable[due]))
        n = int(impacts[i]) - counted
        wrong[i] = not must <= n <= len(due) + optional
        n = min(max(n, must), len(due) + optional)  # past a wrong count, go on as if it had been right
        merge = max(len(due) - n, 0)
        if merge:
            merged.extend(int(j) for j in due[mergeable[due]][-merge:])
        p = max(p, before[i]) + max(n - len(due), 0)
        counted += n
    return ImpactCounts(np.flatnonzero(_spread(wrong, changed)), np.array(sorted(merged), dtype=np.int64))


def _spread(values: np.ndarray, set_at: np.ndarray) -> np.ndarray:
    """values where set_at is True, and elsewhere the value at the last such index before."""
    last = np.maximum.accumulate(np.where(set_at, np.arange(len(values)), 0))
    return values[last]


def height_scale(h_exact: np.ndarray, R: float) -> float:
    """The scene's height scale [m]: max(|h_exact|, R). Errors are judged relative to it."""
    return max(float(np.max(np.abs(h_exact))), R)


def flight_apex(exact: ExactSolution, t0: float, h0: float, v0: float, F_ext: float | None = None) -> float:
    """How high above R [m] a flight from (h0 [m], v0 [m/s]) at t0 [s] rises, up to the end of exact's run.

    The apex's height above R in closed form, under F_ext [N] (default exact.F_ext, a constant); a
    flight that never comes back (the external force lifts the ball) is measured by how high it gets
    by exact.t_end.
    """
    return _apex(exact.ball, exact.F_ext if F_ext is None else F_ext, exact.t_end, t0, h0, v0)


def _apex(ball: Ball, F_ext: float, t_end: float, t0: float, h0: float, v0: float) -> float:
    g_eff = ball.effective_gravity(F_ext)
    if v0 > 0.0 and not g_eff > 0.0:
        return h0 - ball.R + v0 * (t_end - t0)
    return h0 - ball.R + (0.5 * v0 * v0 / g_eff if v0 > 0.0 else 0.0)


def event_hops(exact: ExactSolution) -> list[float]:
    """The hop [m] above R each exact event bounds: the flight an impact ends or a departure starts.

    The one measure of a hop that the rule for hops too small to matter applies to: a hop no
    higher than a solver's hop resolution may be merged into the contact around it (see
    event_mismatches, and impact_counts for a result that only counts impacts).

    Parameters
    ----------
    exact : ExactSolution
        The exact solution.

    Returns
    -------
    list of float
        One hop height [m] per event of exact.events, in order.

    Examples
    --------
    >>> from bouncingball.physics import Ball
    >>> [round(hop, 6) for hop in event_hops(ExactSolution(Ball(), 2.0, 0.0, 0.0, 1.0))]
    [1.94, 1.406531]
    """
    flight_hops = [flight_apex(exact, p.t_start, p.h0, p.v0, p.F_ext) if p.mode == Mode.FLIGHT else 0.0
                   for p in exact.phases]
    if len(exact.phases) == len(exact.events) + 1:
        # exact.events[i] ends phase i and starts phase i + 1: the hop an event bounds is the flight on its side.
        return [flight_hops[i] if e.kind == IMPACT else flight_hops[i + 1] for i, e in enumerate(exact.events)]
    # F_ext changed in flight (a ForceTable): phases also start at the changes. An impact ends the flight
    # phase before it, a departure starts the one at its time; the highest piece of that flight is its hop.
    starts = np.array([p.t_start for p in exact.phases])
    modes = [p.mode for p in exact.phases]
    hops = []
    for e in exact.events:
        i = int(np.searchsorted(starts, e.time, side="right")) - (2 if e.kind == IMPACT else 1)
        j = i
        while 0 <= j < len(modes) and modes[j] == Mode.FLIGHT:  # the whole flight, across the changes
            j += -1 if e.kind == IMPACT else 1
        span = range(j + 1, i + 1) if e.kind == IMPACT else range(i, j)
        hops.append(max((flight_hops[k] for k in span), default=0.0))
    return hops


def event_mismatches(events: list[Event], exact: ExactSolution, height_tolerance: float,
                     min_hop: float) -> list[str]:
    """How events differ from the exact solution's, beyond what the tolerances allow; [] if they agree.

    Every exact event bounding a hop that rises more than min_hop [m] above R must be found, of
    the same kind, at a time within height_tolerance / |v| of the exact one (the time in which
    the ball moves by the height tolerance: a grazing event, v ~ 0, is located loosely). A
    departure and the impact after it whose hop stays within min_hop of R may be missing (the
    contact then goes on through the hop) or, the other way round, present in events alone. An
    event within its time tolerance of the end may be in one list only: the other falls past it.
    """
    return _mismatches(events, exact.events, event_hops(exact),
                       lambda event: flight_apex(exact, event.time, exact.ball.R, event.velocity), exact.t_end,
                       height_tolerance, min_hop, "exact")


def reference_event_mismatches(events: list[Event], reference: list[Event], ball: Ball, h0: float, v0: float,
                               t_end: float, height_tolerance: float, min_hop: float,
                               F_ext: float = 0.0) -> list[str]:
    """event_mismatches' rule against a reference run's events, for a law without an exact solution.

    Only the crossings of R (impacts and departures) are compared: a solver that clips the contact force in
    its right-hand side (SciPy's methods under the Hunt-Crossley law) has no release or engage events. The hop
    each reference event bounds is its flight's apex under the constant F_ext [N]: from (h0 [m], v0 [m/s])
    for a first impact, from the departure's speed for every other.
    """
    found = [event for event in events if event.kind in (IMPACT, DEPARTURE)]
    wanted = [event for event in reference if event.kind in (IMPACT, DEPARTURE)]

    def apex(event: Event) -> float:
        return _apex(ball, F_ext, t_end, event.time, ball.R, event.velocity)

    hops = []
    for i, event in enumerate(wanted):
        if event.kind == DEPARTURE:
            hops.append(apex(event))
        elif i > 0 and wanted[i - 1].kind == DEPARTURE:
            hops.append(hops[-1])
        else:  # the first impact (or one after a contact that ended without a departure): the drop's own flight
            hops.append(_apex(ball, F_ext, t_end, 0.0, h0, v0) if i == 0 else math.inf)
    return _mismatches(found, wanted, hops, apex, t_end, height_tolerance, min_hop, "reference")


def _mismatches(found: list[Event], wanted: list[Event], bounded_hop: list[float], apex, t_end: float,
                height_tolerance: float, min_hop: float, source: str) -> list[str]:
    """event_mismatches' rule: wanted events (from source) with the hop each bounds; apex(event) a found departure's."""
    def allowed(event: Event) -> float:
        return height_tolerance / abs(event.velocity) if event.velocity else math.inf

    def at_the_end(event: Event) -> bool:
        return t_end - event.time <= allowed(event)

    problems: list[str] = []
    i = j = 0
    while i < len(wanted) or j < len(found):
        if i < len(wanted) and j < len(found) and found[j].kind == wanted[i].kind:
            if abs(found[j].time - wanted[i].time) <= allowed(wanted[i]):
                i, j = i + 1, j + 1
                continue
        if i < len(wanted) and bounded_hop[i] <= min_hop:
            i += 2 if wanted[i].kind == DEPARTURE else 1  # a departure and its impact, or a first impact
            continue
        if (j < len(found) and found[j].kind == DEPARTURE and apex(found[j]) <= min_hop
                and (j + 1 == len(found) or found[j + 1].kind == IMPACT)):
            j += 2
            continue
        if i < len(wanted) and j == len(found) and at_the_end(wanted[i]):
            i += 1
            continue
        if j < len(found) and i == len(wanted) and at_the_end(found[j]):
            j += 1
            continue
        if i < len(wanted):
            got = f"found {found[j].kind} at t = {found[j].time!r} s" if j < len(found) else "found nothing"
            problems.append(f"{source} {wanted[i].kind} at t = {wanted[i].time!r} s (hop {bounded_hop[i]:.3g} m): "
                            f"{got}")
            i += 1
        else:
            problems.append(f"extra {found[j].kind} at t = {found[j].time!r} s")
            j += 1
    return problems
