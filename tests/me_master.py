"""A small FMI 3.0 model-exchange master that restarts its integrator only when the FMU says so.

It behaves as the Reference-FMUs' fmusim does in model exchange (FMI3MESimulation.c, FMICVode.c), written
from that behaviour, not copied: CVODE (scikit-sundae, BDF) integrates the FMU's continuous states with
its event indicators as root functions, absolute tolerances the states' nominals times the relative
tolerance, read once at the start. At a root it enters event mode, iterates fmi3UpdateDiscreteStates
and re-initialises CVODE only where the FMU reported valuesOfContinuousStatesChanged or
nominalsOfContinuousStatesChanged; otherwise CVODE carries on from its own internal step, past the
root, as such a master does. After each step without a root it calls fmi3CompletedIntegratorStep where the model
description asks for it (needsCompletedIntegratorStep), and enters event mode where the FMU asks for it.
`restart="always"` re-initialises after every event instead (as FMPy does).

    python tests/me_master.py UNZIPPED_FMU [RTOL] [always]   prints t, h, impacts at the last point
"""

from __future__ import annotations

import ctypes
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class MasterRun:
    """What the master saw: the output grid, the outputs on it, and each event's flags."""

    t: np.ndarray
    h: np.ndarray
    impacts: np.ndarray
    restarts: int = 0
    events: list[tuple[float, bool, bool]] = field(default_factory=list)  # (t, values changed, nominals changed)
    nominals: list[tuple[float, ...]] = field(default_factory=list)  # at the start and after each event
    nominals_changed_between_events: int = 0  # steps after which the nominals differed without an event
    log: list[tuple[int, str]] = field(default_factory=list)
    step_events: int = 0  # events the FMU asked for in fmi3CompletedIntegratorStep
    error_estimate: np.ndarray | None = None  # the output error_estimate on the grid


def run(unzipped: Path, t_end: float = 8.0, output_interval: float = 0.01, rtol: float = 1e-8,
        restart: str = "when told", start_values: dict[str, float | str] | None = None) -> MasterRun:
    """Simulate the unzipped FMI 3.0 FMU in model exchange to t_end; restart "when told" or "always"."""
    from fmpy import read_model_description
    from fmpy.fmi3 import FMU3Model
    from sksundae.cvode import CVODE

    description = read_model_description(str(unzipped))
    references = {v.name: v.valueReference for v in description.modelVariables}
    needs_completed_step = description.modelExchange.needsCompletedIntegratorStep
    log: list[tuple[int, str]] = []
    fmu = FMU3Model(guid=description.guid, unzipDirectory=str(unzipped),
                    modelIdentifier=description.modelExchange.modelIdentifier, instanceName="me_master")
    fmu.instantiate(logMessage=lambda env, status, category, message: log.append((status, message.decode())))
    n_x, n_z = fmu.getNumberOfContinuousStates(), fmu.getNumberOfEventIndicators()
    x, dx, z, nominals = (np.zeros(n) for n in (n_x, n_x, n_z, n_x))
    pointer = ctypes.POINTER(ctypes.c_double)
    px, pdx, pz, pn = (a.ctypes.data_as(pointer) for a in (x, dx, z, nominals))

    for name, value in (start_values or {}).items():
        if isinstance(value, str):
            fmu.setString([references[name]], [value])
        else:
            fmu.setFloat64([references[name]], [value])
    fmu.enterInitializationMode(tolerance=rtol, startTime=0.0, stopTime=t_end)
    fmu.exitInitializationMode()
    update_discrete_states(fmu)
    fmu.enterContinuousTimeMode()
    fmu.getContinuousStates(px, n_x)
    fmu.getNominalsOfContinuousStates(pn, n_x)
    atol = nominals * rtol
    seen = [tuple(nominals)]
    changed_between_events = 0

    def at(t, y):  # the FMU at CVODE's time and states
        fmu.setTime(t)
        x[:] = y
        fmu.setContinuousStates(px, n_x)

    def rates(t, y, yp):
        at(t, y)
        fmu.getContinuousStateDerivatives(pdx, n_x)
        yp[:] = dx

    def indicators(t, y, out):
        at(t, y)
        fmu.getEventIndicators(pz, n_z)
        out[:] = z

    solver = CVODE(rates, eventsfn=indicators, num_events=n_z, method="BDF", rtol=rtol, atol=atol,
                   max_num_steps=100_000)
    solver.init_step(0.0, x.copy())
    grid = np.linspace(0.0, t_end, round(t_end / output_interval) + 1)
    outputs = [references["h"], references["impacts"], references["error_estimate"]]
    rows, events, restarts, t, step_events = [], [], 0, 0.0, 0

    def record():
        rows.append((fmu.getFloat64([outputs[0]])[0], fmu.getInt32([outputs[1]])[0], fmu.getFloat64([outputs[2]])[0]))

    record()
    for target in grid[1:]:
        while t < target:
            result = solver.step(target)
            if not result.success:
                raise RuntimeError(f"CVODE failed at t = {result.t}: {result.message}")
            t, x[:] = result.t, result.y
            fmu.setTime(t)
            fmu.setContinuousStates(px, n_x)
            if result.status != 2:  # 2: CVODE returned at a root
                step_event = needs_completed_step and \
                    fmu.completedIntegratorStep(noSetFMUStatePriorToCurrentPoint=True)[0]
                if not step_event:  # the FMU asks for event mode where the step went past an event unseen
                    fmu.getNominalsOfContinuousStates(pn, n_x)
                    changed_between_events += tuple(nominals) != seen[-1]
                    continue
                step_events += 1
            fmu.enterEventMode()
            values_changed, nominals_changed = update_discrete_states(fmu)
            fmu.enterContinuousTimeMode()
            events.append((t, values_changed, nominals_changed))
            fmu.getNominalsOfContinuousStates(pn, n_x)
            seen.append(tuple(nominals))
            if values_changed or nominals_changed or restart == "always":
                fmu.getContinuousStates(px, n_x)
                solver.init_step(t, x.copy())
                restarts += 1
        record()
    fmu.terminate()
    fmu.freeInstance()
    h, impacts, estimate = (np.array(column) for column in zip(*rows, strict=True))
    return MasterRun(grid, h, impacts, restarts, events, seen, changed_between_events, log, step_events, estimate)


def update_discrete_states(fmu) -> tuple[bool, bool]:
    """Event iteration: fmi3UpdateDiscreteStates until it needs no more; whether values, nominals changed."""
    values_changed = nominals_changed = False
    while True:
        needs_update, terminate, nominals, values, _, _ = fmu.updateDiscreteStates()
        values_changed |= bool(values)
        nominals_changed |= bool(nominals)
        if terminate:
            raise RuntimeError("the FMU asked to terminate")
        if not needs_update:
            return values_changed, nominals_changed


if __name__ == "__main__":
    outcome = run(Path(sys.argv[1]), rtol=float(sys.argv[2]) if len(sys.argv) > 2 else 1e-8,
                  restart="always" if "always" in sys.argv[3:] else "when told")
    print(outcome.t[-1], outcome.h[-1], outcome.impacts[-1], f"{outcome.restarts} restarts")
