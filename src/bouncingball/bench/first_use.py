"""The compiled engine's first use as a user meets it: `bouncingball bench --first-use` writes first_use.md.

A wheel built from this checkout (`pip wheel`, which compiles the engine's code into it), installed
with its [fast] and [fmu] extras in a fresh virtual environment; then, each in a fresh process with
an empty user-wide cache (its own XDG_CACHE_HOME): the first `simulate(engine="compiled")` of the
article, and the FMU that venv's `build-fmu` makes, unzipped afresh, run by FMPy's `simulate_fmu`
over its first 1 s with its default engine (auto: the compiled one, its native library). Each
case is timed from the process's start (the interpreter and every import included) and, within the
process, the call alone; REPEATS processes per case, interleaved.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

from ..output import atomic_write
from ..solvers.engines.ahead_of_time import NATIVE_LIBRARY
from .environment import environment, environment_lines
from .text import table

REPEATS = 5
PAGE = "first_use.md"
PROJECT = Path(__file__).resolve().parents[3]  # the checkout: pyproject.toml, src/bouncingball/bench/first_use.py

_SIMULATE = r"""
import json, time
started = time.perf_counter()
import bouncingball as bb
result = bb.simulate(bb.Ball(), 2.0, 0.0, 8.0, 1e-3, engine="compiled")
print(json.dumps({"call": time.perf_counter() - started, "engine": result.stats.engine}))
"""

_FMU = r"""
import json, sys, time
from fmpy import extract, simulate_fmu
unzipped = extract(sys.argv[1], sys.argv[2])
started = time.perf_counter()
result = simulate_fmu(unzipped, stop_time=1.0, output_interval=1e-3)
print(json.dumps({"call": time.perf_counter() - started, "h": float(result["h"][-1])}))
"""


@dataclass(frozen=True)
class Case:
    """One first use, over fresh processes [s]: each process's whole wall time and the call's own."""

    name: str
    process: list[float]
    call: list[float]
    said: str  # what the processes wrote on stderr (a compile is announced there), "" if nothing


@dataclass(frozen=True)
class Study:
    wheel_build: float  # pip wheel [s], the engine's compile included
    wheel_size: int  # [bytes]
    cache_files: int  # numba's cache files the wheel carries
    fmu_build: float  # build-fmu in the venv [s], the FMU's engine compiled included
    fmu_size: int  # [bytes]
    fmu_cache: tuple[int, int]  # the compiled engine the FMU ships (its native library, or numba's cache where that
    # could not be built): its size [bytes], as stored in the FMU (compressed)
    cases: list[Case]


def _run(command: list, cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    completed = subprocess.run([str(part) for part in command], cwd=cwd, env=env, capture_output=True, text=True,
                               timeout=900, check=False)
    if completed.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, command))} failed:\n{completed.stderr[-2000:]}")
    return completed


def measure(repeats: int = REPEATS) -> Study:
    """Build and install the wheel, then time each case's first use in repeats fresh processes, interleaved."""
    if not (PROJECT / "pyproject.toml").is_file():
        raise RuntimeError(f"bench --first-use builds a wheel from the checkout, and there is none at {PROJECT}")
    with tempfile.TemporaryDirectory(prefix="bouncingball_first_use_") as temp:
        temp = Path(temp)
        started = time.perf_counter()
        _run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", temp / "dist", PROJECT], cwd=temp)
        wheel_build = time.perf_counter() - started
        [wheel] = (temp / "dist").glob("bouncingball-*.whl")
        wheel_size = wheel.stat().st_size
        with zipfile.ZipFile(wheel) as archive:
            cache_files = sum(name.endswith((".nbi", ".nbc")) for name in archive.namelist())
        _run([sys.executable, "-m", "venv", temp / "venv"], cwd=temp)
        python = temp / "venv" / "bin" / "python"
        _run([python, "-m", "pip", "install", "--quiet", f"{wheel}[fast,fmu]"], cwd=temp)
        # an empty user-wide cache: the build compiles the FMU's engine (it keeps no compile in the user's cache)
        build_env = {**os.environ, "XDG_CACHE_HOME": str(temp / "build-cache")}
        build_env.pop("NUMBA_CACHE_DIR", None)
        started = time.perf_counter()
        _run([temp / "venv" / "bin" / "bouncingball", "build-fmu", "-o", temp / "BouncingBall.fmu"], cwd=temp,
             env=build_env)
        fmu_build = time.perf_counter() - started
        fmu_size = (temp / "BouncingBall.fmu").stat().st_size
        with zipfile.ZipFile(temp / "BouncingBall.fmu") as archive:
            shipped = [info for info in archive.infolist()
                       if info.filename.startswith(("resources/numba-cache/", f"resources/{NATIVE_LIBRARY}"))]
        fmu_cache = (sum(info.file_size for info in shipped), sum(info.compress_size for info in shipped))
        programs = {"simulate(engine=\"compiled\"), the article": [python, "-c", _SIMULATE],
                    "the FMU, simulate_fmu over 1 s": [python, "-c", _FMU, temp / "BouncingBall.fmu"]}
        runs: dict[str, list[tuple[float, float, str]]] = {name: [] for name in programs}
        for repeat in range(repeats):
            for name, command in programs.items():
                home = temp / f"cache-{repeat}-{list(programs).index(name)}"  # empty: nothing cached yet
                env = {**os.environ, "XDG_CACHE_HOME": str(home)}
                env.pop("NUMBA_CACHE_DIR", None)
                command = [*command, temp / f"unzipped-{repeat}"] if "FMU" in name else command
                started = time.perf_counter()
                completed = _run(command, cwd=temp, env=env)
                process = time.perf_counter() - started
                runs[name].append((process, json.loads(completed.stdout.splitlines()[-1])["call"],
                                   completed.stderr.strip()))
    cases = [Case(name, [r[0] for r in rows], [r[1] for r in rows], "; ".join(sorted({r[2] for r in rows if r[2]})))
             for name, rows in runs.items()]
    return Study(wheel_build, wheel_size, cache_files, fmu_build, fmu_size, fmu_cache, cases)


