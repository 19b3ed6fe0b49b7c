"""What the sweep writes: the table (CSV and Parquet), heat maps per solver on shared colour scales and the page."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from ..contact_laws import LAWS
from ..output import atomic_write
from ..solvers import ARTICLE_LABEL
from ..solvers.phase_machine.settings import DEFAULT_RTOL, HOP_RESOLUTION, MERGED_HOP_MARGIN
from . import store
from .child import HEIGHT_TOLERANCE
from .grid import ARTICLE_BALL, DEFAULT_CONTACT, HC_N, Grid, damping_field, held, k_unit, range_fields

HEIGHT_LIMIT = 1e-5  # m: CVODE's height error above this at the defaults is listed as wrong
TABLE_CSV = "stability_map.csv"
TABLE_PARQUET = store.TABLE
MARKDOWN = "stability_map.md"
SWEEP_PACKAGES = ("numba", "dask", "distributed", "pandas", "pyarrow")
TARGET = 1e-6  # m: bench --hunt-crossley's matched error, a second column of the Hunt-Crossley map's summary
# Event correctness as colours: counts agree; counts differ only by hops too small to resolve (merged
# into a contact: accuracy.event_mismatches finds nothing); events missing, extra or off; failed; timed out.
OUTCOMES = ("events match", "tiny hops merged", "events wrong", "failed", "timed out")
# The damping axis (grid.damping_field) as the maps' axis label and the page's column header.
DAMPING_LABELS = {"zeta": ("damping ratio zeta", "damping ratio"), "alpha": ("damping alpha [s/m]", "alpha [s/m]")}


def outcome(frame):
    """0..4 per row: index into OUTCOMES."""
    code = np.where(frame["events_found"] == frame["events_exact"], 0, 1)
    code = np.where(frame["event_mismatches"] > 0, 2, code)
    code = np.where(frame["status"] == "failed", 3, code)
    return np.where(frame["status"] == "timed out", 4, code)


def cvode_wrong(frame, limit: float = HEIGHT_LIMIT):
    """CVODE's rows that did not finish, missed, added or misplaced an event, or erred above limit [m]."""
    rows = frame[frame["solver"].str.startswith("cvode")]
    bad = (rows["status"] != "finished") | (rows["event_mismatches"] != 0) | ~(rows["max_height_error"] <= limit)
    return rows[bad]


def cvode_merged_hops(frame):
    """CVODE's finished rows whose event count differs only by hops below the resolution."""
    rows = frame[frame["solver"].str.startswith("cvode") & (frame["status"] == "finished")]
    return rows[(rows["event_mismatches"] == 0) & (rows["events_found"] != rows["events_exact"])]


def file_stem(solver: str) -> str:
    return "stability_map_" + solver.replace(":", "-")


def write_heat_maps(frame, grid: Grid, output_dir: Path) -> list[Path]:
    """One PNG per solver (heat_map_figure), named after it in output_dir."""
    import matplotlib.pyplot as plt

    written = []
    for solver in grid.solvers:
        figure = heat_map_figure(frame, grid, solver)
        path = output_dir / f"{file_stem(solver)}.png"
        with atomic_write(path) as temporary:
            figure.savefig(temporary, dpi=90, format="png")
        plt.close(figure)
        written.append(path)
    return written


def _tick(value: float) -> str:
    """1e+04 as 1e4; a value between powers of ten as 3.2e3 (2 digits, the same form on every axis); 0 as 0."""
    if value == 0.0:
        return "0"
    exponent = math.log10(value)
    if abs(exponent - round(exponent)) < 1e-9:
        return f"1e{round(exponent)}"
    power = math.floor(exponent)
    return f"{value / 10.0 ** power:.2g}e{power}"


def _by_reference(grid: Grid) -> bool:
    """Whether the runs are measured against a reference run: the law has no exact solution (Hunt-Crossley)."""
    return not LAWS[grid.contact].closed_form


def _truth(grid: Grid) -> str:
    """What the errors are measured against: the exact solution, or (Hunt-Crossley) the reference run."""
    return "the reference run" if _by_reference(grid) else "the exact solution"


def _law_title(grid: Grid) -> str:
    """", contact law NAME" after a title, "" for the default law (the pages of before the laws)."""
    return "" if grid.contact == DEFAULT_CONTACT else f", contact law {grid.contact}"


ERROR_FLOOR = 1e-16  # m: an error of 0 is drawn as this (a log colour scale has no 0)


