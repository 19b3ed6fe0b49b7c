"""Our FMU beside a C FMU in the Reference-FMUs' own master: `bouncingball bench --c-fmu DIR` writes c_fmu.md.

DIR holds ``fmusim`` and the Reference-FMUs' BouncingBall as ``Ref_BouncingBall_fmi2.fmu`` and
``Ref_BouncingBall_fmi3.fmu``, built from github.com/modelica/Reference-FMUs (its fmusim/ and BouncingBall/, with
its CMake). Our FMUs are built from this checkout (build-fmu, FMI 2.0 and 3.0). Every measure is a fresh fmusim
process, ours and theirs alternated, ``ROUNDS`` rounds, medians; each FMU at its own default scene (ours the
article's, theirs a rigid ball dropped from 1 m), every output recorded after every 1 ms step as fmusim does:

- start-up: a 1-step run (load, instantiate, initialise, one doStep, free), the whole process timed;
- cost per extra step: (a run of 8 s) minus the 1-step run, over its extra steps, as the goal is set; and, since a
  start-up's spread (about 0.1 s on 2 cores) is a dozen microseconds over 7999 steps, the same over ``LONG_RUN``
  [s] with both balls bouncing all along (``BOUNCING``: ours without damping, theirs with e = 1), which measures
  a step to a fraction of a microsecond;
- model exchange on their scene (``ME_SCENE``: rigid, e = 0.7, v_min = 0.1, dropped from 1 m bottom height, 3 s,
  outputs every 10 ms), fmusim's CVODE at each of ``ME_TOLERANCES``: the largest height error against the exact
  solution (their h is the ball's bottom: ours less R), and the calls of the master's integrator counted in
  fmusim's call log (derivatives and completed steps); an error within ``ME_ROUNDING`` of theirs is theirs.

The goals: start-up at most ``STARTUP_GOAL``, a step at most ``STEP_RATIO_GOAL`` times theirs, and in model
exchange an error at most theirs at each tolerance with no more calls.
"""

from __future__ import annotations

import collections
import csv
import random
import statistics
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..accuracy import exact_on_grid
from ..output import atomic_write
from ..physics import Ball
from .environment import environment, environment_lines
from .text import table

PAGE = "c_fmu.md"
# The goal asks for medians of 5; 15 narrow every figure. The 8 s figure stays wide: the 1-step run's interquartile
# range, 0.025 s, is 3 us a step over 7999 steps (ours about 2 us, theirs 0.9); its ratio came out 0.8x to 4.1x from
# page to page, which the page's interval says (_step_verdict).
ROUNDS = 15
STEP = 1e-3  # [s]
LONG_RUN = 800.0  # [s]
ARTICLE_RUN = 8.0  # [s], the goal's run
RUNS = (STEP, ARTICLE_RUN, LONG_RUN)  # stop times [s]: the 1-step run, the article, the long run (BOUNCING)
BOUNCING = {"ours": ("b", "0"), "theirs": ("e", "1")}  # start values: a ball that bounces to the end
STARTUP_GOAL = 0.5  # [s]
STEP_RATIO_GOAL = 3.0
THEIRS = {2: "Ref_BouncingBall_fmi2.fmu", 3: "Ref_BouncingBall_fmi3.fmu"}


class MastersMissing(ValueError):
    """The folder lacks fmusim or the Reference-FMUs' FMUs."""


def masters(folder: str | Path) -> tuple[Path, dict[int, Path]]:
    """fmusim and the Reference-FMUs' BouncingBall FMUs by FMI version, in folder; MastersMissing says what lacks."""
    folder = Path(folder)
    fmusim, theirs = folder / "fmusim", {version: folder / name for version, name in THEIRS.items()}
    missing = [str(path) for path in (fmusim, *theirs.values()) if not path.is_file()]
    if missing:
        raise MastersMissing(f"--c-fmu {folder}: missing {', '.join(missing)}; the folder must hold fmusim and the "
                             "Reference-FMUs' BouncingBall FMUs, built from github.com/modelica/Reference-FMUs "
                             "(fmusim/ and BouncingBall/ with its CMake)")
    return fmusim, theirs


