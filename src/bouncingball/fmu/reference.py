"""The FMU's reference result: the exact solution of its default experiment, shipped beside it (build_fmu writes it)."""

from __future__ import annotations

from pathlib import Path

from ..output import atomic_write


def reference_path(fmu: str | Path) -> Path:
    """Where the build writes the FMU's reference result: beside it, <name>_ref.csv (BouncingBall_ref.csv)."""
    fmu = Path(fmu)
    return fmu.with_name(f"{fmu.stem}_ref.csv")


def write_reference_csv(path: str | Path) -> Path:
    """The exact solution of the FMU's default experiment, on its output grid, in the columns the FMU outputs.

    As the FMI cross-check convention does, the FMU's result for its default experiment (the
    article scene, 0 to 8 s, every 1 ms) is shipped beside it: time and the outputs h, v, a,
    contact (0 or 1), contact_force, impacts, from the exact solution.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV to write (whole or not at all).

    Returns
    -------
    pathlib.Path
        path.

    Examples
    --------
    >>> write_reference_csv("BouncingBall_ref.csv")  # doctest: +SKIP
    PosixPath('BouncingBall_ref.csv')
    """
    import numpy as np

    from ..physics import Mode
    from ..scenes import load_scene
    from ..solvers.exact import ExactSolution
    from ..solvers.result import IMPACT, output_grid
    from .variables import SOLUTION_OUTPUTS as OUTPUTS

    scene = load_scene("article")
    ball = scene.ball
    t = output_grid(0.0, scene.t_end, scene.output_interval)
    solution = ExactSolution(ball, scene.h0, scene.v0, 0.0, scene.t_end, scene.F_ext)
    h, v = solution.state(t)
    modes = [Mode(mode) for mode in solution.modes(t)]
    columns = {
        "h": h, "v": v,
        "a": [ball.acceleration(*state, scene.F_ext) for state in zip(h, v, modes, strict=True)],
        "contact": [int(mode == Mode.CONTACT) for mode in modes],
        "contact_force": [ball.contact_force(*state) for state in zip(h, v, modes, strict=True)],
        "impacts": np.searchsorted([e.time for e in solution.events if e.kind == IMPACT], t, side="right"),
    }
    if set(columns) != set(OUTPUTS):
        raise AssertionError(f"the reference has columns {sorted(columns)}, the FMU outputs {sorted(OUTPUTS)}")
    with atomic_write(path) as temporary, temporary.open("w", encoding="utf-8") as file:
        file.write(",".join(("time", *OUTPUTS)) + "\n")
        for row in zip(t.tolist(), *(np.asarray(columns[name]).tolist() for name in OUTPUTS), strict=True):
            file.write(",".join(map(repr, row)) + "\n")
    return Path(path)
