"""The compiled engine's code compiled ahead, for any CPU of its architecture: made at a build, read at first use.

numba compiles the compiled engine at its first use in a process with an empty cache: about a minute.
So a wheel's build (the build backend, src/bouncingball_build.py) and an FMU's (fmu/build.py) run
``compile_portable``: the engine compiled once in a fresh process for numba's generic CPU of the
host's architecture (``PORTABLE_CPU``, the baseline instruction set, which every CPU of that
architecture runs), its numba cache files shipped with the package (``SHIPPED`` inside it) or in
the FMU's resources. At the engine's first use, solvers/engines/jit.py's ``cache_allowed`` copies them into
the user-wide cache where they fit (this numba, Python and architecture, the sources' digest), else
numba compiles for the host, saying so before it does.

``compile_kept`` is compile_portable kept in the user-wide cache (what build-fmu runs): a second
build of the same sources, on the same Python, numba and architecture, takes the kept compile
instead of compiling again.

``python -m bouncingball.solvers.engines.ahead_of_time`` compiles the package it is run from and puts the
files in its SHIPPED folder (what the wheel's build runs in the package it built). Imports neither
numba nor the engine: the compile runs in a child process.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import importlib.metadata
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

NATIVE_LIBRARY = "bouncingball_engine.so"  # the native engine's library (solvers/engines/native_build.py's)
NATIVE_FAILURE = "native-failure.txt"  # beside numba's files where the library could not be built: why
SHIPPED = "numba-cache"  # the folder of the shipped cache files: inside the package (a wheel), in an FMU's resources
# What numba's compile of the whole engine takes, as messages say it: 47 s on a quiet 2-core machine (44 s of CPU),
# 50-62 s beside another job (measured at ea3518a; "about 15 s" once, for a smaller engine).
COMPILE_TIME = "about a minute"
PORTABLE_CPU = "generic"  # numba's name (NUMBA_CPU_NAME) of its architecture's baseline CPU

# Run in a fresh process with the package's copy on its path: every compiled entry point a run reaches (a grid run;
# advance and advance_in_step, with and without stopping at events, for the stepping API and an FMU's doStep; the
# C entry points an FMU's loader calls, compiled at their import). Given a C compiler's command (JSON), the native
# engine's library too, from the code just compiled (native_build.py), beside numba's cache files; where it cannot
# be built, why (the last line on stderr).
_COMPILE = """
import importlib, json, sys
package = importlib.import_module(sys.argv[1])
cvode = importlib.import_module(sys.argv[1] + ".solvers.cvode")
importlib.import_module(sys.argv[1] + ".solvers.engines.c_entry")
package.simulate(package.Ball(), 2.0, 0.0, 1.0, 1e-3, engine="compiled")
settings = cvode.CvodeSettings(engine="compiled")
for stop_at_event in (False, True):
    integrator = cvode.BallIntegrator(package.Ball(), 2.0, 0.0, 0.0, 0.0, settings)
    for i in range(1, 1001):
        if not integrator.advance_within_step(i * 1e-3):
            integrator.advance(i * 1e-3, stop_at_event=stop_at_event)
if len(sys.argv) > 2:
    try:
        jit = importlib.import_module(sys.argv[1] + ".solvers.engines.jit")
        native_build = importlib.import_module(sys.argv[1] + ".solvers.engines.native_build")
        digest = jit.sources_digest(jit.engine_sources())
        native_build.build(jit.cache_folder(digest), digest, json.loads(sys.argv[2]))
    except Exception as error:
        print(f"{type(error).__name__}: {error}".replace(chr(10), " "), file=sys.stderr)
