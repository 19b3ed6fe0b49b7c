"""`bouncingball sweep`: check the input, run the grid on a cluster, write the table, heat maps and markdown."""

from __future__ import annotations

import sys
import time

from .. import validation
from ..contact_laws import LAWS
from ..output import check_output_folder
from . import grid as grids
from .child import DEFAULT_TIME_CAP

QUICK_TIME_CAP = 1.0  # s


def build_grid(k: str | None = None, zeta: str | None = None, m: str | None = None, h0: str | None = None,
               t_end: float | None = None, solvers: str | None = None, quick: bool = False,
               contact: str | None = None, alpha: str | None = None) -> grids.Grid:
    """The Grid from the command line's text (None: the default, or with quick the small grid).

    contact: the contact law (default linear); the no-pull law runs CVODE alone unless solvers says otherwise.
    The Hunt-Crossley law's damping axis is alpha [s/m] (grid.parse_alpha's text), k in N/m^1.5; the linear
    laws' is zeta. Each refuses the other's.

    Raises
    ------
    ValueError
        Naming the option, its value and what is allowed.

    Examples
    --------
    >>> build_grid(k="1e2:1e6:3", zeta="0.1", solvers="cvode,article").runs()[0]["solver"]
    'cvode'
    """
    contact = grids.DEFAULT_CONTACT if contact is None else grids.check_contact("--contact", contact)
    damping = grids.damping_field(contact)
    if damping != "zeta" and zeta is not None:
        raise ValueError(f"--zeta = {zeta!r} is not allowed with --contact {contact}: its damping is {damping} "
                         f"[{grids.UNITS[damping]}]; use --{damping}")
    if damping != "alpha" and alpha is not None:
        raise ValueError(f"--alpha = {alpha!r} is not allowed with --contact {contact}: it is the Hunt-Crossley "
                         f"law's damping; use --{damping}")
    defaults = {"k": grids.default_k(contact, quick), "m": grids.DEFAULT_M, "h0": grids.DEFAULT_H0}
    if damping == "zeta":
        defaults["zeta"] = grids.QUICK_ZETA if quick else grids.DEFAULT_ZETA
    axes = {field: defaults[field] if text is None else grids.parse_range(field, text)
            for field, text in (("k", k), ("zeta", zeta), ("m", m), ("h0", h0)) if field in defaults}
    if damping == "alpha":
        axes["alpha"] = (grids.QUICK_ALPHA if quick else grids.DEFAULT_ALPHA) if alpha is None else \
            grids.parse_alpha(alpha)
    default = grids.DEFAULT_SOLVERS if LAWS[contact].article_algorithm else ("cvode",)
    names = default if solvers is None else tuple(name.strip() for name in solvers.split(","))
    for name in names:
        if name.lower() not in (known.lower() for known in grids.solver_names()):
            raise ValueError(f"--solvers: {name!r} is not allowed: each must be one of "
                             f"{', '.join(grids.solver_names())}")
    if t_end is not None and not (0.0 < t_end < float("inf")):
        raise ValueError(f"--t-end = {t_end!r} s is not allowed: it must be finite and > 0")
    return grids.Grid(**axes, t_end=grids.DEFAULT_T_END if t_end is None else t_end, solvers=names, contact=contact)


def sweep_command(args) -> int:
    """Run `bouncingball sweep` from parsed arguments; every input is checked before a cluster starts."""
    from .run import check_settings

    grid = build_grid(args.k, args.zeta, args.m, args.h0, args.t_end, args.solvers, args.quick, args.contact,
                      args.alpha)
    time_cap = args.time_cap if args.time_cap is not None else QUICK_TIME_CAP if args.quick else DEFAULT_TIME_CAP
    check_settings(time_cap, args.workers, args.batch_size)
    connect_timeout = validation.positive("--connect-timeout", args.connect_timeout, "s")
    if args.scheduler and args.workers:
        raise ValueError(f"--workers = {args.workers} is not allowed with --scheduler: the cluster has its own")
    output_dir = check_output_folder("--output-dir", args.output_dir)
    from .store import check_fresh

    check_fresh(output_dir, args.resume, args.overwrite)
    for module in ("distributed", "pandas", "pyarrow", "matplotlib", "tqdm"):  # before the hours of work
        __import__(module)
    from . import report

    started = time.perf_counter()
    options = dict(output_dir=output_dir, resume=args.resume, overwrite=args.overwrite, time_cap=time_cap,
                   batch_size=args.batch_size)
    try:
        frame, cluster = _run(grid, args, options, connect_timeout)
    except KeyboardInterrupt:
        raise KeyboardInterrupt(_resume_hint(output_dir, args)) from None
    scaling = None
    if args.scaling:
        workers = frame.attrs["workers"]
        one = _timed_on_local_cluster(grid, 1, time_cap, frame.attrs["batch_size"])
        # The sweep itself, when it ran the whole grid on a LocalCluster, is the many-worker timing.
        many = frame.attrs["wall_time"] if not args.scheduler and frame.attrs["runs_done"] == len(frame) else \
            _timed_on_local_cluster(grid, workers, time_cap, frame.attrs["batch_size"])
        scaling = (one, many, workers)
    command = "bouncingball sweep " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["sweep"] else "run_sweep"
    info = {"command": command.strip(), "time_cap": time_cap, "cluster": cluster, "scaling": scaling}
    written = report.write_tables(frame, output_dir)
    images = report.write_heat_maps(frame, grid, output_dir)
    written += images
    written.append(report.write_markdown(frame, grid, info, output_dir, images))
    for path in written:
        print(f"wrote {path}")
    counts = frame["status"].value_counts().to_dict()
    print(f"{len(frame)} runs ({frame.attrs['runs_done']} run now): "
          + ", ".join(f"{count} {status}" for status, count in counts.items())
          + f"; CVODE wrong in {len(report.cvode_wrong(frame))} cells", file=sys.stderr)
    timed_out = timeouts_line(frame, time_cap)
    if timed_out:
        print(timed_out, file=sys.stderr)
    print(f"sweep finished in {time.perf_counter() - started:.0f} s", file=sys.stderr)
    return 0