def _index(axis: tuple[float, ...], value: float) -> int:
    """Where value is on the axis, to a few ulps: an axis rebuilt from its ends (grid_of) may differ in the last bit."""
    return int(np.flatnonzero(np.isclose(axis, value, rtol=1e-12, atol=0.0))[0])


def colour_limits(frame) -> dict[str, tuple[float, float]]:
    """(vmin, vmax) of each quantity's log colour scale over every finished run of the table, whatever its solver.

    heat_map_figure draws every solver's map of a quantity on this one scale, so a colour means one
    error (one number of right-hand-side calls) in every file of the sweep.
    """
    done = frame[frame["status"] == "finished"]
    errors = np.maximum(done["max_height_error"].to_numpy(dtype=float), ERROR_FLOOR)
    calls = done["rhs_calls"].to_numpy(dtype=float)
    calls = calls[calls > 0]
    limits = {}
    for name, values in (("max_height_error", errors), ("rhs_calls", calls)):
        low, high = (float(values.min()), float(values.max())) if len(values) else (1.0, 10.0)
        limits[name] = (low, high if high > low else low * 10.0)
    return limits


def heat_map_figure(frame, grid: Grid, solver: str):
    """One solver's heat maps: event-count correctness, max height error and right-hand-side calls over (k, damping).

    The error and the calls are coloured on log scales shared by every solver of the table
    (colour_limits), each with a colour bar in its units, so that one colour means one value in
    every solver's figure. The work is shown as right-hand-side calls, not wall time: at a run of
    milliseconds the wall time is mostly the load of the machine the sweep shared, the calls are the
    same on any machine. One row of panels per (m, h0). A cell of the error or calls map that is
    white has no value: its run timed out or failed (the left map says which); a white cell of the
    left map was not run. A legend under each map with white cells says so.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap, LogNorm
    from matplotlib.patches import Patch

    damping = grid.damping
    ks, zetas = grid.axis("k"), grid.axis(damping)
    pairs = [(m, h0) for m in grid.axis("m") for h0 in grid.axis("h0")]
    colours = ListedColormap(["#4daf4a", "#a6d96a", "#e41a1c", "#984ea3", "#999999"])
    limits = colour_limits(frame)
    reference = _by_reference(grid)
    error_name = f"max |h - h_{'ref' if reference else 'exact'}| [m]"
    units = (None, error_name, "right-hand-side calls")
    norms = (None, LogNorm(*limits["max_height_error"]), LogNorm(*limits["rhs_calls"]))
    rows = frame[frame["solver"] == solver]
    figure, axes = plt.subplots(len(pairs), 3, figsize=(17, 5.2 * len(pairs)), squeeze=False, layout="constrained")
    for row_axes, (m, h0) in zip(axes, pairs, strict=True):
        part = rows[(rows["m"] == m) & (rows["h0"] == h0)]
        maps = [np.full((len(zetas), len(ks)), np.nan) for _ in range(3)]
        for _, run in part.iterrows():
            i, j = _index(zetas, run[damping]), _index(ks, run["k"])
            maps[0][i, j] = outcome(part.loc[[run.name]])[0]
            finished = run["status"] == "finished"
            maps[1][i, j] = max(run["max_height_error"], ERROR_FLOOR) if finished else np.nan
            maps[2][i, j] = run["rhs_calls"] if finished and run["rhs_calls"] > 0 else np.nan
        shared = f"one colour scale for all {len(grid.solvers)} solvers' maps" if len(grid.solvers) > 1 else "log scale"
        titles = (f"events against {_truth(grid)}", f"{error_name}\n({shared})",
                  f"right-hand-side calls (the work, the same on any\nmachine, unlike wall time) ({shared})")
        blanks = ("white: not run", "white: no data (the run timed out\nor failed, as the left map shows)",
                  "white: no data (the run timed out\nor failed, as the left map shows)")
        for panel, (axis, values, title, blank) in enumerate(zip(row_axes, maps, titles, blanks, strict=True)):
            if panel == 0:
                image = axis.imshow(values, origin="lower", cmap=colours, vmin=-0.5, vmax=4.5, aspect="auto")
                bar = figure.colorbar(image, ax=axis, ticks=range(5))
                bar.ax.set_yticklabels(OUTCOMES, fontsize=10)
            else:
                image = axis.imshow(values, origin="lower", cmap="viridis", norm=norms[panel], aspect="auto")
                bar = figure.colorbar(image, ax=axis)
                bar.set_label(units[panel], fontsize=10)
                bar.ax.tick_params(labelsize=10)
            axis.set_xticks(range(len(ks)), [_tick(k) for k in ks], rotation=60, fontsize=10)
            axis.set_yticks(range(len(zetas)), [_tick(z) for z in zetas], fontsize=10)
            axis.set_xlabel(f"stiffness k [{k_unit(grid.contact)}]", fontsize=11)
            axis.set_ylabel(DAMPING_LABELS[damping][0], fontsize=11)
            law = _law_title(grid) + "".join(f" ({name} = {value:g})" for name, value in held(grid.contact).items())
            axis.set_title(f"{solver}: {title}\nm = {m:g} kg, h0 = {h0:g} m{law}", fontsize=11)
            if np.isnan(values).any():
                axis.legend(handles=[Patch(facecolor="white", edgecolor="0.4", label=blank)], loc="upper center",
                            bbox_to_anchor=(0.5, -0.22), fontsize=10, frameon=False)
    return figure


def grid_of(frame) -> Grid:
    """The Grid a sweep's table was run on: each axis from its values, the solvers in the order they come."""
    axes = {}
    contact = str(frame["contact"].iloc[0]) if "contact" in frame else DEFAULT_CONTACT  # a table of before the laws
    for field in range_fields(contact):
        values = np.unique(frame[field].to_numpy(dtype=float))
        axes[field] = (float(values[0]), float(values[-1]), len(values))
    if damping_field(contact) == "alpha":  # its values, not a range
        axes["alpha"] = tuple(float(x) for x in np.unique(frame["alpha"].to_numpy(dtype=float)))
    return Grid(**axes, t_end=float(frame["t_end"].iloc[0]), output_interval=float(frame["output_interval"].iloc[0]),
                solvers=tuple(dict.fromkeys(frame["solver"])), contact=contact)


