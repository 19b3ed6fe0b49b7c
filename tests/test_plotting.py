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


def _panels(fig) -> dict:
    return {ax.get_label(): ax for ax in fig.axes}


def _events_drawn(ax) -> dict[str, np.ndarray]:
    """The event strip's ticks: {legend label: times}."""
    return {c.get_label().split(" (")[0]: np.sort(c.get_positions()) for c in ax.collections}


def test_article_has_height_events_log_error_and_zoom_panels_and_the_legend_outside_them():
    result, exact = _run(bb.Ball(), 8.0)
    fig = height_figure(result, exact)
    panels = _panels(fig)
    assert list(panels) == ["height", "events", "error", "zoom"]
    height, error = panels["height"], panels["error"]
    assert error.get_yscale() == "log" and height.get_yscale() == "linear"
    labels = [t.get_text() for t in height.get_legend().texts]
    assert labels[:2] == ["cvode", "exact solution"]
    # the exact solution is drawn (not hidden), and the error drawn is the run's own against it
    lines = {line.get_label(): line for line in height.get_lines()}
    drawn = lines["exact solution"]
    at = np.searchsorted(exact.t, drawn.get_xdata())
    assert np.array_equal(drawn.get_ydata(), exact.h[at]) and len(at) <= 4 * COLUMNS  # of 8001
    assert drawn.get_ydata().min() == exact.h.min() and drawn.get_ydata().max() == exact.h.max()
    drawn_error = error.get_lines()[0].get_ydata()
    assert np.nanmax(drawn_error) == pytest.approx(np.max(np.abs(result.h - exact.h)), rel=0)
    _assert_legends_outside_every_panel(fig)
    # every event a tick of its own on the strip, at the exact events' times
    exact_events = ExactSolution(bb.Ball(), 2.0, 0.0, 0.0, 8.0).events
    ticks = _events_drawn(panels["events"])
    truth = oracle_counts(bb.Ball())
    impacts, departures = f"{truth.impacts} impacts", f"{truth.departures} departures"
    assert sorted(ticks) == sorted([impacts, departures])
    assert np.allclose(ticks[impacts], [e.time for e in exact_events if e.kind == "impact"], atol=1e-9)
    assert np.allclose(ticks[departures], [e.time for e in exact_events if e.kind == "departure"], atol=1e-9)


def test_the_error_estimate_is_drawn_and_the_errors_are_in_the_title():
    result, exact = _run(bb.Ball(), 8.0)
    assert result.error_estimate > 0.0
    fig = height_figure(result, exact, title="scene article")
    error = _panels(fig)["error"]
    estimates = [line for line in error.get_lines() if line.get_label().startswith("error estimate of cvode")]
    assert len(estimates) == 1 and set(estimates[0].get_ydata()) == {result.error_estimate}
    low, high = error.get_ylim()
    assert low < result.error_estimate < high  # inside the panel, not clipped away
    title = fig.get_suptitle()
    measured = np.max(np.abs(result.h - exact.h))
    assert title.startswith("scene article\n") and f"max |h - h_exact| = {measured:.2g} m" in title
    assert f"error estimate {result.error_estimate:.2g} m" in title
    # Without the exact solution (the Hunt-Crossley law has none) the estimate is the panel
    alone = height_figure(result)
    assert [line.get_ydata()[0] for line in _panels(alone)["error"].get_lines()] == [result.error_estimate]
    assert "max |h - h_exact|" not in alone.get_suptitle()
    scipy = bb.simulate(bb.Ball(), 2.0, 0.0, 1.0, solver="scipy")  # no estimate: no panel, and the title says so
    fig = height_figure(scipy)
    assert "error" not in _panels(fig) and "no error estimate" in fig.get_suptitle()


def test_the_last_second_is_zoomed_and_its_events_can_be_counted():
    result, exact = _run(bb.Ball(), 8.0)
    zoom = _panels(height_figure(result, exact))["zoom"]
    assert zoom.get_xlim() == (7.0, 8.0)
    inside = [e for e in ExactSolution(bb.Ball(), 2.0, 0.0, 0.0, 8.0).events if e.time >= 7.0]
    impacts = [e.time for e in inside if e.kind == "impact"]
    departures = [e.time for e in inside if e.kind == "departure"]
    assert len(impacts) >= 5  # closer together than anywhere else in the run
    markers = {line.get_label(): line.get_xdata() for line in zoom.get_lines()}
    assert np.allclose(markers[f"{len(impacts)} impacts"], impacts, atol=1e-9)
    assert np.allclose(markers[f"{len(departures)} departures"], departures, atol=1e-9)
    assert f"{len(impacts)} impacts, {len(departures)} departures" in zoom.get_title()
    # markers at least a few pixels apart: each can be told from the next
    zoom.figure.canvas.draw()
    pixels = zoom.transData.transform(np.column_stack([sorted(impacts + departures), np.zeros(len(inside))]))[:, 0]
    assert np.min(np.diff(pixels)) > 8.0


