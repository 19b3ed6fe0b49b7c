"""The FMU under contact_law = linear-no-pull, against the no-pull law's mpmath truth (tests/nopull_truth.py).

Co-simulation (FMI 2.0, FMI 3.0 with early return) runs the FMU's own CVODE through the phase machine: heights
within 1e-9 m, every event (impact, release, engagement, departure) where the truth has it, the contact force
never below 0. In FMI 3.0 model exchange the master integrates, the event indicator is the current sub-mode's
(model_exchange.event_indicator): the master sees every event and restarts at each, its heights within its tolerance.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from fmu_helpers import assert_fmu_page_quotes, page_figure
from nopull_truth import NoPullTruth

sys.path.insert(0, str(Path(__file__).parent))
from me_master import run as run_me_master  # noqa: E402

fmpy = pytest.importorskip("fmpy")

HEIGHT_TOLERANCE = 1e-9  # m
# name: (b [N s/m], h0 [m], v0 [m/s], t_end [s], event time tolerance [s]) on the article's m, k, R, g: the article
# (impact, release, departure, 18 times); critical damping (pressed again below R, then at rest); thrown up from
# inside the ground (free at once)
CASES = {"article": (10.0, 2.0, 0.0, 8.0, 2.5e-10), "critical": (200.0, 0.5, 0.0, 3.0, 1e-11),
         "free-start": (50.0, 0.059, 3.0, 1.5, 5e-11)}
_truths: dict[str, NoPullTruth] = {}


def _truth(name):
    if name not in _truths:
        b, h0, v0, t_end, _ = CASES[name]
        _truths[name] = NoPullTruth(1.0, 1e4, b, 0.06, 9.81, h0, v0, t_end)
    return _truths[name]


def _start_values(name, engine="sksundae"):
    b, h0, v0, _, _ = CASES[name]
    return {"contact_law": "linear-no-pull", "b": b, "h": h0, "v": v0, "engine": engine}


def _simulate(fmu, name, **options):
    return fmpy.simulate_fmu(str(fmu), start_values=_start_values(name, options.pop("engine", "sksundae")),
                             stop_time=CASES[name][3], output_interval=1e-3,
                             output=["h", "impacts", "contact", "contact_force"], **options)


def _assert_follows_truth(result, truth):
    assert np.max(np.abs(result["h"] - np.array(truth.heights(result["time"])))) <= HEIGHT_TOLERANCE
    assert result["impacts"][-1] == sum(kind == "impact" for _, kind, _, _ in truth.events)
    assert np.min(result["contact_force"]) >= 0.0
    # contact: while the ground pushes, so never where the truth is free or flies (away from the events)
    forces = np.array([float(truth.force(t)) for t in result["time"]])
    assert not np.any(result["contact"][forces < -1e-6]) and np.all(result["contact"][forces > 1e-6])


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
@pytest.mark.parametrize("name", list(CASES))
def test_fmi2_co_simulation_follows_the_no_pull_truth(fmu, name, engine):
    _assert_follows_truth(_simulate(fmu, name, engine=engine), _truth(name))


@pytest.mark.parametrize("name", list(CASES))
def test_fmi3_co_simulation_returns_early_at_each_event_of_the_no_pull_truth(fmu3, name):
    truth = _truth(name)
    result = _simulate(fmu3, name, early_return_allowed=True)
    _assert_follows_truth(result, truth)
    t = result["time"]
    early = np.unique(t[np.abs(t * 1e3 - np.round(t * 1e3)) > 1e-6])
    events = np.array([float(time) for time, _, _, _ in truth.events])
    events = events[np.abs(events * 1e3 - np.round(events * 1e3)) > 1e-6]  # an event on the grid is no early return
    assert len(early) == len(events) >= 3
    assert np.max(np.abs(early - events)) <= CASES[name][4]


# how docs/fmu.md names the cases whose model-exchange errors it gives
PAGE_CASES = {"article": "on the article", "critical": "with critical damping"}


@pytest.mark.parametrize("name", list(CASES))
def test_model_exchange_sees_every_sub_mode_switch(unzipped3, name):
    """The master restarting only when told: at each of the truth's events, and within its tolerance."""
    truth = _truth(name)
    values = {key: value for key, value in _start_values(name).items() if key != "engine"}
    errors = []
    for rtol, tolerance in ((1e-8, 5e-5), (1e-10, 2e-6)):
        run = run_me_master(unzipped3, t_end=CASES[name][3], output_interval=1e-3, rtol=rtol, start_values=values)
        errors.append(np.max(np.abs(run.h - np.array(truth.heights(run.t)))))
        assert errors[-1] <= tolerance
        assert len(run.events) == run.restarts == len(truth.events) and run.step_events == 0
        times = np.array([time for time, _, _ in run.events])
        assert np.max(np.abs(times - [float(time) for time, _, _, _ in truth.events])) <= 1e-4
        assert all(nominals and not values for _, values, nominals in run.events)  # no jump: h and v are continuous
    if name in PAGE_CASES:
        assert_fmu_page_quotes(f"{PAGE_CASES[name]}, {page_figure(errors[0])} m at rtol 1e-8 and "
                               f"{page_figure(errors[1])} m at 1e-10")
    if name == "article":
        assert_fmu_page_quotes(f"every event of the mpmath solution ({len(truth.events)} on the article's 8 s)")


def test_check_judges_a_no_pull_run_by_its_start_values(fmu):
    from bouncingball.check.judge import check_result

    result = _simulate(fmu, "article")
    columns = {"time": result["time"], "h": result["h"], "impacts": result["impacts"]}
    passed = check_result(columns, "article", {"contact_law": "linear-no-pull"})
    impacts = sum(kind == "impact" for _, kind, _, _ in _truth("article").events)
    assert passed.passed and passed.impacts_found == passed.impacts_exact == impacts
    assert passed.max_height_error <= HEIGHT_TOLERANCE
    assert not check_result(columns, "article").passed  # the published law's damper pulls: 21 impacts