def main(argv: list[str] | None = None) -> int:
    """Redraw the heat maps from a sweep's stored table: ``python -m bouncingball.sweep.report DIR``."""
    import pyarrow.parquet as pq

    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print(f"usage: python -m bouncingball.sweep.report DIR (the folder holding {TABLE_PARQUET})", file=sys.stderr)
        return 2
    output_dir = Path(args[0])
    frame = pq.read_table(output_dir / TABLE_PARQUET).to_pandas()
    for path in write_heat_maps(frame, grid_of(frame), output_dir):
        print(f"wrote {path}")
    return 0


def write_tables(frame, output_dir: Path) -> list[Path]:
    """The whole table as CSV (without the run keys) and Parquet (with them, as --resume reads).

    The CSV's numbers are pandas' default, the shortest text that reads back as the same double.
    """
    columns = [column for column in frame.columns if column != "key"]
    csv_path = output_dir / TABLE_CSV
    with atomic_write(csv_path) as temporary:
        frame[columns].to_csv(temporary, index=False)
    return [csv_path, store.write_table(frame, output_dir)]


def _summary(frame, grid: Grid) -> list[str]:
    target = _by_reference(grid)
    lines = ["| solver | runs | finished | event counts match | events right | failed | timed out | "
             f"max error <= {HEIGHT_LIMIT:g} m | " + (f"max error <= {TARGET:g} m | " if target else "")
             + "median max error [m] | median wall time [ms] | RHS calls (sum) |", "|" + " --- |" * (11 + target)]
    for solver in grid.solvers:
        rows = frame[frame["solver"] == solver]
        done = rows[rows["status"] == "finished"]
        calls = done["rhs_calls"][done["rhs_calls"] >= 0]
        matched = int((done["events_found"] == done["events_exact"]).sum())
        right = int((done["event_mismatches"] == 0).sum())
        lines.append(f"| {solver} | {len(rows)} | {len(done)} | {matched} | {right}"
                     f" | {int((rows['status'] == 'failed').sum())} | {int((rows['status'] == 'timed out').sum())}"
                     f" | {int((done['max_height_error'] <= HEIGHT_LIMIT).sum())}"
                     + (f" | {int((done['max_height_error'] <= TARGET).sum())}" if target else "")
                     + f" | {done['max_height_error'].median():.2e} | {done['wall_time'].median() * 1e3:.3g}"
                     f" | {int(calls.sum())} |")
    return lines


