"""The work-precision plot and the sweep's heat maps, redrawn from the stored results in docs/."""

import csv
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


def test_work_precision_groups_the_fmu_series_and_names_the_reference_lines():
    points = tables.read_work_precision_csv(DOCS / "work_precision.csv")
    fig = plots.work_precision_figure(points)
    legend = fig.legends[0]
    texts = [t.get_text() for t in legend.get_texts()]
    headings = [t.get_text() for t in legend.get_texts() if t.get_fontweight() == "bold"]
    assert headings == [heading for heading, _ in plots.FAMILIES]
    fmu_labels = sorted({p.solver.label for p in points if p.solver.kind == "fmu"})
    start = texts.index("the FMU through FMPy")
    assert len(fmu_labels) == 4 and texts[start + 1:start + 5] == ["1 ms steps", "10 ms steps",
                                                                   "1 ms steps, compiled engine",
                                                                   "10 ms steps, compiled engine"]
    for ax in fig.axes:
        levels = [line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "--"
                  and len(set(line.get_ydata())) == 1 and line.get_xdata()[0] == 0]
        assert sorted(levels) == sorted(MATCHED_ERRORS)
    names = [t.get_text() for t in fig.axes[-1].texts]
    assert "1e-6 m" in names and "1e-9 m" in names
    fig.canvas.draw()
    box = legend.get_window_extent()
    assert not any(_overlaps(box, ax.get_window_extent()) for ax in fig.axes)


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
        outcome, error, wall = fig.axes[:3]  # the colour bars come after the maps
        missing = np.zeros((len(grid.axis("zeta")), len(grid.axis("k"))), bool)
        for row in rows.itertuples():
            missing[grid.axis("zeta").index(row.zeta), grid.axis("k").index(row.k)] = row.status != "finished"
        for ax in (error, wall):
            assert np.array_equal(np.isnan(ax.get_images()[0].get_array().filled(np.nan)), missing)
            legend = ax.get_legend()
            if missing.any():
                assert legend.get_texts()[0].get_text().startswith("white: no data (the run timed out")
                assert legend.get_patches()[0].get_facecolor()[:3] == (1.0, 1.0, 1.0)
            else:
                assert legend is None
        assert outcome.get_legend() is None  # every cell was run
        for ax in (outcome, error, wall):
            assert all(label.get_fontsize() >= 10 for label in ax.get_xticklabels() + ax.get_yticklabels())
            assert [label.get_text() for label in ax.get_xticklabels()][:3] == ["1e2", "1e3", "1e4"]
        assert (solver != "cvode") == missing.any()  # the stored map: only the SciPy runs time out
