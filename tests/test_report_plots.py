"""The work-precision plot and the sweep's heat maps, redrawn from the stored results in docs/."""

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")
import matplotlib.pyplot as plt  # noqa: E402

from bouncingball.bench import plots, tables  # noqa: E402
from bouncingball.bench.targets import MATCHED_ERRORS  # noqa: E402

DOCS = Path(__file__).resolve().parents[1] / "docs"
pytestmark = pytest.mark.skipif(not (DOCS / "work_precision.csv").is_file(), reason="runs in a source checkout")


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _overlaps(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_the_stored_work_precision_points_read_back_as_written(tmp_path):
    points = tables.read_work_precision_csv(DOCS / "work_precision.csv")
    copy = tables.write_work_precision_csv(points, tmp_path / "again.csv")
    def rows(path):  # every column but h_key (the saved h values are not read back)
        with open(path, newline="", encoding="utf-8") as file:
            return [row[:-1] for row in csv.reader(file)]

    stored = rows(DOCS / "work_precision.csv")
    assert rows(copy) == stored and len(points) == len(stored) - 1 > 200  # every point, the header aside


def _legend_texts(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]


def test_work_precision_has_a_row_per_family_at_most_8_series_a_panel_and_the_legends_outside():
    points = tables.read_work_precision_csv(DOCS / "work_precision.csv")
    fig = plots.work_precision_figure(points)
    assert len(fig.axes) == len(plots.FAMILIES) * len(plots.PANELS)
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    assert [legend.get_title().get_text() for legend in legends] == [heading for heading, _ in plots.FAMILIES]
    assert all(legend.get_title().get_fontweight() == "bold" for legend in legends)
    texts = [t.get_text() for t in legends[1].get_texts()]
    assert texts[:4] == ["1 ms steps, scikit-sundae engine", "10 ms steps, scikit-sundae engine",
                         "1 ms steps, compiled engine (the default)", "10 ms steps, compiled engine (the default)"]
    for ax in fig.axes:
        series = [line for line in ax.get_lines() if not line.get_label().startswith("_")]
        assert len(series) <= plots.MAX_SERIES
        levels = [line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "--"
                  and len(set(line.get_ydata())) == 1 and line.get_xdata()[0] == 0]
        assert sorted(levels) == (sorted(MATCHED_ERRORS) if series else [])
        # reference lines under every curve (and over the grid); nothing drawn over a curve inside the panel
        compared = [line for line in series if line.get_label().endswith("to compare")]
        curves = [line for line in series if len(set(line.get_ydata())) > 1 and len(set(line.get_xdata())) > 1
                  and line not in compared]
        references = compared + [line for line in ax.get_lines() if line not in curves + compared
                                 and line.get_linestyle() != "None"]
        assert all(r.get_zorder() < c.get_zorder() for r in references for c in curves)
        assert not ax.texts or not series  # no annotations on the data (the empty panel says why it is empty)
    # every solver of the table is drawn, each in its family's row, the C floor and exact solution with CVODE
    solvers = {plots._label(p) for p in points}
    drawn = {line.get_label().split(" (= ")[0] for ax in fig.axes for line in ax.get_lines()}
    assert solvers <= drawn
    fig.canvas.draw()
    for legend in legends:
        box = legend.get_window_extent()
        assert not any(_overlaps(box, ax.get_window_extent()) for ax in fig.axes) and box.x1 <= fig.bbox.x1
    assert "the errors the tables compare at\n(1e-6, 1e-9 m)" in _legend_texts(fig)


def _quick(points):
    """The stored points as `bench --quick` would have them: its tolerances only, and its repeats."""
    from bouncingball.bench.work_precision import QUICK

    return [dataclasses.replace(p, times=p.times[:QUICK.repeats]) for p in points
            if p.rtol is None or any(math.isclose(p.rtol, rtol) for rtol in QUICK.rtols)]


@pytest.mark.parametrize("quick", [False, True])
def test_work_precision_names_each_line_hidden_under_another(quick):
    """A line drawn under a later one with the same errors, at times closer than a marker, is named as hidden."""
    points = tables.read_work_precision_csv(DOCS / "work_precision.csv")
    fig = plots.work_precision_figure(_quick(points) if quick else points)
    texts = _legend_texts(fig)
    found = set()
    for ax in fig.axes:
        lines = [line for line in ax.get_lines() if not line.get_label().startswith("_")
                 and not line.get_label().endswith("to compare")]
        for i, line in enumerate(lines):
            x, y = line.get_xdata(), line.get_ydata()
            covering = [later.get_label() for later in lines[i + 1:]
                        if np.array_equal(later.get_ydata(), y) and len(x) > 1
                        and np.all(np.abs(np.log(np.divide(later.get_xdata(), x))) < np.log(plots.SAME_TIME_FACTOR))]
            if covering:
                found.add(line.get_label())
                assert "hidden under it" in line.get_label() and f"= {covering[0]}" in line.get_label()
    assert found and all(label in texts for label in found)
    assert sorted(text for text in texts if "hidden" in text) == sorted(found)
    # The stored run: CVODE Adams and auto take the same steps, so their errors are equal in both panels.
    assert any(text.startswith("Adams (= auto") for text in texts)


def test_a_quick_work_precision_figure_says_it_is_quick():
    points = tables.read_work_precision_csv(DOCS / "work_precision.csv")
    full = plots.work_precision_figure(points).get_suptitle()
    rtols = {p.rtol for p in points if p.rtol is not None}
    assert "QUICK" not in full and f"{len(rtols)} tolerances" in full and "median of 5 timed runs" in full
    quick = plots.work_precision_figure(_quick(points)).get_suptitle()
    assert quick.startswith("QUICK run (bouncingball bench --quick): 4 tolerances") and "2 timed runs" in quick
    assert "not the published figure" in quick


def test_work_precision_redraws_from_the_csv(tmp_path):
    assert plots.main([str(DOCS / "work_precision.csv"), str(tmp_path / "wp.png")]) == 0
    assert (tmp_path / "wp.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_heat_maps_explain_their_white_cells_and_label_legibly():
    pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    from bouncingball.sweep.report import grid_of, heat_map_figure

    frame = pq.read_table(DOCS / "stability_map.parquet").to_pandas()
    grid = grid_of(frame)
    assert len(grid.cells()) * len(grid.solvers) == len(frame)
    assert grid.solvers == ("cvode", "article", "scipy:DOP853")
    for solver in grid.solvers:
        rows = frame[frame["solver"] == solver]
        fig = heat_map_figure(frame, grid, solver)
        outcome, error, work = fig.axes[:3]  # the colour bars come after the maps
        missing = np.zeros((len(grid.axis("zeta")), len(grid.axis("k"))), bool)
        calls = np.full(missing.shape, np.nan)
        for row in rows.itertuples():
            cell = grid.axis("zeta").index(row.zeta), grid.axis("k").index(row.k)
            missing[cell] = row.status != "finished"
            calls[cell] = row.rhs_calls if row.status == "finished" else np.nan
        # The work as right-hand-side calls, which do not depend on the machine's load (wall time does).
        assert "right-hand-side calls" in work.get_title() and "wall time [s]" not in work.get_title()
        np.testing.assert_allclose(work.get_images()[0].get_array().filled(np.nan), calls)
        for ax in (error, work):
            assert np.array_equal(np.isnan(ax.get_images()[0].get_array().filled(np.nan)), missing)
            legend = ax.get_legend()
            if missing.any():
                assert legend.get_texts()[0].get_text().startswith("white: no data (the run timed out")
                assert legend.get_patches()[0].get_facecolor()[:3] == (1.0, 1.0, 1.0)
            else:
                assert legend is None
        assert outcome.get_legend() is None  # every cell was run
        for ax in (outcome, error, work):
            assert all(label.get_fontsize() >= 10 for label in ax.get_xticklabels() + ax.get_yticklabels())
            assert [label.get_text() for label in ax.get_xticklabels()][:3] == ["1e2", "1e3", "1e4"]
        assert (solver != "cvode") == missing.any()  # the stored map: only the SciPy runs time out


def test_every_solver_s_heat_maps_share_one_colour_scale_per_quantity_with_a_bar_in_its_units():
    """A colour means one error (one number of calls) in every solver's figure: the same log norm in all of them."""
    pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq
    from matplotlib.colors import LogNorm

    from bouncingball.sweep.report import grid_of, heat_map_figure

    frame = pq.read_table(DOCS / "stability_map.parquet").to_pandas()
    grid = grid_of(frame)
    done = frame[frame["status"] == "finished"]
    expected = {"error": (max(done["max_height_error"].min(), 1e-16), done["max_height_error"].max()),
                "calls": (done.loc[done["rhs_calls"] > 0, "rhs_calls"].min(), done["rhs_calls"].max())}
    # the stored table: the solvers' own ranges differ by orders of magnitude, so a scale of each would mislead
    own = {solver: done.loc[done["solver"] == solver, "max_height_error"].max() for solver in grid.solvers}
    assert max(own.values()) / min(own.values()) > 1e3
    for solver in grid.solvers:
        fig = heat_map_figure(frame, grid, solver)
        for ax, quantity, unit in ((fig.axes[1], "error", "max |h - h_exact| [m]"),
                                   (fig.axes[2], "calls", "right-hand-side calls")):
            image = ax.get_images()[0]
            assert isinstance(image.norm, LogNorm)
            assert (image.norm.vmin, image.norm.vmax) == pytest.approx(expected[quantity], rel=1e-12)
            assert image.colorbar.ax.get_ylabel() == unit
            assert "one colour scale for all 3 solvers' maps" in ax.get_title()
        plt.close(fig)
