"""The files the compiled engine is compiled from, and their digest: what its compiled code is keyed by.

numba's disk cache (solvers/engines/jit.py) and the FMU's native engine (solvers/engines/native.py) hold code
compiled from these sources; each checks the digest of the sources at hand before it runs that code.

Imports neither numba nor the engine.
"""

from __future__ import annotations

import hashlib
import os
import sys

from ...contact_laws.dispatch import LAW_MODULES

# Every source the compiled code is compiled from, relative to the package: the modules whose functions
# compiled.py gives compiled_together, those whose constants they read (rule 5), jit.py and compiled.py.
ENGINE_SOURCES = ("codes.py", "rounding.py", "oscillator.py", "equations.py", "contact_laws/dispatch.py",
                  *(f"contact_laws/{module.__name__.rpartition('.')[2]}.py" for module in LAW_MODULES), "physics.py",
                  *(f"solvers/phase_machine/{name}.py" for name in (
                      "settings", "phases", "layout", "error_estimate", "engine_protocol", "integrated_contact",
                      "machine", "drivers", "dense_output")),
                  "solvers/engines/jit.py", "solvers/engines/phase_solver.py", "solvers/engines/entry_contract.py",
                  "solvers/engines/compiled.py", "solvers/engines/c_entry.py")

_PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this module's package


def engine_sources() -> list[str]:
    """The files numba compiles the compiled engine from (ENGINE_SOURCES): an imported module's own file (in an FMU,
    maybe that of a copy the master deleted since), else the one in this module's copy of the package.
    """
    root = __name__.split(".")[0]
    files = []
    for relative in ENGINE_SOURCES:
        module = sys.modules.get(".".join((root, *relative.removesuffix(".py").removesuffix("/__init__").split("/"))))
        files.append(getattr(module, "__file__", None) or os.path.join(_PACKAGE_DIR, *relative.split("/")))
    return files


def sources_digest(files) -> str:
    """The SHA-256 of the files' contents, in their order, and of the package's name (the compiled code names its
    modules): what the compiled code's disk cache is keyed by.
    """
    digest = hashlib.sha256(__name__.split(".")[0].encode() + b"\0")
    for file in files:
        with open(file, "rb") as source:
            digest.update(source.read())
    return digest.hexdigest()
