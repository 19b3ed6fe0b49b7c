"""The run's figure: its panels, the legend outside the data, long runs decimated with every extreme kept, the zoom."""

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.accuracy import accuracy_of_result
from bouncingball.cli import main
from bouncingball.solvers.exact import ExactSolution

pytest.importorskip("matplotlib")
import matplotlib.pyplot as plt  # noqa: E402

from bouncingball.plotting import COLUMNS, decimate, height_figure, parse_time_range  # noqa: E402
from oracle_counts import oracle_counts  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _run(ball, t_end, output_interval=1e-3, **options):
    result = bb.simulate(ball, 2.0, 0.0, t_end, output_interval, **options)
    return result, accuracy_of_result(result, 2.0, 0.0)[1].result()


def _drawn_points(ax) -> int:
    return sum(len(line.get_xdata()) for line in ax.get_lines())


def _overlaps(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def _assert_legends_outside_every_panel(fig):
    fig.canvas.draw()
    legends = [ax.get_legend() for ax in fig.axes]
    assert all(legends)
    for legend in legends:
        box = legend.get_window_extent()
        assert not any(_overlaps(box, ax.get_window_extent()) for ax in fig.axes)
        assert box.x1 <= fig.bbox.x1  # and inside the figure


def test_decimate_keeps_every_extreme_and_at_most_four_points_per_column():
    t = np.linspace(0.0, 10.0, 200_001)
    y = np.sin(7.0 * t) * np.exp(-0.1 * t) + 1e-3 * np.cos(900.0 * t)
    keep = decimate(t, y, columns=500)
    assert len(keep) <= 4 * 500 and keep[0] == 0 and keep[-1] == len(t) - 1
    assert np.all(np.diff(keep) > 0)  # in time order
    edges = np.linspace(0.0, 10.0, 501)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):  # each column's own max and min are drawn
        inside = (t >= lo) & ((t < hi) | (hi == 10.0))  # the last column holds the end
        drawn = np.zeros_like(inside)
        drawn[keep] = True
        assert y[inside].max() == y[inside & drawn].max() and y[inside].min() == y[inside & drawn].min()


def test_article_has_height_and_log_error_panels_and_the_legend_outside_them():
    result, exact = _run(bb.Ball(), 8.0)
    fig = height_figure(result, exact)
    height, error = fig.axes
    assert error.get_yscale() == "log" and height.get_yscale() == "linear"
    labels = height.get_legend().texts
    truth = oracle_counts(bb.Ball())
    impacts, departures = f"{truth.impacts} impacts", f"{truth.departures} departures"
    assert [t.get_text() for t in labels][:4] == ["cvode", "exact solution", impacts, departures]
    # the exact solution is drawn (not hidden), and the error drawn is the run's own against it
    lines = {line.get_label(): line for line in height.get_lines()}
    drawn = lines["exact solution"]
    at = np.searchsorted(exact.t, drawn.get_xdata())
    assert np.array_equal(drawn.get_ydata(), exact.h[at]) and len(at) <= 4 * COLUMNS  # of 8001
    assert drawn.get_ydata().min() == exact.h.min() and drawn.get_ydata().max() == exact.h.max()
    drawn_error = error.get_lines()[0].get_ydata()
    assert np.nanmax(drawn_error) == pytest.approx(np.max(np.abs(result.h - exact.h)), rel=0)
    _assert_legends_outside_every_panel(fig)
    # impacts at the exact impact times, on h = R
    impact_line = lines[impacts]
    exact_impacts = [e.time for e in ExactSolution(bb.Ball(), 2.0, 0.0, 0.0, 8.0).events if e.kind == "impact"]
    assert np.allclose(impact_line.get_xdata(), exact_impacts, atol=1e-9)
    assert set(impact_line.get_ydata()) == {bb.Ball().R}


