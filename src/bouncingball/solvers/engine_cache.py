"""The compiled engine's code compiled ahead, for any CPU of its architecture: made at a build, read at first use.

numba compiles the compiled engine at its first use in a process with an empty cache: about 15 s.
So a wheel's build (the build backend, src/bouncingball_build.py) and an FMU's (fmu/build.py) run
``compile_portable``: the engine compiled once in a fresh process for numba's generic CPU of the
host's architecture (``PORTABLE_CPU``, the baseline instruction set, which every CPU of that
architecture runs), its numba cache files shipped with the package (``SHIPPED`` inside it) or in
the FMU's resources. At the engine's first use, solvers/jit.py's ``cache_allowed`` copies them into
the user-wide cache where they fit (this numba, Python and architecture, the sources' digest), else
numba compiles for the host, saying so before it does.

``python -m bouncingball.solvers.engine_cache`` compiles the package it is run from and puts the
files in its SHIPPED folder (what the wheel's build runs in the package it built). Imports neither
numba nor the engine: the compile runs in a child process.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

SHIPPED = "numba-cache"  # the folder of the shipped cache files: inside the package (a wheel), in an FMU's resources
PORTABLE_CPU = "generic"  # numba's name (NUMBA_CPU_NAME) of its architecture's baseline CPU

# Run in a fresh process with the package's copy on its path: every compiled entry point a run reaches (a grid run;
# advance and advance_in_step, with and without stopping at events, for the stepping API and an FMU's doStep).
_COMPILE = """
import importlib, sys
package = importlib.import_module(sys.argv[1])
cvode = importlib.import_module(sys.argv[1] + ".solvers.cvode")
package.simulate(package.Ball(), 2.0, 0.0, 1.0, 1e-3, engine="compiled")
settings = cvode.CvodeSettings(engine="compiled")
for stop_at_event in (False, True):
    integrator = cvode.BallIntegrator(package.Ball(), 2.0, 0.0, 0.0, 0.0, settings)
    for i in range(1, 1001):
        if not integrator.advance_within_step(i * 1e-3):
            integrator.advance(i * 1e-3, stop_at_event=stop_at_event)
"""


def say_on_stderr(message: str) -> None:
    """Say message on stderr, as the package's own (what the compiled engine's first use says before compiling)."""
    print(f"bouncingball: {message}", file=sys.stderr, flush=True)


def compile_portable(package: Path, into: Path, shipped_by: str) -> Path | None:
    """Compile the compiled engine of the package's copy (folder package) for PORTABLE_CPU, its cache in into.

    Runs in a fresh process. Returns the folder of numba's cache files, or None where the engine
    cannot be compiled here (no numba, or a SUNDIALS the engine cannot bind), which is said on
    stderr with the reason: what shipped_by (a wheel, the FMU) then ships has no compiled code,
    and the engine compiles at its first use where it runs.
    """
    environment = {key: value for key, value in os.environ.items() if key != "NUMBA_CPU_FEATURES"}
    # The package's copy first on the path the caller has (a build environment's reaches its children that way).
    path = os.pathsep.join(filter(None, (str(package.parent), os.environ.get("PYTHONPATH"))))
    environment.update(PYTHONPATH=path, PYTHONDONTWRITEBYTECODE="1", NUMBA_CACHE_DIR=str(into),
                       NUMBA_CPU_NAME=PORTABLE_CPU)
    completed = subprocess.run([sys.executable, "-c", _COMPILE, package.name], cwd=package.parent, env=environment,
                               capture_output=True, text=True, check=False)
    folders = sorted((into / "bouncingball").glob("numba-*"))
    if completed.returncode != 0 or len(folders) != 1:
        why = (completed.stderr.strip().splitlines() or [f"exit status {completed.returncode}"])[-1]
        say_on_stderr(f"{shipped_by} ships no cache of its compiled engine, which could not be compiled here ({why}):"
                      " it compiles at its first use where it runs")
        return None
    return folders[0]


PACKAGE = Path(__file__).resolve().parents[1]  # this copy of the package


def package_shipped() -> str | None:
    """The cache shipped inside this copy of the package (a wheel's), or None (a source checkout's, an FMU's copy)."""
    folder = PACKAGE / SHIPPED
    return str(folder) if folder.is_dir() else None


def main() -> int:
    """Compile this copy of the package for PORTABLE_CPU into its SHIPPED folder (a wheel's build runs it)."""
    target = PACKAGE / SHIPPED
    # A build folder kept from an earlier build holds that build's files: the engine would read them (retargeted to
    # this CPU) instead of compiling, and they would ship beside the new ones.
    shutil.rmtree(target, ignore_errors=True)
    with tempfile.TemporaryDirectory(prefix="bouncingball_numba_") as temp:
        cache = compile_portable(PACKAGE, Path(temp), "the wheel")
        if cache is None:
            return 0  # a wheel without the shipped cache still works: it compiles at first use, and says so
        target.mkdir(parents=True, exist_ok=True)
        for path in sorted(cache.glob("*.nb[ci]")):
            shutil.copyfile(path, target / path.name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
