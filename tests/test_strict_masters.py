"""The FMUs in masters that behave as some importers do: a C co-simulation master that stops at any status
but OK, run with a looser tolerance than the FMU's rtol (as OMSimulator passes 1e-4), and a model-exchange
master that restarts its integrator only when the FMU says so (tests/me_master.py, as fmusim does)."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from bouncingball.fmu.build import shared_libpython
from bouncingball.physics import Ball
from bouncingball.solvers.exact import ExactSolution
from fmu_helpers import C_MASTER3, assert_fmu_page_quotes, compile_c_master, exact_at, page_figure
from me_master import run as run_model_exchange
from oracle_counts import oracle_counts

fmpy = pytest.importorskip("fmpy", reason="the FMU tests need the [fmu] extra")
pytest.importorskip("pythonfmu3", reason="the FMI 3.0 FMU tests need the [fmu] extra")

LOOSER = "1e-4"  # OMSimulator's tolerance where its user gives none; the FMU's rtol is 1e-12


@pytest.fixture(scope="module", params=[2, 3], ids=["fmi2", "fmi3"])
def strict_master(request, tmp_path_factory):
    """(C master, unzipped FMU, value references): any status but OK ends the run with 10 + that status."""
    if shared_libpython() is None:
        pytest.skip("this Python has no shared libpython: its FMU can run only in a master that runs Python")
    version = request.param
    source = {} if version == 2 else {"source": C_MASTER3}
    binary = compile_c_master(tmp_path_factory.mktemp("strict") / f"fmi{version}_master", **source)
    if binary is None:
        pytest.skip("no C compiler (cc or gcc) to build the C master")
    unzipped = request.getfixturevalue("unzipped" if version == 2 else "unzipped3")
    description = fmpy.read_model_description(str(unzipped))
    references = {v.name: v.valueReference for v in description.modelVariables}
    return binary, unzipped, description.guid, references


@pytest.mark.parametrize("tolerance", [LOOSER, "1e-14"], ids=["looser", "tighter"])
def test_a_master_that_stops_at_any_status_but_ok_runs_the_fmu_at_its_own_tolerance(strict_master, tolerance):
    """A looser tolerance is said in the log (status warning there), and every call returns OK."""
    binary, unzipped, guid, r = strict_master
    completed = subprocess.run([binary, unzipped, "BouncingBall", guid, "8", "0.01", f"t={tolerance}",
                                f"o{r['h']}", f"i{r['impacts']}"], env={"PATH": "/usr/bin:/bin"},
                               capture_output=True, text=True, check=False, timeout=300)
    assert completed.returncode == 0, completed.stdout + completed.stderr[-3000:]
    table = np.loadtxt(completed.stdout.splitlines())
    h, _, impacts = exact_at(table[:, 0])
    # rtol stays the FMU's 1e-12 with the looser tolerance (at 1e-4 itself the ball would miss impacts)
    assert np.max(np.abs(table[:, 1] - h)) < 1e-8
    np.testing.assert_array_equal(table[:, 2], impacts)
    assert impacts[-1] == oracle_counts(Ball()).impacts
    if tolerance == LOOSER and "fmi2" in binary.name:  # the FMI 3.0 FMU does not read the master's tolerance
        assert f"tolerance = {float(tolerance)!r}" in completed.stderr and "is looser than" in completed.stderr


def test_the_fmi2_fmu_in_fmpy_with_a_looser_tolerance_returns_ok_and_logs_it(unzipped):
    """FMPy's own call: fmi2ExitInitializationMode returns fmi2OK (FMPy raises on fmi2Error, logs the rest)."""
    from fmu_helpers import Instance

    ball = Instance(unzipped)
    statuses = [ball.fmu.setupExperiment(tolerance=float(LOOSER), startTime=0.0),
                ball.fmu.enterInitializationMode(), ball.fmu.exitInitializationMode()]
    assert statuses == [0, 0, 0]  # fmi2OK
    assert any(status == 1 and "is looser than the FMU's rtol" in message for status, message in ball.log)
    ball.fmu.terminate()
    ball.fmu.freeInstance()


# --- model exchange in a master that restarts its integrator only when told -----------------------------
ARTICLE_IMPACTS = [e.time for e in ExactSolution(Ball(), 2.0, 0.0, 0.0, 8.0).events if e.kind.value == "impact"]


