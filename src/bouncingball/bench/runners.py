"""The solvers the benchmarks compare, one call each, and their errors against the exact solution."""

from __future__ import annotations

import inspect
import textwrap
import time
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..accuracy import Accuracy, ExactOnGrid, accuracy_of, exact_on_grid
from ..fmu import pythonfmu_workarounds
from ..fmu.variables import start_values_of
from ..scenes import Scene, load_scene
from ..solvers import ARTICLE_LABEL
from ..solvers.exact import ExactSolution
from ..solvers.result import IMPACT, AccuracyWarning, Event, output_grid

SCIPY_METHODS = ("RK45", "DOP853", "LSODA", "Radau", "BDF")
EXPLICIT_SCIPY_METHODS = ("RK45", "DOP853")


@dataclass(frozen=True)
class Solver:
    """One solver configuration: kind is cvode, scipy, article, exact, fmu, empty (the empty pythonfmu slave) or floor
    (the compiled engine's CVODE work in C, bench/c_floor.py)."""

    label: str
    kind: str
    method: str = ""
    comm_step: float = 0.0  # FMU communication step [s]
    engine: str = ""  # CVODE and the FMU: "sksundae" or "compiled"

    @property
    def takes_tolerances(self) -> bool:
        return self.kind in ("cvode", "scipy", "fmu", "floor")

    @property
    def is_fmu(self) -> bool:
        return self.kind in ("fmu", "empty")


def cvode(method: str, engine: str = "sksundae") -> Solver:
    """CVODE with method; the label names the engine unless it is scikit-sundae's."""
    suffix = "" if engine == "sksundae" else f" ({engine})"
    return Solver(f"CVODE {method}{suffix}", "cvode", method, engine=engine)


def scipy(method: str) -> Solver:
    return Solver(f"solve_ivp {method}", "scipy", method)


def fmu(comm_step: float, engine: str = "sksundae") -> Solver:
    """The FMU with its parameter engine, which the label names."""
    return Solver(f"FMU via FMPy ({engine}), {comm_step * 1e3:g} ms", "fmu", comm_step=comm_step, engine=engine)


def empty_slave(comm_step: float) -> Solver:
    return Solver(f"empty pythonfmu slave, {comm_step * 1e3:g} ms", "empty", comm_step=comm_step)


CVODE_AUTO = cvode("auto")
CVODE_COMPILED = cvode("auto", "compiled")
ARTICLE = Solver(ARTICLE_LABEL, "article", "RK45")
EXACT = Solver("exact solution", "exact")
EXACT_EVALUATION = Solver("exact solution, evaluation only", "evaluation")
C_FLOOR = Solver("C floor (the compiled engine's CVODE work in C)", "floor", "auto", engine="compiled")


@dataclass
class Run:
    """What one run produced: the grid t [s], h [m] and v [m/s] (None when not recorded), events, work, wall time."""

    t: np.ndarray | None
    h: np.ndarray | None
    v: np.ndarray | None
    events: list[Event] | None  # None: not observable (FMU); impacts says how many
    impacts: int | None
    rhs_calls: int | None
    steps: int
    wall_time: float
    wall_time_in_c: float | None = None  # the C floor: the part of wall_time spent in C


@dataclass(frozen=True)
class FmuPaths:
    """Extracted FMUs: the ball, and the empty slave that measures the overhead floor; error if the build failed.

    ball_fmu: the ball's .fmu file, to unzip afresh (numba's cache is then cold, as in simulate_fmu).
    """

    ball: Path | None
    empty: Path | None
    error: str = ""
    ball_fmu: Path | None = None
    ball3: Path | None = None  # the FMI 3.0 FMU and the empty pythonfmu3 slave, extracted (None: not built)
    empty3: Path | None = None