def write_page(study: Study, path: Path) -> Path:
    rows = [[case.name, f"{min(case.process):.2f}", f"{statistics.median(case.process):.2f}",
             f"{min(case.call):.2f}", f"{statistics.median(case.call):.2f}", case.said or "nothing"]
            for case in study.cases]
    lines = [
        "# First use",
        "",
        "Generated by `bouncingball bench --first-use --output-dir docs`.",
        "",
        *environment_lines(environment()),
        "",
        __doc__.split("\n\n", 1)[1].replace("\n", " ").strip().replace("REPEATS", str(len(study.cases[0].process))),
        "",
        f"The wheel: built in {study.wheel_build:.0f} s, the compiled engine's compile included; "
        f"{study.wheel_size / 1e6:.1f} MB with {study.cache_files} numba cache files.",
        "",
        f"The FMU: `build-fmu` in that venv took {study.fmu_build:.0f} s, the FMU's compiled engine's compile "
        f"included; the FMU is {study.fmu_size / 1e6:.1f} MB, its compiled engine {study.fmu_cache[0] / 1e6:.1f} MB "
        f"({study.fmu_cache[1] / 1e6:.1f} MB compressed).",
        "",
        *table(["first use", "process, min [s]", "process, median [s]", "call, min [s]", "call, median [s]",
                "said on stderr"], rows),
        "",
    ]
    with atomic_write(path) as temporary:
        temporary.write_text("\n".join(lines), encoding="utf-8")
    return path


def run(output_dir: Path, repeats: int = REPEATS) -> list[Path]:
    return [write_page(measure(repeats), output_dir / PAGE)]
