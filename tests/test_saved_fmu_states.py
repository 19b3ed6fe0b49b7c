"""FMU states saved by bouncingball at b7244be (before issue 41's refactor) load in this version and continue bit
for bit; a state of another format is refused by its name. The states and the steps after them were written by
tests/saved_fmu_states.py at b7244be."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bouncingball.fmu import slave_base
from bouncingball.fmu.variables import MODEL_NAME
from saved_fmu_states import SAVED_AFTER, STEPS_AFTER, host, steps

SAVED = json.loads((Path(__file__).parent / "data" / "saved_fmu_states.json").read_text(encoding="utf-8"))


@pytest.mark.parametrize("law", sorted(SAVED))
def test_a_state_saved_before_the_refactor_continues_bit_for_bit(law):
    saved = SAVED[law]
    slave = host(saved["start_values"])  # a fresh instance, as a master restoring into another one
    slave._set_fmu_state(slave._fmu_state_from_bytes(saved["state"].encode("utf-8")))
    assert slave.errors() == []
    assert steps(slave, SAVED_AFTER, STEPS_AFTER) == [tuple(row) for row in saved["after"]]


def test_a_state_of_another_format_is_refused_by_its_name_and_changes_nothing():
    saved = SAVED["linear"]
    slave = host(saved["start_values"])
    slave.modelName = MODEL_NAME  # what pythonfmu gives the slave, and its refusal names
    before = steps(slave, 0, 3)
    state = json.loads(saved["state"])
    state["format"] = "bouncingball-fmu-state-7"
    slave._set_fmu_state(state)
    assert len(slave.errors()) == 1 and slave_base.STATE_FORMAT in slave.errors()[0]
    fresh = host(saved["start_values"])
    assert steps(fresh, 0, 3) == before and steps(slave, 3, 2) == steps(fresh, 3, 2)


def test_a_state_saved_before_a_contact_parameter_existed_takes_its_default():
    """A state of an FMU that had not yet the parameter n (as if saved before the Hunt-Crossley law came): the
    parameter takes its default, which the state's law does not read, and the run continues bit for bit."""
    saved = SAVED["linear"]
    state = json.loads(saved["state"])
    del state["values"]["n"]
    slave = host(saved["start_values"])
    slave._set_fmu_state(state)
    assert slave.errors() == []
    assert steps(slave, SAVED_AFTER, STEPS_AFTER) == [tuple(row) for row in saved["after"]]
