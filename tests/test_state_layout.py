"""The phase machine's state (phase_machine/layout.py): one list of named fields, and what each holds makes sense.

A field written under a wrong name (a segment's start where its end belongs, a count into a time) breaks one
of the relations below between the named fields, which hold after every call of either driver, in either
engine, whatever the targets.
"""

import dataclasses
import math

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.codes import DEPARTURE, IMPACT
from bouncingball.physics import Mode
from bouncingball.solvers.integrator import BallIntegrator
from bouncingball.solvers.phase_machine import layout
from bouncingball.solvers.phase_machine.settings import CvodeSettings, hop_tolerance

COUNTS = ("IMPACTS", "DEPARTURES", "STEPS", "RHS_CALLS", "NFEV", "RS_IMPACTS", "RS_DEPARTURES", "RS_STEPS",
          "RS_RHS_CALLS")
MODES = {float(mode) for mode in Mode}  # every mode there is
FREE_LAWS = ("linear-no-pull", "hunt-crossley")  # the laws whose contact has the free sub-mode below R


def test_one_field_list_makes_every_container_and_each_field_is_declared_once():
    """The record's dtype, the dataclass and the ctypes view have the fields of the groups, in their order."""
    names = [field.name for group in layout.GROUPS.values() for field in group]
    assert len(names) == len(set(names)) == len(layout.FIELDS)
    assert list(layout.STATE_DTYPE.names) == names
    assert set(layout.STATE_DTYPE.fields.values()) == {(np.dtype(np.float64), offset) for offset in
                                                       range(0, 8 * len(names), 8)}
    assert [field.name for field in dataclasses.fields(layout.MachineState)] == names
    assert [name for name, _ in layout.StateView._fields_] == names
    assert all(field.meaning for field in layout.FIELDS)


def test_both_containers_start_alike_and_the_record_is_the_views_memory():
    interpreted, same = layout.interpreted_state()
    view, memory = layout.compiled_state()
    record = memory.view(layout.STATE_DTYPE)[0]
    assert interpreted is same
    for field in layout.FIELDS:
        for value in (getattr(interpreted, field.name), getattr(view, field.name), record[field.name]):
            assert value == field.initial or (math.isnan(field.initial) and math.isnan(value)), field.name
    assert math.isnan(view.rest_t) and math.isnan(interpreted.last_impact)  # not at rest, no impact yet
    view.rs_t, record["pend_x"] = 1.25, -3.5  # one memory: a write through either is read through the other
    assert (record["rs_t"], view.pend_x) == (1.25, -3.5)
    copy = layout.copied(view)
    copy.rs_t = 2.0
    assert view.rs_t == 1.25 and layout.copied(interpreted) is not interpreted