def _fmusim(command: list[str]) -> None:
    """Run fmusim's command; RuntimeError with its end of output where it fails."""
    completed = subprocess.run(command, capture_output=True, text=True, check=False)
    if completed.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed (exit code {completed.returncode}):\n"
                           f"{(completed.stdout + completed.stderr)[-2000:]}")


def run_seconds(fmusim: Path, fmu: Path, stop_time: float, *options: str) -> float:
    """One fmusim process co-simulating fmu from 0 to stop_time at STEP, every output recorded: its wall time [s]."""
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        _fmusim([str(fmusim), "--output-interval", repr(STEP), "--stop-time", repr(stop_time), "--output-file",
                 str(Path(folder) / "out.csv"), *options, str(fmu)])
        return time.perf_counter() - started


ME_TOLERANCES = (1e-4, 1e-6, 1e-8, 1e-10)
ME_STOP, ME_INTERVAL = 3.0, 0.01  # [s]
ME_SCENE = Ball(contact="rigid", e=0.7, v_min=0.1)  # theirs; dropped from 1 m (bottom height), at rest
ME_DROP = 1.0  # [m], the bottom's height
ME_CALLS = ("fmi3GetContinuousStateDerivatives", "fmi3CompletedIntegratorStep")
# [m] An error within this of theirs is theirs: our state x = h - R is held as h (its roundings R's ulp, 6.9e-18 m)
# and our ball leaves the ground an ulp of R above it where theirs leaves at DBL_MIN, so with the same nominals
# (1, theirs; ours capped at 1) the two runs' heights differ by up to 1.8e-13 m (fmusim; 6.8e-14 m in FMPy's CVode)
# and their errors by 8e-15 m (3e-14 m). With a nominal of v of 4.43 m/s ours was 8e-13 m above theirs at 1e-10.
ME_ROUNDING = 2e-13


@dataclass(frozen=True)
class ExchangeRun:
    """One model-exchange run: the largest height error [m] and the master's integrator calls into the FMU."""

    tolerance: float
    error: float
    calls: int


def model_exchange_run(fmusim: Path, fmu: Path, tolerance: float, ours: bool) -> ExchangeRun:
    """fmusim's CVODE on ME_SCENE at tolerance: our FMU (ours) or theirs, its height error and calls counted."""
    R = ME_SCENE.R
    with tempfile.TemporaryDirectory() as folder:
        out, log = Path(folder) / "out.csv", Path(folder) / "calls.log"
        command = [str(fmusim), "--interface-type", "me", "--solver", "cvode", "--tolerance", repr(tolerance),
                   "--stop-time", repr(ME_STOP), "--output-interval", repr(ME_INTERVAL), "--log-fmi-calls",
                   "--fmi-log-file", str(log), "--output-file", str(out)]
        if ours:
            for name, value in (("contact_law", "rigid"), ("e", ME_SCENE.e), ("v_min", ME_SCENE.v_min),
                                ("h", ME_DROP + R), ("R", R)):
                command += ["--start-value", name, str(value)]
        _fmusim([*command, str(fmu)])
        with open(out, encoding="utf-8", newline="") as file:
            rows = list(csv.reader(file))
        calls = collections.Counter(line.split("(", 1)[0] for line in log.read_text(encoding="utf-8").splitlines())
    header = [name.strip('"') for name in rows[0]]
    t = [float(row[0]) for row in rows[1:]]
    h = [float(row[header.index("h")]) + (0.0 if ours else R) for row in rows[1:]]
    exact = exact_on_grid(t, ME_SCENE, ME_DROP + R, 0.0)
    return ExchangeRun(tolerance, max(abs(a - b) for a, b in zip(h, exact.h, strict=True)),
                       sum(calls[name] for name in ME_CALLS))


@dataclass(frozen=True)
class Costs:
    """One FMU's medians: start-up [s] and the cost of an extra step [s] over each longer run, with the 5% and 95%
    quantiles of that cost over resamples of the runs (INTERVAL_RESAMPLES, with replacement): its uncertainty."""

    label: str
    startup: float
    per_step: dict[float, float]  # by stop time [s]
    interval: dict[float, tuple[float, float]] = field(default_factory=dict)  # by stop time [s]


INTERVAL_RESAMPLES = 400


def _per_step(startups: list[float], runs: list[float], stop: float) -> float:
    return (statistics.median(runs) - statistics.median(startups)) / (round(stop / STEP) - 1)


