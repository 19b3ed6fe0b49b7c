"""What engine "auto" weighs: each engine's first use in a fresh process and its cost per CVODE step.

Each measure runs in a new Python process (the first use is a process's), `repeats` times, and
the median is kept. The page compares them with the constants choose_engine uses.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
from dataclasses import dataclass

from ..solvers import engine_selection

# One fresh process: the article once (the engine's first use), then twice more (hot).
_PROGRAM = r"""
import json, sys, time
import bouncingball as bb
ball = bb.Ball()
bb.simulate(ball, 2.0, 0.0, 0.01, solver="exact")
times, steps = [], 0
for _ in range(3):
    started = time.perf_counter()
    result = bb.simulate(ball, 2.0, 0.0, 8.0, engine=sys.argv[1])
    times.append(time.perf_counter() - started)
    steps = result.stats.steps
print(json.dumps({"first": times[0], "hot": min(times[1:]), "steps": steps}))
"""


@dataclass(frozen=True)
class FirstUse:
    """Medians over fresh processes [s]: an engine's first article run and a hot one; CVODE's steps."""

    engine: str
    first: float
    hot: float
    steps: int

    @property
    def load(self) -> float:
        """The first use's extra cost [s]: loading the engine."""
        return self.first - self.hot


REPEATS = 5


def measure(repeats: int = REPEATS) -> dict[str, FirstUse]:
    """Each engine's first use and hot run on the article, interleaved over repeats fresh processes."""
    runs: dict[str, list[dict]] = {"compiled": [], "sksundae": []}
    for _ in range(repeats):
        for engine in runs:
            completed = subprocess.run([sys.executable, "-c", _PROGRAM, engine], capture_output=True, text=True,
                                       timeout=300, check=True)
            runs[engine].append(json.loads(completed.stdout))
    return {engine: FirstUse(engine, statistics.median(r["first"] for r in rows),
                             statistics.median(r["hot"] for r in rows), rows[0]["steps"])
            for engine, rows in runs.items()}


def break_even_rows(measured: dict[str, FirstUse]) -> list[tuple[str, str, str]]:
    """(quantity, measured, used by choose_engine) for the benchmark page."""
    compiled, sksundae = measured["compiled"], measured["sksundae"]
    saving = (sksundae.hot - compiled.hot) / compiled.steps
    fresh = (compiled.load - sksundae.load) / saving
    used_fresh = ((engine_selection.COMPILED_FIRST_USE - engine_selection.SKSUNDAE_FIRST_USE)
                  / engine_selection.STEP_SAVING)
    return [
        ("compiled engine's first use [s]", f"{compiled.load:.3g}", f"{engine_selection.COMPILED_FIRST_USE:g}"),
        ("scikit-sundae engine's first use [s]", f"{sksundae.load:.3g}", f"{engine_selection.SKSUNDAE_FIRST_USE:g}"),
        ("saved per CVODE step [us]", f"{saving * 1e6:.3g}", f"{engine_selection.STEP_SAVING * 1e6:g}"),
        ("break-even in a fresh process [steps]", f"{fresh:.0f}", f"{used_fresh:.0f}"),
        ("break-even once scikit-sundae is loaded [steps]", f"{compiled.load / saving:.0f}",
         f"{engine_selection.COMPILED_FIRST_USE / engine_selection.STEP_SAVING:.0f}"),
    ]
