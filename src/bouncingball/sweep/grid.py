"""The sweep's parameter grid: ranges of k, the damping (zeta, or alpha for Hunt-Crossley), m and h0; the solvers.

No Dask, pandas or pyarrow here: the grid is checked before any cluster starts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import validation
from ..bench import runners
from ..contact_laws import CONTACT_LAWS, LAWS
from ..physics import Ball
from ..scenes import SCENE_DEFAULTS, Scene
from ..solvers.phase_machine.settings import DEFAULT_ATOL, DEFAULT_RTOL, METHODS

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
UNITS = {"k": "N/m", "zeta": "", "alpha": "s/m", "m": "kg", "h0": "m"}
DEFAULT_CONTACT = CONTACT_LAWS[0]  # the registry's default law: its runs' keys and pages name no law
# The contact laws whose balls the grid describes: those with a k and a damping to map (ContactLaw.damping_axis).
MAPPED_CONTACT_LAWS = tuple(name for name, law in LAWS.items() if law.damping_axis is not None)
# The law parameters the grid holds fixed where a law reads them: n at Hertz's 1.5 for spheres (the Hunt-Crossley
# law's grid is then k [N/m^1.5] and alpha [s/m], alpha = 0 the undamped Hertz contact).
HC_N = 1.5
HELD = {"n": HC_N}
DEFAULT_HC_K = (1e3, 1e9, 13)  # N/m^1.5, half decades
DEFAULT_ALPHA_TEXT = "0,1e-4:1:9"  # s/m: 0 and half decades (DEFAULT_ALPHA, below)
QUICK_HC_K = (1e3, 1e9, 3)
QUICK_ALPHA = (0.0, 1e-2, 1.0)
# k's (default, quick) range by its unit (k_unit): a stiffness's scale depends on its unit.
K_RANGES = {"N/m": (DEFAULT_K, QUICK_K), f"N/m^{HC_N:g}": (DEFAULT_HC_K, QUICK_HC_K)}


def check_contact(name: str, value: object) -> str:
    """The contact law, spelled as in MAPPED_CONTACT_LAWS; ValueError naming name and the laws (the rigid law: why)."""
    try:
        return validation.choice(name, value, MAPPED_CONTACT_LAWS)
    except ValueError as error:
        law = LAWS.get(str(value).lower())
        why = f" (the {law.name} law has no k or damping to map)" if law is not None else ""
        raise ValueError(f"{error}{why}") from None


def damping_field(contact: str) -> str:
    """The grid's damping axis for a contact law (ContactLaw.damping_axis): "zeta", or "alpha" (Hunt-Crossley)."""
    return LAWS[contact].damping_axis


def k_unit(contact: str) -> str:
    """The unit of k under a contact law (ContactLaw.k_unit) at the parameters HELD: N/m, or N/m^1.5 (Hunt-Crossley)."""
    return LAWS[contact].k_unit.format(**HELD)


def held(contact: str) -> dict[str, float]:
    """The parameters HELD that the contact law reads (n under the Hunt-Crossley law), by name."""
    return {name: value for name, value in HELD.items() if name in LAWS[contact].parameters}


def range_fields(contact: str) -> tuple[str, ...]:
    """The grid's axes that are (low, high, points) ranges under a contact law: zeta is one, alpha a list of values."""
    return ("k", "zeta", "m", "h0") if damping_field(contact) == "zeta" else ("k", "m", "h0")


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


ALPHA_FORM = "comma-separated values >= 0 and LO:HI:N log-spaced ranges (0 < LO <= HI), e.g. 0,1e-4:1:5"


def parse_alpha(text: str) -> tuple[float, ...]:
    """Parse the Hunt-Crossley damping axis, "0,1e-4:1:5" (0 and 5 log-spaced values), into sorted values [s/m].

    Raises
    ------
    ValueError
        Naming --alpha, the value and the allowed form, if an item is malformed, negative or not finite.

    Examples
    --------
    >>> parse_alpha("0,1e-2:1:3")
    (0.0, 0.01, 0.1, 1.0)
    """
    values: list[float] = []
    for item in text.split(","):
        if ":" in item:
            try:
                values += log_points(*parse_range("alpha", item.strip()))
            except ValueError:
                raise ValueError(f"--alpha = {text!r} is not allowed: {item.strip()!r} is not LO:HI:N with "
                                 f"0 < LO <= HI and 1 <= N <= {MAX_POINTS}; it must be {ALPHA_FORM}") from None
            continue
        try:
            value = float(item)
        except ValueError:
            raise ValueError(f"--alpha = {text!r} is not allowed: it must be {ALPHA_FORM}") from None
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f"--alpha = {text!r} is not allowed: {item.strip()} s/m is not finite and >= 0; "
                             f"it must be {ALPHA_FORM}")
        values.append(value)
    return check_alpha(values)