def _interval(startups: list[float], runs: list[float], stop: float) -> tuple[float, float]:
    """The 5% and 95% quantiles of _per_step over resamples of both lists (a bootstrap, seeded: the same runs give the
    same interval)."""
    rng = random.Random(0)
    costs = sorted(_per_step(rng.choices(startups, k=len(startups)), rng.choices(runs, k=len(runs)), stop)
                   for _ in range(INTERVAL_RESAMPLES))
    return costs[INTERVAL_RESAMPLES // 20], costs[INTERVAL_RESAMPLES - 1 - INTERVAL_RESAMPLES // 20]


def measure(fmusim: Path, fmus: dict[str, Path], rounds: int = ROUNDS) -> list[Costs]:
    """The costs of each FMU (by label: "ours, ..." or "theirs, ..."), every run of every FMU alternated within each
    round; the long run with BOUNCING's start values."""
    times = {(label, stop): [] for label in fmus for stop in RUNS}
    for _ in range(rounds):
        for stop in RUNS:
            for label, fmu in fmus.items():
                name, value = BOUNCING[label.split(",")[0]]
                options = ("--start-value", name, value) if stop == LONG_RUN else ()
                times[label, stop].append(run_seconds(fmusim, fmu, stop, *options))
    return [Costs(label, statistics.median(times[label, STEP]),
                  {stop: _per_step(times[label, STEP], times[label, stop], stop) for stop in RUNS[1:]},
                  {stop: _interval(times[label, STEP], times[label, stop], stop) for stop in RUNS[1:]})
            for label in fmus]


def _exchange_lines(exchange: dict[str, list[ExchangeRun]]) -> tuple[list[str], list[str]]:
    """The model-exchange table and its verdicts."""
    rows, worse = [], []
    for ours, theirs in zip(exchange["ours"], exchange["theirs"], strict=True):
        rows.append([f"{ours.tolerance:.0e}", f"{ours.error:.3e}", f"{theirs.error:.3e}",
                     f"{ours.error / theirs.error:.4f}", str(ours.calls), str(theirs.calls)])
        if ours.error > theirs.error + ME_ROUNDING or ours.calls > theirs.calls:
            worse.append(f"{ours.tolerance:.0e}")
    header = ["tolerance", "ours: max height error [m]", "theirs [m]", "ours / theirs", "ours: calls",
              "theirs: calls"]
    verdict = (f"- model exchange, error at most theirs with no more calls at every tolerance: "
               f"{'met' if not worse else 'NOT MET (at ' + ', '.join(worse) + ')'}")
    return table(header, rows), [verdict]


def _step_verdict(ours: Costs, theirs: Costs, stop: float, run: str) -> str:
    """Ours against theirs at the run of stop [s]: met or not where ours' interval (if measured) is on one side of the
    goal; "not resolved" where it spans it."""
    ratio = ours.per_step[stop] / theirs.per_step[stop]
    verdict, spread = "met" if ratio <= STEP_RATIO_GOAL else "NOT MET", ""
    if stop in ours.interval:
        low, high = ours.interval[stop]
        spread = (f"; ours {ours.per_step[stop] * 1e6:.2f} us, {low * 1e6:.2f} to {high * 1e6:.2f} us over resampled "
                  "runs (5% to 95%)")
        low_ratio, high_ratio = low / theirs.per_step[stop], high / theirs.per_step[stop]
        if low_ratio <= STEP_RATIO_GOAL < high_ratio:
            verdict = f"not resolved (ours' interval is {low_ratio:.2f}x to {high_ratio:.2f}x theirs)"
        else:
            verdict = "met" if high_ratio <= STEP_RATIO_GOAL else "NOT MET"
    return f"{ratio:.2f}x theirs ({run}{spread}; goal <= {STEP_RATIO_GOAL:g}x): {verdict}"


def page(costs: list[Costs], rounds: int, environment_at_start: dict[str, str],
         exchange: dict[str, list[ExchangeRun]]) -> str:
    by_label = {cost.label: cost for cost in costs}
    rows, verdicts = [], []
    for version in (2, 3):
        ours, theirs = by_label[f"ours, FMI {version}.0"], by_label[f"theirs, FMI {version}.0"]
        for cost in (ours, theirs):
            rows.append([cost.label, f"{cost.startup:.3f}", *(f"{cost.per_step[stop] * 1e6:.2f}" for stop in RUNS[1:]),
                         *(f"{cost.per_step[stop] / theirs.per_step[stop]:.2f}" for stop in RUNS[1:])])
        verdicts.append(f"- FMI {version}.0 start-up {ours.startup:.3f} s (goal <= {STARTUP_GOAL:g} s): "
                        f"{'met' if ours.startup <= STARTUP_GOAL else 'NOT MET'}")
        for stop, run in ((ARTICLE_RUN, "8 s, the article: the goal's own run, within its start-up's spread"),
                          (LONG_RUN, f"{LONG_RUN:g} s bouncing: the same step to a fraction of a microsecond")):
            verdicts.append(f"- FMI {version}.0 cost per extra step {_step_verdict(ours, theirs, stop, run)}")
    exchange_table, exchange_verdicts = _exchange_lines(exchange)
    exchange_intro = [
        f"Model exchange (FMI 3.0), their scene: a rigid ball, e = {ME_SCENE.e:g}, v_min = {ME_SCENE.v_min:g} m/s, "
        f"dropped from {ME_DROP:g} m (its bottom), {ME_STOP:g} s, outputs every {ME_INTERVAL:g} s; fmusim's CVODE "
        "at each tolerance. The error is the largest |h - h_exact| at the outputs (the exact solution of the rigid "
        "law); the calls are the master's integrator's into the FMU (fmi3GetContinuousStateDerivatives and "
        "fmi3CompletedIntegratorStep, counted in fmusim's call log). An error within "
        f"{ME_ROUNDING:g} m of theirs counts as theirs: the rounding of our state x = h - R, held as h."]
    header = ["FMU", "start-up (1-step run) [s]", "per extra step, 8 s [us]",
              f"per extra step, {LONG_RUN:g} s bouncing [us]", "ratio to theirs, 8 s", f"ratio, {LONG_RUN:g} s"]
    lines = ["# Our FMU beside a C FMU in fmusim", "",
             "The Reference-FMUs' master, fmusim, co-simulating our FMU (the article's ball) and the Reference-FMUs' "
             "BouncingBall (C, a rigid ball, forward Euler at its own fixed step) at 1 ms steps, every output "
             "recorded after every step. Each figure is the median of fresh processes, ours and theirs alternated "
             f"({rounds} rounds); start-up is a 1-step run, a step's cost the longer run less the 1-step run, over "
             f"its extra steps (the {LONG_RUN:g} s run with both balls bouncing to its end: ours without damping, "
             "theirs with e = 1; the 8 s figure carries the start-up's spread, about 0.1 s, over only 7999 steps). "
             "Regenerate: `bouncingball bench --c-fmu DIR --output-dir docs` (DIR: fmusim and "
             f"{THEIRS[2]}, {THEIRS[3]}).", "", *table(header, rows), "", *exchange_intro, "",
             *exchange_table, "", "Goals:", "", *verdicts, *exchange_verdicts, "",
             "Machine:", "", *environment_lines(environment_at_start), ""]
    return "\n".join(lines)


def run(output_dir: Path, folder: str | Path, quick: bool = False) -> list[Path]:
    """Build our FMUs, measure them beside theirs in fmusim, write PAGE; the paths written."""
    from ..fmu.build import build_fmu

    fmusim, theirs = masters(folder)
    started_in = environment()
    with tempfile.TemporaryDirectory() as build_folder:
        fmus = {}
        for version in (2, 3):
            fmus[f"ours, FMI {version}.0"] = build_fmu(Path(build_folder) / f"BouncingBall{version}.fmu", version)
            fmus[f"theirs, FMI {version}.0"] = theirs[version]
        rounds = 2 if quick else ROUNDS
        costs = measure(fmusim, fmus, rounds)
        exchange = {who: [model_exchange_run(fmusim, fmus[f"{who}, FMI 3.0"], tolerance, who == "ours")
                          for tolerance in ME_TOLERANCES] for who in ("ours", "theirs")}
    path = output_dir / PAGE
    with atomic_write(path) as temporary:
        temporary.write_text(page(costs, rounds, started_in, exchange), encoding="utf-8")
    return [path]
