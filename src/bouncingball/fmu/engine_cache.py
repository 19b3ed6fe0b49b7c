"""The compiled engine in the FMU: compiled at build, as native code (or numba's cache), run at the FMU's start.

A master unzips the FMU into a new folder, and the compiled engine's first use in its process would
compile it (about a minute), or import numba and read its cache (about 0.7 s). So build-fmu compiles the engine of the
FMU's copy of the package once, in a fresh process, for any CPU of the host's architecture
(solvers/engines/ahead_of_time.py), and links that code into the native engine's library (native_build.py), which
the FMU ships in its resources and the slave runs without numba (``activate_native``; solvers/engines/native.py).
Where the library could not be built, the FMU ships numba's cache files instead (SHIPPED), which the slave's first
use of the engine (first_use) takes where they fit the host (its numba, Python and architecture, the sources'
digest: solvers/engines/jit.py's cache_allowed), else numba compiles once, said in the FMU's log before it does,
into the user-wide cache that every later process reads.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import sys
from pathlib import Path

from ..solvers.engines import native
from ..solvers.engines.ahead_of_time import NATIVE_LIBRARY, SHIPPED, compile_kept


def compile_cache(package: Path, into: Path, compiler: list[str]) -> Path | None:
    """The FMU's copy of the package (folder package) compiled for any CPU of the host's architecture (compile_kept:
    kept in the user-wide cache, a build of the same sources before it taken; into only where that cache cannot be
    written), with the native engine's library linked by compiler, or None where it cannot be (no numba here:
    nothing said, the FMU's log says it where it runs; no engine: said on stderr)."""
    if importlib.util.find_spec("numba") is None:
        return None
    return compile_kept(package, into, "the FMU", compiler)


def shipped_files(cache: Path | None) -> list[tuple[Path, str]]:
    """(file, its name in the FMU): the native engine's library (in resources, where the slave looks for it:
    native_library) where compile_cache built it, else numba's cache files in cache (resources/SHIPPED).

    Not both: the library runs wherever numba's cache would (the same architecture; it needs no Python, no numba),
    and numba's cache files, about 19 MB, would cost a master that unzips the FMU about 0.4 s of each start."""
    if cache is None:
        return []
    if (cache / NATIVE_LIBRARY).is_file():
        return [(cache / NATIVE_LIBRARY, f"resources/{NATIVE_LIBRARY}")]
    return [(path, f"resources/{SHIPPED}/{path.name}") for path in sorted(cache.glob("*.nb[ci]"))]


def native_library(resources: str | None) -> str | None:
    """The native engine's library the FMU ships in its resources (resources: their folder), or None."""
    path = os.path.join(resources, NATIVE_LIBRARY) if resources else None
    return path if path and os.path.isfile(path) else None


_refusal = {"reason": None, "said": False}  # why the FMU's native engine does not run here: said once per process


def activate_native(resources: str | None) -> None:
    """Run the compiled engine from the native library the FMU ships (solvers/engines/native.py) where it fits this
    host; where it does not, numba's compiled engine runs where it can, and first_use says why, once."""
    path = native_library(resources)
    reason = None if path is None else native.activate(path)
    if reason is not None and _refusal["reason"] is None:
        _refusal["reason"] = reason


def first_use(resources: str | None, say):
    """Around the slave's integrator made with an engine that may be the compiled one: its first import in this
    process takes the code from the FMU's shipped cache, or says through say (the FMU's log) that numba compiles;
    before, once, why the FMU's native engine does not run (activate_native)."""
    if _refusal["reason"] is not None and not _refusal["said"]:
        _refusal["said"] = True
        say(f"the FMU's native engine is not used: {_refusal['reason']}")
    compiled = f"{__package__.rpartition('.')[0]}.solvers.engines.compiled"
    if importlib.util.find_spec("numba") is None or compiled in sys.modules or native.active() is not None:
        return contextlib.nullcontext()
    try:
        from ..solvers.engines import jit
    except ImportError:  # a numba that cannot be imported: the engine's choice says why
        return contextlib.nullcontext()
    shipped = os.path.join(resources, SHIPPED) if resources else None
    return jit.first_use(shipped if shipped and os.path.isdir(shipped) else None, say)
