"""The compiled engine's numba cache in the FMU: compiled at build, read at the FMU's first use of the engine.

A master unzips the FMU into a new folder, and the compiled engine's first use in its process would
compile it (about 12 s). So build-fmu compiles the engine of the FMU's copy of the package once, in
a fresh process, and ships numba's cache files in the FMU's resources (SHIPPED). The slave's first
use of the engine (first_use) takes them where they fit the host (its numba and CPU, the sources'
digest: solvers/jit.py's cache_allowed), else numba compiles once, said in the FMU's log before it
does, into the user-wide cache that every later process reads.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

SHIPPED = "numba-cache"  # the folder of numba's cache files in the FMU's resources

# Run in a fresh process with the FMU's copy of the package on its path: every compiled entry point the FMU reaches
# (a grid run for the documentation's; advance and advance_in_step, with and without stopping at events, for doStep).
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


def compile_cache(package: Path, into: Path) -> Path | None:
    """Compile the compiled engine of the package's copy (folder package) in a fresh process, its cache in into.

    Returns the folder of numba's cache files, or None where the engine cannot be compiled here
    (no numba, or a SUNDIALS the engine cannot bind): the FMU then ships none, and compiles where it
    runs. The latter, with numba installed, is said on stderr with the reason.
    """
    if importlib.util.find_spec("numba") is None:
        return None
    environment = {**os.environ, "PYTHONPATH": str(package.parent), "NUMBA_CACHE_DIR": str(into)}
    completed = subprocess.run([sys.executable, "-c", _COMPILE, package.name], cwd=package.parent, env=environment,
                               capture_output=True, text=True, check=False)
    folders = sorted((into / "bouncingball").glob("numba-*"))
    if completed.returncode != 0 or len(folders) != 1:
        why = (completed.stderr.strip().splitlines() or [f"exit status {completed.returncode}"])[-1]
        print(f"bouncingball: the FMU ships no cache of its compiled engine, which could not be compiled here ({why}):"
              " it compiles at its first use where it runs", file=sys.stderr)
        return None
    return folders[0]


def shipped_files(cache: Path | None) -> list[tuple[Path, str]]:
    """(file, its name in the FMU) for each of numba's cache files in cache (compile_cache's), in resources/SHIPPED."""
    if cache is None:
        return []
    return [(path, f"resources/{SHIPPED}/{path.name}") for path in sorted(cache.glob("*.nb[ci]"))]


def first_use(resources: str | None, say):
    """Around the slave's integrator made with an engine that may be the compiled one: its first import in this
    process takes the code from the FMU's shipped cache, or says through say (the FMU's log) that numba compiles."""
    if importlib.util.find_spec("numba") is None or f"{__package__.rpartition('.')[0]}.solvers.compiled" in sys.modules:
        return contextlib.nullcontext()
    try:
        from ..solvers import jit
    except ImportError:  # a numba that cannot be imported: the engine's choice says why
        return contextlib.nullcontext()
    shipped = os.path.join(resources, SHIPPED) if resources else None
    return jit.first_use(shipped if shipped and os.path.isdir(shipped) else None, say)
