"""The FMU under contact_law = rigid, against the rigid law's independent mpmath truth (tests/rigid_truth.py).

FMI 2.0 and 3.0 co-simulation run the FMU's own CVODE through the phase machine: held to 1e-9 m, every
impact time to 1e-11 s. FMI 3.0 model exchange is integrated by the master: held to what the master's
tolerance allows, with each impact a state jump (valuesOfContinuousStatesChanged), no fall through the
ground where the master's integrator steps over a bounce, and the Reference-FMUs' ball (h0 = 1 m above
the ground, e = 0.7) with and without their v_min.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from bouncingball.bench.c_fmu import ME_ROUNDING
from fmu_helpers import assert_fmu_page_quotes, page_figure
from rigid_truth import RigidTruth

sys.path.insert(0, str(Path(__file__).parent))
from me_master import run as run_me_master  # noqa: E402

fmpy = pytest.importorskip("fmpy")

R, G = 0.06, 9.81
T_END = 4.0
HEIGHT_TOLERANCE = 1e-9  # m
EVENT_TOLERANCE = 1e-11  # s
# (e, v_min, drop above R [m]): the Reference-FMUs' ball ideal and with their v_min; a livelier one
CASES = [(0.7, 0.0, 1.0), (0.7, 0.1, 1.0), (0.9, 0.5, 2.0)]


def _start_values(e, v_min, drop, engine="sksundae"):
    return {"contact_law": "rigid", "e": e, "v_min": v_min, "h": R + drop, "engine": engine}


def _simulate(fmu, start_values, **options):
    return fmpy.simulate_fmu(str(fmu), start_values=start_values, stop_time=T_END, output_interval=1e-3,
                             output=["h", "v", "impacts", "contact", "a", "contact_force"], **options)


def _assert_follows_truth(result, truth, height_tolerance, time_slack=1e-9):
    error = np.max(np.abs(result["h"] - np.array(truth.heights(result["time"]))))
    assert error <= height_tolerance, error
    impacts, truth_impacts = int(result["impacts"][-1]), [v for t, v in truth.impacts if t <= T_END]
    assert 0 < impacts <= len(truth_impacts)
    # the bounces not taken one by one are summed: each lower than the heights' tolerance
    assert all(float(v) ** 2 / (2 * G) <= height_tolerance for v in truth_impacts[impacts:])
    rest = float(truth.rest_time) if truth.rest_time is not None and truth.rest_time <= T_END else np.inf
    resting = result["time"] >= rest + time_slack
    assert np.all(result["contact"][resting])
    # on R from the last impact counted: the bounces after it (summed) stay within the tolerance of R
    last_impact = float(truth.impacts[impacts - 1][0])
    assert not np.any(result["contact"][result["time"] < last_impact - time_slack])
    assert np.all(result["h"][resting] == R) and np.all(result["v"][resting] == 0.0)
    assert np.all(result["a"][resting] == 0.0) and np.all(result["contact_force"][resting] == G)  # m = 1 kg
    return error


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
@pytest.mark.parametrize("e, v_min, drop", CASES)
def test_fmi2_co_simulation_follows_the_rigid_truth(fmu, e, v_min, drop, engine):
    truth = RigidTruth(R, G, e, v_min, R + drop, 0.0, T_END)
    _assert_follows_truth(_simulate(fmu, _start_values(e, v_min, drop, engine)), truth, HEIGHT_TOLERANCE)


@pytest.mark.parametrize("e, v_min, drop", CASES)
def test_fmi3_co_simulation_returns_early_at_each_impact_of_the_rigid_truth(fmu3, e, v_min, drop):
    truth = RigidTruth(R, G, e, v_min, R + drop, 0.0, T_END)
    result = _simulate(fmu3, _start_values(e, v_min, drop), early_return_allowed=True)
    _assert_follows_truth(result, truth, HEIGHT_TOLERANCE)
    # the early returns are the rows off the 1 ms grid: each at an impact of the truth, in order
    t = result["time"]
    early = t[np.abs(t * 1e3 - np.round(t * 1e3)) > 1e-6]
    impacts = [float(time) for time, _ in truth.impacts[:int(result["impacts"][-1])]]
    assert len(np.unique(early)) == len(impacts)
    assert len(early) >= 3
    assert np.max(np.abs(np.unique(early) - impacts[:len(np.unique(early))])) <= EVENT_TOLERANCE


@pytest.mark.parametrize("restart", ["when told", "always"])
@pytest.mark.parametrize("v_min", [0.0, 0.1])
@pytest.mark.parametrize("rtol, tolerance", [(1e-4, 2e-3), (1e-6, 3e-5), (1e-8, 5e-7), (1e-10, 5e-9)])
def test_model_exchange_jumps_at_each_impact_and_never_falls_through(unzipped3, rtol, tolerance, v_min, restart):
    """The model-exchange master at its tolerance: heights within what it resolves, and the ball ends on R.

    At rtol 1e-4 and 1e-6 with v_min = 0 the master's CVODE once stepped over a bounce too low for it, and the
    ball fell through the ground (10 m below it at 4 s) with every status OK: a rising ball's event indicator (at
    least the smallest double) keeps it from that without fmi3CompletedIntegratorStep, which the FMU no longer asks
    for (the master calls it only where needsCompletedIntegratorStep says so, as fmusim).
    """
    truth = RigidTruth(R, G, 0.7, v_min, R + 1.0, 0.0, T_END)
    run = run_me_master(unzipped3, t_end=T_END, output_interval=1e-3, rtol=rtol, restart=restart,
                        start_values={"contact_law": "rigid", "e": 0.7, "v_min": v_min, "h": R + 1.0})
    error = np.max(np.abs(run.h - np.array(truth.heights(run.t))))
    assert error <= tolerance, error
    # docs/fmu.md gives one figure per rtol: with and without v_min, restarting when told or always, alike
    assert_fmu_page_quotes(f"{page_figure(error)} m at {'rtol ' if rtol == 1e-4 else ''}1e{round(np.log10(rtol))} with "
                           f"v_min = {v_min:g},")
    assert run.h[-1] == R and 0 < run.impacts[-1] <= len(truth.impacts)
    if v_min > 0.0:
        assert run.impacts[-1] == len(truth.impacts) == 11
    jumps = [values_changed for _, values_changed, _ in run.events]
    assert sum(jumps) >= run.impacts[-1] - run.step_events  # every impact the master located is a state jump
    assert all(nominals for _, values, nominals in run.events if values)


def test_fmpy_model_exchange_follows_the_rigid_truth_to_its_tolerance(fmu3):
    truth = RigidTruth(R, G, 0.7, 0.0, R + 1.0, 0.0, T_END)
    result = _simulate(fmu3, _start_values(0.7, 0.0, 1.0), fmi_type="ModelExchange", solver="CVode",
                       relative_tolerance=1e-8)
    error = _assert_follows_truth(result, truth, 5e-7, time_slack=1e-3)  # the master locates the low bounces' impacts
    assert_fmu_page_quotes(f"FMPy's CVode (v_min = 0): {page_figure(error)} m at 1e-8.")


# The Reference-FMUs' FMUs and fmusim (README there), beside the clone as ../shared/masters; absent from a user's clone
MASTERS = Path(os.environ.get("BOUNCINGBALL_MASTERS", Path(__file__).resolve().parents[2] / "shared" / "masters"))


def _their_scene_in_fmpy_cvode(fmu, rtol: float, theirs: bool = False) -> tuple[float, int]:
    """Their scene (e 0.7, v_min 0.1, 1 m above the ground, 3 s, 10 ms) in FMPy's CVode: (max |h error| [m], the
    calls of fmi3GetContinuousStateDerivatives and fmi3CompletedIntegratorStep)."""
    calls = []
    values = {} if theirs else {"contact_law": "rigid", "e": 0.7, "v_min": 0.1, "h": R + 1.0}
    result = fmpy.simulate_fmu(str(fmu), start_values=values, stop_time=3.0, output_interval=0.01, output=["h"],
                               fmi_type="ModelExchange", solver="CVode", relative_tolerance=rtol,
                               fmi_call_logger=lambda line: calls.append(line.split("(")[0]))
    truth = RigidTruth(R, G, 0.7, 0.1, R + 1.0, 0.0, 3.0)
    error = float(np.max(np.abs(result["h"] + (R if theirs else 0.0) - np.array(truth.heights(result["time"])))))
    return error, sum(call in ("fmi3GetContinuousStateDerivatives", "fmi3CompletedIntegratorStep") for call in calls)


def test_model_exchange_restarts_each_bounce_from_x_0_as_cheaply_as_possible(fmu3):
    """FMPy's CVode at 1e-8, the Reference-FMUs' scene: 294 derivative calls, no fmi3CompletedIntegratorStep, 1.3e-7 m.

    With the state h (0.06 m at each impact, CVODE's first step after the restart bounded by 0.1 |h| / |v| rather
    than by its tolerance) and the call asked for: 324 derivative calls, 311 completed steps, 2.6e-7 m.
    """
    error, calls = _their_scene_in_fmpy_cvode(fmu3, 1e-8)
    assert calls <= 300 and error <= 1.3e-7, (calls, error)


@pytest.mark.skipif(not (MASTERS / "Ref_BouncingBall_fmi3.fmu").is_file(), reason="../shared/masters is absent")
@pytest.mark.parametrize("rtol", [1e-4, 1e-6, 1e-8, 1e-10])
def test_model_exchange_costs_what_the_reference_fmus_ball_does(fmu3, rtol):
    """No more calls than their C ball in FMPy's CVode, and at most its error (our nominals capped at 1, as theirs
    are; FMPy, as fmusim, reads them once) up to the rounding of our state x = h - R, held as h (ME_ROUNDING)."""
    ours, ours_calls = _their_scene_in_fmpy_cvode(fmu3, rtol)
    theirs, their_calls = _their_scene_in_fmpy_cvode(MASTERS / "Ref_BouncingBall_fmi3.fmu", rtol, theirs=True)
    assert ours_calls <= their_calls and ours <= theirs + ME_ROUNDING, (ours_calls, their_calls, ours, theirs)


def test_fmpy_model_exchange_lifts_a_resting_rigid_ball_when_f_ext_exceeds_its_weight(fmu3):
    """On R at rest until 0.5 s, then F_ext = 2 m g: the ball rises at g from 0.5 s (its indicator F_ext/m - g)."""
    signal = np.array([(0.0, 0.0), (0.5, 0.0), (0.5, 2.0 * G)], dtype=[("time", float), ("F_ext", float)])
    result = fmpy.simulate_fmu(str(fmu3), start_values=_start_values(0.7, 0.0, 0.0), stop_time=1.0,
                               output_interval=1e-3, input=signal, output=["h", "contact"],
                               fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-10)
    rising = np.clip(result["time"] - 0.5, 0.0, None)
    assert np.max(np.abs(result["h"] - (R + 0.5 * G * rising**2))) <= 1e-8
    assert np.all(result["contact"][result["time"] < 0.5]) and not np.any(result["contact"][result["time"] > 0.51])


@pytest.mark.parametrize("name, value, message", [
    ("contact_law", "soft", "contact_law = 'soft' is not allowed: it must be one of linear, rigid"),
    ("e", 1.5, "e = 1.5 is not allowed: it must be in [0, 1]"),
    ("v_min", -0.1, "v_min = -0.1 m/s is not allowed: it must be finite and >= 0"),
])
def test_a_bad_contact_law_parameter_is_refused_at_initialisation_naming_it(fmu, name, value, message):
    messages = []
    with pytest.raises(Exception, match="fmi2ExitInitializationMode"):
        fmpy.simulate_fmu(str(fmu), start_values={"contact_law": "rigid", name: value}, stop_time=0.1,
                          logger=lambda *args: messages.append(args[-1].decode()), debug_logging=True)
    assert any(message in line for line in messages), messages


def test_check_judges_a_rigid_run_by_its_start_values(fmu):
    """`check` takes contact_law, e and v_min as start values: the rigid run passes, judged as linear it fails."""
    from bouncingball.check.judge import check_result

    values = _start_values(0.7, 0.1, 1.0)
    result = _simulate(fmu, values)
    columns = {"time": result["time"], "h": result["h"], "impacts": result["impacts"]}
    passed = check_result(columns, "article", values)
    impacts = len(RigidTruth(R, G, 0.7, 0.1, R + 1.0, 0.0, T_END).impacts)
    assert passed.passed and passed.impacts_found == passed.impacts_exact == impacts
    assert passed.max_height_error <= HEIGHT_TOLERANCE
    as_linear = check_result(columns, "article", {"h": R + 1.0})
    assert not as_linear.passed and as_linear.max_height_error > 0.1


def test_run_takes_the_contact_law_from_the_command_line_and_reports_restitution(capsys):
    """`run --contact rigid --e 0.8`; the linear law's first bounce against the damped oscillator's restitution."""
    import math

    from bouncingball.cli import main

    assert main(["run", "--contact", "rigid", "--e", "0.8", "--v-min", "0.1", "--t-end", "3"]) == 0
    out = capsys.readouterr().out
    assert "rigid contact, e = 0.8, v_min = 0.1 m/s" in out and "restitution e = 0.8 at each impact" in out
    assert main(["run", "--t-end", "1"]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if "restitution" in line)
    first = float(line.split(": ")[1].split()[0].rstrip(","))
    zeta = 10.0 / (2.0 * math.sqrt(1e4))  # the article's ball; gravity changes it by about g / (w v) = 1.6 %
    assert first == pytest.approx(math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta**2)), rel=0.02)
    assert main(["run", "--contact", "soft"]) == 2
    assert "contact = 'soft' is not allowed: it must be one of linear, rigid" in capsys.readouterr().err


def test_a_ball_below_the_ground_in_flight_is_said_once(unzipped3):
    """A master that stepped over an impact unseen (not calling fmi3CompletedIntegratorStep): the log says so, once."""
    import ctypes

    from fmpy import read_model_description
    from fmpy.fmi3 import FMU3Model

    description = read_model_description(str(unzipped3))
    log = []
    fmu = FMU3Model(guid=description.guid, unzipDirectory=str(unzipped3),
                    modelIdentifier=description.modelExchange.modelIdentifier, instanceName="fell")
    fmu.instantiate(logMessage=lambda env, status, category, message: log.append((status, message.decode())))
    fmu.setString([{v.name: v.valueReference for v in description.modelVariables}["contact_law"]], ["rigid"])
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.updateDiscreteStates()
    fmu.enterContinuousTimeMode()
    x, z = (ctypes.c_double * 2)(-1.0, -5.0), (ctypes.c_double * 1)()
    fmu.setContinuousStates(x, 2)
    for _ in range(3):
        fmu.getEventIndicators(z, 1)
    said = [(status, message) for status, message in log if "below the ground in flight" in message]
    assert len(said) == 1 and said[0][0] == 1 and "stepped over an impact without an event" in said[0][1]  # warning
    assert z[0] == (-1.0 + R) - R  # the states are x = h - R and v: h = -0.94 m
    fmu.terminate()
    fmu.freeInstance()


@pytest.mark.parametrize("h0, v0, tolerance", [(R + 1.0, 0.0, 2e-3), (R, 3.0, 1e-3)])
def test_fmpy_model_exchange_at_a_loose_tolerance_has_no_event_storm(fmu3, h0, v0, tolerance):
    """At rtol 1e-4 FMPy's CVODE found a root every 2e-10 s while a rigid ball rose from R below its tolerance:
    31,582 events, 67,164 rows in 4 s. Now a row per output point and per event."""
    truth = RigidTruth(R, G, 0.7, 0.0, h0, v0, T_END)
    result = fmpy.simulate_fmu(str(fmu3), start_values={"contact_law": "rigid", "h": h0, "v": v0}, stop_time=T_END,
                               output_interval=1e-3, output=["h", "impacts"], fmi_type="ModelExchange",
                               solver="CVode", relative_tolerance=1e-4)
    assert len(result) <= 4001 + 2 * 50
    assert np.max(np.abs(result["h"] - np.array(truth.heights(result["time"])))) <= tolerance
    assert result["h"][-1] == R


def test_validate_runs_a_rigid_scene_file_without_the_articles_algorithm(fmu, tmp_path):
    """The Reference-FMUs' ball as a scene file: the FMU's impacts and heights against the exact ones, SciPy not run."""
    from bouncingball.fmu.validate import validate

    scene = tmp_path / "reference.toml"
    scene.write_text('contact = "rigid"\ne = 0.7\nv_min = 0.1\nh0 = 1.06\nt_end = 3.0\n')
    said = []
    report = validate(str(scene), fmu=fmu, progress=said.append)
    assert any("SciPy algorithm is not run: it models the linear contact law, not rigid" in line for line in said)
    rows = {row.name: row for row in report.rows}
    assert set(rows) == {"FMU (FMPy)", "CVODE (in-process)", "exact"}
    fmu_row = rows["FMU (FMPy)"].accuracy
    events = len(RigidTruth(R, G, 0.7, 0.1, 1.06, 0.0, 3.0).impacts)  # every event of the rigid law an impact
    assert fmu_row.max_height_error <= HEIGHT_TOLERANCE and fmu_row.events_found == fmu_row.events_exact == events
    assert report.impacts_match_at_every_point


def test_a_parameter_the_law_does_not_read_is_logged_as_a_warning_and_ignored(fmu):
    """A master may set every parameter to its start value (SSP): the FMU cannot refuse alpha on a rigid ball, so it
    says so in its log, once, and runs the rigid ball as if alpha and k were at their defaults."""
    messages = []
    values = _start_values(0.7, 0.1, 1.0)
    result = fmpy.simulate_fmu(str(fmu), start_values={**values, "alpha": 0.3, "k": 1e12}, stop_time=2.0,
                               output_interval=1e-3, output=["h"], debug_logging=True,
                               logger=lambda *args: messages.append((args[-3], args[-1].decode())))
    plain = fmpy.simulate_fmu(str(fmu), start_values=values, stop_time=2.0, output_interval=1e-3, output=["h"])
    assert np.array_equal(result["h"], plain["h"])
    said = [(status, text) for status, text in messages if "is ignored" in text]
    assert said == [(1, "k = 1000000000000.0, alpha = 0.3 is ignored (taken at its default) with contact_law = "
                        "'rigid': that law reads only e, v_min (besides m, R and g); leave it at its default (k = "
                        "10000.0, alpha = 0.0) or choose a contact law that reads it (hunt-crossley, linear, "
                        "linear-no-pull)")], messages
