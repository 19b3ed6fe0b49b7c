"""scikit-sundae's own SUNDIALS library, bound with ctypes: the functions the compiled engine calls, checked.

The library is the one in scikit-sundae's wheel (``scikit_sundae.libs``), so the process holds one
SUNDIALS, and its version is checked (SUNDIALSGetVersion) before anything else. Every function we
call is looked up in these libraries' own handles, so a host process that exports SUNDIALS
symbols of its own (another SUNDIALS) cannot capture our calls. The libraries' calls among
themselves are bound when they are first loaded, usually by scikit-sundae's import; if we load
them first, RTLD_DEEPBIND (where the platform has it) binds them to each other too.
``unavailable_reason()`` says why the library cannot be used here, or None; ``message(flag)``
says what a CVODE flag means; ``free(functions, handles)`` frees a solver's SUNDIALS objects.
"""

from __future__ import annotations

import ctypes
import glob
import importlib.util
import os
import sys
from dataclasses import dataclass

# SUNDIALS' major version we bind: its C API (the declarations below) is stable within a major.
SUPPORTED_MAJOR = 7
CV_RTFUNC_FAIL = -12

# The C functions we call, as C declares them: (return type, argument types). tests/test_compiled.py
# checks each against the declarations scikit-sundae ships (sksundae/*.pxd) where it has one.
FUNCTIONS = {
    "core": {
        "SUNDIALSGetVersion": ("int", ("char*", "int")),
        "SUNContext_Create": ("int", ("SUNComm", "SUNContext*")),
        "SUNContext_Free": ("void", ("SUNContext*",)),
        "SUNContext_ClearErrHandlers": ("int", ("SUNContext",)),
        "N_VGetArrayPointer": ("sunrealtype*", ("N_Vector",)),
        "N_VDestroy": ("void", ("N_Vector",)),
        "SUNMatDestroy": ("void", ("SUNMatrix",)),
        "SUNLinSolFree": ("int", ("SUNLinearSolver",)),
    },
    "cvode": {
        "N_VNew_Serial": ("N_Vector", ("sunindextype", "SUNContext")),
        "SUNDenseMatrix": ("SUNMatrix", ("sunindextype", "sunindextype", "SUNContext")),
        "SUNDenseMatrix_Cols": ("sunrealtype**", ("SUNMatrix",)),
        "SUNLinSol_Dense": ("SUNLinearSolver", ("N_Vector", "SUNMatrix", "SUNContext")),
        "CVodeCreate": ("void*", ("int", "SUNContext")),
        "CVodeInit": ("int", ("void*", "CVRhsFn", "sunrealtype", "N_Vector")),
        "CVodeReInit": ("int", ("void*", "sunrealtype", "N_Vector")),
        "CVodeSStolerances": ("int", ("void*", "sunrealtype", "sunrealtype")),
        "CVodeSetUserData": ("int", ("void*", "void*")),
        "CVodeSetLinearSolver": ("int", ("void*", "SUNLinearSolver", "SUNMatrix")),
        "CVodeSetJacFn": ("int", ("void*", "CVLsJacFn")),
        "CVodeSetMaxNonlinIters": ("int", ("void*", "int")),
        "CVodeSetMaxConvFails": ("int", ("void*", "int")),
        "CVodeRootInit": ("int", ("void*", "int", "CVRootFn")),
        "CVodeSetRootDirection": ("int", ("void*", "int*")),
        "CVodeSetInitStep": ("int", ("void*", "sunrealtype")),
        "CVodeSetMinStep": ("int", ("void*", "sunrealtype")),
        "CVodeSetMaxStep": ("int", ("void*", "sunrealtype")),
        "CVodeSetMaxOrd": ("int", ("void*", "int")),
        "CVodeSetMaxNumSteps": ("int", ("void*", "long int")),
        "CVodeSetStopTime": ("int", ("void*", "sunrealtype")),
        "CVodeClearStopTime": ("int", ("void*",)),
        "CVode": ("int", ("void*", "sunrealtype", "N_Vector", "sunrealtype*", "int")),
        "CVodeGetRootInfo": ("int", ("void*", "int*")),
        "CVodeGetNumRhsEvals": ("int", ("void*", "long int*")),
        "CVodeFree": ("void", ("void**",)),
    },
}
_CTYPES = {"int": ctypes.c_int, "long int": ctypes.c_long, "sunrealtype": ctypes.c_double,
           "sunindextype": ctypes.c_int, "SUNComm": ctypes.c_int, "void": None, "char*": ctypes.c_char_p}


