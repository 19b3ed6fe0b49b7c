"""A stability map over the parameter space (k, damping ratio, m, h0), run on dask.distributed.

Not imported by `import bouncingball`: the `sweep` command and `from bouncingball.sweep import
run_sweep` load it (and Dask, pandas, pyarrow) only when used. Needs the `[sweep]` extra.
"""

from .grid import Cell, Grid, parse_range, solver_names
from .run import run_sweep

__all__ = ["Cell", "Grid", "parse_range", "run_sweep", "solver_names"]
