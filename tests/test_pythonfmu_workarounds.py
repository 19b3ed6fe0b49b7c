"""pythonfmu's reference-counting bug, shown in a plain pythonfmu slave, and none of it left in our FMUs.

pythonfmu 0.7 takes a reference from its slave script's namespace at each fmi2Instantiate that it never took
(bouncingball/fmu/pythonfmu_workarounds.py). Counted here, independently of that module: the references the
namespace's holders have to it (gc.get_referrers; a list counts each time it holds it) against its reference
count. A count below its holders' is a namespace freed while they still point at it. Each count runs in a process of
its own: the plain slave's can crash it.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

COUNT = r'''
import gc, json, sys
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave


def references_missing(module):
    """How many references module's namespace has from its holders that its reference count lacks (0: none)."""
    gc.collect()
    namespace = module.__dict__
    held = 0
    for holder in gc.get_referrers(namespace):
        if isinstance(holder, list):
            for item in holder:
                held += item is namespace
        else:
            held += 1
    return held - (sys.getrefcount(namespace) - 2)  # getrefcount's own argument, and the name namespace


folder, instances = sys.argv[1], int(sys.argv[2])
description = read_model_description(folder)
missing = []
slave = FMU3Slave if description.fmiVersion.startswith("3") else FMU2Slave
for _ in range(instances):
    fmu = slave(guid=description.guid, unzipDirectory=folder,
                modelIdentifier=description.coSimulation.modelIdentifier, instanceName="counted")
    fmu.instantiate()
    fmu.freeInstance()
    with open(folder + "/resources/slavemodule.txt") as file:
        missing.append(references_missing(sys.modules[file.read().strip()]))
print(json.dumps(missing))
'''

PLAIN_SLAVE = '''
from pythonfmu import Fmi2Slave, Real
from pythonfmu.enums import Fmi2Causality, Fmi2Variability


class PlainSlave(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.0
        self.register_variable(Real("x", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous))

    def do_step(self, current_time, step_size):
        return True
'''


def references_missing_after_each_instance(folder, instances: int) -> list[int]:
    completed = subprocess.run([sys.executable, "-c", COUNT, str(folder), str(instances)], capture_output=True,
                               text=True, timeout=300, check=False)
    assert completed.returncode == 0, completed.stdout + completed.stderr[-3000:]
    return json.loads(completed.stdout.splitlines()[-1])


def test_pythonfmu_takes_a_reference_from_a_plain_slave_script_at_each_instance(tmp_path):
    """The bug the workaround is for; where a pythonfmu release fixes it, this fails: drop the workaround then."""
    from fmpy import extract
    from pythonfmu import FmuBuilder

    script = tmp_path / "bouncingball_test_plain_slave.py"
    script.write_text(textwrap.dedent(PLAIN_SLAVE), encoding="utf-8")
    fmu = FmuBuilder.build_FMU(script, dest=tmp_path)
    assert references_missing_after_each_instance(extract(str(fmu), str(tmp_path / "plain")), 2) == [1, 2]


def test_our_fmi2_slave_script_keeps_every_reference_its_holders_count_on(unzipped):
    assert references_missing_after_each_instance(unzipped, 4) == [0, 0, 0, 0]


def test_our_fmi3_slave_script_keeps_every_reference_its_holders_count_on(unzipped3):
    pytest.importorskip("pythonfmu3")
    assert references_missing_after_each_instance(unzipped3, 4) == [0, 0, 0, 0]


def test_the_bench_empty_slave_carries_the_workaround(tmp_path):
    """It is pythonfmu's binary alone, instantiated many times in one process by the bench."""
    from fmpy import extract
    from pythonfmu import FmuBuilder

    from bouncingball.bench.runners import EMPTY_SLAVE_MODULE, EMPTY_SLAVE_SCRIPT

    script = tmp_path / f"{EMPTY_SLAVE_MODULE}.py"
    script.write_text(textwrap.dedent(EMPTY_SLAVE_SCRIPT), encoding="utf-8")
    fmu = FmuBuilder.build_FMU(script, dest=tmp_path)
    assert references_missing_after_each_instance(extract(str(fmu), str(tmp_path / "empty")), 4) == [0, 0, 0, 0]
