"""The run drawn: height, its events, its error and error estimate, its energy, its last bounces zoomed (matplotlib).

A long run has far more output points than the figure has pixels: each panel draws, for every
pixel column, the first, last, lowest and highest sample in it (decimate), which is the same
picture with every extreme kept. Where the bounces come closer than a few pixels apart, a line
would only fill the band h sweeps: the height panel draws each bounce's highest and lowest h
instead, the error panel the largest error in each pixel column and the energy panel each
bounce's extremes of the drift. The events are thin ticks on a strip of their own, and the last
bounces are drawn again, zoomed, with every event marked, so that they can be counted at any
density; --plot-range (t_range) zooms in.
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
IMPACT_COLOUR, DEPARTURE_COLOUR = "C3", "C2"
ZOOM_TIME = 1.0  # s: the zoom panel shows at least the last second ...
ZOOM_IMPACTS = 3  # ... and at least the last 3 impacts


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
    """The figure of a run: h(t), its events, its error, for an undamped ball its energy, and its last second zoomed.

    Parameters
    ----------
    result : SimulationResult
        The run to draw.
    exact : SimulationResult, optional
        The exact solution on the same grid (accuracy.exact_on_grid(...).result()): drawn with the run, and
        the run's error against it in a panel of its own on a log axis.
    title : str, optional
        The figure's title (default: the solver's name and the number of events); the run's max error
        against the exact solution and its error estimate are added to it.
    t_range : (float, float), optional
        Draw only from t_range[0] to t_range[1] [s].

    Returns
    -------
    matplotlib.figure.Figure
        One column of panels, each with its legend outside it on the right: the height; the events as
        thin ticks on a strip of their own (impacts, departures), where markers on the curve would
        hide each other; the error against the exact solution with the run's own error estimate
        (result.error_estimate) as a dashed line; the relative energy drift (E - E0) / |E0| of an
        undamped ball; and, where the drawn time is much longer than its last bounces, those
        drawn again on a time axis of their own, every event marked, so that they can be counted.
        All but the zoom share the time axis. Each panel's axes are labelled with its name (height,
        events, error, energy, zoom: Axes.get_label()).
    """
    require_matplotlib()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if exact is result or (exact is not None and len(exact.t) != len(result.t)):
        exact = None
    selected = _selection(result.t, t_range)
    t, h = result.t[selected], result.h[selected]
    shown = t_range or (t[0], t[-1])
    events = [e for e in result.events if shown[0] <= e.time <= shown[1]]
    estimate = result.error_estimate if result.solver != "exact" else None
    conservative = result.ball.b == 0.0 and not isinstance(result.F_ext, ForceTable)
    zoom = _zoom_window(events, shown)
    panels = (["height"] + (["events"] if events else []) + (["error"] if exact is not None or estimate else [])
              + (["energy"] if conservative else []) + (["zoom"] if zoom else []))
    heights = {"height": 3.0, "events": 0.7, "error": 1.6, "energy": 1.4, "zoom": 2.2}
    fig = plt.figure(layout="constrained", figsize=(FIGURE_WIDTH, 0.9 + sum(heights[p] for p in panels)))
    grid = fig.add_gridspec(len(panels), 1, height_ratios=[heights[p] for p in panels])
    axes = {"height": fig.add_subplot(grid[0], label="height")}
    for row, panel in enumerate(panels[1:], start=1):
        axes[panel] = fig.add_subplot(grid[row], sharex=None if panel == "zoom" else axes["height"], label=panel)
    _height_panel(axes["height"], result, t, h, exact, selected, events)
    if events:
        _events_panel(axes["events"], events)
    if "error" in axes:
        error = None if exact is None else np.abs(h - exact.h[selected])
        _error_panel(axes["error"], result.solver, t, error, _dense([e.time for e in events if e.kind == IMPACT]),
                     estimate)
    if conservative:
        impacts = [e.time for e in events if e.kind == IMPACT]
        _energy_panel(axes["energy"], result, selected, impacts if _dense(impacts) else None)
    whole = [axes[p] for p in panels if p != "zoom"]
    for ax in whole[:-1]:
        ax.tick_params(labelbottom=False)
    whole[-1].set_xlabel("time t [s]")
    whole[-1].set_xlim(*shown)
    if zoom:
        for ax in whole[:2]:  # where the zoom is, on the height and the events
            ax.axvspan(*zoom, color="0.5", alpha=0.12, lw=0, label="_zoomed below")
        _zoom_panel(axes["zoom"], result, exact, [e for e in events if e.time >= zoom[0]], zoom)
    title = title or f"{result.solver}, {plural(len(result.events), 'event')}"
    title = title if t_range is None else f"{title}; drawn from t = {t_range[0]:g} to {t_range[1]:g} s"
    fig.suptitle(f"{title}\n{_error_summary(result, exact)}")
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


def _error_summary(result: SimulationResult, exact: SimulationResult | None) -> str:
    """The title's second line: the run's max error against the exact solution and its own estimate [m]."""
    parts = []
    if exact is not None:
        parts.append(f"max |h - h_exact| = {np.nanmax(np.abs(result.h - exact.h)):.2g} m")
    if result.error_estimate is not None:
        what = "rounding error estimate" if result.solver == "exact" else "error estimate"
        parts.append(f"{what} {result.error_estimate:.2g} m")
    if not parts:
        parts.append(f"no error estimate ({result.solver} makes none)")
    return ", ".join(parts)


def _zoom_window(events: list, shown: tuple[float, float]) -> tuple[float, float] | None:
    """(start, end) [s] of the zoom: the last ZOOM_TIME, or the last ZOOM_IMPACTS impacts where they take longer;
    None where that is more than a third of the time shown (the whole is then readable as it is)."""
    impacts = [e.time for e in events if e.kind == IMPACT]
    if not impacts:
        return None
    start = shown[1] - ZOOM_TIME
    if len(impacts) >= ZOOM_IMPACTS:
        start = min(start, impacts[-ZOOM_IMPACTS] - 0.1 * (shown[1] - impacts[-ZOOM_IMPACTS]))
    if shown[1] - start > (shown[1] - shown[0]) / 3.0:
        return None
    return start, shown[1]


def per_bounce(t: np.ndarray, y: np.ndarray, impacts: list[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(middle time [s], lowest y, highest y) of each stretch from one impact to the next (and before the first).

    Examples
    --------
    >>> t = np.linspace(0.0, 3.0, 301)
    >>> middles, low, high = per_bounce(t, np.sin(2 * np.pi * t), [1.0, 2.0])
    >>> middles.tolist(), bool(np.allclose(high, 1.0)), bool(np.allclose(low, -1.0))
    ([0.5, 1.5, 2.5], True, True)
    """
    starts = np.unique(np.searchsorted(t, impacts))
    starts = starts[starts < len(t)]
    if len(starts) == 0 or starts[0] != 0:
        starts = np.concatenate(([0], starts))
    middles = t[np.minimum(starts + np.diff(np.append(starts, len(t))) // 2, len(t) - 1)]
    return middles, np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts)


def _height_panel(ax, result, t, h, exact, selected, events) -> None:
    R = result.ball.R
    impacts = [e.time for e in events if e.kind == IMPACT]
    if _dense(impacts):
        # A line would fill the band h sweeps on every bounce: draw each bounce's highest and lowest h instead.
        middles, lowest, highest = per_bounce(t, h, impacts)
        ax.plot(middles, highest, color=RUN_COLOUR, lw=1.4,
                label=f"highest h of each bounce\n(of {plural(len(impacts), 'bounce')},\ntoo close to draw here)")
        ax.plot(middles, lowest, color=LOWEST_COLOUR, lw=1.4, label="lowest h of each bounce\n(at the output times)")
    else:
        keep = decimate(t, h)
        ax.plot(t[keep], h[keep], color=RUN_COLOUR, lw=2.2, alpha=0.8, label=result.solver)
        if exact is not None:
            h_exact = exact.h[selected]
            keep = decimate(t, h_exact)
            ax.plot(t[keep], h_exact[keep], color=EXACT_COLOUR, lw=0.8, ls=(0, (4, 3)), label="exact solution")
    _draw_ground(ax, result, t, f"h = R = {R:g} m (contact)")
    if result.rest_time is not None and t[0] <= result.rest_time <= t[-1]:
        rest = "riding the ground" if result.ground.moves else "at rest"
        ax.axvline(result.rest_time, color="0.4", lw=0.8, ls=":", label=f"{rest} from {result.rest_time:.4g} s")
    ax.set_ylabel("height of the centre h [m]")
    ax.grid(True, color="0.92")


def _events_panel(ax, events) -> None:
    """Each event a thin tick on its own row, impacts above the other kinds: no marker hides another."""
    impacts = [e.time for e in events if e.kind == IMPACT]
    others = [e.time for e in events if e.kind != IMPACT]
    dense = " (ticks closer than\nthe pixels: counted\nin the zoom below)" if _dense(impacts) else ""
    for times, row, colour, kind in ((impacts, 1, IMPACT_COLOUR, "impact"), (others, 0, DEPARTURE_COLOUR, "departure")):
        if times:
            ax.eventplot(times, lineoffsets=row, linelengths=0.8, linewidths=0.6, colors=colour,
                         label=plural(len(times), kind) + (dense if row == 1 else ""))
    ax.set_ylim(-0.6, 1.6)
    ax.set_yticks([0, 1], ["departures", "impacts"], fontsize=8)
    ax.set_ylabel("events", fontsize=9)


def _dense(impacts: list[float]) -> bool:
    """True when the bounces come closer than PIXELS_PER_BOUNCE pixel columns apart."""
    return len(impacts) * PIXELS_PER_BOUNCE > COLUMNS


def _error_panel(ax, solver: str, t: np.ndarray, error: np.ndarray | None, dense: bool,
                 estimate: float | None) -> None:
    positive = np.zeros(0, bool) if error is None else error > 0.0
    if error is not None and not np.any(positive):
        ax.text(0.5, 0.5, "h equals h_exact at every output time", transform=ax.transAxes, ha="center", va="center")
    elif error is not None and dense:  # its dips at each bounce would fill the panel: the largest error per column
        centres, _, high = envelope(t[positive], error[positive])
        ax.plot(centres, high, color=RUN_COLOUR, lw=1.2, label=f"largest |h - h_exact| of {solver}\n"
                                                          f"in each {(t[-1] - t[0]) / COLUMNS:.3g} s")
    elif error is not None:
        keep = decimate(t, np.where(positive, error, np.nan))
        ax.plot(t[keep], error[keep], color=RUN_COLOUR, lw=1.0, label=f"|h - h_exact| of {solver}")
    if estimate:
        ax.axhline(estimate, color=RUN_COLOUR, lw=1.2, ls=(0, (6, 3)),
                   label=f"error estimate of {solver}:\n{estimate:.2g} m (its own,\nwithout the exact solution)")
    if np.any(positive) or estimate:
        ax.set_yscale("log")
    else:
        ax.set_yticks([])
    ax.set_ylabel("|h - h_exact| [m]" if error is not None else "error [m]")
    ax.grid(True, which="major", color="0.92")


def _energy_panel(ax, result: SimulationResult, selected: slice, impacts: list[float] | None) -> None:
    """The relative drift (E - E0) / |E0|, every tick label in full (no offset or multiplier above the axis).

    impacts: the impact times [s] where the bounces are too close to draw (then each bounce's extremes), else None.
    """
    from matplotlib.ticker import FuncFormatter

    energy = result.energy
    drift = (energy - energy[0]) / abs(energy[0]) if energy[0] else energy - energy[0]
    t, drift = result.t[selected], drift[selected]
    if impacts is not None:  # it swings on each bounce: its lowest and highest there, so that a trend shows
        middles, low, high = per_bounce(t, drift, impacts)
        ax.fill_between(middles, low, high, color=RUN_COLOUR, alpha=0.2, lw=0)
        ax.plot(middles, high, color=RUN_COLOUR, lw=1.0,
                label="highest and lowest drift\nof each bounce\n(b = 0: the exact energy\nis constant)")
        ax.plot(middles, low, color=RUN_COLOUR, lw=1.0, label="_lowest")
    else:
        keep = decimate(t, drift)
        ax.plot(t[keep], drift[keep], color=RUN_COLOUR, lw=1.0,
                label="energy drift of the run\n(b = 0: the exact energy\nis constant)")
    ax.axhline(0.0, color="0.4", lw=0.6)
    ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:.3g}"))
    ax.set_ylabel("(E - E0) / |E0|" if energy[0] else "E - E0 [J]")
    ax.grid(True, color="0.92")


