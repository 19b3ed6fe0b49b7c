"""The sweep's parameter grid: log-spaced ranges of k, damping ratio, m and h0, and the solvers to run.

No Dask, pandas or pyarrow here: the grid is checked before any cluster starts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import validation
from ..bench import runners
from ..physics import Ball
from ..scenes import SCENE_DEFAULTS, Scene
from ..solvers.settings import DEFAULT_ATOL, DEFAULT_RTOL, METHODS

ARTICLE_BALL = Ball()  # every cell keeps its R and g, and its m by default
DEFAULT_K = (1e2, 1e14, 13)  # N/m: (low, high, points), log-spaced
DEFAULT_ZETA = (1e-4, 1e2, 7)  # damping ratio b / (2 sqrt(k m))
DEFAULT_M = (ARTICLE_BALL.m, ARTICLE_BALL.m, 1)  # kg
DEFAULT_H0 = (SCENE_DEFAULTS["h0"], SCENE_DEFAULTS["h0"], 1)  # m
DEFAULT_T_END = SCENE_DEFAULTS["t_end"]  # s
DEFAULT_OUTPUT_INTERVAL = SCENE_DEFAULTS["output_interval"]  # s
DEFAULT_SOLVERS = ("cvode", "article", "scipy:DOP853")
QUICK_K = (1e2, 1e14, 4)
QUICK_ZETA = (1e-4, 1e2, 3)
MAX_POINTS = 1000  # per axis: a bigger grid is a typo, not a study
MAX_RUNS = 1_000_000
UNITS = {"k": "N/m", "zeta": "", "m": "kg", "h0": "m"}
# The contact laws whose balls the (k, zeta) grid describes: the rigid law has neither.
MAPPED_CONTACT_LAWS = ("linear", "linear-no-pull")


def solver_names() -> tuple[str, ...]:
    """Every solver spelling the sweep accepts: cvode[:METHOD], article, scipy:METHOD."""
    cvode = ("cvode", *(f"cvode:{method}" for method in METHODS if method != "auto"))
    return (*cvode, "article", *(f"scipy:{method}" for method in runners.SCIPY_METHODS))


def solver_spec(name: str) -> runners.Solver:
    """The bench's Solver spec for a sweep solver name (the same names as the CLI and the bench).

    "cvode" is CVODE with method auto and engine auto (compiled where numba can run it), "cvode:BDF"
    fixes the method; "article" is the reference article's solve_ivp RK45 with max_step 0.01 at
    SciPy's tolerances; "scipy:METHOD" is solve_ivp METHOD with unbounded steps.

    Raises
    ------
    ValueError
        If name is not one of solver_names().
    """
    name = validation.choice("solver", name, solver_names())
    if name == "article":
        return runners.ARTICLE
    kind, _, method = name.partition(":")
    if kind == "cvode":
        return runners.cvode(method or "auto", engine="auto")
    return runners.scipy(method)


def tolerances(name: str) -> tuple[float | None, float | None]:
    """(rtol, atol) for a solver: CVODE's defaults for every solver that takes them, None for the article's.

    atol None: CVODE's rule relative to each phase, rtol times the scene's height for SciPy's methods.
    """
    return (None, None) if name == "article" else (DEFAULT_RTOL, DEFAULT_ATOL)


def parse_range(field: str, text: str) -> tuple[float, float, int]:
    """Parse "LO:HI:N" (or a single value "X") into (low, high, points).

    Raises
    ------
    ValueError
        Naming the field, the value and the allowed form, if text is malformed, a bound is not
        finite and > 0, HI < LO, N < 1, or N > 1 with LO == HI.

    Examples
    --------
    >>> parse_range("k", "1e2:1e14:13")
    (100.0, 100000000000000.0, 13)
    >>> parse_range("m", "2")
    (2.0, 2.0, 1)
    """
    parts = text.split(":")
    allowed = f"it must be LO:HI:N with 0 < LO <= HI and 1 <= N <= {MAX_POINTS}, or a single value > 0"
    try:
        if len(parts) == 1:
            low = high = float(parts[0])
            points = 1
        elif len(parts) == 3:
            low, high, points = float(parts[0]), float(parts[1]), int(parts[2])
        else:
            raise ValueError
    except ValueError:
        raise ValueError(f"--{field} = {text!r} is not allowed: {allowed}") from None
    if not (math.isfinite(low) and math.isfinite(high) and 0.0 < low <= high and 1 <= points <= MAX_POINTS):
        raise ValueError(f"--{field} = {text!r} is not allowed: {allowed}")
    if points > 1 and low == high:
        raise ValueError(f"--{field} = {text!r} is not allowed: {points} points need LO < HI")
    return low, high, points


def log_points(low: float, high: float, points: int) -> tuple[float, ...]:
    """points log-spaced values from low to high, both included (exactly)."""
    if points == 1:
        return (float(low),)
    values = np.logspace(math.log10(low), math.log10(high), points)
    values[0], values[-1] = low, high
    return tuple(float(x) for x in values)


@dataclass(frozen=True)
class Cell:
    """One point of the parameter space: stiffness k [N/m], damping ratio zeta, mass m [kg], drop height h0 [m].

    contact: the ball's contact law, one of MAPPED_CONTACT_LAWS.
    """

    k: float
    zeta: float
    m: float
    h0: float
    contact: str = "linear"

    @property
    def b(self) -> float:
        """The damping coefficient b = 2 zeta sqrt(k m) [N s/m]."""
        return 2.0 * self.zeta * math.sqrt(self.k * self.m)

    def scene(self, t_end: float, output_interval: float) -> Scene:
        """The cell as a Scene: the article's R and g, dropped at rest from h0."""
        ball = Ball(m=self.m, k=self.k, b=self.b, R=ARTICLE_BALL.R, g=ARTICLE_BALL.g, contact=self.contact)
        return Scene(f"k={self.k:.3g},zeta={self.zeta:.3g},m={self.m:.3g},h0={self.h0:.3g}", "sweep cell",
                     ball, self.h0, 0.0, t_end, output_interval)