def test_undamped_long_run_draws_few_points_keeps_the_extremes_and_adds_an_energy_panel():
    result, exact = _run(bb.Ball(b=0.0), 1000.0, 1e-2)
    assert len(result.t) == 100_001 and result.impacts > COLUMNS // 6  # closer than the pixels can show
    fig = height_figure(result, exact)
    height, error, energy = fig.axes
    for ax in fig.axes:
        assert _drawn_points(ax) <= 4 * COLUMNS + 2 * result.impacts + 10
    lines = {line.get_label().split("\n")[0]: line for line in height.get_lines()}
    assert np.max(lines["highest h of each bounce"].get_ydata()) == np.max(result.h)
    assert np.min(lines["lowest h of each bounce"].get_ydata()) == np.min(result.h)
    assert np.max(error.get_lines()[0].get_ydata()) == np.max(np.abs(result.h - exact.h))
    drift = (result.energy - result.energy[0]) / result.energy[0]
    drawn = energy.get_lines()[0].get_ydata()
    assert drawn.min() == drift.min() and drawn.max() == drift.max()
    assert energy.get_ylabel() == "(E - E0) / |E0|"
    _assert_legends_outside_every_panel(fig)


@pytest.mark.parametrize(("ball", "t_end", "interval"), [(bb.Ball(), 8.0, 1e-3), (bb.Ball(b=0.0), 1000.0, 1e-2)])
def test_the_run_has_one_colour_in_every_panel_and_the_exact_solution_another(ball, t_end, interval):
    from matplotlib.colors import to_hex

    result, exact = _run(ball, t_end, interval)
    fig = height_figure(result, exact)
    height, *others = fig.axes
    labels = {line.get_label().split("\n")[0]: to_hex(line.get_color()) for line in height.get_lines()}
    run = labels.get("cvode", labels.get("highest h of each bounce"))
    assert len(others) == (2 if ball.b == 0.0 else 1)
    for ax in others:  # the error and the energy are the run's (the zero line aside)
        assert {to_hex(line.get_color()) for line in ax.get_lines() if not line.get_label().startswith("_")} == {run}
    if "exact solution" in labels:
        assert labels["exact solution"] != run


def test_a_damped_ball_has_no_energy_panel_and_the_exact_solver_no_error_panel():
    result, exact = _run(bb.Ball(), 2.0)
    assert len(height_figure(result, exact).axes) == 2
    alone = bb.simulate(bb.Ball(), 2.0, 0.0, 2.0, solver="exact")
    assert len(height_figure(alone, alone).axes) == 1


def test_plot_range_zooms_and_counts_the_events_inside():
    result, exact = _run(bb.Ball(b=0.0), 1000.0, 1e-2)
    fig = height_figure(result, exact, t_range=(995.0, 1000.0))
    assert fig.axes[-1].get_xlim() == (995.0, 1000.0)
    inside = [e for e in ExactSolution(bb.Ball(b=0.0), 2.0, 0.0, 0.0, 1000.0).events if 995.0 <= e.time <= 1000.0]
    impacts = sum(e.kind == "impact" for e in inside)
    labels = [t.get_text() for t in fig.axes[0].get_legend().texts]
    assert f"{impacts} impacts" in labels and "exact solution" in labels  # few bounces: drawn as lines again
    assert "drawn from t = 995 to 1000 s" in fig._suptitle.get_text()


def test_parse_time_range_refuses_what_is_not_inside_the_run():
    assert parse_time_range("--plot-range", "0:8", 0.0, 8.0) == (0.0, 8.0)
    for text in ("5:2", "0:9", "-1:2", "abc", "3", "2:2", "nan:1"):
        with pytest.raises(ValueError, match="--plot-range .* is not allowed"):
            parse_time_range("--plot-range", text, 0.0, 8.0)


def test_cli_plot_range_is_checked_before_the_run(tmp_path, capsys):
    plot = tmp_path / "h.png"
    assert main(["run", "article", "--plot", str(plot), "--plot-range", "2:9"]) == 2
    assert "--plot-range '2:9' is not allowed" in capsys.readouterr().err and not plot.exists()
    assert main(["run", "zero-gravity", "--plot", str(plot), "--plot-range", "1.5:2.5"]) == 0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_titles_say_one_event_not_one_events(tmp_path, capsys):
    ball = bb.Ball(g=0.0)
    result = bb.simulate(ball, 2.0, -1.0, 1.95, solver="exact")  # the impact at 1.94 s, no departure yet
    assert len(result.events) == 1
    fig = height_figure(result)
    assert fig._suptitle.get_text() == "exact, 1 event"
    texts = {t.get_text() for t in fig.axes[0].get_legend().texts}
    assert "1 impact" in texts and not any("departure" in text for text in texts)  # none to mark
