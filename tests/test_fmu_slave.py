"""The FMU's slave in-process (fmu.documentation._Host, the slave as the FMU runs it, without an FMI library): each
output read by its own getter, the outputs before initialisation from the start values without an integrator, and
the integrator's warnings in the master's log without touching the host's warnings filters.

Expected values are the contact laws' forces written out here and the integrator's own state at t0.
"""

from __future__ import annotations

import math
import warnings

import pytest

from bouncingball.fmu import slave_base
from bouncingball.fmu.documentation import _Host, _Status
from bouncingball.fmu.variables import OUTPUTS
from bouncingball.physics import Mode
from bouncingball.scenes import load_scene
from bouncingball.solvers.cvode import SolverError
from bouncingball.solvers.engines import sundials_log


def _slave(**values) -> _Host:
    slave = _Host(stop_at_event=False)
    for name, value in values.items():
        slave.setters[name](value)
    slave.setup_experiment(0.0)
    return slave


def _start_outputs(slave: _Host) -> tuple[float, bool, float]:
    return slave.getters["a"](), slave.getters["contact"](), slave.getters["contact_force"]()


def test_each_output_is_read_by_its_getter():
    """The table pairs every output and nothing else; after a run each reads the integrator's own quantity."""
    slave = _slave()
    assert sorted(slave._output_getters()) == sorted(OUTPUTS)
    slave.exit_initialization_mode()
    for i in range(64):  # to 0.64 s, in the first contact (0.6277 to 0.659 s)
        assert slave.do_step(i * 0.01, 0.01), slave.errors()
    integrator = slave._integrator
    assert integrator.mode == Mode.CONTACT and integrator.impacts == 1  # in contact: every output non-trivial
    expected = {"h": integrator.h, "v": integrator.v, "a": integrator.acceleration, "contact": True,
                "contact_force": integrator.contact_force, "impacts": 1,
                "error_estimate": integrator.error_estimate}  # with the contact so far (run_estimate)
    assert {name: slave.getters[name]() for name in OUTPUTS} == expected
    assert expected["contact_force"] > 0.0 and expected["a"] > 0.0


# (start values, a [m/s2], contact, contact force [N]) written out from each law's force, m = 1 kg, g = 9.81 m/s2,
# R = 0.06 m, k = 1e4 N/m, b = 10 N.s/m unless set
START_CASES = [
    (dict(h=1.0, v=0.0), -9.81, False, 0.0),
    (dict(h=1.0, v=-3.0, F_ext=2.0), -7.81, False, 0.0),
    (dict(h=0.05, v=-1.0), (1e4 * 0.01 + 10.0 - 9.81), True, 1e4 * 0.01 + 10.0),
    (dict(h=0.06, v=-1.0), 10.0 - 9.81, True, 10.0),  # at R moving down: in contact
    (dict(h=0.05, v=-1.0, m=2.0), (1e4 * 0.01 + 10.0 - 2.0 * 9.81) / 2.0, True, 1e4 * 0.01 + 10.0),
    (dict(h=0.05, v=-1.0, contact_law="linear-no-pull"), (1e4 * 0.01 + 10.0 - 9.81), True, 1e4 * 0.01 + 10.0),
    # no-pull, rising fast below R: k (R - h) - b v = 100 - 200 < 0, free (a parabola), no force
    (dict(h=0.05, v=20.0, contact_law="linear-no-pull"), -9.81, False, 0.0),
    (dict(h=0.06, v=0.0, contact_law="rigid"), 0.0, True, 9.81),  # resting on R, carrying its weight
    (dict(h=0.06, v=0.0, F_ext=12.0, contact_law="rigid"), 12.0 - 9.81, False, 0.0),  # lifted off
    # Hunt-Crossley: k delta^n (1 + 3/2 alpha delta'), delta = 0.01 m, delta' = 1 m/s
    (dict(h=0.05, v=-1.0, contact_law="hunt-crossley", alpha=0.2),
     1e4 * 0.01 ** 1.5 * 1.3 - 9.81, True, 1e4 * 0.01 ** 1.5 * 1.3),
]