def run_solver(solver: Solver, scene: Scene, output_interval: float, rtol: float | None = None,
               atol: float | None = None, fmus: FmuPaths | None = None, record: bool = True) -> Run:
    """Run scene with solver on a grid of output_interval [s] (the FMU: its communication step).

    rtol None means the solver's defaults; atol None CVODE's rule (relative to each phase's scale), and
    for SciPy's methods rtol times the scene's height scale. record=False asks the FMU for h only (a timed run).
    """
    tolerances = {} if rtol is None else {"rtol": rtol} if atol is None else {"rtol": rtol, "atol": atol}
    if solver.is_fmu:
        return _run_fmu(solver, scene, tolerances, fmus, record)
    if solver.kind == "evaluation":
        return _run_exact_evaluation(scene, output_interval)
    if solver.kind == "floor":
        return _run_floor(solver, scene, output_interval, rtol, atol)
    options = {"output_interval": output_interval}
    if solver.kind == "cvode":
        options.update(method=solver.method, engine=solver.engine, **tolerances)
    elif solver.kind == "scipy":
        options.update(method=solver.method, max_step=0.0, **tolerances)
        if rtol is not None and atol is None:
            options["atol"] = rtol * max(abs(scene.h0), scene.ball.R)
    name = {"cvode": "cvode", "scipy": "scipy", "article": "scipy", "exact": "exact"}[solver.kind]
    with warnings.catch_warnings():
        # the work-precision runs loosen rtol on purpose and measure their errors: the warning says nothing here
        warnings.simplefilter("ignore", AccuracyWarning)
        started = time.perf_counter()
        result = scene.simulate(name, **options)
        wall_time = time.perf_counter() - started
    return Run(result.t, result.h, result.v, result.events, result.impacts, result.stats.rhs_calls,
               result.stats.steps, wall_time)


def warm_up() -> None:
    """Load both CVODE engines in this process (the compiled one where it runs) with a short run on each.

    What a capped child runs before its first timed run (capped.run_capped's warm_up), so that the
    run's time is its own, not the engines' loading.
    """
    from ..solvers.engine_selection import choose_engine

    choose_engine("auto")  # loads the compiled engine where it runs; "auto" then takes it for every run
    scene = load_scene("article")
    scene.simulate("cvode", t_end=0.5)
    scene.simulate("cvode", t_end=0.5, engine="sksundae")


def _run_exact_evaluation(scene: Scene, output_interval: float) -> Run:
    """The floor of the exact solution's time: its phases built untimed, then only the grid and the evaluation."""
    solution = ExactSolution(scene.ball, scene.h0, scene.v0, 0.0, scene.t_end, scene.F_ext)
    started = time.perf_counter()
    grid = output_grid(0.0, scene.t_end, output_interval)
    h, v = solution.state(grid)
    wall_time = time.perf_counter() - started
    events = list(solution.events)
    return Run(grid, h, v, events, sum(event.kind == IMPACT for event in events), None, len(solution.phases),
               wall_time)


def _run_floor(solver: Solver, scene: Scene, output_interval: float, rtol: float | None, atol: float | None) -> Run:
    from . import c_floor

    started = time.perf_counter()
    result = c_floor.run(scene.ball, scene.h0, scene.v0, scene.t_end, output_interval, scene.F_ext, rtol, atol,
                         solver.method)
    wall_time = time.perf_counter() - started
    return Run(result.t, result.h, result.v, result.events, sum(e.kind == IMPACT for e in result.events),
               result.rhs_calls, result.steps, wall_time, result.seconds_in_c)


# The warnings the ball FMU logged in the bench's runs (status >= fmi2Warning), kept out of the terminal: `bench`
# counts them in one line and writes their text into its report. FMPy's own logger would print each.
FMU_WARNINGS: list[str] = []


def _keep_fmu_warning(environment, instance_name, status, category, message) -> None:
    if status >= 1:  # fmi2Warning and worse; the OK lines (the compiled engine's first use) are notes
        FMU_WARNINGS.append(message.decode("utf-8", "replace"))


def _run_fmu(solver: Solver, scene: Scene, tolerances: dict, fmus: FmuPaths | None, record: bool) -> Run:
    from fmpy import simulate_fmu

    if fmus is None or fmus.error:
        raise RuntimeError(f"the FMUs could not be built: {fmus.error if fmus else 'not built'}")
    if solver.kind == "empty":
        path, output, start_values = fmus.empty, ["x"], {}
    else:
        path, output = fmus.ball, ["h", "v", "impacts"] if record else ["h"]
        start_values = {**start_values_of(scene), **tolerances}
        if solver.engine:
            start_values["engine"] = solver.engine
        if solver.engine == "compiled":  # where it cannot run here, it cannot in the FMU: say why
            from ..solvers.engine_selection import choose_engine

            choose_engine("compiled")
    # FMPy passes the DefaultExperiment's tolerance (the default rtol) unless told one, and the FMU's rtol is
    # the tighter of the two: a swept rtol looser than the default is passed as the tolerance too.
    started = time.perf_counter()
    result = simulate_fmu(str(path), start_time=0.0, stop_time=scene.t_end, output_interval=solver.comm_step,
                          start_values=start_values, output=output, relative_tolerance=tolerances.get("rtol"),
                          logger=_keep_fmu_warning)
    wall_time = time.perf_counter() - started
    names = result.dtype.names
    return Run(result["time"], result["h"] if "h" in names else None, result["v"] if "v" in names else None,
               None, int(result["impacts"][-1]) if "impacts" in names else None, None, len(result) - 1, wall_time)


