"""The work-precision plot: max height error against median wall time, one line per solver, a row per family.

Redraw docs/work_precision.png from docs/work_precision.csv without rerunning the benchmark:
``python -m bouncingball.bench.plots docs/work_precision.csv docs/work_precision.png``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..output import atomic_write
from .targets import MATCHED_ERRORS
from .work_precision import DENSE, QUICK, SPARSE, Point, by_solver

# The families, one row of panels each: (heading, the solver kinds in it). The floors and references go with the
# family they bound: the C floor and the exact solution with CVODE, the empty slave with the FMU.
FAMILIES = (("CVODE (this package)", ("cvode", "floor", "exact", "evaluation")),
            ("the FMU through FMPy", ("fmu", "empty")), ("SciPy solve_ivp", ("article", "scipy")))
MAX_SERIES = 8  # lines with a legend entry per panel, at most: more cannot be told apart
COMPARED = "auto (compiled)"  # CVODE's default, drawn thin and grey in the other families' panels to compare with
SCIPY_COLOURS = {"RK45": "C9", "DOP853": "C8", "LSODA": "C5", "Radau": "#d4a017", "BDF": "C7"}  # muted, apart
FLOORS = ("exact", "evaluation", "empty")  # no error to plot: their time is a floor, drawn as a vertical line
# Two lines with the same errors whose times differ by less than this factor are one line on these log axes.
SAME_TIME_FACTOR = 1.1
PANELS = (("dense", f"{DENSE * 1e3:g} ms"), ("sparse", f"{SPARSE:g} s"))


def _curve(points: list[Point]) -> tuple[list[float], list[float]]:
    ok = sorted((p for p in points if p.status == "ok" and p.errors), key=lambda p: -(p.rtol or 0.0))
    return [p.median for p in ok], [max(p.errors.max_height_error, 1e-16) for p in ok]


def _style(point: Point, index: int) -> dict:
    """How one solver's line looks: its family sets the colour range and the line style."""
    solver = point.solver
    if solver.kind == "cvode":
        return {"color": ("C0", "C1", "C2", "C3")[index % 4], "ls": "-", "lw": 2.2, "marker": "o", "ms": 4}
    if solver.kind == "fmu":  # one family: purple, the compiled engine darker; the step as the marker
        compiled = solver.engine == "compiled"
        return {"color": "#54278f" if compiled else "#9e9ac8", "ls": "--", "lw": 1.3,
                "marker": "s" if solver.comm_step > DENSE else "o", "ms": 4}
    if solver.kind == "article":
        return {"color": "0.35", "ls": "none", "marker": "*", "ms": 13}
    if solver.kind == "floor":  # the compiled engine's work in C: its colour, a thin line of its own
        return {"color": "C3", "ls": ":", "lw": 1.6, "marker": "D", "ms": 3}
    return {"color": SCIPY_COLOURS.get(solver.method, "0.5"), "ls": "-.", "lw": 1.0, "marker": "o", "ms": 3}


def _label(point: Point) -> str:
    """The solver's name within its family (the family's heading says the rest)."""
    solver = point.solver
    if solver.kind == "fmu":
        engine = "compiled engine (the default)" if solver.engine == "compiled" else "scikit-sundae engine"
        return f"{solver.comm_step * 1e3:g} ms steps, {engine}"
    if solver.kind == "empty":
        return f"empty pythonfmu slave, {solver.comm_step * 1e3:g} ms steps"
    return solver.label.removeprefix("solve_ivp ").removeprefix("CVODE ")


def hidden_lines(points: list[Point]) -> dict[str, str]:
    """The legend label of each line that lies under a line drawn after it, as the legend names it then.

    Under means: the same errors at every tolerance and times within SAME_TIME_FACTOR (CVODE Adams under
    auto, which takes Adams in flight and in contact at the article's stiffness). A line hidden in some
    panels only says in which.
    """
    hidden: dict[str, dict[str, str]] = {}  # label -> {panel: the label of the line over it}
    shown: dict[str, list[str]] = {}  # label -> the panels it is drawn in
    for section, panel in PANELS:
        curves = [(_label(group[0]), *_curve(group)) for group in by_solver(points, section).values()
                  if group[0].solver.kind not in FLOORS]
        for i, (label, x, y) in enumerate(curves):
            if x:
                shown.setdefault(label, []).append(panel)
            for other, x_other, y_other in curves[i + 1:]:
                if x and y == y_other and all(max(a, b) < SAME_TIME_FACTOR * min(a, b)
                                              for a, b in zip(x, x_other, strict=True)):
                    hidden.setdefault(label, {})[panel] = other
    notes = {}
    for label, panels in hidden.items():
        where = "" if list(panels) == shown[label] else f" in the {' and '.join(panels)} panel"
        notes[label] = f"{label} (= {' and '.join(dict.fromkeys(panels.values()))}{where}, hidden under it)"
    return notes


def run_kind(points: list[Point]) -> str:
    """The figure's title: what the run measured, and whether it is a quick one (`bouncingball bench --quick`)."""
    rtols = sorted({p.rtol for p in points if p.rtol is not None}, reverse=True)
    repeats = max((len(p.times) for p in points), default=0)
    span = f"rtol {rtols[0]:g} to {rtols[-1]:g}" if rtols else "no tolerances"
    what = f"{len(rtols)} tolerances ({span}), median of {repeats} timed runs each"
    if set(rtols) <= set(QUICK.rtols) and repeats <= QUICK.repeats:
        return f"QUICK run (bouncingball bench --quick): {what}\nnot the published figure: its times are noisy"
    return f"Work against precision: {what}"