def _ctype(name: str):
    return _CTYPES[name] if name in _CTYPES else ctypes.c_void_p  # every pointer and handle


class EngineUnavailable(RuntimeError):
    """The compiled engine cannot run here; the message says why."""


@dataclass(frozen=True)
class Library:
    """The bound SUNDIALS functions (ctypes) and their addresses, with the version found."""

    version: str
    path: str
    functions: dict
    addresses: dict


def sksundae_cvode_class():
    """scikit-sundae's CVODE class, its first import in the process made with RTLD_DEEPBIND (where the platform has
    it): its modules then call their own SUNDIALS libraries, which a host process that exports another SUNDIALS (a C
    master linked to a system SUNDIALS 6) would otherwise capture, and crash. Imported where its engine runs, not with
    the package: the import takes ~0.4 s (it loads SciPy), which the compiled engine, needing only the libraries,
    does not pay. Where scikit-sundae is imported already (a Python host did), it is used as it is."""
    deep_bind = getattr(os, "RTLD_DEEPBIND", 0)
    flags = sys.getdlopenflags()
    if deep_bind and "sksundae" not in sys.modules:
        import numpy  # noqa: F401  (numpy resolves as usual; only scikit-sundae and what it loads bind deep)

        sys.setdlopenflags(flags | deep_bind)
    try:
        from sksundae.cvode import CVODE
    finally:
        sys.setdlopenflags(flags)
    return CVODE


def _library_paths() -> dict[str, str]:
    spec = importlib.util.find_spec("sksundae")
    if spec is None or not spec.submodule_search_locations:
        raise EngineUnavailable("scikit-sundae is not installed")
    site = os.path.dirname(list(spec.submodule_search_locations)[0])
    folder = os.path.join(site, "scikit_sundae.libs")
    paths = {}
    for part in FUNCTIONS:
        found = sorted(glob.glob(os.path.join(folder, f"libsundials_{part}-*.so*")))
        if len(found) != 1:
            raise EngineUnavailable(f"scikit-sundae's SUNDIALS {part} library was not found as one file in {folder} "
                                    f"(found {len(found)}); the compiled engine binds the Linux wheel's libraries")
        paths[part] = found[0]
    return paths


_LIBRARY: Library | None = None
_UNAVAILABLE: str | None = None


def library() -> Library:
    """Open (once) the SUNDIALS libraries of scikit-sundae's wheel; raise EngineUnavailable if not usable."""
    global _LIBRARY, _UNAVAILABLE
    if _LIBRARY is not None:
        return _LIBRARY
    if _UNAVAILABLE is not None:
        raise EngineUnavailable(_UNAVAILABLE)
    try:
        _LIBRARY = _open()
    except EngineUnavailable as error:
        _UNAVAILABLE = str(error)
        raise
    return _LIBRARY


