"""The compiled engine's numba cache in the FMU: compiled at build, read at the FMU's first use of the engine.

A master unzips the FMU into a new folder, and the compiled engine's first use in its process would
compile it (about 15 s). So build-fmu compiles the engine of the FMU's copy of the package once, in
a fresh process, for any CPU of the host's architecture (solvers/engines/ahead_of_time.py), and ships numba's
cache files in the FMU's resources (SHIPPED). The slave's first use of the engine (first_use) takes
them where they fit the host (its numba, Python and architecture, the sources' digest:
solvers/engines/jit.py's cache_allowed), else numba compiles once, said in the FMU's log before it does,
into the user-wide cache that every later process reads.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import sys
from pathlib import Path

from ..solvers.engines.ahead_of_time import SHIPPED, compile_kept


def compile_cache(package: Path, into: Path) -> Path | None:
    """The FMU's copy of the package (folder package) compiled for any CPU of the host's architecture (compile_kept:
    kept in the user-wide cache, a build of the same sources before it taken; into only where that cache cannot be
    written), or None where it cannot be (no numba here: nothing said, the FMU's log says it where it runs; no
    engine: said on stderr)."""
    if importlib.util.find_spec("numba") is None:
        return None
    return compile_kept(package, into, "the FMU")


def shipped_files(cache: Path | None) -> list[tuple[Path, str]]:
    """(file, its name in the FMU) for each of numba's cache files in cache (compile_cache's), in resources/SHIPPED."""
    if cache is None:
        return []
    return [(path, f"resources/{SHIPPED}/{path.name}") for path in sorted(cache.glob("*.nb[ci]"))]


def first_use(resources: str | None, say):
    """Around the slave's integrator made with an engine that may be the compiled one: its first import in this
    process takes the code from the FMU's shipped cache, or says through say (the FMU's log) that numba compiles."""
    compiled = f"{__package__.rpartition('.')[0]}.solvers.engines.compiled"
    if importlib.util.find_spec("numba") is None or compiled in sys.modules:
        return contextlib.nullcontext()
    try:
        from ..solvers.engines import jit
    except ImportError:  # a numba that cannot be imported: the engine's choice says why
        return contextlib.nullcontext()
    shipped = os.path.join(resources, SHIPPED) if resources else None
    return jit.first_use(shipped if shipped and os.path.isdir(shipped) else None, say)