def _law_lines(grid: Grid, info: dict) -> list[str]:
    """The page's opening paragraph and its Grid section's axis lines, in the law's terms."""
    cap = f"each run under a wall-time cap of {info['time_cap']:g} s"
    table = f"The whole table: [{TABLE_CSV}]({TABLE_CSV}) (also {TABLE_PARQUET})."
    axes = f"- m [kg]: {', '.join(f'{x:.3g}' for x in grid.axis('m'))}; h0 [m]: " \
           f"{', '.join(f'{x:.3g}' for x in grid.axis('h0'))}; v0 = 0; R = {ARTICLE_BALL.R:g} m, " \
           f"g = {ARTICLE_BALL.g:g} m/s2; contact law {grid.contact}"
    if not _by_reference(grid):
        return [f"Generated by `{info['command']}`: every cell of a log-spaced grid over stiffness k and damping "
                f"ratio zeta = b / (2 sqrt(k m)) run by each solver on dask.distributed, {cap}, and compared with "
                f"the exact solution on its own output grid. {table}"], [
                f"- k [N/m]: {', '.join(f'{x:.3g}' for x in grid.axis('k'))}",
                f"- damping ratio: {', '.join(f'{x:.3g}' for x in grid.axis('zeta'))}", axes]
    from ..bench.hunt_crossley_study import REFERENCE_ATOL, REFERENCE_HELD_WITHIN, REFERENCE_RTOL

    return [f"Generated by `{info['command']}`: every cell of a grid over the Hunt-Crossley law's stiffness k "
            f"[N/m^{HC_N:g}] (log-spaced) and damping alpha [s/m] (its force k delta^n (1 + 3/2 alpha delta'), "
            f"clipped at 0, delta = R - h the penetration, n = {HC_N:g} fixed: Hertz's exponent for spheres) run "
            f"by each solver on dask.distributed, {cap}, and compared with the cell's reference run on its own "
            f"output grid. {table}", "",
            "## Errors against a reference run, not an exact solution", "",
            "This law has no exact solution. Every error on this page (max height error, events found and their "
            "times; the table's events_exact column holds the reference's event count) is measured against a "
            f"reference run per cell: the compiled CVODE engine at rtol {REFERENCE_RTOL:g}, atol "
            f"{REFERENCE_ATOL:g}, on the same output grid (the reference of `bouncingball bench --hunt-crossley`). "
            "An error here is the distance between two numerical solutions, and the reference's own error is not "
            f"in it: the tests hold the reference within {REFERENCE_HELD_WITHIN:g} m of an independent mpmath solution "
            "(tests/hunt_crossley_truth.py) on the benchmark's scene (tests/test_hunt_crossley.py) and on a cell "
            "of this map (tests/test_sweep.py). An error well below that says the run agrees with the reference, "
            "not that it is that accurate. The cvode rows run the reference's own engine (engine auto: the "
            "compiled one where numba runs) at a looser tolerance, so they share its implementation of the law "
            "and only the tests against the truth would show a fault in it; scipy:DOP853 and the article's "
            "algorithm are SciPy's solve_ivp over the package's right-hand side (the force clipped there), a "
            "different integrator and event handling."], [
            f"- k [N/m^{HC_N:g}]: {', '.join(f'{x:.3g}' for x in grid.axis('k'))}",
            f"- damping alpha [s/m]: {', '.join(f'{x:.3g}' for x in grid.axis('alpha'))}; n = {HC_N:g} in every "
            "cell", axes,
            "- one m and one h0 suffice: the motion depends on k / m, not on k and m apart (m delta'' = m g - "
            "k delta^n (1 + 3/2 alpha delta')), so the k axis covers m; h0 sets the impact speed v, and the "
            "restitution depends mostly on alpha v (docs/hunt_crossley_restitution.png), which the alpha axis "
            "spans. The grid is kept small enough to run here in minutes on 2 workers (Execution below)."]


