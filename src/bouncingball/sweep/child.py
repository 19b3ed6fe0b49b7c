"""The child process of a CappedRunner: one run per JSON line on stdin, one result line on stdout.

Run as `python -m bouncingball.sweep.child`. It exits when its stdin closes (its worker is gone).
"""

from __future__ import annotations

import json
import os
import sys

from ..accuracy import event_mismatches
from ..bench import runners
from ..solvers.settings import DEFAULT_RTOL, merged_hop_limit
from .capped import MEASURES
from .grid import Cell, solver_spec, tolerances

HEIGHT_TOLERANCE = 1e-6  # m: an event must be within the time the ball takes to move this far


def measure(spec: dict) -> dict:
    """Run one (cell, solver) and compare it with the exact solution on the run's own output grid.

    The only place the sweep calls the bench's runner and the comparison with the exact solution.

    Parameters
    ----------
    spec : dict
        A run from Grid.runs(): k, zeta, m, h0, t_end, output_interval and solver.

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
        scene = Cell(spec["k"], spec["zeta"], spec["m"], spec["h0"]).scene(spec["t_end"], spec["output_interval"])
        run = runners.run_solver(solver_spec(spec["solver"]), scene, scene.output_interval,
                                 *tolerances(spec["solver"]))
        exact, errors = runners.exact_and_errors(scene, run)
        rtol, atol = tolerances(spec["solver"])
        mismatches = event_mismatches(run.events, exact.solution, HEIGHT_TOLERANCE,
                                      merged_hop_limit(scene.ball, rtol or DEFAULT_RTOL, atol, scene.F_ext))
    except Exception as error:  # a failed run is a row of the map, not a crash of the sweep
        reason = f"{type(error).__name__}: {error}".splitlines()[0][:300]
        return {"status": "failed", "reason": reason, **MEASURES}
    return {"status": "finished", "reason": "", "events_found": errors.events_found,
            "events_exact": errors.events_exact, "event_mismatches": len(mismatches),
            "first_mismatch": mismatches[0] if mismatches else "", "max_height_error": errors.max_height_error,
            "max_event_time_error": errors.max_event_time_error, "wall_time": run.wall_time,
            "rhs_calls": -1 if run.rhs_calls is None else int(run.rhs_calls), "steps": int(run.steps)}


def _die_with_parent() -> None:
    """On Linux, be killed when the worker that started us dies (else a long run would outlive it)."""
    parent = int(os.environ.get("BOUNCINGBALL_SWEEP_PARENT", "0"))
    if sys.platform.startswith("linux"):
        import ctypes
        import signal

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if parent and os.getppid() != parent:  # the parent died before prctl
        sys.exit(0)


def main() -> None:
    _die_with_parent()
    # Our answers go to the original stdout; anything else printed to fd 1 (a C library's warning)
    # goes to stderr instead, so that it cannot corrupt the protocol.
    answers = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    import bouncingball
    from bouncingball.solvers.engines import choose_engine

    # Load the CVODE engines before the first cap starts: this process runs many (engine "auto" then
    # takes the compiled one, where it runs, for every run).
    choose_engine("auto")
    bouncingball.simulate(bouncingball.Ball(), 2.0, 0.0, 0.5)
    print("ready", file=answers)
    for line in sys.stdin:
        if line.strip():
            print(json.dumps(measure(json.loads(line))), file=answers)


if __name__ == "__main__":
    main()