def relations_broken(state, ball: bb.Ball, rtol: float) -> list[str]:
    """The relations between named fields that the state breaks (an empty list: none)."""
    s = {name.upper(): float(getattr(state, name)) for name in layout.NAMES}
    broken = []

    def need(condition: bool, what: str) -> None:
        if not condition:
            broken.append(f"{what}: " + ", ".join(f"{k}={v!r}" for k, v in s.items() if k in what))

    need(s["MODE"] in MODES and s["RS_MODE"] in MODES and s["SEG_MODE"] in MODES, "MODE RS_MODE SEG_MODE")
    need(Mode.FREE not in (s["MODE"], s["RS_MODE"], s["SEG_MODE"]) or ball.contact in FREE_LAWS,
         "MODE RS_MODE SEG_MODE")
    for name in COUNTS:
        need(s[name] >= 0.0 and s[name] == math.floor(s[name]), name)
    for name in ("IMPACTS", "DEPARTURES", "STEPS", "RHS_CALLS"):
        need(s["RS_" + name] <= s[name], f"RS_{name} {name}")
    need(s["DEPARTURES"] <= s["IMPACTS"] <= s["DEPARTURES"] + 1.0, "DEPARTURES IMPACTS")  # from a drop
    # below R (pressed or free) after an impact not yet followed by its departure
    need((s["MODE"] != Mode.FLIGHT) == s["IMPACTS"] - s["DEPARTURES"], "MODE IMPACTS DEPARTURES")
    need(s["RS_T"] <= s["T"], "RS_T T")
    need(math.isnan(s["LAST_IMPACT"]) or s["RS_LAST_IMPACT"] <= s["LAST_IMPACT"] <= s["T"], "LAST_IMPACT RS_T")
    for time, low in (("T", "T_LOW"), ("RS_T", "RS_T_LOW"), ("ORIGIN", "ORIGIN_LOW"), ("PEND_T", "PEND_T_LOW")):
        need(abs(s[low]) <= np.spacing(abs(s[time])), f"{time} {low}")
    if s["NEEDS_INIT"] == 0.0:  # CVODE runs the phase from ORIGIN in the frame (LENGTH, SPEED)
        need(s["RS_T"] <= s["ORIGIN"] <= s["STEP_T"] and s["LENGTH"] > 0.0 and s["SPEED"] > 0.0,
             "RS_T ORIGIN STEP_T LENGTH SPEED")
    if s["SEGMENT"] != 0.0:  # the kept last step holds the current time
        need(s["SEG_T0"] <= s["T"] <= s["SEG_T1"], "SEG_T0 T SEG_T1")
        need(s["SEG_MODE"] == s["MODE"] or s["T"] == s["SEG_T1"], "SEG_MODE MODE")
        if s["NEEDS_INIT"] == 0.0:  # a CVODE step's: its end is the last step end
            need((s["STEP_T"], s["STEP_X"], s["STEP_V"]) == (s["SEG_T1"], s["SEG_X1"], s["SEG_V1"]),
                 "STEP_T STEP_X STEP_V SEG_T1 SEG_X1 SEG_V1")
    if s["PENDING"] != 0.0:  # an event ahead; an impact or a departure on R, leaving the mode's side
        need(s["T"] <= s["PEND_T"], "T PEND_T")
        if s["PEND_KIND"] in (IMPACT, DEPARTURE):
            need(s["PEND_V"] <= 0.0 if s["MODE"] == Mode.FLIGHT else s["PEND_V"] >= 0.0, "PEND_V MODE PEND_KIND")
    if not math.isnan(s["REST_T"]):
        need(s["MODE"] == Mode.CONTACT and s["REST_T"] <= s["T"] and s["REST_X"] < 0.0, "MODE REST_T REST_X T")
    margin = max(hop_tolerance(ball, rtol, None, 0.0), 1e3 * rtol * ball.R)
    need(s["X"] >= -margin if s["MODE"] == Mode.FLIGHT else s["X"] <= margin, "X MODE")
    # SCALE: set where the first phase ends (0 before)
    need(s["ERR_MAX"] >= 0.0 and s["ERR_X"] == s["ERR_X"] and (s["SCALE"] == 0.0 or s["SCALE"] >= ball.R),
         "ERR_MAX ERR_X SCALE")
    need(s["LOAD"] == ball.m * ball.g and s["HOP"] == hop_tolerance(ball, rtol, None, 0.0), "LOAD HOP")
    return broken


# the article's drop under the published law and under the no-pull law (free below R before each departure)
@pytest.mark.parametrize("contact", ["linear", "linear-no-pull"])
@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_the_slots_hold_what_their_names_say_after_every_call(engine, contact):
    ball, rtol = bb.Ball(contact=contact), 1e-10
    integrator = BallIntegrator(ball, 2.0, 0.0, settings=CvodeSettings(rtol=rtol, engine=engine))
    targets = np.cumsum(np.random.default_rng(1).uniform(1e-5, 2e-2, 400))
    modes = set()
    for number, target in enumerate(targets[targets < 3.0]):
        integrator.advance(float(target), stop_at_event=number % 3 == 0)
        assert relations_broken(integrator._state, ball, rtol) == [], (engine, integrator.t)
        modes.add(integrator._state.mode)
    integrator.integrate_grid(np.linspace(integrator.t, integrator.t + 2.0, 201))
    assert relations_broken(integrator._state, ball, rtol) == []
    assert integrator.impacts >= 5  # events on the way (the article: 6 impacts by 5 s)
    assert modes == ({Mode.FLIGHT, Mode.CONTACT, Mode.FREE} if contact in FREE_LAWS else {Mode.FLIGHT, Mode.CONTACT})


def test_a_wrong_slot_is_caught():
    """The check itself: a segment whose ends are swapped, and a count written into a time, are each found."""
    ball, rtol = bb.Ball(), 1e-10
    integrator = BallIntegrator(ball, 2.0, 0.0, settings=CvodeSettings(rtol=rtol, engine="sksundae"))
    integrator.advance(0.7)
    state = layout.copied(integrator._state)
    assert relations_broken(state, ball, rtol) == []
    swapped = layout.copied(state)
    swapped.seg_t0, swapped.seg_t1 = state.seg_t1, state.seg_t0
    assert relations_broken(swapped, ball, rtol) != []
    miswritten = layout.copied(state)
    miswritten.last_impact = state.impacts + 5.0  # a count where a time belongs
    assert relations_broken(miswritten, ball, rtol) != []
    for mode in (float(Mode.FREE), 3.0):  # the free sub-mode under the linear law; no mode at all
        wrong = layout.copied(state)
        wrong.seg_mode = mode
        assert any(what.startswith("MODE RS_MODE SEG_MODE") for what in relations_broken(wrong, ball, rtol))
