"""numba for the compiled engine: plain functions compiled together, numba's disk cache, C calls by address.

``compiled_together`` compiles plain-Python functions of floats and arrays (physics, the phase
machine) as they are, so one source runs interpreted in one engine and compiled in the other;
``cache_allowed`` keeps numba's disk cache true to every source the compiled code inlines, in a folder
named after their contents (so a copy of the package elsewhere, an FMU's, finds it too), taken from
a cache shipped with the package or the FMU where it fits the host; the
``call_*`` intrinsics call a C function whose address is a run-time integer (``doubles`` and
``addresses`` read pointers from integers), so that no process-specific constant is baked into
the code and it can be cached on disk.

The rules for the source compiled together
------------------------------------------
compiled.py gives ``compiled_together`` every function of the modules it lists (``functions_of(rounding, oscillator,
equations, *LAW_MODULES, dispatch, physics, phases, error_estimate, machine, drivers, dense_output)``). numba
compiles, at their first call, those that the compiled entry points reach (the functions compiled.py keeps compiled
copies of: run_phases, fill_grid, advance, advance_in_step and the callbacks' scaled_rates, root_values,
scaled_jacobian), from the very source the scikit-sundae engine runs interpreted. A function so reached:

1. Calls another compiled function by its bare name, defined in its own module or imported with
   ``from .x import name``. ``compiled_together`` re-binds bare global names only: a call written
   ``equations.gap_flow_value(...)`` reaches the plain Python function through the module, and numba
   fails to type it, far from its cause.
2. Reads as globals only those functions, numbers (int, float, bool) and tuples of them, the modules
   ``math`` and ``numpy`` (the functions numba supports), the builtins numba supports (abs, min,
   max, float, int, range, ...) and the type BallParameters (contact_laws.common.parameters_at builds one).
   numba freezes a global number into the code it compiles: changing it at run time (a monkeypatch)
   reaches the interpreted engine, not the compiled one.
3. Takes and returns floats, ints, bools, tuples of them and numpy arrays: no Python object (a Ball,
   a Mode, a settings dataclass); the ball travels as the namedtuple Ball.parameters, read by field
   (``parameters.m``), and the machine's state as a record of layout.STATE_DTYPE (interpreted: a
   layout.MachineState), read and written by field (``state.rs_t``). The one exception
   is the module ``math`` or ``numpy`` as an argument (``xp``), for code written once for floats and
   arrays; an argument's attributes are an array's (shape, ctypes, ...) or that module's functions.
4. Uses nothing numba cannot compile: no keyword-only or variadic parameters (``*args``,
   ``**kwargs``), no nested function, lambda or class, no try, with, yield, global or f-string. A
   function that needs one for the interpreted engine (the float-or-array dispatch of
   oscillator.unit_response) has a plain-float stand-in in ``compiled_together``'s ``bound``
   (oscillator.unit_response_value), and the compiled code calls that.
5. Lives in a source the cache digest covers, as does every constant it reads: a new compiled module,
   or one whose constants the compiled code imports (layout.py's fields, settings.py's tolerances),
   goes into ``ENGINE_SOURCES`` too, or a change to it leaves numba's disk cache with the old code.

Functions of those modules that no entry point reaches (dense_output.interpolate) run interpreted only; rule 1
holds for them too, so that reaching one later does not break it.
tests/test_jit_rules.py reads the functions compiled.py gives ``compiled_together`` and checks
these rules on their syntax trees.

Import this module only to compile: it imports numba.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import glob
import os
import pickle
import shutil
import sys
from collections.abc import Callable
from types import FunctionType

import numba
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from .ahead_of_time import COMPILE_TIME, PORTABLE_CPU, package_shipped, say_on_stderr, user_cache_root
from .sources import ENGINE_SOURCES, engine_sources, sources_digest  # noqa: F401  (the API)

_PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this module's package


def readable_sources(files) -> list[str]:
    """files (engine_sources'), each one gone from disk replaced by its source in this module's copy of the package.

    An FMU's modules imported by an earlier instance come from its unzipped copy, which the master
    (FMPy) may have deleted since; this module (imported with the compiled engine, at its first use) then comes
    from the copy of the instance at hand (fmu/slave_base.py's _search_package_in), whose sources are the same:
    the copy's package is named after their digest. A package imported from one folder finds a gone file gone here
    too.
    """
    return [file if os.path.isfile(file) else os.path.join(_PACKAGE_DIR, *relative.split("/"))
            for file, relative in zip(files, ENGINE_SOURCES, strict=True)]


def cache_folder(digest: str) -> str:
    """The folder holding the code compiled from the sources of this digest, in the user-wide cache."""
    return os.path.join(user_cache_root(), f"numba-{digest[:24]}")


# What cache_allowed says before numba compiles, and the cache it may take the code from instead: the one shipped
# in the package (a wheel's), or the one first_use names around the compiled engine's import (an FMU's).
_say: Callable[[str], None] = say_on_stderr
_shipped: str | None = package_shipped()


@contextlib.contextmanager
def first_use(shipped: str | None, say: Callable[[str], None]):
    """Within: cache_allowed takes a cache that fits this host from folder shipped, and says through say that numba
    compiles (before it does) where neither the user-wide cache nor shipped holds code for this host.
    """
    global _say, _shipped
    saved = _say, _shipped
    _say, _shipped = say, shipped
    try:
        yield
    finally:
        _say, _shipped = saved


def cache_allowed(files) -> bool:
    """Whether numba may cache the code compiled from files on disk; it then reads and writes it in cache_folder.

    numba keys each cached function by its own source file's path and time alone, but compiled code
    inlines the functions it calls from other files: after a change to physics.py alone it loaded
    compiled.py's old code (the engines then disagreed). And the FMU's copy of the package, unzipped
    into a new folder by most masters, found no cache at all. So the code compiled from files is
    kept in one folder named after the digest of all their contents (a change to any is a new
    folder), wherever the files are. Where that folder holds no code for this host's numba and CPU,
    it is first taken from the shipped cache (the package's own, a wheel's; or first_use's, an
    FMU's: engine_cache.py compiled it for any CPU of its architecture) if that fits, its code filed
    under this host's CPU as it is copied; else numba compiles, said through first_use's say (on
    stderr unless first_use says otherwise) before it does. A file gone from disk (the master deleted
    the unzipped FMU an earlier instance imported it from) is read in this module's copy
    (readable_sources). Where it is gone from there too, or the folder cannot be written, nothing
    is cached: numba compiles in every such process, said the same way.
    Processes importing at once (Dask's workers) take turns under one lock file, and every file is
    written whole (a temporary file renamed) or not at all.
    """
    readable = readable_sources(files)
    if not all(os.path.isfile(file) for file in readable):
        _say(f"numba compiles the compiled engine in this process ({COMPILE_TIME}), and cannot keep it: its sources "
             "are gone from disk")
        return False
    digest = sources_digest(readable)
    folder = cache_folder(digest)
    try:
        os.makedirs(folder, exist_ok=True)
        with open(os.path.join(folder, "lock"), "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
            misfit = cache_misfit(folder, digest)
            if misfit is not None and _shipped is not None:
                unfit = cache_misfit(_shipped, digest, portable=True)
                if unfit is None:
                    _copy_cache(_shipped, folder)
                    misfit = None
                else:
                    misfit = f"the cache shipped with it does not fit ({unfit})"
            if misfit is not None:
                _say(f"numba compiles the compiled engine for this host, once ({COMPILE_TIME}; {misfit}), into "
                     f"{folder}")
        _use_folder([*files, *readable], folder, digest)  # numba names a function's source as it was imported
    except Exception as error:  # a numba without these internals, or a cache folder we cannot write
        _say(f"numba compiles the compiled engine in this process ({COMPILE_TIME}), and cannot keep it: its cache "
             f"folder {folder} cannot be used ({type(error).__name__}: {error})")
        return False
    return True


def cache_misfit(folder: str, digest: str, portable: bool = False) -> str | None:
    """Why the code cached in folder cannot run here (none for this Python, another numba, CPU or set of sources);
    None if it can. portable: code compiled for PORTABLE_CPU on this host's architecture runs here too (a shipped
    cache, which _copy_cache retargets to this host's CPU as it copies it).
    """
    indexes = _indexes(folder)
    if not indexes:
        others = sorted({path.rsplit(".", 2)[-2] for path in glob.glob(os.path.join(folder, "*.nbi"))})
        if others:
            return f"its code was compiled for Python {', '.join(others)}, this is {_python_tag()}"
        return "no code compiled from these sources yet"
    host = _host_key()
    fits = {host, (host[0], PORTABLE_CPU, "")} if portable else {host}
    for path in indexes:
        try:
            version, stamp, keys = _index(path)
        except Exception as error:  # cut short or garbled (a full disk, a killed copy): a misfit, copied over
            return f"its index {os.path.basename(path)} cannot be read ({type(error).__name__})"
        if version != numba.__version__:
            return f"its code was compiled by numba {version}, this is numba {numba.__version__}"
        if stamp != digest:
            return "its code was compiled from other sources"
        if not any(key[1] in fits for key in keys):
            built = sorted({f"{key[1][1]} ({key[1][0]})" for key in keys})
            return f"its code was compiled for the CPU {', '.join(built)}, this is {host[1]} ({host[0]})"
    return None


# --- numba's private API: its cache's locators and index (numba 0.59 to 0.68 at least) ------------------
# tests/test_compiled.py (test_numbas_private_api_that_jit_uses_is_still_there) fails loudly on an upgrade that
# changes any of it, instead of the compiled engine silently compiling afresh in every process.
def _use_folder(files, folder: str, digest: str) -> None:
    """numba caches the functions of files in folder, their freshness the digest (not each file's path and time)."""
    from numba.core.caching import CacheImpl

    locator = _digest_locator()
    for file in files:
        locator.folders[os.path.realpath(file)] = (folder, digest)
    if locator not in CacheImpl._locator_classes:
        CacheImpl._locator_classes.insert(0, locator)


def _host_key() -> tuple:
    """numba's key of the code this host runs: (LLVM's target triple, the CPU's name, its features)."""
    from numba.core.registry import cpu_target

    return cpu_target.target_context.codegen().magic_tuple()


def _python_tag() -> str:
    """What numba's cache file names say of this Python: py311 for CPython 3.11, say."""
    return f"py{sys.version_info[0]}{sys.version_info[1]}{sys.abiflags}"


def _indexes(folder: str) -> list[str]:
    """numba's index files (.nbi) in folder for this Python (numba names them ...-<line>.py311.nbi, say)."""
    return glob.glob(os.path.join(folder, f"*.{_python_tag()}.nbi"))


def _copy_cache(source: str, folder: str) -> None:
    """Copy numba's cache files from source into folder, each written whole, the data before the indexes that name
    it; in this Python's indexes (the ones cache_misfit read) the code compiled for PORTABLE_CPU is filed under
    this host's CPU, where numba looks for it. Other files are copied byte for byte.
    """
    from numba.core.serialize import dumps

    host = _host_key()
    portable = (host[0], PORTABLE_CPU, "")
    retargeted = set(_indexes(source))
    for path in sorted(glob.glob(os.path.join(source, "*.nb[ci]")), key=lambda p: p.endswith(".nbi")):
        written = os.path.join(folder, f".{os.path.basename(path)}.{os.getpid()}")
        if path in retargeted:
            version, stamp, overloads = _index(path)
            overloads = {(key[0], host if key[1] == portable else key[1], *key[2:]): data
                         for key, data in overloads.items()}
            with open(written, "wb") as file:
                pickle.dump(version, file, protocol=-1)
                file.write(dumps((stamp, overloads)))
        else:
            shutil.copyfile(path, written)
        os.replace(written, os.path.join(folder, os.path.basename(path)))


def _index(path: str) -> tuple:
    """(numba's version, the source stamp, {an overload's key: its data file}) of one of numba's index files (.nbi).

    A key is (signature, (LLVM's target triple, the CPU's name, its features), the code's hashes).
    """
    with open(path, "rb") as file:
        version = pickle.load(file)
        if version != numba.__version__:
            return version, None, {}
        stamp, overloads = pickle.loads(file.read())
    return version, stamp, overloads


@functools.cache
def _digest_locator():
    from numba.core.caching import _CacheLocator

    class DigestLocator(_CacheLocator):
        folders: dict = {}  # the real path of a source: (its cache folder, the digest of the sources)

        def __init__(self, folder: str, digest: str, line: int):
            self._folder, self._digest, self._line = folder, digest, line

        def ensure_cache_path(self):
            os.makedirs(self._folder, exist_ok=True)

        def get_cache_path(self):
            return self._folder

        def get_source_stamp(self):
            return self._digest

        def get_disambiguator(self):
            return str(self._line)

        @classmethod
        def from_function(cls, py_func, py_file):
            found = cls.folders.get(os.path.realpath(py_file))
            return None if found is None else cls(*found, py_func.__code__.co_firstlineno)

    return DigestLocator


# --- end of numba's private API ----------------------------------------------------------------------


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