@dataclass(frozen=True)
class Grid:
    """A log-spaced grid: each axis a (low, high, points) triple; every cell is run by every solver.

    Examples
    --------
    >>> grid = Grid(k=(1e2, 1e6, 3), zeta=(1e-2, 1.0, 2), solvers=("cvode", "article"))
    >>> len(grid.cells()), len(grid.runs())
    (6, 12)
    """

    k: tuple[float, float, int] = DEFAULT_K
    zeta: tuple[float, float, int] = DEFAULT_ZETA
    m: tuple[float, float, int] = DEFAULT_M
    h0: tuple[float, float, int] = DEFAULT_H0
    t_end: float = DEFAULT_T_END
    output_interval: float = DEFAULT_OUTPUT_INTERVAL
    solvers: tuple[str, ...] = DEFAULT_SOLVERS
    contact: str = "linear"

    def __post_init__(self) -> None:
        for field in ("k", "zeta", "m", "h0"):
            low, high, points = getattr(self, field)
            text = f"{low!r}:{high!r}:{points!r}"
            if isinstance(points, bool) or not isinstance(points, int):
                raise ValueError(f"{field} = {text} is not allowed: N must be an integer")
            object.__setattr__(self, field, parse_range(field, text))
        t_end = validation.positive("t_end", self.t_end, "s")
        object.__setattr__(self, "t_end", t_end)
        object.__setattr__(self, "output_interval",
                           validation.in_range("output_interval", self.output_interval, 0.0, t_end, "s"))
        if isinstance(self.solvers, str) or not self.solvers:
            raise ValueError(f"solvers = {self.solvers!r} is not allowed: it must be a non-empty list of "
                             f"{', '.join(solver_names())}")
        names = tuple(dict.fromkeys(validation.choice("solver", name, solver_names()) for name in self.solvers))
        object.__setattr__(self, "solvers", names)
        contact = validation.choice("contact", self.contact, MAPPED_CONTACT_LAWS)
        object.__setattr__(self, "contact", contact)
        other = next((name for name in names if not name.startswith("cvode")), None)
        if contact != "linear" and other is not None:
            raise ValueError(f"solver = {other!r} is not allowed with contact = {contact!r}: the article's algorithm "
                             "and SciPy's methods model the linear contact law only; use cvode, cvode:Adams or "
                             "cvode:BDF")
        runs = len(self.cells()) * len(names)
        if runs > MAX_RUNS:
            raise ValueError(f"the grid = {runs} runs is not allowed: at most {MAX_RUNS}")

    def axis(self, field: str) -> tuple[float, ...]:
        """The values of one axis ("k", "zeta", "m" or "h0")."""
        return log_points(*getattr(self, field))

    def cells(self) -> list[Cell]:
        """Every cell of the grid, k varying fastest."""
        return [Cell(k, zeta, m, h0, self.contact) for m in self.axis("m") for h0 in self.axis("h0")
                for zeta in self.axis("zeta") for k in self.axis("k")]

    def runs(self) -> list[dict]:
        """Every (cell, solver) as the plain dict a worker receives; key identifies it for --resume."""
        return [{"key": run_key(cell, solver, self.t_end, self.output_interval), "k": cell.k, "zeta": cell.zeta,
                 "m": cell.m, "h0": cell.h0, "b": cell.b, "t_end": self.t_end,
                 "output_interval": self.output_interval, "solver": solver, "contact": cell.contact}
                for cell in self.cells() for solver in self.solvers]


def run_key(cell: Cell, solver: str, t_end: float, output_interval: float) -> str:
    """A text key that identifies one run exactly (floats as repr); the linear law's keys name no law (as before)."""
    law = "" if cell.contact == "linear" else f"|{cell.contact}"
    return f"{solver}|{cell.k!r}|{cell.zeta!r}|{cell.m!r}|{cell.h0!r}|{t_end!r}|{output_interval!r}{law}"
