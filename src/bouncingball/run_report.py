"""What `bouncingball run` says about a result beyond its numbers: its events, and why they differ from the exact ones.

The rule for the differences is the package's one rule for hops too small to resolve
(cvode.merged_hop_limit, the rule `check` applies): CVODE may merge a hop no higher than it into
the contact around it. accuracy.event_mismatches lists what that rule does not explain.
"""

from __future__ import annotations

from .accuracy import event_hops, event_mismatches
from .contact_laws import impact_is_instantaneous
from .solvers.exact import ExactSolution
from .solvers.lyapunov import MIN_IMPACTS, LyapunovExponent
from .solvers.result import Event, SimulationResult

EVENTS_SHOWN = 3  # the first and the last this many events are listed
MISMATCHES_SHOWN = 3


def plural(count: int, noun: str) -> str:
    """'1 event', '2 events', '0 events'.

    Examples
    --------
    >>> plural(1, "impact"), plural(0, "departure"), plural(41, "event")
    ('1 impact', '0 departures', '41 events')
    """
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def lyapunov_line(exponent: LyapunovExponent) -> str:
    """The run's largest Lyapunov exponent in words: its value per impact and per second, or why there is none.

    Examples
    --------
    >>> lyapunov_line(LyapunovExponent(-0.693, -6.93, 2000, 200.0))
    '-0.693 per impact, -6.93 per second (< 0: a small error dies out)'
    >>> lyapunov_line(LyapunovExponent(0.345, 1.72, 300, 60.0, 2, 4.2))
    '+0.345 per impact, +1.72 per second (> 0: a small error grows), since the last rest or ride ended at 4.2 s'
    >>> lyapunov_line(LyapunovExponent(float("-inf"), float("-inf"), 22, 4.6, 1, 0.0))
    '-inf: the run ends resting or riding, where it no longer depends on where it started'
    >>> lyapunov_line(LyapunovExponent(float("nan"), float("nan"), 3, 1.0))
    'none: 3 impacts, too few to say (20 or more)'
    """
    if exponent.per_impact == float("-inf"):
        return "-inf: the run ends resting or riding, where it no longer depends on where it started"
    since = f" since the last rest or ride ended at {exponent.since:.6g} s" if exponent.forgotten else ""
    if exponent.per_impact != exponent.per_impact:
        return f"none: {plural(exponent.impacts, 'impact')}{since}, too few to say ({MIN_IMPACTS} or more)"
    verdict = "> 0: a small error grows" if exponent.per_impact > 0.0 else "< 0: a small error dies out"
    line = f"{exponent.per_impact:+.3g} per impact, {exponent.per_second:+.3g} per second ({verdict})"
    return line + ("," + since if since else "")


def event_counts(events: list[Event]) -> str:
    """'41 (21 impacts, 20 departures)', '2 (1 impact, 1 departure)': the plurals right.

    The no-pull law's releases and engagements are counted too where there are any
    ('54 (18 impacts, 18 departures, 18 releases)').
    """
    counts = [plural(sum(event.kind == kind for event in events), noun) for kind, noun in
              (("impact", "impact"), ("departure", "departure"), ("release", "release"), ("engage", "engagement"))
              if kind in ("impact", "departure") or any(event.kind == kind for event in events)]
    return f"{len(events)} ({', '.join(counts)})"


def event_lines(events: list[Event], shown: int = EVENTS_SHOWN) -> list[str]:
    """The first and last `shown` events, one line each (time, kind, velocity), the others counted between."""
    def line(number: int, event: Event) -> str:
        return f"#{number:<5d} {f't = {event.time:.12g} s':22s}  {event.kind:9s}  v = {event.velocity:+.6g} m/s"

    if len(events) <= 2 * shown + 1:
        return [line(i + 1, e) for i, e in enumerate(events)]
    hidden = len(events) - 2 * shown
    return ([line(i + 1, e) for i, e in enumerate(events[:shown])] + [f"... {plural(hidden, 'more event')}"]
            + [line(len(events) - shown + i + 1, e) for i, e in enumerate(events[-shown:])])


