"""The result type shared by every solver, and the output grid."""

from __future__ import annotations

import math
import os
import sys
import warnings
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from .. import codes
from ..ground import Ground
from ..limits import check_output_interval
from ..physics import Ball
from .forcing import ForceTable
from .lyapunov import LyapunovExponent
from .phase_machine.settings import DEFAULT_RTOL, MIN_RTOL, PROMISE


class EventKind(StrEnum):
    """What a mode switch is: an impact starts a contact, a departure ends one.

    A str enum, like `physics.Mode` an enum: it compares equal to, prints and writes to CSV as its
    value ("impact", "departure"). Under the no-pull law a contact also has its sub-mode switches below
    R, where the force k (R - h) - b v crosses 0: a release (pressed to free: the force would pull) and
    an engagement (free to pressed); a departure there leaves the free sub-mode.
    """

    IMPACT = codes.EVENT_KIND_NAMES[codes.IMPACT]
    DEPARTURE = codes.EVENT_KIND_NAMES[codes.DEPARTURE]
    RELEASE = codes.EVENT_KIND_NAMES[codes.RELEASE]
    ENGAGE = codes.EVENT_KIND_NAMES[codes.ENGAGE]


IMPACT = EventKind.IMPACT
DEPARTURE = EventKind.DEPARTURE
RELEASE = EventKind.RELEASE
ENGAGE = EventKind.ENGAGE
EVENT_KINDS = tuple(EventKind(name) for name in codes.EVENT_KIND_NAMES)  # by the machine's code (codes.IMPACT ..)


@dataclass(frozen=True)
class Event:
    """A mode switch: time [s], kind (impact, departure; release or engage) and the velocity there [m/s]."""

    time: float
    kind: EventKind
    velocity: float


@dataclass
class SolverStats:
    """Work done: internal steps, right-hand-side calls, events and wall time [s].

    For CVODE also the engine that ran ("compiled" or "sksundae"), why it was chosen, and
    first_use_time [s]: making the engine ready before the run (on its first use in the process:
    importing numba and compiling its functions or loading them from numba's disk cache, or
    importing scikit-sundae; its CVODE objects), which wall_time leaves out.
    """

    steps: int = 0
    rhs_calls: int = 0
    events: int = 0
    wall_time: float = 0.0
    engine: str = ""
    engine_reason: str = ""
    first_use_time: float = 0.0


@dataclass
class SimulationResult:
    """What a solver returns: height h [m] and velocity v [m/s] on the output grid t [s], events and work.

    Attributes
    ----------
    solver : str
        "cvode", "exact" or "scipy".
    ball : Ball
        The ball simulated.
    t, h, v : numpy.ndarray
        The output grid [s] (its last point is t_end exactly), height [m] and velocity [m/s] there.
    events : list of Event
        Every impact and departure in time order, located by the solver (not at grid points).
    rest_time : float or None
        Start [s] of the contact that never ends (the ball at rest; on a moving ground, riding it for
        good), or None.
    stats : SolverStats
        Steps, right-hand-side calls, events, wall time; for CVODE the engine and why.
    F_ext : float or ForceTable
        The external force [N]: a float when it was constant, the validated forcing.ForceTable
        (times, values) when it was a table.
    options : dict
        The solver's settings as used (for CVODE also the method chosen in contact).
    error_estimate : float or None
        An estimate of max |h - h_true| [m] over the output grid, from what the run did (for CVODE
        each phase's own error against its exact flow, carried by the run's sensitivity: see
        README, "How far from the truth"); the exact solver's is its rounding; None for the SciPy
        reference, which does not estimate it.
    ground : Ground
        The ground under the ball (still at 0 unless the run was given another).
    lyapunov : LyapunovExponent or None
        The run's largest Lyapunov exponent, per impact and per second, from the same transition and saltation
        matrices as its error estimate (solvers.lyapunov): over its flights since the last rest or ride (-inf
        where it ends resting or riding), NaN where too short to say; None for the solvers that do not compute it
        (so far all but "exact").

    Examples
    --------
    >>> import bouncingball as bb
    >>> result = bb.simulate(bb.Ball(), 2.0, 0.0, 1.0, solver="exact")
    >>> [str(event.kind) for event in result.events]
    ['impact', 'departure']
    >>> round(result.events[0].time, 6)  # sqrt(2 (h0 - R) / g)
    0.6289
    >>> result.impacts, result.rest_time is None
    (1, True)
    """

    solver: str
    ball: Ball
    t: np.ndarray
    h: np.ndarray
    v: np.ndarray
    events: list[Event]
    rest_time: float | None
    stats: SolverStats
    F_ext: float | ForceTable = 0.0
    options: dict = field(default_factory=dict)
    error_estimate: float | None = None
    ground: Ground = field(default_factory=Ground)
    lyapunov: LyapunovExponent | None = None

    @property
    def event_times(self) -> np.ndarray:
        """The events' times [s]."""
        return np.array([e.time for e in self.events])

    @property
    def impacts(self) -> int:
        """How many of the events are impacts."""
        return sum(e.kind == IMPACT for e in self.events)

    @property
    def energy(self) -> np.ndarray:
        """Total energy [J] on the output grid; with a table, the potential -F_ext h of the force at each time."""
        F_ext = self.F_ext.at(self.t) if isinstance(self.F_ext, ForceTable) else self.F_ext
        return self.ball.energy(self.h, self.v, F_ext)