def _run(grid: grids.Grid, args, options: dict, connect_timeout: float):
    """(The sweep's table, the cluster it ran on in words): on the scheduler of --scheduler, or a LocalCluster."""
    from distributed import Client

    from .run import run_sweep

    output_dir = options["output_dir"]
    if args.scheduler:
        try:
            client = Client(args.scheduler, timeout=connect_timeout)
        except OSError as error:  # distributed's "Timed out trying to connect to ... after 10 s"
            raise ValueError(f"--scheduler = {args.scheduler!r} is not allowed: no Dask scheduler answered there "
                             f"within --connect-timeout = {connect_timeout:g} s ({error})") from None
        output_dir.mkdir(parents=True, exist_ok=True)
        with client:
            return run_sweep(grid, client, **options), f"the scheduler at {args.scheduler}"
    output_dir.mkdir(parents=True, exist_ok=True)
    return run_sweep(grid, workers=args.workers, **options), "LocalCluster (one single-threaded worker process each)"


def timeouts_line(frame, time_cap: float) -> str:
    """One line saying which runs timed out and whether that is expected ("" if none did).

    The SciPy peers (article, scipy:METHOD) on stiff cells take millions of explicit steps: a timeout there is
    what the map is meant to show. CVODE's are not expected: the line says so and where to look.
    """
    out = frame[frame["status"] == "timed out"]
    if out.empty:
        return ""
    parts = []
    for solver, rows in out.groupby("solver", sort=False):
        low, high = rows["k"].min(), rows["k"].max()
        parts.append(f"{solver} {len(rows)} (k {low:.3g}{'' if low == high else f' to {high:.3g}'})")
    cvode = out["solver"].str.startswith("cvode")
    verdict = ("the SciPy peers on stiff cells, whose explicit steps shrink with the contact (expected)"
               if not cvode.any() else f"{int(cvode.sum())} of them CVODE's, which is not expected: see the "
               "timed-out cells in stability_map.md")
    return f"timed out (past --time-cap = {time_cap:g} s): {', '.join(parts)}: {verdict}"


def _resume_hint(output_dir, args) -> str:
    """What Ctrl-C leaves and the exact command that goes on from it: this one, with --resume for --overwrite."""
    import shlex
    from pathlib import Path

    from .store import results_in

    kept = len(results_in(output_dir))
    argv = [word for word in getattr(args, "argv", None) or sys.argv[1:] if word not in ("--overwrite", "--resume")]
    program = "bouncingball" if Path(sys.argv[0]).name == "bouncingball" else f"{sys.executable} -m bouncingball.cli"
    command = shlex.join([*shlex.split(program), *argv, "--resume"])
    return (f"{kept} finished batch(es) kept in {output_dir}; to run only the rest: {command}" if kept else
            f"no batch had finished, nothing written in {output_dir}; to start again: {command}")


def _timed_on_local_cluster(grid: grids.Grid, workers: int, time_cap: float, batch_size: int) -> float:
    """Wall time [s] of the whole grid on a fresh LocalCluster of `workers` (nothing written)."""
    from .run import run_sweep

    print(f"scaling: the grid again on {workers} worker(s)", file=sys.stderr)
    return run_sweep(grid, workers=workers, time_cap=time_cap, batch_size=batch_size).attrs["wall_time"]
