"""What one fmi2DoStep costs, and what the first use of each CVODE engine costs, with the FMU driven call by call.

The FMU rows of the work-precision sweep time whole `simulate_fmu` runs, which also instantiate the
FMU and read every output at every step. Here a fresh Python process drives each FMU through FMPy's
FMU2Slave and times each doStep call: the empty pythonfmu slave (the floor any pythonfmu slave pays),
the ball as build-fmu makes it (its default engine, auto), with engine sksundae and with engine
compiled, each also with fmi2GetFMUstate taken before every step (what a master that may reject steps
does; timed with its doStep). Each case runs once untimed (the engine's first use), then `repeats`
times round-robin over the cases; each run gives the mean and the median of its calls. The first use
(from loading the FMU's binary to the end of the first doStep) is timed apart, each in its own fresh
process, with a user-wide numba cache of its own: "cold" on a folder just unzipped, the cache empty
(the compiled engine's code then comes from the FMU's shipped cache), "warm" on the same folder a
second time.

The FMI 3.0 FMU is stepped the same way through FMU3Slave, against an empty pythonfmu3 slave: without
early return, and with early return allowed and event mode used (its doSteps then include one per
event; the cost is given per communication step).
"""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from .runners import FmuPaths

ENGINES = ("sksundae", "compiled")
DEFAULT = "auto"  # the ball FMU at its default engine, as build-fmu makes it
EMPTY = "empty pythonfmu slave"
EMPTY3 = "empty pythonfmu3 slave"
FMI3 = "FMI 3.0"  # the FMI 3.0 FMU's cases: (FMI3, False) without early return, (FMI3, True) with it and event mode
CHILD_TIMEOUT = 600.0  # s
RESULT_MARKER = "BOUNCINGBALL_BENCH_RESULT "

CHILD = r'''
import json, statistics, sys, time
from ctypes import byref

from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                       fmi2CallbackLoggerTYPE)
from fmpy.fmi3 import FMU3Slave
from fmpy import calloc, free
from fmpy.logging import addLoggerProxy

job = json.loads(sys.argv[1])
errors = []


def logger(environment, instance_name, status, category, message):
    if status >= 3:
        errors.append(message.decode("utf-8", "replace"))


callbacks = fmi2CallbackFunctions()
callbacks.logger = fmi2CallbackLoggerTYPE(logger)
callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
addLoggerProxy(byref(callbacks))
descriptions = {}


def logger3(environment, status, category, message):
    logger(environment, b"", status, category, message)


def start3(description, folder, early_return, name):
    """An FMI 3.0 FMU instance after initialisation, in step mode (early_return: with event mode too)."""
    fmu = FMU3Slave(guid=description.guid, unzipDirectory=folder,
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate(eventModeUsed=early_return, earlyReturnAllowed=early_return, logMessage=logger3)
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    if early_return:
        fmu.updateDiscreteStates()
        fmu.enterStepMode()
    fmu.fmi3 = True
    return fmu


def start(folder, engine, name, early_return=False):
    """An FMU instance after initialisation (engine: None for the empty slave)."""
    if folder not in descriptions:
        descriptions[folder] = read_model_description(folder)
    description = descriptions[folder]
    if description.fmiVersion.startswith("3"):
        return start3(description, folder, early_return, name)
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=folder,
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate(callbacks=callbacks)
    if engine is not None:
        [reference] = [v.valueReference for v in description.modelVariables if v.name == "engine"]
        fmu.setString([reference], [engine])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    return fmu


def steps(fmu, step, n, take_state):
    """n doSteps of step [s], each timed; with take_state, fmi2GetFMUstate before each (the previous one freed).
    Returns {"mean": the calls' total / n, "median": the median call}."""
    state = None
    t = 0.0
    clock, calls = time.perf_counter, []
    if getattr(fmu, "fmi3", False):  # FMI 3.0: an early return is followed by event mode, then the step's rest
        i = 1
        while i <= n:
            started = clock()
            needed, _, early, reached = fmu.doStep(t, i * step - t)
            calls.append(clock() - started)
            if early:
                t = reached
                if needed:
                    fmu.enterEventMode()
                    fmu.updateDiscreteStates()
                    fmu.enterStepMode()
            else:
                t, i = i * step, i + 1
        return {"mean": sum(calls) / n, "median": statistics.median(calls)}
    for i in range(1, n + 1):
        started = clock()
        if take_state:
            if state is not None:
                fmu.freeFMUstate(state)
            state = fmu.getFMUstate()
        fmu.doStep(t, i * step - t)
        calls.append(clock() - started)
        t = i * step
    if state is not None:
        fmu.freeFMUstate(state)
    return {"mean": sum(calls) / n, "median": statistics.median(calls)}


try:
    if job["mode"] == "first use":
        started = time.perf_counter()
        fmu = start(job["folder"], job["engine"], "first")
        fmu.doStep(0.0, job["step"])
        result = {"seconds": time.perf_counter() - started}
        fmu.terminate()
        fmu.freeInstance()
    else:
        cases, n = job["cases"], job["n"]
        times = {case["key"]: [] for case in cases}
        for repeat in range(1 + job["repeats"]):  # repeat 0: each engine's first use, untimed
            for case in cases:
                fmu = start(case["folder"], case["engine"], case["key"], case.get("early_return", False))
                per_call = steps(fmu, job["step"], n, case["take_state"])
                fmu.terminate()
                fmu.freeInstance()
                if repeat:
                    times[case["key"]].append(per_call)
        result = {"times": times}
except FMICallException as error:
    result = {"error": "; ".join(errors) or str(error)}
print(sys.argv[2] + json.dumps(result))  # RESULT_MARKER
'''