def check_alpha(values) -> tuple[float, ...]:
    """The alpha axis as sorted distinct floats [s/m]; ValueError naming alpha unless each is finite and >= 0."""
    if isinstance(values, str) or not 1 <= len(values) <= MAX_POINTS:
        raise ValueError(f"alpha = {values!r} is not allowed: it must be 1 to {MAX_POINTS} values [s/m], "
                         "each finite and >= 0")
    return tuple(sorted({validation.non_negative("alpha", value, "s/m") for value in values}))


def log_points(low: float, high: float, points: int) -> tuple[float, ...]:
    """points log-spaced values from low to high, both included (exactly)."""
    if points == 1:
        return (float(low),)
    values = np.logspace(math.log10(low), math.log10(high), points)
    values[0], values[-1] = low, high
    return tuple(float(x) for x in values)


DEFAULT_ALPHA = parse_alpha(DEFAULT_ALPHA_TEXT)


def default_k(contact: str, quick: bool = False) -> tuple[float, float, int]:
    """The k axis a contact law's grid has by default (with quick the small one's), by k's unit: K_RANGES."""
    return K_RANGES[k_unit(contact)][quick]


def refuse_other_damping(contact: str, zeta, alpha, alpha_unit: str, what: str) -> None:
    """ValueError if the damping field that contact does not use is given.

    That is zeta under the Hunt-Crossley law, alpha under the linear laws. what: "damping" for a cell,
    "damping axis" for a grid; alpha_unit: how alpha's value is shown (" s/m" for a number).
    """
    axis = damping_field(contact)
    if axis != "zeta" and zeta is not None:
        raise ValueError(f"zeta = {zeta!r} is not allowed with contact = {contact!r}: its {what} is {axis} "
                         f"[{UNITS[axis]}], not a damping ratio")
    if axis != "alpha" and alpha is not None:
        raise ValueError(f"alpha = {alpha!r}{alpha_unit} is not allowed with contact = {contact!r}: its {what} is the "
                         "damping ratio zeta")


@dataclass(frozen=True)
class Cell:
    """One point of the parameter space: stiffness k, damping, mass m [kg], drop height h0 [m].

    contact: the ball's contact law, one of MAPPED_CONTACT_LAWS. Under the linear laws k is in N/m and the
    damping is the damping ratio zeta (alpha None); under the Hunt-Crossley law k is in N/m^1.5, n = HC_N,
    and the damping is alpha [s/m] (zeta None).
    """

    k: float
    zeta: float | None
    m: float
    h0: float
    contact: str = DEFAULT_CONTACT
    alpha: float | None = None

    def __post_init__(self) -> None:
        contact = check_contact("contact", self.contact)
        object.__setattr__(self, "contact", contact)
        refuse_other_damping(contact, self.zeta, self.alpha, " s/m", "damping")
        if damping_field(contact) == "alpha":
            if self.alpha is None:
                raise ValueError(f"alpha = None is not allowed with contact = {contact!r}: it must be finite "
                                 "and >= 0 [s/m]")
            object.__setattr__(self, "alpha", validation.non_negative("alpha", self.alpha, "s/m"))

    @property
    def damping(self) -> float:
        """The value on the grid's damping axis: alpha [s/m] under the Hunt-Crossley law, else zeta."""
        return getattr(self, damping_field(self.contact))

    @property
    def b(self) -> float | None:
        """The damping coefficient b = 2 zeta sqrt(k m) [N s/m]; None under the Hunt-Crossley law (no linear damper)."""
        return None if self.zeta is None else 2.0 * self.zeta * math.sqrt(self.k * self.m)

    def scene(self, t_end: float, output_interval: float) -> Scene:
        """The cell as a Scene: the article's R and g, dropped at rest from h0 (the law's parameters HELD as held)."""
        damping = damping_field(self.contact)
        law_damping = {"b": self.b} if damping == "zeta" else {damping: self.damping}
        ball = Ball(m=self.m, k=self.k, R=ARTICLE_BALL.R, g=ARTICLE_BALL.g, contact=self.contact, **law_damping,
                    **held(self.contact))
        return Scene(f"k={self.k:.3g},{damping}={self.damping:.3g},m={self.m:.3g},h0={self.h0:.3g}", "sweep cell",
                     ball, self.h0, 0.0, t_end, output_interval)


def cell_of(run: dict) -> Cell:
    """The Cell of a run from Grid.runs() (or a table's row): its zeta or alpha, the other NaN or absent."""
    def given(field):
        value = run.get(field)
        return None if value is None or (isinstance(value, float) and math.isnan(value)) else value

    return Cell(run["k"], given("zeta"), run["m"], run["h0"], run.get("contact", DEFAULT_CONTACT), given("alpha"))


