"""The run drawn: height with the events, its error against the exact solution, its energy (matplotlib, imported here).

A long run has far more output points than the figure has pixels: each panel draws, for every
pixel column, the first, last, lowest and highest sample in it (decimate), which is the same
picture with every extreme kept. Where the bounces come closer than a few pixels apart, a line
would only fill the band h sweeps: the height panel draws each bounce's highest and lowest h
instead, and the error panel the largest error in each pixel column; --plot-range (t_range)
zooms in.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .output import atomic_write
from .run_report import plural
from .solvers.forcing import ForceTable
from .solvers.result import IMPACT, SimulationResult

FIGURE_WIDTH = 11.0  # inches
DPI = 110
COLUMNS = 900  # pixel columns of the data area at FIGURE_WIDTH and DPI (the legend takes the rest)
PIXELS_PER_BOUNCE = 6  # bounces closer than this are drawn as the envelope of h
# One colour for the run in every panel (its height, its error, its energy), another for the exact solution
RUN_COLOUR, LOWEST_COLOUR, EXACT_COLOUR = "C0", "C9", "k"


def parse_time_range(option: str, text: str, t_start: float, t_end: float) -> tuple[float, float]:
    """'T0:T1' as (T0, T1) [s]: numbers with t_start <= T0 < T1 <= t_end; ValueError naming option otherwise.

    Examples
    --------
    >>> parse_time_range("--plot-range", "2:4.5", 0.0, 8.0)
    (2.0, 4.5)
    """
    first, colon, second = text.partition(":")
    try:
        t0, t1 = float(first), float(second)
    except ValueError:
        t0 = t1 = float("nan")
    if not (colon and t_start <= t0 < t1 <= t_end):
        raise ValueError(f"{option} {text!r} is not allowed: it must be T0:T1 [s] with {t_start!r} <= T0 < T1 <= "
                         f"{t_end!r} (the run's times), for example {t_start!r}:{t_end!r}")
    return t0, t1


def decimate(t: np.ndarray, y: np.ndarray, columns: int = COLUMNS) -> np.ndarray:
    """Indices of the samples to draw: in each of `columns` equal slices of time, its first, last, lowest and highest.

    A line through them covers the same pixels as one through every sample, so each extreme is
    kept; at most 4 columns samples are drawn (all of them when there are no more). NaN samples
    (a run that stopped early) are left out.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 10_001)
    >>> keep = decimate(t, np.sin(40 * t), columns=100)
    >>> len(keep) <= 400, bool(np.isclose(np.sin(40 * t)[keep].max(), np.sin(40 * t).max()))
    (True, True)
    """
    finite = np.flatnonzero(np.isfinite(y))
    if len(finite) <= 4 * columns:
        return finite
    t, y = t[finite], y[finite]
    edges = np.searchsorted(t, np.linspace(t[0], t[-1], columns + 1)[1:-1])
    starts = np.unique(np.concatenate(([0], edges)))
    ends = np.append(starts[1:], len(t))
    keep = [starts, ends - 1]
    for start, end in zip(starts, ends, strict=True):
        part = y[start:end]
        keep.append([start + int(np.argmin(part)), start + int(np.argmax(part))])
    return finite[np.unique(np.concatenate([np.asarray(k).ravel() for k in keep]))]


def envelope(t: np.ndarray, y: np.ndarray, columns: int = COLUMNS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(column centres [s], lowest y, highest y) over `columns` equal slices of time holding samples."""
    edges = np.linspace(t[0], t[-1], columns + 1)
    column = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, columns - 1)
    low = np.full(columns, np.inf)
    high = np.full(columns, -np.inf)
    np.minimum.at(low, column, y)
    np.maximum.at(high, column, y)
    held = np.isfinite(low)
    return 0.5 * (edges[:-1] + edges[1:])[held], low[held], high[held]


