"""Height against time with the events marked (matplotlib, imported only here)."""

from __future__ import annotations

from pathlib import Path

from .output import atomic_write
from .solvers.result import IMPACT, SimulationResult


def plot_height(result: SimulationResult, path: str | Path, title: str = "", exact: SimulationResult | None = None
                ) -> Path:
    """Save a PNG of h(t) with impacts and departures marked, and the exact solution if given."""
    require_matplotlib()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
    if exact is not None and exact is not result:
        ax.plot(exact.t, exact.h, color="0.75", lw=3.0, label="exact")
    ax.plot(result.t, result.h, color="C0", lw=1.2, label=f"{result.solver}")
    impacts = [e.time for e in result.events if e.kind == IMPACT]
    departures = [e.time for e in result.events if e.kind != IMPACT]
    R = result.ball.R
    ax.plot(impacts, [R] * len(impacts), "v", color="C3", ms=5, label=f"impact ({len(impacts)})")
    ax.plot(departures, [R] * len(departures), "^", color="C2", ms=5, label=f"departure ({len(departures)})")
    ax.axhline(R, color="0.4", lw=0.6, ls="--")
    if result.rest_time is not None:
        ax.axvline(result.rest_time, color="0.4", lw=0.8, ls=":", label=f"at rest from {result.rest_time:.3f} s")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("height of the centre h [m]")
    ax.set_title(title or f"bouncing ball, {result.solver}")
    ax.legend(loc="upper right", fontsize=8)
    path = Path(path)
    with atomic_write(path) as temporary:
        fig.savefig(temporary, dpi=110, format=path.suffix.lstrip(".").lower() or "png")
    plt.close(fig)
    return path


def require_matplotlib() -> None:
    """Fail early, with the install command, where matplotlib is missing."""
    from importlib.util import find_spec

    if find_spec("matplotlib") is None:
        raise ImportError("plotting needs matplotlib: pip install 'bouncingball[plot]'")