def test_undamped_long_run_draws_few_points_keeps_the_extremes_and_adds_an_energy_panel():
    result, exact = _run(bb.Ball(b=0.0), 1000.0, 1e-2)
    assert len(result.t) == 100_001 and result.impacts > COLUMNS // 6  # closer than the pixels can show
    fig = height_figure(result, exact)
    panels = _panels(fig)
    assert list(panels) == ["height", "events", "error", "energy", "zoom"]
    height, error, energy = panels["height"], panels["error"], panels["energy"]
    for ax in fig.axes:
        assert _drawn_points(ax) <= 4 * COLUMNS + 2 * result.impacts + 10
    lines = {line.get_label().split("\n")[0]: line for line in height.get_lines()}
    assert np.max(lines["highest h of each bounce"].get_ydata()) == np.max(result.h)
    assert np.min(lines["lowest h of each bounce"].get_ydata()) == np.min(result.h)
    assert np.max(error.get_lines()[0].get_ydata()) == np.max(np.abs(result.h - exact.h))
    drift = (result.energy - result.energy[0]) / result.energy[0]
    drawn = np.concatenate([line.get_ydata() for line in energy.get_lines()[:2]])
    assert drawn.min() == drift.min() and drawn.max() == drift.max()
    assert energy.get_ylabel() == "(E - E0) / |E0|"
    _assert_legends_outside_every_panel(fig)
    # the drift is read from its own tick labels: no offset or multiplier above the axis
    fig.canvas.draw()
    assert energy.yaxis.get_offset_text().get_text() == ""
    ticks = [(tick, label.get_text()) for tick, label in zip(energy.get_yticks(), energy.get_yticklabels(),
                                                               strict=True)]
    assert len(ticks) >= 3 and all(np.isclose(float(text.replace("\u2212", "-")), tick, rtol=1e-3, atol=0)
                                   for tick, text in ticks)
    # the last bounces drawn whole, beside the envelope: at least 3 impacts, the curve reaching the top
    zoom = panels["zoom"]
    start, end = zoom.get_xlim()
    assert end == 1000.0 and sum(e.kind == "impact" and e.time >= start for e in result.events) >= 3
    assert np.max(zoom.get_lines()[0].get_ydata()) > 1.99


@pytest.mark.parametrize(("ball", "t_end", "interval"), [(bb.Ball(), 8.0, 1e-3), (bb.Ball(b=0.0), 1000.0, 1e-2)])
def test_the_run_has_one_colour_in_every_panel_and_the_exact_solution_another(ball, t_end, interval):
    from matplotlib.colors import to_hex

    result, exact = _run(ball, t_end, interval)
    fig = height_figure(result, exact)
    panels = _panels(fig)
    labels = {line.get_label().split("\n")[0]: to_hex(line.get_color()) for line in panels["height"].get_lines()}
    run = labels.get("cvode", labels.get("highest h of each bounce"))
    assert ("energy" in panels) == (ball.b == 0.0)
    for ax in (panels[name] for name in ("error", "energy") if name in panels):  # the run's (the zero line aside)
        assert {to_hex(line.get_color()) for line in ax.get_lines() if not line.get_label().startswith("_")} == {run}
    if "exact solution" in labels:
        assert labels["exact solution"] != run


def test_a_damped_ball_has_no_energy_panel_and_the_exact_solver_no_error_panel():
    result, exact = _run(bb.Ball(), 2.0)
    assert list(_panels(height_figure(result, exact))) == ["height", "events", "error"]  # 2 s: no zoom either
    alone = bb.simulate(bb.Ball(), 2.0, 0.0, 2.0, solver="exact")
    fig = height_figure(alone, alone)
    assert list(_panels(fig)) == ["height", "events"]
    assert f"rounding error estimate {alone.error_estimate:.2g} m" in fig.get_suptitle()


def test_plot_range_zooms_and_counts_the_events_inside():
    result, exact = _run(bb.Ball(b=0.0), 1000.0, 1e-2)
    fig = height_figure(result, exact, t_range=(995.0, 1000.0))
    panels = _panels(fig)
    assert "zoom" not in panels and panels["energy"].get_xlim() == (995.0, 1000.0)
    inside = [e for e in ExactSolution(bb.Ball(b=0.0), 2.0, 0.0, 0.0, 1000.0).events if 995.0 <= e.time <= 1000.0]
    impacts = sum(e.kind == "impact" for e in inside)
    assert f"{impacts} impacts" in _events_drawn(panels["events"])
    labels = [t.get_text() for t in panels["height"].get_legend().texts]
    assert "exact solution" in labels  # few bounces: drawn as lines again
    assert "drawn from t = 995 to 1000 s" in fig.get_suptitle()


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
    assert fig.get_suptitle().split("\n")[0] == "exact, 1 event"
    assert list(_events_drawn(_panels(fig)["events"])) == ["1 impact"]  # no departure to mark
