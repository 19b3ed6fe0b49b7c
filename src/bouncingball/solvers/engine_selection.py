"""Which CVODE engine runs: the compiled one where it can run and pays back its first use, else scikit-sundae's."""

from __future__ import annotations

import importlib.util
import math
import sys

from .. import validation
from ..physics import Ball
from .exact import ExactSolution
from .forcing import ForceTable
from .phase_machine.settings import ENGINES

# engine="auto" (choose_engine): the first use of each engine in a process and what the compiled one
# saves per CVODE step, measured by `bouncingball bench` (docs/benchmarks.md, "Choosing the engine").
COMPILED_FIRST_USE = 0.50  # s: numba's import and the compiled code read from its disk cache
SKSUNDAE_FIRST_USE = 0.43  # s: scikit-sundae's import (it loads SciPy)
STEP_SAVING = 13.5e-6  # s per CVODE step
STEPS_PER_PHASE = 46  # CVODE's steps per flight or contact at the default rtol (the article: 1925 in 42 phases)
_COMPILED_MODULE = __name__.rpartition(".")[0] + ".engines.compiled"
_sksundae_steps = 0  # CVODE steps this process ran on scikit-sundae: what engine "auto" paid instead of loading


def compiled_break_even() -> float:
    """CVODE steps over which the compiled engine's first use in this process pays back; 0 once it is loaded.

    Loading it (importing numba, reading the compiled code from its disk cache) costs
    COMPILED_FIRST_USE, loading scikit-sundae's engine (its import loads SciPy) SKSUNDAE_FIRST_USE
    (nothing once imported), and each CVODE step is STEP_SAVING cheaper compiled: 5,185 steps in a
    fresh process, 37,037 once scikit-sundae is loaded.
    """
    paid = loaded()
    if "compiled" in paid:
        return 0.0
    sksundae_cost = 0.0 if "sksundae" in paid else SKSUNDAE_FIRST_USE
    return max(COMPILED_FIRST_USE - sksundae_cost, 0.0) / STEP_SAVING


def expected_steps(ball: Ball, h0: float, v0: float, t_start: float, t_end: float,
                   F_ext: float | ForceTable = 0.0, at_most: float = math.inf) -> float:
    """CVODE's steps for a run, estimated from its phases (the exact solution's, counted up to at_most steps).

    STEPS_PER_PHASE per flight or contact; a rest costs none (it is taken in closed form).
    """
    max_phases = None if math.isinf(at_most) else int(at_most / STEPS_PER_PHASE) + 2
    exact = ExactSolution(ball, h0, v0, t_start, t_end, F_ext, max_phases=max_phases)
    return STEPS_PER_PHASE * (len(exact.phases) - (exact.rest_time is not None))


def choose_engine(engine: str = "auto", steps: float | None = None) -> tuple[str, str]:
    """The engine that runs ("compiled" or "sksundae") and why.

    "auto" takes the compiled engine when numba is installed and scikit-sundae's SUNDIALS library
    can be bound, else scikit-sundae's own, except for a run of fewer expected CVODE steps than
    compiled_break_even(): there loading the compiled engine would cost more than it saves. The
    steps this process already ran on scikit-sundae count too, so a process of many short runs
    loads the compiled engine once they would have paid for it (renting until the rent paid equals
    the price, then buying: never more than about twice the time of the better choice in hindsight).
    steps: the run's expected steps (expected_steps), None when unknown (an integrator advanced
    piece by piece, as the FMU's, or a process about to run many: the compiled engine).
    "compiled" raises ImportError where it cannot run.
    """
    engine = validation.choice("engine", engine, ENGINES)
    if engine == "sksundae":
        return "sksundae", "requested"
    from .engines import native

    library = native.active()  # loaded already (an FMU's): nothing to pay back
    if library is not None:
        return "compiled", "requested" if engine == "compiled" else f"the native engine {library.path}"
    if engine == "auto" and steps is not None and _numba_installed():
        break_even = compiled_break_even()
        if _sksundae_steps + steps < break_even:
            return "sksundae", (f"about {steps:.0f} CVODE steps expected, fewer than the {break_even:.0f} over "
                                "which loading the compiled engine in this process pays back")
    try:
        from .engines import compiled
    except ImportError as error:
        reason = f"numba is not installed ({error}): {_install_numba()}"
    except Exception as error:  # numba is there but cannot compile the engine (an incompatible release)
        reason = f"numba could not compile the engine ({type(error).__name__}: {error})".splitlines()[0]
    else:
        reason = compiled.unavailable_reason()
        if reason is None:
            version = compiled.library().version
            return "compiled", "requested" if engine == "compiled" else f"numba and SUNDIALS {version} available"
    if engine == "compiled":
        raise ImportError(f"engine 'compiled' is not available: {reason}")
    return "sksundae", f"compiled engine unavailable: {reason}"


def _numba_installed() -> bool:
    try:
        return importlib.util.find_spec("numba") is not None
    except (ImportError, ValueError):  # a module set to None in sys.modules (hidden), or a broken one
        return False


def loaded() -> set[str]:
    """The engines already loaded in this process ("compiled", "sksundae"): their first use is paid."""
    return ({"compiled"} if _COMPILED_MODULE in sys.modules else set()) | (
        {"sksundae"} if "sksundae.cvode" in sys.modules else set())


def note_sksundae_steps(steps: int) -> None:
    """Count steps run on scikit-sundae in this process (what engine "auto" weighs; see choose_engine)."""
    global _sksundae_steps
    _sksundae_steps += steps


def _install_numba() -> str:
    """How to add numba: the [fast] extra, as this bouncingball was installed (extras.install_command).

    The FMU's copy of the package (named otherwise) runs in a host Python that has no bouncingball to add an
    extra to: there, numba alone.
    """
    if __name__.split(".")[0] != "bouncingball":
        return "pip install numba, into the Python that runs the FMU"
    from ..extras import install_command

    return install_command("fast")