def errors_against_exact(scene: Scene, run: Run) -> Accuracy:
    """Compare run with the exact solution on the run's own grid: by its events, or its impacts (FMU)."""
    return exact_and_errors(scene, run)[1]


def exact_and_errors(scene: Scene, run: Run) -> tuple[ExactOnGrid, Accuracy]:
    """The exact solution on the run's own grid, and errors_against_exact's record from it."""
    exact = exact_on_grid(run.t, scene.ball, scene.h0, scene.v0, scene.F_ext, t_start=0.0)
    return exact, accuracy_of(exact, run.h, events=run.events, impacts=run.impacts, v=run.v)


# The empty slaves are pythonfmu's (pythonfmu3's) binary alone: they carry the workarounds of its bugs themselves.
PYTHONFMU_WORKAROUNDS = inspect.getsource(pythonfmu_workarounds) + '''

keep_script_namespace(globals(), locals())
release_python_state_first(os.path.dirname(__file__))
'''
EMPTY_SLAVE_SCRIPT = '''\
"""An FMU that does nothing: the per-doStep cost any pythonfmu slave pays, stepped by the same master."""

from pythonfmu import Fmi2Slave, Real
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability


class BenchEmptySlave(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.0
        self.register_variable(Real("x", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.exact))

    def do_step(self, current_time, step_size):
        return True


''' + PYTHONFMU_WORKAROUNDS
# Two pythonfmu FMUs whose scripts share a module name cannot live in one process: keep this name distinctive.
EMPTY_SLAVE_MODULE = "bouncingball_bench_empty_slave"
EMPTY3_SLAVE_SCRIPT = '''\
"""An FMI 3.0 FMU that does nothing: the per-doStep cost any pythonfmu3 slave pays, stepped by the same master."""

from pythonfmu3 import Fmi3Slave, Float64
from pythonfmu3.enums import Fmi3Causality, Fmi3Initial, Fmi3Variability


class BenchEmptySlave3(Fmi3Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.time, self.x = 0.0, 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Float64("x", causality=Fmi3Causality.output, variability=Fmi3Variability.continuous,
                                       initial=Fmi3Initial.exact))

    def do_step(self, current_time, step_size):
        return True


''' + PYTHONFMU_WORKAROUNDS
EMPTY3_SLAVE_MODULE = "bouncingball_bench_empty3_slave"


def build_fmus(directory: Path) -> FmuPaths:
    """Build the ball's FMU and the empty slave into directory and extract both."""
    from fmpy import extract
    from pythonfmu import FmuBuilder

    from ..fmu.build import build_fmu

    try:
        ball = build_fmu(directory / "BouncingBall.fmu")
        script = directory / f"{EMPTY_SLAVE_MODULE}.py"
        script.write_text(textwrap.dedent(EMPTY_SLAVE_SCRIPT), encoding="utf-8")
        empty = FmuBuilder.build_FMU(script, dest=directory)
    except Exception as error:  # no compiler, unsupported platform...: the FMU rows say why
        return FmuPaths(None, None, f"{type(error).__name__}: {error}")
    paths = FmuPaths(Path(extract(str(ball), str(directory / "ball"))),
                     Path(extract(str(empty), str(directory / "empty"))), ball_fmu=Path(ball))
    try:
        from pythonfmu3 import FmuBuilder as Fmu3Builder

        ball3 = build_fmu(directory / "BouncingBall3.fmu", fmi_version=3)
        script = directory / f"{EMPTY3_SLAVE_MODULE}.py"
        script.write_text(textwrap.dedent(EMPTY3_SLAVE_SCRIPT), encoding="utf-8")
        empty3 = Fmu3Builder.build_FMU(script, dest=directory)
    except Exception:  # without pythonfmu3: the FMI 3.0 rows are left out
        return paths
    return replace(paths, ball3=Path(extract(str(ball3), str(directory / "ball3"))),
                               empty3=Path(extract(str(empty3), str(directory / "empty3"))))
