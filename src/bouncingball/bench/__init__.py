"""Benchmarks: error against run time on the article scene, and a stability matrix over extreme scenes.

`bouncingball bench` writes docs/benchmarks.md, docs/work_precision.png and the raw numbers as CSV;
`bouncingball bench --stability` writes docs/stability.md and docs/stability.csv. SciPy,
matplotlib, FMPy, pythonfmu and tqdm are imported only inside the benchmark functions.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path


def bench_command(output_dir: str | Path = "bench-results", quick: bool = False, stability: bool = False,
                  hunt_crossley: bool = False) -> int:
    """`bouncingball bench`: run the work-precision study (or, with stability, the stability matrix; with
    hunt_crossley, that law against DOP853)."""
    from ..output import check_output_folder

    output_dir = check_output_folder("--output-dir", output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    if hunt_crossley:
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