class AccuracyWarning(UserWarning):
    """A run's error estimate passes the promise, 1e-6 of its height scale max(|h|, R).

    The result is not to be trusted from the time the warning names (an ill-conditioned run, or one
    double precision cannot follow). It is still returned, with its error_estimate.
    """


def accuracy_warning(estimate: float, scale: float, since: float, now: float,
                     rtol: float = DEFAULT_RTOL) -> AccuracyWarning | None:
    """The AccuracyWarning for an error estimate [m] by the time now [s], past the promise from since [s].

    The promise is judged at the height scale [m]. None where the estimate is within the promise.
    """
    if estimate <= PROMISE * scale:
        return None
    if rtol > DEFAULT_RTOL:  # a tolerance the user loosened: the promise is made at the defaults
        advice = (f"rtol = {rtol:g} is looser than the default {DEFAULT_RTOL:g}, which the promise is made at: "
                  f"tighten rtol to {DEFAULT_RTOL:g} or below")
    elif rtol > MIN_RTOL:
        advice = (f"a small error grows fast here (an ill-conditioned run): tighten rtol (now {rtol:g}), which "
                  f"shrinks the estimate, down to rtol = {MIN_RTOL:g}")
    else:
        advice = (f"no setting can help: rtol is already the tightest, {MIN_RTOL:g}, and a small error grows faster "
                  "here than double precision can follow (an ill-conditioned run); shorten the run")
    return AccuracyWarning(f"by t = {now:.6g} s the run's error estimate is {estimate:.2g} m, {estimate / scale:.2g} "
                           f"of its height scale {scale:.3g} m: past the promise of {PROMISE:g} from t = "
                           f"{since:.6g} s on; {advice}")


def warn_at_caller(warning: Warning) -> None:
    """warnings.warn(warning), attributed to the first caller outside this package: the user's line.

    The warning is issued from deep inside a solver, at a depth that depends on the path (simulate,
    BallIntegrator.advance, the FMU); a fixed stacklevel would point into the package.
    """
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep
    frame, level = sys._getframe(0), 1
    while frame is not None and frame.f_code.co_filename.startswith(package):
        frame, level = frame.f_back, level + 1
    warnings.warn(warning, stacklevel=level)


DEFAULT_OUTPUT_INTERVAL = 1e-3  # s: the article's output grid, every default grid's (simulate, scenes, bench)
MAX_OUTPUT_POINTS = 50_000_000  # 1.2 GB of t, h and v: more would exhaust a workstation's memory


def output_grid(t_start: float, t_end: float, output_interval: float) -> np.ndarray:
    """t_start, t_start + dt, ... and t_end exactly as the last point: strictly increasing times.

    ValueError for t_end before t_start, beyond MAX_OUTPUT_POINTS, or for an output_interval below a few
    ulps of the times (limits.check_output_interval), which double precision cannot tell apart.
    """
    if not t_end >= t_start:  # NaN too
        raise ValueError(f"t_end = {t_end!r} s is not allowed: it must be >= t_start = {t_start!r} s")
    check_output_interval(t_start, t_end, output_interval)
    n = math.floor((t_end - t_start) / output_interval * (1.0 + 1e-12))
    if n + 1 > MAX_OUTPUT_POINTS:
        raise ValueError(f"output_interval = {output_interval!r} s is not allowed from {t_start!r} to {t_end!r} s: "
                         f"it gives {n + 1:.4g} output points, more than {MAX_OUTPUT_POINTS:.0e}; "
                         f"choose output_interval >= {(t_end - t_start) / (MAX_OUTPUT_POINTS - 1):.3g} s")
    grid = t_start + output_interval * np.arange(n + 1)
    if t_end - grid[-1] > 1e-9 * output_interval:
        grid = np.append(grid, t_end)
    grid[-1] = t_end
    if not np.all(np.diff(grid) > 0.0):  # cannot happen above MIN_GRID_ULPS ulps: a bug if it does
        raise AssertionError(f"output grid from {t_start!r} to {t_end!r} s every {output_interval!r} s "
                             "does not increase strictly")
    return grid