def write_markdown(frame, grid: Grid, info: dict, output_dir: Path, images: list[Path]) -> Path:
    """docs/stability_map.md: the machine, the grid, the timing and overhead lines, CVODE's wrong cells, the maps."""
    from ..bench.environment import environment, environment_lines, versions

    env = environment()
    attrs = frame.attrs
    law = _law_title(grid)
    truth = _truth(grid)
    short = "reference" if _by_reference(grid) else "exact"
    damping = grid.damping
    damping_header = DAMPING_LABELS[damping][1]
    k_header = f"k [{k_unit(grid.contact)}]"
    opening, axis_lines = _law_lines(grid, info)
    lines = [f"# Stability map over the parameter space{law}", "", *opening, "",
             *environment_lines(env), f"- sweep: {versions(SWEEP_PACKAGES)}", "",
             "## Grid", "", *axis_lines,
             f"- t_end = {grid.t_end:g} s, output every {grid.output_interval:g} s; solvers: {', '.join(grid.solvers)} "
             "(cvode: method auto, engine auto; scipy:METHOD: solve_ivp with unbounded steps; both at CVODE's "
             f"default rtol {DEFAULT_RTOL:g}, the scipy methods with atol rtol times the scene's height; "
             f"article: {ARTICLE_LABEL} at SciPy's tolerances)", "",
             "## Execution", "",
             f"- cluster: {info['cluster']}, {attrs['workers']} workers, {attrs['threads']} threads",
             f"- wall time: {attrs['wall_time']:.1f} s for {attrs['runs_done']} runs (first task submitted to last "
             f"result; cluster start not included)",
             f"- Dask's overhead: {attrs['overhead'] * 1e3:.2f} ms per task (no-op tasks over all workers); batch "
             f"size {attrs['batch_size']} runs per task, so {attrs['overhead'] / attrs['batch_size'] * 1e3:.2f} ms "
             "per run, against a median run of "
             f"{frame.loc[frame['status'] == 'finished', 'wall_time'].median() * 1e3:.3g} ms"
             + (" (the reference run not included)" if _by_reference(grid) else "")]
    scaling = info.get("scaling")
    if scaling:
        one, many, n = scaling
        lines.append(f"- scaling: the same grid on a LocalCluster of 1 worker {one:.1f} s, of {n} workers "
                     f"{many:.1f} s: {one / many:.2f}x")
    else:
        lines.append("- scaling: not measured (run with --scaling)")
    wrong = cvode_wrong(frame)
    lines += ["", "## Summary", "", *_summary(frame, grid), "", "## Where CVODE is wrong", ""]
    if len(wrong):
        lines += [f"CVODE runs that did not finish, missed, added or misplaced an event (beyond the hops below "
                  f"its resolution, see below), or erred above {HEIGHT_LIMIT:g} m:", "",
                  f"| solver | {k_header} | {damping_header} | m [kg] | h0 [m] | status | events ({short}) | "
                  "max error [m] | reason |", "|" + " --- |" * 9]
        for _, row in wrong.iterrows():
            reason = row["reason"] or row["first_mismatch"]
            lines.append(f"| {row['solver']} | {row['k']:.3g} | {row[damping]:.3g} | {row['m']:.3g} "
                         f"| {row['h0']:.3g} | {row['status']} | {row['events_found']} ({row['events_exact']}) "
                         f"| {row['max_height_error']:.2e} | {reason} |")
    else:
        lines.append(f"None: in every cell CVODE finished, found {truth}'s events (up to the hops below "
                     f"its resolution, below) and stayed within {HEIGHT_LIMIT:g} m.")
    merged = cvode_merged_hops(frame)
    if len(merged):
        lines += ["", f"In these cells CVODE's event count differs from {truth}'s only by the last, "
                  "tiny hops before rest: each missing departure-impact pair bounds a hop lower than "
                  f"`cvode.merged_hop_limit`, {MERGED_HOP_MARGIN:g} x {HOP_RESOLUTION:g} rtol times the static "
                  f"deflection m g / k above R (rtol {DEFAULT_RTOL:g}), which CVODE merges into the contact (the "
                  "ball is then at rest to within its tolerance); `accuracy.event_mismatches` finds every other "
                  f"event within the time the ball takes to move {HEIGHT_TOLERANCE:g} m. Not a defect: those hops "
                  "are below what the tolerances resolve.", "",
                  f"| solver | {k_header} | {damping_header} | m [kg] | h0 [m] | events ({short}) | max error [m] |",
                  "|" + " --- |" * 7]
        lines += [f"| {row['solver']} | {row['k']:.3g} | {row[damping]:.3g} | {row['m']:.3g} | {row['h0']:.3g} "
                  f"| {row['events_found']} ({row['events_exact']}) | {row['max_height_error']:.2e} |"
                  for _, row in merged.iterrows()]
    lines += ["", "## Heat maps", ""]
    lines += [f"![{path.stem}]({path.name})" for path in images]
    path = output_dir / MARKDOWN
    with atomic_write(path) as temporary:
        temporary.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


if __name__ == "__main__":
    sys.exit(main())