@pytest.mark.parametrize(("values", "a", "contact", "force"), START_CASES)
def test_outputs_before_initialisation_are_the_start_states_without_an_integrator(monkeypatch, values, a, contact,
                                                                                   force):
    """a, contact and contact_force of the start state, no integrator made for them; the integrator made at
    initialisation then says the same at t0."""
    slave = _slave(**values)

    def refused(*args, **kwargs):
        raise AssertionError("an integrator was made before initialisation")

    with monkeypatch.context() as patched:
        patched.setattr(slave_base, "BallIntegrator", refused)
        got = _start_outputs(slave)
    assert got[1] is contact
    assert got[0] == pytest.approx(a, rel=1e-14, abs=1e-14) and got[2] == pytest.approx(force, rel=1e-14, abs=1e-14)
    slave.exit_initialization_mode()
    assert slave.errors() == [] and slave._integrator.t == 0.0
    after = _start_outputs(slave)
    if values.get("contact_law") == "hunt-crossley":  # its force from h = R + (h - R), rounded: to an ulp or so
        assert after[1] is contact and after[0] == pytest.approx(got[0], rel=1e-15)
        assert after[2] == pytest.approx(got[2], rel=1e-15)
    else:
        assert after == got


@pytest.mark.parametrize("values", [dict(m=-1.0), dict(h=math.nan), dict(h=0.05, contact_law="rigid"),
                                    dict(contact_law="stiff"), dict(atol=1e-300), dict(rtol=2.0)])
def test_outputs_before_initialisation_of_a_value_initialisation_refuses_are_not_numbers(values):
    slave = _slave(**values)
    a, contact, force = _start_outputs(slave)
    assert math.isnan(a) and contact is False and math.isnan(force)
    slave.exit_initialization_mode()
    assert len(slave.errors()) == 1 and slave._integrator is None  # refused there, naming the value


def test_an_accuracy_warning_reaches_the_log_once_and_the_hosts_filters_are_not_touched(capfd):
    """The article at rtol 1e-3, looser than the promise's: its AccuracyWarning logged once with status warning,
    though the host turns every warning into an error; nothing on stderr, the host's filters as they were."""
    scene = load_scene("article")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        filters, show = warnings.filters, warnings.showwarning
        slave = _slave(rtol=1e-3)
        slave.exit_initialization_mode()
        steps = round(scene.t_end / 0.01)
        assert all(slave.do_step(i * 0.01, 0.01) for i in range(steps)), slave.errors()
        assert warnings.filters is filters and warnings.showwarning is show
    said = [(status, message) for status, message in slave.messages if status != _Status.ok]
    assert len(said) == 1 and said[0][0] == _Status.warning, said
    assert "past the promise of 1e-06 from t = " in said[0][1] and "rtol = 0.001 is looser" in said[0][1]
    assert slave._warnings == [] and capfd.readouterr().err == ""


def test_sundials_warnings_reach_the_log_in_order_and_a_failed_step_says_them_before_its_error(monkeypatch):
    """Each read of a solver's warnings file finds a new one (made here): each logged once, in order, after the
    call; where the step then fails, they come before its error."""
    made = []

    def new_messages(self):
        made.append(f"CVode: warning {len(made)} made by the test")
        return made[-1:]

    monkeypatch.setattr(sundials_log.SundialsLog, "new_messages", new_messages)
    slave = _slave()
    slave.exit_initialization_mode()
    for i in range(100):
        assert slave.do_step(i * 0.01, 0.01), slave.errors()
    assert len(made) >= 5
    assert slave.messages == [(_Status.warning, f"SUNDIALS {message}") for message in made]
    made.clear()
    del slave.messages[:]
    integrator = slave._integrator

    def failing(*args):
        integrator._unreported = integrator._logs  # what a CVODE call leaves to read: both solvers' files here
        raise SolverError("CVODE failed (made by the test)")

    monkeypatch.setattr(integrator, "_advance", failing)
    assert not slave.do_step(1.0, 1.0)  # beyond CVODE's last step: _advance runs
    assert len(made) == 2
    assert slave.messages == [*((_Status.warning, f"SUNDIALS {message}") for message in made),
                              (_Status.error, "CVODE failed (made by the test)")]