def test_model_exchange_is_right_in_a_master_that_restarts_only_when_told(unzipped3):
    """rtol 1e-8: every impact, within 1e-4 m; the restart comes from the nominals, not from values said changed."""
    run = run_model_exchange(unzipped3, t_end=8.0, output_interval=0.01, rtol=1e-8)
    h, _, impacts = exact_at(run.t)
    truth = oracle_counts(Ball())
    assert len(ARTICLE_IMPACTS) == truth.impacts
    assert run.impacts[-1] == truth.impacts
    assert np.max(np.abs(run.h - h)) <= 1e-4
    mismatched = np.flatnonzero(run.impacts != impacts)  # an impact within 1e-5 s of an output time may count there
    assert all(min(abs(run.t[i] - t) for t in ARTICLE_IMPACTS) < 1e-5 for i in mismatched)
    # h and v never jump: the FMU never says their values changed (the standard forbids it), but every
    # switch of the equations changes the nominals, so the master restarts there
    assert len(run.events) == truth.events
    assert [values for _, values, _ in run.events] == [False] * truth.events
    assert [nominals for _, _, nominals in run.events] == [True] * truth.events
    assert run.restarts == truth.events
    error, impacts = page_figure(np.max(np.abs(run.h - h))), f"{truth.impacts}/{truth.impacts}"
    assert_fmu_page_quotes(f"rtol 1e-8: {error} m, {impacts}, restarted at all {truth.events} events",
                           f"now it restarts at all {truth.events} events and gives {error} m, {impacts}")


def test_a_switch_says_the_nominals_changed_even_where_the_new_phase_has_the_same(unzipped3):
    """Weightless, k/m = 100 1/s2, R = 0.05 m, from h = 0.08 m at v = -0.5 m/s: the flight's nominals of x = h - R and
    v (max(|x|, R), max(|v|, R)) = (0.05, 0.5) are the contact's (|v| / w, |v|) = (0.05, 0.5) to the bit. The
    impact still switches the equations: a master that restarts only when told must be told there."""
    values = {"m": 1.0, "k": 100.0, "b": 0.0, "R": 0.05, "g": 0.0, "h": 0.08, "v": -0.5}
    run = run_model_exchange(unzipped3, t_end=1.0, output_interval=0.01, rtol=1e-8, start_values=values)
    assert run.nominals[0] == run.nominals[1]  # the case itself: the same nominals either side of the impact
    assert [nominals for _, _, nominals in run.events] == [True] * len(run.events) and len(run.events) == 2
    # undamped and weightless: the ball leaves at the speed it came with, and flies up at it (t = 0.06 + pi / 10)
    departure = 0.06 + np.pi / 10.0
    h_true = np.where(run.t > departure, 0.05 + 0.5 * (run.t - departure), run.h)
    assert np.max(np.abs(run.h - h_true)) < 1e-5  # measured 9.2e-8 m


def test_nominals_follow_the_phase_are_positive_and_fixed_between_events(unzipped3):
    """Flight: the apex height above R (of x = h - R) and the impact speed; contact: its amplitude and largest speed;
    each at most 1 (FMI's default nominal: FMPy's and fmusim's CVODE take atol = rtol x nominal)."""
    run = run_model_exchange(unzipped3, t_end=3.0, output_interval=0.01, rtol=1e-8)
    assert run.nominals_changed_between_events == 0
    ball = Ball()
    (h_start, v_start), (h_contact, v_contact) = run.nominals[0], run.nominals[1]
    impact_speed = np.sqrt(2 * ball.g * (2.0 - ball.R))
    assert 2.0 - ball.R > 1.0 and impact_speed > 1.0 and (h_start, v_start) == (1.0, 1.0)  # both capped
    # the first contact from the impact speed: amplitude sqrt((m g / k)^2 + (s / w)^2) < 1 m, speed w times it > 1 m/s
    w, d = np.sqrt(ball.k / ball.m), ball.m * ball.g / ball.k
    amplitude = np.hypot(d, impact_speed / w)
    assert w * amplitude > 1.0 and h_contact == pytest.approx(amplitude, rel=1e-6) and v_contact == 1.0
    assert all(0 < h <= 1 and 0 < v <= 1 for h, v in run.nominals)
    # each flight's apex falls (the ball loses energy at every bounce): its nominal too, once below 1 m
    apexes = [h for h, _ in run.nominals[2::2]]
    assert apexes[0] == 1.0 and apexes[-1] < 1.0
    assert all(later < earlier or later == earlier == 1.0 for earlier, later in zip(apexes, apexes[1:], strict=False))


def test_loose_model_exchange_is_as_accurate_as_restarting_after_every_event(unzipped3):
    """rtol 1e-4: the master's own accuracy, the same as where it restarts at every event (as FMPy does)."""
    told = run_model_exchange(unzipped3, t_end=8.0, output_interval=0.01, rtol=1e-4)
    always = run_model_exchange(unzipped3, t_end=8.0, output_interval=0.01, rtol=1e-4, restart="always")
    h, _, _ = exact_at(told.t)
    error_told, error_always = np.max(np.abs(told.h - h)), np.max(np.abs(always.h - h))
    assert error_told <= 1.01 * error_always
    assert told.restarts == always.restarts == len(told.events)
    assert_fmu_page_quotes(f"rtol 1e-4: {page_figure(error_told)} m, {told.impacts[-1]}/21, the same as restarting "
                           "after every event")