@dataclass(frozen=True)
class StepCost:
    """One case: slave (EMPTY, EMPTY3, FMI3, DEFAULT or the engine's name), whether a state is taken at every step,
    seconds per doStep (per communication step with early return: the FMI 3.0 FMU, early return allowed and event
    mode): each timed repeat's mean and median call."""

    slave: str
    take_state: bool
    times: tuple[float, ...] = ()  # the mean doStep [s], one per timed repeat
    note: str = ""
    early_return: bool = False
    medians: tuple[float, ...] = ()  # the median doStep [s], one per timed repeat

    @property
    def mean(self) -> float:
        """The median over the repeats of their mean doStep [s]: what a run of many doSteps pays per step."""
        return statistics.median(self.times) if self.times else math.nan

    @property
    def median(self) -> float:
        """The median over the repeats of their median doStep [s]: a typical call, its rare slow ones left out."""
        return statistics.median(self.medians) if self.medians else math.nan


@dataclass(frozen=True)
class FirstUse:
    """Loading the FMU and running its first doStep in a fresh process [s], numba's cache cold or warm."""

    engine: str
    cache: str  # "cold" or "warm"
    seconds: float = math.nan
    note: str = ""


@dataclass
class FmuStepCosts:
    step: float  # communication step [s]
    steps: int  # doSteps per timed run
    repeats: int
    costs: list[StepCost] = field(default_factory=list)
    first_use: list[FirstUse] = field(default_factory=list)
    note: str = ""  # why nothing ran

    def per_step(self, slave: str, take_state: bool = False) -> float:
        found = [c.mean for c in self.costs if (c.slave, c.take_state) == (slave, take_state)]
        return found[0] if found else math.nan

    def first(self, engine: str, cache: str) -> float:
        found = [f.seconds for f in self.first_use if (f.engine, f.cache) == (engine, cache)]
        return found[0] if found else math.nan

    def break_even(self, cache: str, take_state: bool = False) -> float:
        """doSteps after which engine compiled has paid back its longer first use (0: its first use is not longer;
        nan: never, or not measured)."""
        extra = self.first("compiled", cache) - self.first("sksundae", cache)
        saved = self.per_step("sksundae", take_state) - self.per_step("compiled", take_state)
        return max(extra, 0.0) / saved if saved > 0.0 else math.nan