def _open() -> Library:
    # Pointers travel through the compiled code as 64-bit integers, and C's long is 64 bits (LP64).
    if ctypes.sizeof(ctypes.c_void_p) != 8 or ctypes.sizeof(ctypes.c_long) != 8:
        raise EngineUnavailable("the compiled engine needs a 64-bit platform with 64-bit C longs (Linux)")
    paths = _library_paths()
    mode = ctypes.RTLD_LOCAL | getattr(os, "RTLD_DEEPBIND", 0) | getattr(os, "RTLD_NOW", 0)
    handles = {}
    for part in ("core", "cvode"):  # cvode needs core; a library already loaded is shared, not loaded twice
        try:
            handles[part] = ctypes.CDLL(paths[part], mode=mode)
        except OSError as error:
            raise EngineUnavailable(f"cannot load {paths[part]}: {error}") from error
    functions, addresses = {}, {}
    for part, declarations in FUNCTIONS.items():
        for name, (restype, argtypes) in declarations.items():
            try:
                function = getattr(handles[part], name)
            except AttributeError as error:
                raise EngineUnavailable(f"{paths[part]} has no {name}") from error
            function.restype = _ctype(restype)
            function.argtypes = [_ctype(a) for a in argtypes]
            functions[name] = function
            addresses[name] = ctypes.cast(function, ctypes.c_void_p).value
    buffer = ctypes.create_string_buffer(64)
    if functions["SUNDIALSGetVersion"](buffer, len(buffer)) != 0:
        raise EngineUnavailable("SUNDIALSGetVersion failed")
    version = buffer.value.decode()
    if version.split(".")[0] != str(SUPPORTED_MAJOR):
        raise EngineUnavailable(f"scikit-sundae ships SUNDIALS {version}; the compiled engine supports "
                                f"SUNDIALS {SUPPORTED_MAJOR}.x only")
    return Library(version, paths["cvode"], functions, addresses)


def unavailable_reason() -> str | None:
    """Why the compiled engine cannot run in this process, or None if it can."""
    try:
        library()
    except EngineUnavailable as error:
        return str(error)
    return None


# CVODE's return flags (cvode.h) and what the failures mean (CVODE's documentation of CVode). Our own
# table: CVodeGetReturnFlagName returns a string the caller must free.
_FLAGS = {
    -1: ("CV_TOO_MUCH_WORK", "could not reach the end point within the maximum number of steps"),
    -2: ("CV_TOO_MUCH_ACC", "could not satisfy the accuracy demanded for an internal step"),
    -3: ("CV_ERR_FAILURE", "error tests failed too many times, or the step reached its minimum"),
    -4: ("CV_CONV_FAILURE", "convergence tests failed too many times, or the step reached its minimum"),
    -5: ("CV_LINIT_FAIL", "the linear solver's initialisation failed"),
    -6: ("CV_LSETUP_FAIL", "the linear solver's setup failed"),
    -7: ("CV_LSOLVE_FAIL", "the linear solver's solve failed"),
    -8: ("CV_RHSFUNC_FAIL", "the right-hand side failed unrecoverably"),
    -12: ("CV_RTFUNC_FAIL", "the root function failed"),
    -20: ("CV_MEM_FAIL", "a memory allocation failed"),
    -21: ("CV_MEM_NULL", "no CVODE memory"),
    -22: ("CV_ILL_INPUT", "an input is illegal"),
    -25: ("CV_BAD_T", "the time is outside the last step"),
    -27: ("CV_TOO_CLOSE", "the output and initial times are too close to each other"),
}


def message(flag: int) -> str:
    """CVODE's return flag in words."""
    if flag >= 0:
        return "success"
    name, meaning = _FLAGS.get(flag, (f"flag {flag}", "see cvode.h"))
    return f"{name}: {meaning}"


def free(functions, handles: dict) -> None:
    """Free a solver's SUNDIALS objects (handles: memory, linear_solver, matrix, vector, context), last made first."""
    # A finalizer cannot raise: SUNLinSolFree's only failure is a NULL solver, which never gets here.
    if "memory" in handles:
        functions["CVodeFree"](ctypes.byref(ctypes.c_void_p(handles.pop("memory"))))
    if "linear_solver" in handles:
        functions["SUNLinSolFree"](handles.pop("linear_solver"))
    if "matrix" in handles:
        functions["SUNMatDestroy"](handles.pop("matrix"))
    if "vector" in handles:
        functions["N_VDestroy"](handles.pop("vector"))
    if "context" in handles:
        functions["SUNContext_Free"](ctypes.byref(handles.pop("context")))