"""


def say_on_stderr(message: str) -> None:
    """Say message on stderr, as the package's own (what the compiled engine's first use says before compiling)."""
    print(f"bouncingball: {message}", file=sys.stderr, flush=True)


def compile_portable(package: Path, into: Path, shipped_by: str, compiler: list[str] | None = None) -> Path | None:
    """Compile the compiled engine of the package's copy (folder package) for PORTABLE_CPU, its cache in into.

    Runs in a fresh process. Returns the folder of numba's cache files, or None where the engine
    cannot be compiled here (no numba, or a SUNDIALS the engine cannot bind), which is said on
    stderr with the reason: what shipped_by (a wheel, the FMU) then ships has no compiled code,
    and the engine compiles at its first use where it runs. With compiler (a C compiler's command), the folder
    also holds the native engine's library (NATIVE_LIBRARY), or stderr says why it does not.
    """
    environment = {key: value for key, value in os.environ.items() if key != "NUMBA_CPU_FEATURES"}
    # The package's copy first on the path the caller has (a build environment's reaches its children that way).
    path = os.pathsep.join(filter(None, (str(package.parent), os.environ.get("PYTHONPATH"))))
    environment.update(PYTHONPATH=path, PYTHONDONTWRITEBYTECODE="1", NUMBA_CACHE_DIR=str(into),
                       NUMBA_CPU_NAME=PORTABLE_CPU)
    native = [json.dumps(compiler)] if compiler else []
    completed = subprocess.run([sys.executable, "-c", _COMPILE, package.name, *native], cwd=package.parent,
                               env=environment, capture_output=True, text=True, check=False)
    folders = sorted((into / "bouncingball").glob("numba-*"))
    if completed.returncode != 0 or len(folders) != 1:
        why = (completed.stderr.strip().splitlines() or [f"exit status {completed.returncode}"])[-1]
        say_on_stderr(f"{shipped_by} ships no cache of its compiled engine, which could not be compiled here ({why}):"
                      " it compiles at its first use where it runs")
        return None
    if compiler and not (folders[0] / NATIVE_LIBRARY).is_file():
        (folders[0] / NATIVE_FAILURE).write_text((completed.stderr.strip().splitlines() or ["no message"])[-1])
        _say_no_native(folders[0], shipped_by)
    return folders[0]


def _say_no_native(cache: Path, shipped_by: str) -> None:
    """Say on stderr why the compile in cache holds no native engine (its NATIVE_FAILURE), and what follows."""
    why = (cache / NATIVE_FAILURE).read_text() if (cache / NATIVE_FAILURE).is_file() else "no message"
    say_on_stderr(f"{shipped_by} ships no native engine, which could not be built here ({why}): it runs numba's "
                  "compiled engine, which adds about 0.7 s to its start")


def user_cache_root() -> str:
    """The user-wide folder of the compiled code's caches.

    $NUMBA_CACHE_DIR/bouncingball if set, else $XDG_CACHE_HOME/bouncingball (default
    ~/.cache/bouncingball): one sub-folder numba-<digest> per set of sources (solvers/engines/jit.py's
    cache_folder), and one portable-<key> per kept compile (compile_kept).
    """
    told = os.environ.get("NUMBA_CACHE_DIR")
    if told:
        return os.path.join(told, "bouncingball")
    return os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
                        "bouncingball")


KEPT_COMPILES = 4  # compile_kept keeps the compiles of this many sets of sources, the most recently used


def compile_kept(package: Path, into: Path, shipped_by: str, compiler: list[str] | None = None) -> Path | None:
    """compile_portable, kept in the user-wide cache: the folder of numba's cache files, or None (as compile_portable).

    The compile (about a minute) is kept in user_cache_root's portable-<key>, the key a digest of all it
    depends on: the package's name and every file of it, the compiling script, this Python and its
    path, the versions of numba, llvmlite, numpy and scikit-sundae this process sees (the child runs
    the same Python, its path the same but for the package's folder first), the architecture and numba's
    settings in the environment. So a second build of the same sources takes it instead of
    compiling again; any change compiles anew. Builds at once take turns under a lock file per key;
    a compile is kept whole (renamed into place) or not at all. Where the user-wide cache cannot
    be written, compile_portable compiles into into.
    """
    root = Path(user_cache_root())
    kept = root / f"portable-{_compile_key(package, compiler)[:24]}"
    try:
        root.mkdir(parents=True, exist_ok=True)
        with open(f"{kept}.lock", "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
            if not kept.is_dir():
                with tempfile.TemporaryDirectory(dir=root, prefix=".portable-") as temp:
                    cache = compile_portable(package, Path(temp), shipped_by, compiler)
                    if cache is None:
                        return None
                    cache.rename(kept)
            elif compiler and not (kept / NATIVE_LIBRARY).is_file():  # each build says it, not only the first
                _say_no_native(kept, shipped_by)
            os.utime(kept)  # its last use, for _forget_old_compiles
    except OSError:  # a user-wide cache that cannot be written
        return compile_portable(package, into, shipped_by, compiler)
    _forget_old_compiles(root)
    return kept


def _compile_key(package: Path, compiler: list[str] | None) -> str:
    """The digest of everything compile_portable's result depends on (compile_kept)."""
    digest = hashlib.sha256()
    for path in sorted(path for path in package.rglob("*") if path.is_file() and "__pycache__" not in path.parts):
        digest.update(path.relative_to(package.parent).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    versions = []
    for distribution in ("numba", "llvmlite", "numpy", "scikit-sundae"):
        with contextlib.suppress(importlib.metadata.PackageNotFoundError):
            versions.append(f"{distribution} {importlib.metadata.version(distribution)}")
    numba_settings = sorted(f"{key}={value}" for key, value in os.environ.items()
                            if key.startswith("NUMBA_") and key not in ("NUMBA_CACHE_DIR", "NUMBA_CPU_FEATURES"))
    where = (sys.executable, os.environ.get("PYTHONPATH", ""))  # the Python, and the numba, the child runs
    for part in (_COMPILE, sys.version, *where, platform.machine(), PORTABLE_CPU, *versions, *numba_settings,
                 json.dumps(compiler)):
        digest.update(part.encode() + b"\0")
    return digest.hexdigest()


def _forget_old_compiles(root: Path) -> None:
    """Remove the kept compiles beyond the KEPT_COMPILES most recently used, once unused for an hour.

    Each under its key's lock, taken without waiting (a build holding it keeps it), renamed away
    before it is deleted: a build finds a kept compile whole or not at all. The folders of a build
    killed while it compiled or deleted (.portable-*, .removed-*) go too, once an hour old. Lock files
    stay: a build may be waiting on one.
    """
    hour_ago = time.time() - 3600
    used = []
    for path in root.glob("portable-*"):
        with contextlib.suppress(OSError):  # removed meanwhile by another build
            if path.is_dir():
                used.append((path.stat().st_mtime, path))
    for last_use, path in sorted(used, reverse=True)[KEPT_COMPILES:]:
        if last_use > hour_ago:
            continue
        with contextlib.suppress(OSError), open(f"{path}.lock", "a") as lock:  # BlockingIOError: a build has it
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if path.stat().st_mtime <= hour_ago:
                removed = root / f".removed-{path.name}-{os.getpid()}"
                path.rename(removed)
                shutil.rmtree(removed, ignore_errors=True)
    for path in [*root.glob(".portable-*"), *root.glob(".removed-*")]:
        with contextlib.suppress(OSError):
            if path.stat().st_mtime <= hour_ago:
                shutil.rmtree(path, ignore_errors=True)


PACKAGE = Path(__file__).resolve().parents[2]  # this copy of the package


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