def height_figure(result: SimulationResult, exact: SimulationResult | None = None, title: str = "",
                  t_range: tuple[float, float] | None = None):
    """The figure of a run: h(t) with the impacts and departures, |h - h_exact| and, for an undamped ball, its energy.

    Parameters
    ----------
    result : SimulationResult
        The run to draw.
    exact : SimulationResult, optional
        The exact solution on the same grid (accuracy.exact_on_grid(...).result()): drawn with the run, and
        the run's error against it in a panel of its own on a log axis.
    title : str, optional
        The figure's title (default: the solver's name and the number of events).
    t_range : (float, float), optional
        Draw only from t_range[0] to t_range[1] [s].

    Returns
    -------
    matplotlib.figure.Figure
        One column of panels sharing the time axis (height, then error, then energy, as they
        apply), each with its legend outside it on the right.
    """
    require_matplotlib()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if exact is result or (exact is not None and len(exact.t) != len(result.t)):
        exact = None
    selected = _selection(result.t, t_range)
    t, h = result.t[selected], result.h[selected]
    conservative = result.ball.b == 0.0 and not isinstance(result.F_ext, ForceTable)
    panels = ["height"] + (["error"] if exact is not None else []) + (["energy"] if conservative else [])
    heights = {"height": 3.0, "error": 1.6, "energy": 1.4}
    fig, axes = plt.subplots(len(panels), 1, sharex=True, layout="constrained", squeeze=False,
                             figsize=(FIGURE_WIDTH, 0.9 + sum(heights[p] for p in panels)),
                             gridspec_kw={"height_ratios": [heights[p] for p in panels]})
    axes = dict(zip(panels, axes[:, 0], strict=True))
    shown = t_range or (t[0], t[-1])
    events = [e for e in result.events if shown[0] <= e.time <= shown[1]]
    _height_panel(axes["height"], result, t, h, exact, selected, events)
    if exact is not None:
        _error_panel(axes["error"], result.solver, t, np.abs(h - exact.h[selected]),
                     _dense([e.time for e in events if e.kind == IMPACT]))
    if conservative:
        _energy_panel(axes["energy"], result, selected)
    axes[panels[-1]].set_xlabel("time t [s]")
    axes[panels[-1]].set_xlim(*shown)
    title = title or f"{result.solver}, {plural(len(result.events), 'event')}"
    fig.suptitle(title if t_range is None else f"{title}; drawn from t = {t_range[0]:g} to {t_range[1]:g} s")
    for ax in (ax for ax in axes.values() if ax.get_legend_handles_labels()[1]):  # beside its panel, outside it
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8, frameon=False)
    return fig


def plot_height(result: SimulationResult, path: str | Path, title: str = "", exact: SimulationResult | None = None,
                t_range: tuple[float, float] | None = None) -> Path:
    """Save height_figure(result, exact, title, t_range) to path (PNG, or the format its suffix names)."""
    import matplotlib.pyplot as plt

    fig = height_figure(result, exact, title, t_range)
    path = Path(path)
    with atomic_write(path) as temporary:
        fig.savefig(temporary, dpi=DPI, format=path.suffix.lstrip(".").lower() or "png")
    plt.close(fig)
    return path


def _selection(t: np.ndarray, t_range: tuple[float, float] | None) -> slice:
    """The samples from t_range[0] to t_range[1], with the one before and after (the line reaches the edges)."""
    if t_range is None:
        return slice(0, len(t))
    first = max(int(np.searchsorted(t, t_range[0], side="right")) - 1, 0)
    last = min(int(np.searchsorted(t, t_range[1], side="left")) + 1, len(t))
    return slice(first, max(last, first + 2))


