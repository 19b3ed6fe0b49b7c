"""What `run` says: the first and last events, why the events differ from the exact ones, the engine's first use."""

import json
import subprocess
import sys

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.accuracy import event_hops
from bouncingball.cli import main
from bouncingball.run_report import event_differences, event_lines
from bouncingball.solvers.cvode import merged_hop_limit
from bouncingball.solvers.exact import ExactSolution
from bouncingball.solvers.result import SimulationResult, SolverStats
from oracle_counts import oracle_counts

TINY = bb.Ball(m=1e-6, k=1e9, R=0.1)  # hops down to 1.6e-14 m before it rests at 2.53 s


def _printed_events(text: str) -> list[tuple[int, float, str, float]]:
    rows = []
    for line in text.splitlines():
        parts = line.split()
        if parts and parts[0].startswith("#") and parts[1] == "t":
            rows.append((int(parts[0][1:]), float(parts[3]), parts[5], float(parts[8])))
    return rows


def test_run_lists_the_first_and_last_events_as_the_exact_solution_has_them(capsys):
    assert main(["run", "article", "--engine", "sksundae"]) == 0
    text = capsys.readouterr().out
    exact = ExactSolution(bb.Ball(), 2.0, 0.0, 0.0, 8.0).events
    rows = _printed_events(text)
    n = oracle_counts(bb.Ball()).events
    assert [row[0] for row in rows] == [1, 2, 3, n - 2, n - 1, n] and f"... {n - 6} more events" in text
    for number, time, kind, velocity in rows:
        assert kind == exact[number - 1].kind
        assert time == pytest.approx(exact[number - 1].time, abs=1e-9)
        assert velocity == pytest.approx(exact[number - 1].velocity, rel=1e-5)
    assert "differences" not in text  # same events, same kinds: the time error line says the rest


def test_one_impact_and_one_departure_are_singular(capsys):
    assert main(["run", "zero-gravity", "--solver", "exact"]) == 0
    text = capsys.readouterr().out
    assert "events      2 (1 impact, 1 departure)" in text
    assert len(_printed_events(text)) == 2


def test_event_lines_show_every_event_of_a_short_list():
    events = ExactSolution(bb.Ball(), 2.0, 0.0, 0.0, 2.0).events
    assert len(event_lines(events)) == len(events) == 4


def _cvode_like(exact: ExactSolution, events, rtol: float) -> SimulationResult:
    """A result with the given events and the exact heights, as a CVODE run at rtol would report it."""
    t = np.linspace(exact.t_start, exact.t_end, 301)
    h, v = exact.state(t)
    return SimulationResult("cvode", exact.ball, t, h, v, list(events), None, SolverStats(), 0.0,
                            {"rtol": rtol, "atol": None})


def test_missing_tiny_hops_are_explained_by_cvodes_merged_hop_rule():
    exact = ExactSolution(TINY, 2.0, 0.0, 0.0, 3.0)
    rtol = 0.1
    limit = merged_hop_limit(TINY, rtol)
    hops = event_hops(exact)
    assert hops[-1] <= limit < hops[-5]  # the last hop may be merged at this rtol, the ones before it not
    lines = event_differences(_cvode_like(exact, exact.events[:-2], rtol), exact, 0.0)
    assert lines[0] == f"61 events where the exact solution has {len(exact.events)}"
    mergeable = [e for e, hop in zip(exact.events, hops, strict=True) if hop <= limit]
    assert len(mergeable) == 4  # the last two hops, 8.2e-14 and 1.6e-14 m: the run merged the last one
    assert lines[1].startswith(f"4 exact events (from t = {mergeable[0].time:.6g} s) bound hops no higher than "
                               f"{limit:.3g} m") and "cvode.merged_hop_limit" in lines[1]
    assert lines[2].startswith("every other event is within")
    assert len(lines) == 3


def test_a_missing_hop_above_the_rule_is_named():
    exact = ExactSolution(TINY, 2.0, 0.0, 0.0, 3.0)
    events = exact.events[:1] + exact.events[3:]  # the first hop, 0.4 m high, is missing
    lines = event_differences(_cvode_like(exact, events, 1e-12), exact, 0.0)
    assert lines[0] == f"{len(events)} events where the exact solution has {len(exact.events)}"
    assert "2 differences from the exact events beyond the hops up to" in lines[1]
    assert lines[2].startswith(f"  exact departure at t = {exact.events[1].time!r} s")
    assert lines[3].startswith(f"  exact impact at t = {exact.events[2].time!r} s")


def test_scipy_missing_the_last_hop_is_shown_with_its_height(capsys):
    pytest.importorskip("scipy")
    assert main(["run", "in-contact", "--solver", "scipy", "--t-end", "2"]) == 0
    text = capsys.readouterr().out
    exact = ExactSolution(bb.Ball(), 0.05, 0.0, 0.0, 2.0)
    hops = event_hops(exact)
    assert f"where the exact solution has {len(exact.events)}" in text
    assert f"exact departure at t = {exact.events[-2].time!r} s (hop {hops[-2]:.3g} m): found nothing" in text


FIRST_USE = """
import json, bouncingball as bb
from bouncingball.scenes import load_scene
scene = load_scene("stiff-rest")
runs = [scene.simulate("cvode", engine="compiled").stats for _ in range(2)]
print(json.dumps([[s.first_use_time, s.wall_time] for s in runs]))
"""


@pytest.mark.slow
def test_the_compiled_engines_first_use_is_measured_apart_from_the_run():
    pytest.importorskip("numba")
    done = subprocess.run([sys.executable, "-c", FIRST_USE], capture_output=True, text=True, check=True)
    (first_use, first_wall), (again, second_wall) = json.loads(done.stdout)
    assert first_use > 0.0 and again == 0.0
    # stiff-rest takes no step: its run is a few ms, the import and loading of numba's code far more
    assert first_wall < first_use and second_wall < first_use
    cli = subprocess.run([sys.executable, "-m", "bouncingball.cli", "run", "stiff-rest", "--engine", "compiled"],
                         capture_output=True, text=True, check=True)
    line = next(line for line in cli.stdout.splitlines() if line.startswith("  first use"))
    assert "ms before the run (not in its wall time)" in line
    plain = subprocess.run([sys.executable, "-m", "bouncingball.cli", "run", "stiff-rest", "--engine", "sksundae"],
                           capture_output=True, text=True, check=True)
    line = next(line for line in plain.stdout.splitlines() if line.startswith("  first use"))
    assert line.endswith("ms before the run (not in its wall time) to import scikit-sundae")
