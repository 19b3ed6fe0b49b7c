"""One run of the sweep, measured in a capped child process: the Dask task that runs a batch of them.

Each worker thread runs its batches' runs one after another through capped.run_capped (one
long-lived child per thread, killed past the cap), so a run that hangs or crashes becomes a row.
"""

from __future__ import annotations

import functools
import math
import os
import socket

from ..accuracy import event_mismatches, reference_event_mismatches
from ..bench import runners
from ..bench.hunt_crossley_study import REFERENCE_ATOL, REFERENCE_RTOL, against
from ..capped import FINISHED, run_capped
from ..contact_laws import LAWS
from ..solvers.phase_machine.settings import DEFAULT_RTOL, merged_hop_limit
from .grid import Cell, cell_of, solver_spec, tolerances

DEFAULT_TIME_CAP = 2.0  # s per run
WORKER_NAME = f"{socket.gethostname()}:{os.getpid()}"
MEASURES = {"events_found": -1, "events_exact": -1, "event_mismatches": -1, "first_mismatch": "",
            "max_height_error": math.nan, "max_event_time_error": math.nan, "wall_time": math.nan, "rhs_calls": -1,
            "steps": -1}
HEIGHT_TOLERANCE = 1e-6  # m: an event must be within the time the ball takes to move this far


def measure(spec: dict) -> dict:
    """Run one (cell, solver) and compare it with the exact solution on the run's own output grid.

    The only place the sweep calls the bench's runner and the comparison with the exact solution. The
    Hunt-Crossley law has none: its runs are compared with the cell's reference run (reference_run), the
    events_exact and the event times being the reference's.

    Parameters
    ----------
    spec : dict
        A run from Grid.runs(): k, zeta (or alpha), m, h0, t_end, output_interval, solver and contact.

    Returns
    -------
    dict
        status "finished" with events_found, events_exact, event_mismatches (events missing,
        extra or off in time beyond what accuracy.event_mismatches allows: hops below
        cvode.merged_hop_limit may be merged into the contact) and the first of them, max_height_error [m],
        max_event_time_error [s], wall_time [s], rhs_calls and steps; or status "failed" with the
        reason (the error's first line).

    Examples
    --------
    >>> row = measure({"k": 1e4, "zeta": 0.05, "m": 1.0, "h0": 2.0, "t_end": 2.0, "output_interval": 1e-3,
    ...                "solver": "cvode"})
    >>> row["status"], row["events_found"], row["max_height_error"] < 1e-6
    ('finished', 4, True)
    """
    try:
        cell = cell_of(spec)
        scene = cell.scene(spec["t_end"], spec["output_interval"])
        run = runners.run_solver(solver_spec(spec["solver"]), scene, scene.output_interval,
                                 *tolerances(spec["solver"]))
        rtol, atol = tolerances(spec["solver"])
        min_hop = merged_hop_limit(scene.ball, rtol or DEFAULT_RTOL, atol, scene.F_ext)
        if not LAWS[cell.contact].closed_form:  # no exact solution: the reference run judges
            reference = reference_run(cell, scene.t_end, scene.output_interval)
            errors = against(reference)(scene, run)
            mismatches = reference_event_mismatches(run.events, reference.events, scene.ball, scene.h0, scene.v0,
                                                    scene.t_end, HEIGHT_TOLERANCE, min_hop, scene.F_ext)
        else:
            exact, errors = runners.exact_and_errors(scene, run)
            mismatches = event_mismatches(run.events, exact.solution, HEIGHT_TOLERANCE, min_hop)
    except Exception as error:  # a failed run is a row of the map, not a crash of the sweep
        reason = f"{type(error).__name__}: {error}".splitlines()[0][:300]
        return {"status": "failed", "reason": reason, **MEASURES}
    return {"status": "finished", "reason": "", "events_found": errors.events_found,
            "events_exact": errors.events_exact, "event_mismatches": len(mismatches),
            "first_mismatch": mismatches[0] if mismatches else "", "max_height_error": errors.max_height_error,
            "max_event_time_error": errors.max_event_time_error, "wall_time": run.wall_time,
            "rhs_calls": -1 if run.rhs_calls is None else int(run.rhs_calls), "steps": int(run.steps)}


@functools.lru_cache(maxsize=4)
def reference_run(cell: Cell, t_end: float, output_interval: float) -> runners.Run:
    """A Hunt-Crossley cell's truth: the compiled engine at REFERENCE_RTOL, REFERENCE_ATOL, on the same output grid [s].

    bench --hunt-crossley's reference (tests/test_hunt_crossley.py and tests/test_sweep.py hold it to the mpmath
    truth). Kept for the cell's next solvers: a batch runs a cell's solvers one after another in one child.
    """
    return runners.run_solver(runners.CVODE_COMPILED, cell.scene(t_end, output_interval), output_interval,
                              REFERENCE_RTOL, REFERENCE_ATOL)


def run_batch(specs: list[dict], time_cap: float) -> list[dict]:
    """Each spec's row, measured in this thread's capped child under time_cap [s] (a Dask task; never raises).

    The child loads both engines before its first run (runners.warm_up), untimed; what a run prints
    is discarded.
    """
    rows = []
    for spec in specs:
        capped = run_capped(measure, (spec,), time_cap, warm_up=runners.warm_up, quiet=True)
        measured = capped.value if capped.status == FINISHED else \
            {"status": capped.status, "reason": capped.note, **MEASURES}
        rows.append({**spec, **measured, "worker": WORKER_NAME})
    return rows


def noop(x):
    """A task that does nothing: its round trip is the overhead Dask adds to a task."""
    return x
