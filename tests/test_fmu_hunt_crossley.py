"""The FMU under contact_law = hunt-crossley, against the law's mpmath truth (tests/hunt_crossley_truth.py).

Co-simulation (FMI 2.0 with both engines, FMI 3.0 with early return) runs the FMU's own CVODE through the phase
machine: heights within 1e-6 of the height scale, every impact, the contact force never below 0, each early return
at the truth's event. In FMI 3.0 model exchange the master integrates (the clip is in the derivative, the event
indicator h - R): it sees every impact and departure and restarts at each, its heights within its tolerance.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from test_hunt_crossley import CASES, TOLERANCE, truth

sys.path.insert(0, str(Path(__file__).parent))
from me_master import run as run_me_master  # noqa: E402

fmpy = pytest.importorskip("fmpy")

# a drop with its bounces; a stiffer law (n = 2.5) thrown down from near R; a start below R in the free sub-mode
NAMES = ("benchmark", "stiff-n", "free-start")


def _start_values(name, engine="sksundae"):
    k, n, alpha, m, R, g, h0, v0, t_end, F_ext = CASES[name]
    return {"contact_law": "hunt-crossley", "k": k, "n": n, "alpha": alpha, "m": m, "R": R, "g": g, "h": h0, "v": v0,
            "engine": engine}


def _simulate(fmu, name, **options):
    return fmpy.simulate_fmu(str(fmu), start_values=_start_values(name, options.pop("engine", "sksundae")),
                             stop_time=CASES[name][8], output_interval=1e-3,
                             output=["h", "impacts", "contact", "contact_force"], **options)


def _heights(name, t):
    return np.array([float(truth(name).state(time)[0]) for time in t])


def _assert_follows_truth(result, name):
    h_true = _heights(name, result["time"])
    scale = max(float(np.max(np.abs(h_true))), CASES[name][4])
    assert np.max(np.abs(result["h"] - h_true)) / scale <= TOLERANCE
    assert result["impacts"][-1] == sum(kind == "impact" for _, kind, _ in truth(name).events)
    assert np.min(result["contact_force"]) >= 0.0
    force, contact = result["contact_force"], result["contact"]
    assert np.all(contact[force > 0.0]) and np.all(force[~contact] == 0.0)  # (at an impact, in contact with 0 N)


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
@pytest.mark.parametrize("name", NAMES)
def test_fmi2_co_simulation_follows_the_hunt_crossley_truth(fmu, name, engine):
    _assert_follows_truth(_simulate(fmu, name, engine=engine), name)


@pytest.mark.parametrize("name", NAMES)
def test_fmi3_co_simulation_returns_early_at_each_event_of_the_hunt_crossley_truth(fmu3, name):
    result = _simulate(fmu3, name, early_return_allowed=True)
    _assert_follows_truth(result, name)
    t = result["time"]
    early = np.unique(t[np.abs(t * 1e3 - np.round(t * 1e3)) > 1e-6])
    events = np.array([float(time) for time, _, _ in truth(name).events])
    events = events[np.abs(events * 1e3 - np.round(events * 1e3)) > 1e-6]  # an event on the grid is no early return
    assert len(early) == len(events) >= 3
    assert np.max(np.abs(early - events)) <= 1e-9


@pytest.mark.parametrize("name", NAMES)
def test_model_exchange_sees_every_impact_and_departure(unzipped3, name):
    """The master restarting only when told, at rtol 1e-10: at each of the truth's events, within 1e-5 m."""
    values = {key: value for key, value in _start_values(name).items() if key != "engine"}
    run = run_me_master(unzipped3, t_end=CASES[name][8], output_interval=1e-3, rtol=1e-10, start_values=values)
    assert np.max(np.abs(run.h - _heights(name, run.t))) <= 1e-5
    # the clip is in the derivative: no release or engagement event, only the crossings of R
    events = [event for event in truth(name).events if event[1] in ("impact", "departure")]
    assert len(run.events) == run.restarts == len(events) and run.step_events == 0
    times = np.array([time for time, _, _ in run.events])
    assert np.max(np.abs(times - [float(time) for time, _, _ in events])) <= 1e-6


def test_check_refuses_a_hunt_crossley_run_by_name_it_has_no_exact_solution(fmu, capsys, tmp_path):
    from bouncingball.check.judge import check_result
    from bouncingball.cli import main

    result = _simulate(fmu, "benchmark")
    columns = {"time": result["time"], "h": result["h"], "impacts": result["impacts"]}
    with pytest.raises(ValueError, match="check judges a run against the exact solution, and contact_law = "
                                         "'hunt-crossley' has none"):
        check_result(columns, "article", {"contact_law": "hunt-crossley"})
    table = tmp_path / "out.csv"
    np.savetxt(table, np.column_stack([result["time"], result["h"]]), delimiter=",", header="time,h", comments="")
    assert main(["check", str(table), "--start-value", "contact_law=hunt-crossley"]) == 2
    assert "contact_law = 'hunt-crossley' has none" in capsys.readouterr().err
