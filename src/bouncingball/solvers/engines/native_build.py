"""The native engine's library: the compiled engine's entry points, as numba compiled them, linked into one library.

Run inside the compile of the engine for the FMU (solvers/engines/ahead_of_time.py's child, numba's generic CPU of
the architecture, every function compiled in this process, not read from a cache): the LLVM code numba generated for
each entry point of c_entry.ENTRY_POINTS (``inspect_llvm``, each one whole, the functions it calls included) is
linked into one module, emitted as one position-independent object by llvmlite, and linked by the C compiler with
native_runtime.c (what numba's runtime gives that code: memory, two math helpers, the error path) into a library
exporting only ``bb_*``: each entry point's address (``bb_<name>_address``), the digest of the sources
(``bb_sources_digest``) and the count of exceptions (``bb_exceptions``). The link refuses any symbol left undefined,
so a library that loads has everything it calls. solvers/engines/native.py loads it.

Imports numba (through c_entry): run it only there.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import tempfile
from pathlib import Path

from .ahead_of_time import NATIVE_LIBRARY
from .entry_contract import ENTRIES
from .native import DIGEST_SYMBOL

RUNTIME_SOURCE = Path(__file__).with_name("native_runtime.c")
_EXPORTS = "{ global: bb_*; local: *; };\n"  # the linker's version script: only the library's own names


def build(folder: str, digest: str, compiler: list[str]) -> Path:
    """The library (NATIVE_LIBRARY) in folder, from the entry points this process compiled, for sources of digest.

    Raises RuntimeError (the compiler's or LLVM's message in it) where it cannot be built.
    """
    import llvmlite.binding as llvm

    from . import c_entry

    whole = None
    declarations = []
    for entry, signature in ENTRIES.items():
        function = c_entry.ENTRY_POINTS[entry]
        module = llvm.parse_assembly(function.inspect_llvm())
        if whole is None:
            whole = module
        else:
            whole.link_in(module)
        returned, arguments = signature.split(" (", 1)
        declarations.append(f'extern {returned} bb_{entry}_impl({arguments} __asm__("{function.native_name}");\n'
                            f"void *const bb_{entry}_address = (void *)bb_{entry}_impl;\n")
    whole.verify()
    machine = llvm.Target.from_default_triple().create_target_machine(reloc="pic", codemodel="default", opt=3)
    target = Path(folder) / NATIVE_LIBRARY
    with tempfile.TemporaryDirectory(prefix="bouncingball_native_") as temp:
        objects, exports, names = (os.path.join(temp, name) for name in ("engine.o", "exports.map", "names.c"))
        Path(objects).write_bytes(machine.emit_object(whole))
        Path(exports).write_text(_EXPORTS)
        Path(names).write_text("#include <stdint.h>\n" + "".join(declarations) +
                               f'const char {DIGEST_SYMBOL}[] = "{digest}";\n')
        command = [*compiler, "-shared", "-fPIC", "-O2", "-o", str(target), names, objects, str(RUNTIME_SOURCE),
                   f"-Wl,--version-script={exports}", "-Wl,-Bsymbolic", "-Wl,--no-undefined", "-lm"]
        completed = subprocess.run(command, capture_output=True, text=True, check=False)
        if completed.returncode != 0:
            detail = completed.stderr.strip() or f"exit status {completed.returncode}"
            raise RuntimeError(f"linking the native engine with {shlex.join(compiler)} failed: {detail}")
    return target