def _zoom_panel(ax, result: SimulationResult, exact: SimulationResult | None, events, window) -> None:
    """The last bounces on a time axis of their own: h, the exact solution and every event marked on h = R."""
    inside = _selection(result.t, window)
    t = result.t[inside]
    keep = decimate(t, result.h[inside])
    ax.plot(t[keep], result.h[inside][keep], color=RUN_COLOUR, lw=2.2, alpha=0.8, label=result.solver)
    if exact is not None:
        keep = decimate(t, exact.h[inside])
        ax.plot(t[keep], exact.h[inside][keep], color=EXACT_COLOUR, lw=0.8, ls=(0, (4, 3)), label="exact solution")
    R = result.ball.R
    impacts = [e.time for e in events if e.kind == IMPACT]
    others = [e.time for e in events if e.kind != IMPACT]
    for times, marker, colour, kind in ((impacts, "v", IMPACT_COLOUR, "impact"), (others, "^", DEPARTURE_COLOUR,
                                                                                  "departure")):
        if times:
            ax.plot(times, R + result.ground.position(np.asarray(times)), marker, color=colour, ms=6,
                    label=plural(len(times), kind))
    _draw_ground(ax, result, t, "_contact")
    ax.set_xlim(*window)
    ax.set_title(f"the last {window[1] - window[0]:.3g} s (shaded above), zoomed: "
                 f"{plural(len(impacts), 'impact')}, {plural(len(others), 'departure')}", fontsize=10)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("h [m]")
    ax.grid(True, color="0.92")


def _draw_ground(ax, result: SimulationResult, t: np.ndarray, label: str) -> None:
    """Where the centre touches the ground: h = R on a still ground; on a moving one R + s(t), the ground s(t) below."""
    R, ground = result.ball.R, result.ground
    if not ground.moves and ground.height == 0.0:
        ax.axhline(R, color="0.4", lw=0.6, ls="--", label=label)
        return
    fine = np.linspace(t[0], t[-1], max(20 * COLUMNS, 2))
    surface = np.asarray(ground.position(fine), dtype=float)
    ax.plot(fine, R + surface, color="0.4", lw=0.6, ls="--",
            label=label if label.startswith("_") else "h = R + s(t) (contact)")
    ax.fill_between(fine, surface, np.min(surface) - 0.05 * (np.max(surface) - np.min(surface) + R), color="0.75",
                    lw=0, label="_ground" if label.startswith("_") else "the ground s(t)")


def require_matplotlib() -> None:
    """Fail early, with the install command, where matplotlib is missing."""
    from importlib.util import find_spec

    if find_spec("matplotlib") is None:
        from .extras import install_command

        raise ImportError(f"plotting needs matplotlib: {install_command('plot')}")
