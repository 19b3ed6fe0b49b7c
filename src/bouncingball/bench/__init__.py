"""Benchmarks: error against run time on the article scene, and a stability matrix over extreme scenes.

`bouncingball bench` writes docs/benchmarks.md, docs/work_precision.png and the raw numbers as CSV;
`bouncingball bench --stability` writes docs/stability.md and docs/stability.csv; `bouncingball bench
--first-use` writes docs/first_use.md. SciPy, matplotlib, FMPy, pythonfmu and tqdm are imported only
inside the benchmark functions.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path


def bench_command(output_dir: str | Path = "bench-results", quick: bool = False, stability: bool = False,
                  first_use: bool = False, hunt_crossley: bool = False) -> int:
    """`bouncingball bench`: run the work-precision study (or, with stability, the stability matrix; with first_use,
    the compiled engine's first use from a wheel; with hunt_crossley, that law against DOP853)."""
    from ..output import check_output_folder

    output_dir = check_output_folder("--output-dir", output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    if first_use:
        from . import first_use as study

        written = study.run(output_dir, repeats=2 if quick else study.REPEATS)
    elif hunt_crossley:
        from . import hunt_crossley as study

        written = study.run(output_dir, quick=quick)
    elif stability:
        from .studies import run_stability_study

        written = run_stability_study(output_dir, quick=quick)
    else:
        from .studies import run_benchmark

        written = run_benchmark(output_dir, quick=quick)
    for path in written:
        print(f"wrote {path}")
    print(f"bench finished in {time.perf_counter() - started:.0f} s", file=sys.stderr)
    return 0
