"""Writes tests/data/saved_fmu_states.json: FMU states saved by a version of bouncingball, and the steps after them.

For each contact law the FMU's slave (in-process, fmu.documentation._Host) runs the article's drop (h = 2 m,
v = 0, the FMU's defaults but the law) in 10 ms steps to t = 0.64 s, saves its state (fmi2GetFMUstate's,
serialized as pythonfmu serializes it), then steps on to t = 1.04 s, recording (h, v) after each step.
tests/test_saved_fmu_states.py restores each state in this version's slave and requires the same steps bit for
bit: a state saved before a change loads after it.

Written at b7244be (before issue 41's refactor): ``cd /tmp && PYTHONPATH=<b7244be checkout>/src python
<this file> <out.json>``.
"""

from __future__ import annotations

import json
import sys

LAWS = ("linear", "rigid", "linear-no-pull", "hunt-crossley")
STEP, SAVED_AFTER, STEPS_AFTER = 0.01, 64, 40


def host(values: dict):
    """A slave set up with values, its experiment started at 0 s."""
    from bouncingball.fmu.documentation import _Host

    slave = _Host(stop_at_event=False)
    for name, value in values.items():
        slave.setters[name](value)
    slave.setup_experiment(0.0)
    slave.exit_initialization_mode()
    return slave


def steps(slave, first: int, count: int) -> list[tuple[str, str]]:
    """(h, v) as repr after each of count steps of STEP from step number first."""
    out = []
    for i in range(first, first + count):
        assert slave.do_step(i * STEP, STEP), slave.errors()
        out.append((repr(slave.getters["h"]()), repr(slave.getters["v"]())))
    return out


def main(path: str) -> None:
    saved = {}
    for law in LAWS:
        values = {"h": 2.0, "v": 0.0, "contact_law": law}
        slave = host(values)
        steps(slave, 0, SAVED_AFTER)
        state = json.dumps(slave._get_fmu_state())  # as pythonfmu serializes it
        saved[law] = {"start_values": values, "state": state,
                      "after": steps(slave, SAVED_AFTER, STEPS_AFTER)}
    with open(path, "w", encoding="utf-8") as file:
        json.dump(saved, file, indent=1)


if __name__ == "__main__":
    main(sys.argv[1])
