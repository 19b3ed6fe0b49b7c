"""numba for the compiled engine: plain functions compiled together, numba's disk cache, C calls by address.

``compiled_together`` compiles plain-Python functions of floats and arrays (physics, the phase
machine) as they are, so one source runs interpreted in one engine and compiled in the other;
``cache_allowed`` keeps numba's disk cache true to every source the compiled code inlines; the
``call_*`` intrinsics call a C function whose address is a run-time integer (``doubles`` and
``addresses`` read pointers from integers), so that no process-specific constant is baked into
the code and it can be cached on disk.

The rules for the source compiled together
------------------------------------------
compiled.py gives ``compiled_together`` every function of the modules it lists
(``functions_of(rounding, physics, exact, phases, error_estimate, machine, dense_output)``). numba
compiles, at their first call, those that the compiled entry points reach (the functions compiled.py
keeps compiled copies of: run_phases, fill_grid, advance, advance_in_step and the callbacks'
scaled_rates, root_values, scaled_jacobian), from the very source the scikit-sundae engine runs
interpreted. A function so reached:

1. Calls another compiled function by its bare name, defined in its own module or imported with
   ``from .x import name``. ``compiled_together`` re-binds bare global names only: a call written
   ``physics.gap_flow_value(...)`` reaches the plain Python function through the module, and numba
   fails to type it, far from its cause.
2. Reads as globals only those functions, numbers (int, float, bool) and tuples of them, the modules
   ``math`` and ``numpy`` (the functions numba supports) and the builtins numba supports (abs, min,
   max, float, int, range, ...). numba freezes a global number into the code it compiles: changing
   it at run time (a monkeypatch) reaches the interpreted engine, not the compiled one.
3. Takes and returns floats, ints, bools, tuples of them and numpy arrays: no Python object (a Ball,
   a Mode, a settings dataclass); the ball travels as the tuple (m, k, b, R, g). The one exception
   is the module ``math`` or ``numpy`` as an argument (``xp``), for code written once for floats and
   arrays; an argument's attributes are an array's (shape, ctypes, ...) or that module's functions.
4. Uses nothing numba cannot compile: no keyword-only or variadic parameters (``*args``,
   ``**kwargs``), no nested function, lambda or class, no try, with, yield, global or f-string. A
   function that needs one for the interpreted engine (the float-or-array dispatch of
   physics.unit_response) has a plain-float stand-in in ``compiled_together``'s ``bound``
   (physics.unit_response_value), and the compiled code calls that.
5. Lives in a source the cache digest covers, as does every constant it reads: a new compiled module,
   or one whose constants the compiled code imports (layout.py's indices, settings.py's tolerances),
   goes into compiled.py's ``cache_allowed(...)`` too, or a change to it leaves numba's disk cache
   with the old code.

Functions of those modules that no entry point reaches (exact.simulate_exact, dense_output.interpolate)
run interpreted only; rule 1 holds for them too, so that reaching one later does not break it.
tests/test_jit_rules.py reads the functions compiled.py gives ``compiled_together`` and checks
these rules on their syntax trees.

Import this module only to compile: it imports numba.
"""

from __future__ import annotations

import fcntl
import glob
import hashlib
import os
from types import FunctionType

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic


def cache_allowed(modules) -> bool:
    """Whether numba may cache the code compiled from modules on disk, after dropping code a changed source outdated.

    numba keys each cached function by its own source file alone, but compiled code inlines the
    functions it calls from other files: after a change to physics.py alone it loaded this module's
    old code (the compiled engine ran the previous right-hand side, found by the engines
    disagreeing). So one digest of every source compiled here (this module, physics.py and the
    phase machine's modules) is kept beside the cache, and all their cached code is removed when
    it differs. Where a source is gone (an FMU's copy of the package, whose unzipped folder the
    master deleted after the process imported it), or the cache cannot be found through numba's
    locators, nothing is cached: it compiles afresh. Processes importing at once (Dask's workers)
    take turns: the check, the removal and the new digest happen under one lock file, and the
    digest is written whole (a temporary file renamed) or not at all.
    """
    files = [module.__file__ for module in modules]
    if not all(os.path.isfile(file) for file in files):
        return False
    digest = hashlib.sha256()
    for file in files:
        with open(file, "rb") as source:
            digest.update(source.read())
    try:
        folders = [cache_folder(file) for file in files]
        stem = os.path.splitext(os.path.basename(files[-1]))[0]
        stamp = os.path.join(folders[-1], f"{stem}.sources-sha256")
        os.makedirs(folders[-1], exist_ok=True)
        with open(stamp + ".lock", "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
            if _read(stamp) != digest.hexdigest():
                for file, folder in zip(files, folders, strict=True):
                    stem = os.path.splitext(os.path.basename(file))[0]
                    for stale in glob.glob(os.path.join(folder, f"{stem}.*.nb[ic]")):
                        os.remove(stale)
                written = f"{stamp}.{os.getpid()}"
                with open(written, "w") as out:
                    out.write(digest.hexdigest())
                os.replace(written, stamp)
    except Exception:  # a numba without these internals, or a cache folder we cannot write
        return False
    return True


def cache_folder(file: str) -> str:
    """The folder numba caches the functions of the source file in, as numba itself finds it.

    The one use of numba's private API (numba.core.caching.CacheImpl._locator_classes, numba 0.59 to
    0.61 at least): tests/test_compiled.py fails loudly if an upgrade removes or changes it.
    """
    from numba.core.caching import CacheImpl

    locators = (cls.from_function(cache_allowed, file) for cls in CacheImpl._locator_classes)
    return next(locator for locator in locators if locator is not None).get_cache_path()


def _read(path: str) -> str | None:
    try:
        with open(path) as file:
            return file.read()
    except OSError:
        return None


def functions_of(*modules) -> tuple:
    """Every function the modules define (not those they import), for compiled_together."""
    return tuple(value for module in modules for value in vars(module).values()
                 if isinstance(value, FunctionType) and value.__module__ == module.__name__)


def compiled_together(functions, bound, cache: bool):
    """numba-compiled copies of plain functions, each one's calls to the others bound to their compiled copies.

    functions: plain Python functions of floats and arrays (physics, phases, machine, dense_output);
    bound: {plain function: its stand-in}, for what only runs interpreted as written (an engine's
    calls, a float-or-array dispatch); a stand-in among functions is taken compiled. Each copy reads
    a copy of its module's globals in which every one of those functions is replaced, so the source
    stays the one that runs interpreted. Returns {plain function: compiled copy}.
    """
    compiled, namespaces = {}, []
    for function in functions:
        namespace = dict(function.__globals__)
        copy = FunctionType(function.__code__, namespace, function.__name__, function.__defaults__,
                            function.__closure__)
        copy.__qualname__ = function.__qualname__
        compiled[function] = njit(copy, cache=cache)
        namespaces.append(namespace)
    replacements = {id(plain): copy for plain, copy in compiled.items()}
    replacements.update({id(plain): compiled.get(stand_in, stand_in) for plain, stand_in in bound.items()})
    for namespace in namespaces:
        for name, value in namespace.items():
            if id(value) in replacements:
                namespace[name] = replacements[id(value)]
    return compiled


# --- calls to C functions whose address is a run-time argument ---------------------------------------
# numba caches compiled code on disk only if it holds no process-specific constant, so the
# addresses of SUNDIALS' functions travel as plain integers and are called through these.
def _codegen(context, builder, signature, args):
    return_type = context.get_value_type(signature.return_type)
    function_type = ir.FunctionType(return_type, [context.get_value_type(a) for a in signature.args[1:]])
    return builder.call(builder.inttoptr(args[0], function_type.as_pointer()), args[1:])


@intrinsic
def call_i1(typingctx, address, a):
    return types.int32(types.intp, a), _codegen


@intrinsic
def call_p1(typingctx, address, a):
    return types.intp(types.intp, a), _codegen


@intrinsic
def call_i2(typingctx, address, a, b):
    return types.int32(types.intp, a, b), _codegen


@intrinsic
def call_i3(typingctx, address, a, b, c):
    return types.int32(types.intp, a, b, c), _codegen


@intrinsic
def call_i5(typingctx, address, a, b, c, d, e):
    return types.int32(types.intp, a, b, c, d, e), _codegen


@intrinsic
def doubles(typingctx, address):
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
    return types.CPointer(types.float64)(types.intp), codegen


@intrinsic
def addresses(typingctx, address):
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
    return types.CPointer(types.intp)(types.intp), codegen
