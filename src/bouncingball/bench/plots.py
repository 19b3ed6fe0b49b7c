"""The work-precision plot: max height error against median wall time, one line per solver."""

from __future__ import annotations

from pathlib import Path

from ..output import atomic_write
from .targets import MATCHED_ERRORS
from .work_precision import DENSE, SPARSE, Point, by_solver


def _curve(points: list[Point]) -> tuple[list[float], list[float]]:
    ok = sorted((p for p in points if p.status == "ok" and p.errors), key=lambda p: -(p.rtol or 0.0))
    return [p.median for p in ok], [max(p.errors.max_height_error, 1e-16) for p in ok]


def plot_work_precision(points: list[Point], path: Path) -> Path:
    """Max height error against median wall time, log-log, one line per solver; one panel per output grid."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    palette = matplotlib.colormaps["tab20"]
    labels = list(by_solver(points, "dense"))
    colours = {label: palette((2 * i) % 20 + (2 * i) // 20) for i, label in enumerate(labels)}
    fig, axes = plt.subplots(1, 2, figsize=(14, 5.5), layout="constrained", sharey=True)
    for ax, section, title in ((axes[0], "dense", f"{DENSE * 1e3:g} ms"), (axes[1], "sparse", f"{SPARSE:g} s")):
        for label, group in by_solver(points, section).items():
            kind = group[0].solver.kind
            times = [p.median for p in group if p.status == "ok"]
            if kind in ("exact", "empty"):  # no error to plot: their time is a floor
                if times:
                    ax.axvline(times[0], color="k" if kind == "exact" else colours[label],
                               ls="-" if kind == "exact" else ":", lw=1.2, label=label)
                continue
            x, y = _curve(group)
            if x:
                ax.plot(x, y, "-" if kind == "cvode" else "--" if kind == "fmu" else "-.",
                        marker="*" if kind == "article" else "o", ms=12 if kind == "article" else 4,
                        lw=2.0 if kind == "cvode" else 1.0, color=colours[label], label=label)
        for target in MATCHED_ERRORS:
            ax.axhline(target, color="0.55", lw=0.8, ls="--", zorder=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("median wall time [s]")
        ax.set_title(f"article scene, {title} output grid")
        ax.grid(True, which="major", color="0.92")
    axes[0].set_ylabel("max |h - h_exact| [m]")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside right center", fontsize=8)
    with atomic_write(path) as temporary:
        fig.savefig(temporary, dpi=100, format="png")
    plt.close(fig)
    return path
