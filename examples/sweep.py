"""A parameter study on Dask: CVODE against the exact solution over a small (k, damping ratio) grid.

Needs: pip install -e '.[sweep]' in the checkout (dask.distributed, pandas, pyarrow).
Usage: python sweep.py [OUTPUT_DIR] [SCHEDULER]   (results stream to OUTPUT_DIR/sweep_parts as they
       arrive; SCHEDULER, e.g. tcp://host:8786, runs on your cluster instead of a local one)
"""

import sys
from pathlib import Path

from bouncingball.sweep import Grid, run_sweep


def main() -> None:
    out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
    scheduler = sys.argv[2] if len(sys.argv) > 2 else None

    # 3 stiffnesses x 2 damping ratios, the article's mass and drop height, 2 s each, with CVODE and
    # the article's algorithm; the exact solution is the truth every run is measured against.
    grid = Grid(k=(1e3, 1e7, 3), zeta=(0.01, 0.5, 2), t_end=2.0, solvers=("cvode", "article"))

    client = None
    if scheduler:  # the user's running cluster; with None, run_sweep starts a LocalCluster and stops it
        from distributed import Client

        client = Client(scheduler)
    # resume: the runs an earlier run of this example left in out_dir are kept, only the others run
    frame = run_sweep(grid, client, output_dir=out_dir, resume=True, time_cap=20.0, progress=False)

    print(f"{'solver':8s}{'k [N/m]':>10s}{'zeta':>7s}  {'status':9s}{'events':>9s}{'max |h - h_exact| [m]':>24s}")
    for row in frame.itertuples():
        events = f"{row.events_found}/{row.events_exact}"
        print(f"{row.solver:8s}{row.k:10.3g}{row.zeta:7.3g}  {row.status:9s}{events:>9s}{row.max_height_error:24.3e}")
    wrong = frame[(frame.solver == "cvode") & ((frame.status != "finished") | (frame.max_height_error > 1e-6))]
    print(f"cvode cells outside 1e-6 m: {len(wrong)} of {int((frame.solver == 'cvode').sum())}")
    print(f"wall time {frame.attrs['wall_time']:.1f} s on {frame.attrs['workers']} workers")


if __name__ == "__main__":  # Dask starts its worker processes by re-importing this script
    main()