def _height_panel(ax, result, t, h, exact, selected, events) -> None:
    R = result.ball.R
    impacts = [e.time for e in events if e.kind == IMPACT]
    departures = [e.time for e in events if e.kind != IMPACT]
    if _dense(impacts):
        # A line would fill the band h sweeps on every bounce: draw each bounce's highest and lowest h instead.
        starts = np.unique(np.searchsorted(t, impacts))
        starts = starts[starts < len(t)]
        if len(starts) == 0 or starts[0] != 0:
            starts = np.concatenate(([0], starts))
        middles = t[np.minimum(starts + np.diff(np.append(starts, len(t))) // 2, len(t) - 1)]
        highest, lowest = np.maximum.reduceat(h, starts), np.minimum.reduceat(h, starts)
        ax.fill_between(middles, lowest, highest, color=RUN_COLOUR, alpha=0.15, lw=0,
                        label=f"{result.solver}: h sweeps this band\non each of {plural(len(impacts), 'bounce')} "
                              "(zoom with\n--plot-range to see them)")
        ax.plot(middles, highest, color=RUN_COLOUR, lw=1.4, label="highest h of each bounce\n(at the output times)")
        ax.plot(middles, lowest, color=LOWEST_COLOUR, lw=1.4, label="lowest h of each bounce\n(at the output times)")
        ax.plot([], [], " ", label=f"{plural(len(impacts), 'impact')}, {plural(len(departures), 'departure')}\n"
                                   "(too close to mark here)")
    else:
        keep = decimate(t, h)
        ax.plot(t[keep], h[keep], color=RUN_COLOUR, lw=2.2, alpha=0.8, label=result.solver)
        if exact is not None:
            h_exact = exact.h[selected]
            keep = decimate(t, h_exact)
            ax.plot(t[keep], h_exact[keep], color=EXACT_COLOUR, lw=0.8, ls=(0, (4, 3)), label="exact solution")
        for times, marker, colour, kind in ((impacts, "v", "C3", "impact"), (departures, "^", "C2", "departure")):
            if times:
                ax.plot(times, [R] * len(times), marker, color=colour, ms=5, label=plural(len(times), kind))
    ax.axhline(R, color="0.4", lw=0.6, ls="--", label=f"h = R = {R:g} m (contact)")
    if result.rest_time is not None and t[0] <= result.rest_time <= t[-1]:
        ax.axvline(result.rest_time, color="0.4", lw=0.8, ls=":", label=f"at rest from {result.rest_time:.4g} s")
    ax.set_ylabel("height of the centre h [m]")
    ax.grid(True, color="0.92")


def _dense(impacts: list[float]) -> bool:
    """True when the bounces come closer than PIXELS_PER_BOUNCE pixel columns apart."""
    return len(impacts) * PIXELS_PER_BOUNCE > COLUMNS


def _error_panel(ax, solver: str, t: np.ndarray, error: np.ndarray, dense: bool) -> None:
    positive = error > 0.0
    if not np.any(positive):
        ax.text(0.5, 0.5, "h equals h_exact at every output time", transform=ax.transAxes, ha="center", va="center")
        ax.set_yticks([])
    elif dense:  # its dips at each bounce would fill the panel: the largest error in each pixel column
        centres, _, high = envelope(t[positive], error[positive])
        ax.plot(centres, high, color=RUN_COLOUR, lw=1.2, label=f"largest |h - h_exact| of {solver}\n"
                                                          f"in each {(t[-1] - t[0]) / COLUMNS:.3g} s")
        ax.set_yscale("log")
    else:
        keep = decimate(t, np.where(positive, error, np.nan))
        ax.plot(t[keep], error[keep], color=RUN_COLOUR, lw=1.0, label=f"|h - h_exact| of {solver}")
        ax.set_yscale("log")
    ax.set_ylabel("|h - h_exact| [m]")
    ax.grid(True, which="major", color="0.92")


def _energy_panel(ax, result: SimulationResult, selected: slice) -> None:
    energy = result.energy
    drift = (energy - energy[0]) / abs(energy[0]) if energy[0] else energy - energy[0]
    t, drift = result.t[selected], drift[selected]
    keep = decimate(t, drift)
    ax.plot(t[keep], drift[keep], color=RUN_COLOUR, lw=1.0,
            label="energy of the run\n(b = 0: the exact one\nis constant)")
    ax.axhline(0.0, color="0.4", lw=0.6)
    ax.set_ylabel("(E - E0) / |E0|" if energy[0] else "E - E0 [J]")
    ax.grid(True, color="0.92")


def require_matplotlib() -> None:
    """Fail early, with the install command, where matplotlib is missing."""
    from importlib.util import find_spec

    if find_spec("matplotlib") is None:
        from .extras import install_command

        raise ImportError(f"plotting needs matplotlib: {install_command('plot')}")