def plot_work_precision(points: list[Point], path: Path) -> Path:
    """Save work_precision_figure(points) to path as PNG."""
    import matplotlib.pyplot as plt

    fig = work_precision_figure(points)
    with atomic_write(path) as temporary:
        fig.savefig(temporary, dpi=100, format="png")
    plt.close(fig)
    return path


def work_precision_figure(points: list[Point]):
    """Max height error against median wall time, log-log, one line per solver; a row of panels per family.

    The columns are the output grids (1 ms, 0.1 s), the rows the families (FAMILIES): CVODE with
    its floors (the C floor, the exact solution), the FMU with the empty slave's floor, SciPy;
    CVODE's default (COMPARED) is drawn again, thin and grey, in the rows it is not in, so that every
    panel compares with it. At most MAX_SERIES lines per panel; all panels share both axes. Each
    row's legend is outside its panels, on the right, titled with the family and naming a line
    hidden under another (hidden_lines). The dashed horizontal lines are the errors the benchmark's
    tables compare the solvers at (in the legend); the vertical lines are times without an error
    (the exact solution, the empty FMU). The title says what the run measured, and whether it was a
    quick one.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(len(FAMILIES), len(PANELS), figsize=(14, 4.2 * len(FAMILIES)), layout="constrained",
                             sharex=True, sharey=True, squeeze=False)
    row_of = {kind: row for row, (_, kinds) in enumerate(FAMILIES) for kind in kinds}
    hidden = hidden_lines(points)
    entries: list[dict[str, object]] = [{} for _ in FAMILIES]
    for column, (section, title) in enumerate(PANELS):
        compared_curve = None
        for index, group in enumerate(by_solver(points, section).values()):
            first = group[0]
            row = row_of[first.solver.kind]
            ax = axes[row][column]
            if first.solver.kind in FLOORS:
                times = [p.median for p in group if p.status == "ok"]
                if times:
                    empty = "0.6" if first.solver.comm_step <= DENSE else "0.3"  # the empty FMU, by its step
                    colour = {"exact": "k", "evaluation": "0.45"}.get(first.solver.kind, empty)
                    ls = {"exact": "-", "evaluation": "--"}.get(first.solver.kind, ":")
                    line = ax.axvline(times[0], color=colour, ls=ls, lw=1.2, label=_label(first), zorder=1.8)
                    entries[row].setdefault(_label(first), line)
                continue
            x, y = _curve(group)
            if not x:
                continue
            label = hidden.get(_label(first), _label(first))
            line, = ax.plot(x, y, label=label, **_style(first, index))
            entries[row].setdefault(label, line)
            if first.solver.kind == "cvode" and _label(first) == COMPARED:
                compared_curve = (x, y)
        for row, (heading, _) in enumerate(FAMILIES):
            ax = axes[row][column]
            ax.set_title(f"{heading}: article scene, {title} output grid", fontsize=11)
            ax.grid(True, which="major", color="0.92")
            ax.tick_params(labelsize=10)
            if not ax.get_lines():
                ax.text(0.5, 0.5, f"no runs of this family on the {title} output grid", transform=ax.transAxes,
                        ha="center", va="center", fontsize=10, color="0.4")
                continue
            if row != row_of["cvode"] and compared_curve:  # under the family's own lines
                name = f"CVODE {COMPARED}, to compare"
                compared, = ax.plot(*compared_curve, color="0.6", lw=1.0, ls="-", label=name, zorder=1.7)
                entries[row].setdefault(name, compared)
            for target in MATCHED_ERRORS:  # over the grid, under every line
                ax.axhline(target, color="0.55", lw=0.8, ls="--", zorder=1.6)
    matched = Line2D([], [], color="0.55", lw=0.8, ls="--")
    targets = ", ".join(f"{target:.0e}".replace("e-0", "e-") for target in MATCHED_ERRORS)
    for row, (heading, _) in enumerate(FAMILIES):
        handles = {**entries[row], f"the errors the tables compare at\n({targets} m)": matched}
        legend = axes[row][-1].legend(list(handles.values()), list(handles), title=heading, loc="upper left",
                                      bbox_to_anchor=(1.03, 1.0), borderaxespad=0.0, fontsize=9, frameon=False)
        legend.get_title().set_fontweight("bold")
        axes[row][0].set_ylabel("max |h - h_exact| [m]", fontsize=11)
    for ax in axes[-1]:
        ax.set_xlabel("median wall time [s]", fontsize=11)
    axes[0][0].set_xscale("log")
    axes[0][0].set_yscale("log")
    title = run_kind(points)
    fig.suptitle(title, x=0.01, ha="left", fontsize=12, color="C3" if title.startswith("QUICK") else "k")
    return fig


def main(argv: list[str] | None = None) -> int:
    """Redraw the plot from the CSV the benchmark wrote: ``python -m bouncingball.bench.plots CSV PNG``."""
    from .tables import read_work_precision_csv

    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2:
        print("usage: python -m bouncingball.bench.plots WORK_PRECISION.csv OUT.png", file=sys.stderr)
        return 2
    print(f"wrote {plot_work_precision(read_work_precision_csv(Path(args[0])), Path(args[1]))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