def _run_child(job: dict, cache: str) -> dict:
    """The CHILD's result for job, run with the user-wide numba cache cache (NUMBA_CACHE_DIR)."""
    completed = subprocess.run([sys.executable, "-c", CHILD, json.dumps(job), RESULT_MARKER], capture_output=True,
                               text=True, timeout=CHILD_TIMEOUT, check=False,
                               env={**os.environ, "NUMBA_CACHE_DIR": cache})
    lines = [line for line in completed.stdout.splitlines() if line.startswith(RESULT_MARKER)]
    if completed.returncode != 0 or not lines:
        tail = (completed.stderr.strip().splitlines() or [f"exit status {completed.returncode}"])[-1]
        return {"error": f"the measuring process failed: {tail}"}
    return json.loads(lines[-1][len(RESULT_MARKER):])


def _engine_unavailable() -> str:
    """Why the compiled engine cannot run in this Python (so not in the FMU it runs either), or ""."""
    from ..solvers.engine_selection import choose_engine

    try:
        choose_engine("compiled")
    except ImportError as error:
        return str(error)
    return ""


def measure(fmus: FmuPaths, step: float, t_end: float, repeats: int) -> FmuStepCosts:
    """The six per-doStep costs and the first uses (cold and warm) of both engines, the FMU at its defaults."""
    n = round(t_end / step)
    result = FmuStepCosts(step, n, repeats)
    if fmus.error or fmus.ball_fmu is None:
        result.note = f"the FMUs could not be built: {fmus.error or 'no .fmu file'}"
        return result
    from fmpy import extract

    unavailable = {"sksundae": "", "compiled": _engine_unavailable()}
    with tempfile.TemporaryDirectory(prefix="bouncingball_fmu_steps_") as temp:
        cache = str(Path(temp) / "numba")
        for engine in ENGINES:
            folder = str(extract(str(fmus.ball_fmu), str(Path(temp) / engine)))
            for state in ("cold", "warm"):  # the same folder and cache: the second process finds the first's
                if unavailable[engine]:
                    result.first_use.append(FirstUse(engine, state, note=unavailable[engine]))
                    continue
                found = _run_child({"mode": "first use", "folder": folder, "engine": engine, "step": step}, cache)
                result.first_use.append(FirstUse(engine, state, found.get("seconds", math.nan),
                                                 found.get("error", "")))
        cases = _cases(fmus)
        runnable = [case for case in cases if not unavailable.get(case["slave"])]
        found = _run_child({"mode": "steps", "cases": runnable, "n": n, "step": step, "repeats": repeats}, cache)
    for case in cases:
        note = unavailable.get(case["slave"]) or found.get("error", "")
        per_call = () if note else found["times"][case["key"]]
        result.costs.append(StepCost(case["slave"], case["take_state"], tuple(c["mean"] for c in per_call), note,
                                     case.get("early_return", False), tuple(c["median"] for c in per_call)))
    return result


def _cases(fmus: FmuPaths) -> list[dict]:
    """The CHILD's step cases: each FMU at each engine and state, the FMI 3.0 FMU at its default engine."""
    cases = [{"key": f"{slave}|{take_state}", "slave": slave, "take_state": take_state,
              "folder": str(fmus.empty if slave == EMPTY else fmus.ball),
              "engine": None if slave in (EMPTY, DEFAULT) else slave}
             for slave in (EMPTY, DEFAULT, *ENGINES) for take_state in (False, True)]
    if fmus.ball3 is not None and fmus.empty3 is not None:
        cases.append({"key": EMPTY3, "slave": EMPTY3, "take_state": False, "folder": str(fmus.empty3), "engine": None})
        cases += [{"key": f"{FMI3}|{early}", "slave": FMI3, "take_state": False, "early_return": early,
                   "folder": str(fmus.ball3), "engine": None} for early in (False, True)]
    return cases
