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
                  first_use: bool = False, hunt_crossley: bool = False, c_fmu: str | None = None) -> int:
    """`bouncingball bench`: run the work-precision study (or, with stability, the stability matrix; with first_use,
    the compiled engine's first use from a wheel; with hunt_crossley, that law against DOP853; with c_fmu, the folder
    of fmusim and the Reference-FMUs' BouncingBall, our FMU beside theirs)."""
    from ..output import check_output_folder

    output_dir = check_output_folder("--output-dir", output_dir)
    if c_fmu is not None:
        from . import c_fmu as c_fmu_study

        c_fmu_study.masters(c_fmu)  # refused before any work: MastersMissing names what the folder lacks
    output_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    headline = []
    if c_fmu is not None:
        written = c_fmu_study.run(output_dir, c_fmu, quick=quick)
    elif first_use:
        from . import first_use as study

        written = study.run(output_dir, repeats=2 if quick else study.REPEATS)
    elif hunt_crossley:
        from . import hunt_crossley_study as study

        written = study.run(output_dir, quick=quick)
    elif stability:
        from .studies import run_stability_study

        written = run_stability_study(output_dir, quick=quick)
    else:
        from .studies import run_benchmark

        written, headline = run_benchmark(output_dir, quick=quick)
    for path in written:
        print(f"wrote {path}")
    report = next((path for path in written if path.suffix == ".md"), None)
    _report_fmu_warnings(report)
    if headline:
        print(f"\nheadline{' (a quick run: few tolerances and repeats)' if quick else ''}; the numbers in {report}:")
        for target in headline:
            print(f"  ({target.tag}) {'met    ' if target.met else 'NOT MET'}  {target.goal}")
    print(f"bench finished in {time.perf_counter() - started:.0f} s", file=sys.stderr)
    return 0


def _report_fmu_warnings(report: Path | None) -> None:
    """The FMU runs' warnings as one line here, their text at the end of the report (the runs loosen rtol past
    the promise on purpose, to measure the error it gives: each such run's FMU says so once)."""
    from .runners import FMU_WARNINGS

    if not FMU_WARNINGS:
        return
    expected = sum("past the promise" in message for message in FMU_WARNINGS)
    where = f"their text at the end of {report}" if report is not None else "not kept"
    print(f"bench: the FMU runs logged {len(FMU_WARNINGS)} warning(s), {expected} of them the accuracy warning "
          f"of an rtol loosened on purpose (expected); {where}", file=sys.stderr)
    if report is not None:
        lines = ["", "## Warnings the FMU logged", "",
                 "Each run whose rtol is looser than the FMU's default logs once that its error estimate passes "
                 "the promise: expected in a work-precision sweep, which measures that error.", "",
                 *(f"- {message}" for message in FMU_WARNINGS), ""]
        with report.open("a", encoding="utf-8") as file:
            file.write("\n".join(lines))
    unexpected = [message for message in FMU_WARNINGS if "past the promise" not in message]
    for message in unexpected[:3]:
        print(f"bench: warning: {message}", file=sys.stderr)