@dataclass(frozen=True)
class Grid:
    """A log-spaced grid: each axis a (low, high, points) triple; every cell is run by every solver.

    The damping axis is zeta under the linear laws (default DEFAULT_ZETA) and alpha [s/m] under the Hunt-Crossley
    law (its values, default DEFAULT_ALPHA: 0 is on no log scale); the other is None. k defaults to DEFAULT_K
    [N/m], or DEFAULT_HC_K [N/m^1.5] under the Hunt-Crossley law.

    Examples
    --------
    >>> grid = Grid(k=(1e2, 1e6, 3), zeta=(1e-2, 1.0, 2), solvers=("cvode", "article"))
    >>> len(grid.cells()), len(grid.runs())
    (6, 12)
    """

    k: tuple[float, float, int] | None = None
    zeta: tuple[float, float, int] | None = None
    m: tuple[float, float, int] = DEFAULT_M
    h0: tuple[float, float, int] = DEFAULT_H0
    t_end: float = DEFAULT_T_END
    output_interval: float = DEFAULT_OUTPUT_INTERVAL
    solvers: tuple[str, ...] = DEFAULT_SOLVERS
    contact: str = DEFAULT_CONTACT
    alpha: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        contact = check_contact("contact", self.contact)
        object.__setattr__(self, "contact", contact)
        refuse_other_damping(contact, self.zeta, self.alpha, "", "damping axis")
        if damping_field(contact) == "alpha":
            object.__setattr__(self, "alpha", check_alpha(DEFAULT_ALPHA if self.alpha is None else self.alpha))
        else:
            object.__setattr__(self, "zeta", DEFAULT_ZETA if self.zeta is None else self.zeta)
        if self.k is None:
            object.__setattr__(self, "k", default_k(contact))
        for field in range_fields(contact):
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
        other = next((name for name in names if not name.startswith("cvode")), None)
        if not LAWS[contact].article_algorithm and other is not None:
            raise ValueError(f"solver = {other!r} is not allowed with contact = {contact!r}: the article's algorithm "
                             "and SciPy's methods model a contact force that is a function of the state (the linear "
                             "and Hunt-Crossley laws); use cvode, cvode:Adams or cvode:BDF")
        runs = len(self.cells()) * len(names)
        if runs > MAX_RUNS:
            raise ValueError(f"the grid = {runs} runs is not allowed: at most {MAX_RUNS}")

    @property
    def damping(self) -> str:
        """The damping axis' field: "zeta", or "alpha" under the Hunt-Crossley law."""
        return damping_field(self.contact)

    def axis(self, field: str) -> tuple[float, ...]:
        """The values of one axis ("k", "zeta" or "alpha" as the law has, "m" or "h0")."""
        if field == "alpha" and self.alpha is not None:
            return self.alpha
        if getattr(self, field, None) is None:
            raise ValueError(f"axis = {field!r} is not allowed with contact = {self.contact!r}: its axes are k, "
                             f"{self.damping}, m and h0")
        return log_points(*getattr(self, field))

    def cells(self) -> list[Cell]:
        """Every cell of the grid, k varying fastest."""
        by_zeta = self.damping == "zeta"
        return [Cell(k, damping if by_zeta else None, m, h0, self.contact, None if by_zeta else damping)
                for m in self.axis("m") for h0 in self.axis("h0") for damping in self.axis(self.damping)
                for k in self.axis("k")]

    def runs(self) -> list[dict]:
        """Every (cell, solver) as the plain dict a worker receives; key identifies it for --resume.

        A field the law has not (zeta and b, or alpha and n) is NaN, so that each table column is of floats.
        """
        n = held(self.contact).get("n", math.nan)
        return [{"key": run_key(cell, solver, self.t_end, self.output_interval), "k": cell.k,
                 "zeta": _or_nan(cell.zeta), "m": cell.m, "h0": cell.h0, "b": _or_nan(cell.b),
                 "alpha": _or_nan(cell.alpha), "n": n, "t_end": self.t_end,
                 "output_interval": self.output_interval, "solver": solver, "contact": cell.contact}
                for cell in self.cells() for solver in self.solvers]


def run_key(cell: Cell, solver: str, t_end: float, output_interval: float) -> str:
    """A text key that identifies one run exactly (floats as repr); the linear law's keys name no law (as before).

    A Hunt-Crossley cell's key names its alpha where the linear laws' hold zeta.
    """
    law = "" if cell.contact == DEFAULT_CONTACT else f"|{cell.contact}"
    field = damping_field(cell.contact)
    damping = repr(cell.zeta) if field == "zeta" else f"{field}={cell.damping!r}"
    return f"{solver}|{cell.k!r}|{damping}|{cell.m!r}|{cell.h0!r}|{t_end!r}|{output_interval!r}{law}"


def _or_nan(value: float | None) -> float:
    """A field the cell's law has not (None) as NaN, so that each table column is of floats."""
    return math.nan if value is None else value