def restitution_line(events: list[Event], ball, ground=None) -> str:
    """Each bounce's coefficient of restitution, departure over impact speed (first and last EVENTS_SHOWN), or "".

    Under the rigid law it is the law's e at every impact (a bounce that would leave slower than v_min,
    or below the Zeno resolution, ends on R instead). On a moving ground (ground: a Ground) the speeds are
    relative to it.

    Examples
    --------
    >>> from bouncingball import Ball, simulate
    >>> restitution_line(simulate(Ball(), 2.0, 0.0, 1.0).events, Ball())
    'departure over impact speed: 0.851 (1 bounce)'
    """
    if impact_is_instantaneous(ball.parameters):
        impacts = sum(event.kind == "impact" for event in events)
        return f"e = {ball.e:g} at each impact (the rigid law's), {plural(impacts, 'impact')}" if impacts else ""
    # each impact and the departure that ends its contact (the no-pull law's releases and engagements between)
    impacts = [(i, event) for i, event in enumerate(events) if event.kind == "impact"]
    ratios = []
    for number, (i, impact) in enumerate(impacts):
        end = impacts[number + 1][0] if number + 1 < len(impacts) else len(events)
        departure = next((event for event in events[i + 1:end] if event.kind == "departure"), None)
        if departure is not None:
            if ground is not None and ground.moves:
                ratios.append((departure.velocity - float(ground.velocity(departure.time)))
                              / (float(ground.velocity(impact.time)) - impact.velocity))
            else:
                ratios.append(departure.velocity / -impact.velocity)
    if not ratios:
        return ""
    shown = [f"{ratio:.3g}" for ratio in ratios]
    if len(shown) > 2 * EVENTS_SHOWN + 1:
        shown = [*shown[:EVENTS_SHOWN], "...", *shown[-EVENTS_SHOWN:]]
    relative = " relative to the ground" if ground is not None and ground.moves else ""
    return f"departure over impact speed{relative}: {', '.join(shown)} ({plural(len(ratios), 'bounce')})"


def hop_limit(result: SimulationResult) -> float:
    """The highest hop [m] the result's solver may merge into the contact: cvode.merged_hop_limit; 0 for the others.

    Under a table of forces, the largest of the limits of its values (as `check` takes it).
    """
    if result.solver != "cvode":
        return 0.0
    from .solvers.cvode import merged_hop_limit

    rtol, atol = result.options["rtol"], result.options["atol"]
    forces = getattr(result.F_ext, "values", (result.F_ext,))
    return max(merged_hop_limit(result.ball, rtol, atol, float(force)) for force in forces)


def event_differences(result: SimulationResult, exact: ExactSolution, height_tolerance: float) -> list[str]:
    """Why the result's events differ from the exact solution's; [] when they are the same in number and kind.

    Events of the same kinds in the same order differ only in time, which the run's max event
    time error says; otherwise the exact events the solver's hop resolution lets it merge are
    counted, and what that rule does not explain is listed.

    Parameters
    ----------
    result : SimulationResult
        A solver's result.
    exact : ExactSolution
        The exact solution over the result's time span.
    height_tolerance : float
        How far [m] the ball may be off where an event is (at least the check's default
        tolerance, testing.DEFAULT_TOLERANCE): an event matches when it is within
        height_tolerance / |v| of the exact one.

    Returns
    -------
    list of str
        The lines to print: the exact events the solver's hop resolution lets it merge (when the
        counts differ), then the differences that rule does not explain.
    """
    if [event.kind for event in result.events] == [event.kind for event in exact.events]:
        return []
    from .check.judge import DEFAULT_TOLERANCE

    height_tolerance = max(height_tolerance, DEFAULT_TOLERANCE)
    limit = hop_limit(result)
    problems = event_mismatches(result.events, exact, height_tolerance, limit)
    lines = []
    if len(result.events) != len(exact.events):
        lines.append(f"{plural(len(result.events), 'event')} where the exact solution has "
                     f"{len(exact.events)}")
        small = [event for event, hop in zip(exact.events, event_hops(exact), strict=True) if hop <= limit]
        if small:
            lines.append(f"{plural(len(small), 'exact event')} (from t = {small[0].time:.6g} s) bound hops no "
                         f"higher than {limit:.3g} m above R, CVODE's hop resolution at rtol "
                         f"{result.options['rtol']:g} (cvode.merged_hop_limit, as `check` "
                         "allows): it merges such hops into the contact around them")
        if not problems:
            lines.append(f"every other event is within the time the ball moves {height_tolerance:.3g} m of the "
                         "exact one")
    if problems:
        rule = f" beyond the hops up to {limit:.3g} m that CVODE may merge" if limit > 0.0 else ""
        lines.append(f"{plural(len(problems), 'difference')} from the exact events{rule}, events matched to "
                     f"within the time the ball moves {height_tolerance:.3g} m:")
        lines += ["  " + problem for problem in problems[:MISMATCHES_SHOWN]]
        if len(problems) > MISMATCHES_SHOWN:
            lines.append(f"  ... {plural(len(problems) - MISMATCHES_SHOWN, 'more difference')}")
    return lines


def first_use_note(first_use_time: float, engine: str) -> str:
    """The engine's first use in the process, which the run's wall time leaves out; '' if none."""
    if not first_use_time:
        return ""
    loading = ("import numba and compile the engine or load it from numba's cache" if engine == "compiled"
               else "import scikit-sundae")
    return f"{first_use_time * 1e3:.0f} ms before the run (not in its wall time) to {loading}"
