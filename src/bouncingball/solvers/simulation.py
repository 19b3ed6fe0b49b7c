"""simulate: one call, three solvers: CVODE (default), the exact solution and the article's SciPy algorithm."""

from __future__ import annotations

import dataclasses
import functools
import inspect

from .. import limits, validation
from ..ground import Ground, as_ground
from ..physics import Ball
from . import forcing
from .forcing import ForceTable
from .phase_machine.settings import DEFAULT_RTOL, CvodeSettings
from .result import DEFAULT_OUTPUT_INTERVAL, SimulationResult

SOLVERS = ("cvode", "exact", "scipy")
_COMMON_PARAMETERS = ("ball", "h0", "v0", "t_end", "output_interval", "t_start", "F_ext", "ground")


def simulate(ball: Ball, h0: float, v0: float, t_end: float, output_interval: float = DEFAULT_OUTPUT_INTERVAL,
             solver: str = "cvode", *, t_start: float = 0.0, F_ext: float | ForceTable | tuple = 0.0,
             ground: Ground | None = None, **options) -> SimulationResult:
    """Simulate the ball from (h0 [m], v0 [m/s]) at t_start to t_end [s] on a grid of output_interval [s].

    Parameters
    ----------
    ball : Ball
        The ball.
    h0, v0 : float
        Height of the centre [m] and velocity [m/s], positive upwards, at t_start.
    t_end : float
        End time [s], > t_start; the last output point is exactly t_end.
    output_interval : float, optional
        Spacing of the output grid [s], in (0, t_end - t_start]; 1 ms by default.
    solver : {"cvode", "exact", "scipy"}, optional
        CVODE with root-finding (default), the exact piecewise-analytic solution, or the reference
        article's SciPy algorithm (needs the [reference] extra).
    t_start : float, optional
        Start time [s].
    F_ext : float or (times, values), optional
        External force [N], positive upwards: a constant, or a piecewise-constant table (times [s]
        strictly increasing, values [N], as many) held at values[i] over [times[i], times[i+1]),
        at values[0] before times[0] and values[-1] after the last time (a ForceTable will do).
        Every solver runs a table piece by piece: the state is continuous at a change, the mode held.
    ground : Ground, optional
        The ground under the ball: still at height 0 by default (Ground.still(height) is the same run
        shifted, for every solver); a moving one is taken by solver="exact", under the rigid law
        (Ground.sine, Ground.table) and the linear and linear-no-pull laws (Ground.sine), and by
        solver="cvode" under every law (Ground.sine). h stays the centre's height in the world frame.
    **options
        For cvode: rtol, atol, method ("auto", "Adams", "BDF"), max_step [s] (0: unbounded),
        engine ("auto", "compiled", "sksundae"), progress (called with the time reached [s] as the
        run goes on, for a progress display). For scipy: method, rtol, atol, max_step,
        max_events, progress. exact takes none.

    Returns
    -------
    SimulationResult
        h and v on the grid t, the events, the rest time (or None) and the work done.

    Raises
    ------
    ValueError
        Before any work, for a value outside its range (the message names it, its value and the
        allowed range), a moving ground a solver or law does not take, an option the solver does
        not take, a scene outside the range double
        precision resolves (bouncingball.limits.check_scene: magnitudes whose squares would
        overflow, an output interval below a few ulps of t), or, for cvode, contacts too short to
        resolve in double precision up to t_end.
    SolverError
        CVODE could not deliver the tolerance (its reason in the message).
    ImportError
        The solver needs an extra that is not installed (the message says which).

    Examples
    --------
    >>> import bouncingball as bb
    >>> result = bb.simulate(bb.Ball(), h0=2.0, v0=0.0, t_end=8.0)
    >>> len(result.t), float(result.t[-1])
    (8001, 8.0)
    >>> exact = bb.simulate(bb.Ball(), 2.0, 0.0, 8.0, solver="exact")
    >>> len(result.events) == len(exact.events), bool(abs(result.h - exact.h).max() < 1e-6)
    (True, True)
    """
    if not isinstance(ball, Ball):
        raise ValueError(f"ball = {ball!r} is not allowed: it must be a bouncingball.Ball")
    solver = validation.choice("solver", solver, SOLVERS)
    h0 = validation.finite("h0", h0, "m")
    v0 = validation.finite("v0", v0, "m/s")
    t_start = validation.finite("t_start", t_start, "s")
    F_ext = forcing.as_force(F_ext)
    t_end = validation.finite("t_end", t_end, "s")
    if not t_end > t_start:
        raise ValueError(f"t_end = {t_end!r} s is not allowed: it must be > t_start = {t_start!r} s")
    output_interval = validation.in_range("output_interval", output_interval, 0.0, t_end - t_start, "s")
    ground = as_ground(ground)
    if ground.moves and solver == "scipy":
        raise ValueError(f"ground = {ground.describe()} is not allowed with solver = 'scipy': the article's "
                         "algorithm has a still ground; solver = 'exact' or 'cvode' take a moving one")
    if ground.moves and solver == "exact":  # the exact solver's rules (CVODE's are machine_ground's, below)
        from .exact_ground import check_moving_ground  # a still ground's run does not pay for its import

        check_moving_ground(ball, ground)  # the laws that cannot take it, named before the solver
    if ground.moves and solver == "cvode":
        from .vibrating_ground import machine_ground

        machine_ground(ball, ground)  # a table, or a law CVODE does not take there, named before any work
        if isinstance(F_ext, ForceTable):
            raise ValueError(f"F_ext table is not allowed with solver = 'cvode' on ground = {ground.describe()}: "
                             "give a constant F_ext there, or use solver = 'exact'")
    ground.check_covers(t_start, t_end)
    if not ground.moves and ground.height != 0.0:  # the same run, shifted
        result = simulate(ball, h0 - ground.height, v0, t_end, output_interval, solver, t_start=t_start,
                          F_ext=F_ext, **options)
        return dataclasses.replace(result, h=result.h + ground.height, ground=ground)
    if solver == "cvode":
        from .cvode import simulate_cvode as run
    elif solver == "scipy":
        try:
            from .scipy_ref import simulate_scipy as run
        except ImportError as error:  # scipy is an optional extra
            from ..extras import install_command

            raise ImportError(f"solver 'scipy' needs SciPy: {install_command('reference')}") from error
    else:
        from .exact import simulate_exact as run
    # A solver's options are the keywords its simulate function takes beyond the common ones.
    allowed = _options_of(run)
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ValueError(f"option {unknown[0]} = {options[unknown[0]]!r} is not allowed for solver "
                         f"'{solver}': it takes {', '.join(allowed) or 'no options'}")
    # Before any solver: what double precision cannot resolve is refused the same way by each; what CVODE
    # cannot resolve at its rtol (limits.check_alpha) by the cvode solver.
    rtol = CvodeSettings(rtol=options.get("rtol", DEFAULT_RTOL)).rtol if solver == "cvode" else None
    above = h0 - ground.position(t_start) if ground.moves else h0  # the range checks' height: above the ground
    if isinstance(F_ext, ForceTable):
        limits.check_forces(ball, above, v0, F_ext.arrays[1], t_start, t_end, output_interval, rtol)
    else:
        limits.check_scene(ball, above, v0, F_ext, t_start, t_end, output_interval, rtol)
    on_ground = {"ground": ground} if ground.moves else {}
    return run(ball, h0, v0, t_end, output_interval, t_start=t_start, F_ext=F_ext, **on_ground, **options)


@functools.cache
def _options_of(run) -> list[str]:
    """The keywords a solver's simulate function takes beyond the common ones: its options."""
    return [name for name in inspect.signature(run).parameters if name not in _COMMON_PARAMETERS]


__all__ = ["SOLVERS", "simulate"]
