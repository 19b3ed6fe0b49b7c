"""What the FMU carries besides itself: documentation/index.html, and the reference result beside it."""

from __future__ import annotations

import csv
import html
import re
import zipfile

import numpy as np
import pytest

from bouncingball.cli import main
from bouncingball.fmu.build import reference_path
from bouncingball.fmu.variables import OUTPUTS, VARIABLES
from bouncingball.physics import Ball
from bouncingball.solvers.exact import ExactSolution
from bouncingball.solvers.result import IMPACT

pytest.importorskip("pythonfmu", reason="the FMU tests need the [fmu] extra")


def test_the_fmu_documentation_names_every_variable_with_its_unit(fmu):
    with zipfile.ZipFile(fmu) as archive:
        page = archive.read("documentation/index.html").decode("utf-8")
    table = page[page.index("<h2>Variables</h2>"):]
    for variable in VARIABLES:
        row = table[table.index(f"<tr><td>{variable.name}</td>"):]
        row = html.unescape(row[:row.index("</tr>")])
        assert f"<td>{variable.unit}</td>" in row and variable.description in row, row
    for text in ("h' = v, v' = -g + F_ext/m", "m v' = -b v + k (R - h) - m g + F_ext", "impact", "departure",
                 "numpy and scikit-sundae", "bouncingball check", "BouncingBall_ref.csv"):
        assert html.escape(text, quote=False) in page, text
    assert "<td>m</td><td>parameter</td><td>kg</td><td>1</td><td>&gt; 0</td>" in page


def test_the_fmu_documentation_is_rendered_from_the_docstrings_not_shown_raw(fmu):
    """docutils renders numpydoc's sections: no "Parameters ----------", no >>> outside a code block."""
    from bouncingball.solvers.cvode import DEFAULT_RTOL
    from bouncingball.validation import exact

    with zipfile.ZipFile(fmu) as archive:
        page = archive.read("documentation/index.html").decode("utf-8")
    assert "----" not in page and "<h3>Parameters</h3>" in page
    assert '<dt>m<span class="classifier">float</span></dt>' in page  # the parameter list, a definition list
    assert "&gt;&gt;&gt;" not in re.sub(r"<pre.*?</pre>", "", page, flags=re.DOTALL)  # examples only as code
    assert f"tolerance {exact(DEFAULT_RTOL)} (the default rtol)" in page and f"<td>{exact(DEFAULT_RTOL)}</td>" in page
    assert not re.search(r"\d\.\d{12,}", page)  # every value in its shortest form (no 9.999999999999999e-13)
    assert "(0.059019 m with the defaults)" in page  # R - m g / k = 0.06 - 9.81 / 1e4, not 0.059018999999999995


def test_fmpy_info_still_reads_the_fmu(fmu):
    fmpy = pytest.importorskip("fmpy")
    assert fmpy.read_model_description(str(fmu)).modelName == "BouncingBall"


def test_the_reference_result_is_the_exact_solution_of_the_default_experiment(fmu):
    path = reference_path(fmu)
    assert path == fmu.with_name("BouncingBall_ref.csv")
    with path.open(newline="") as file:
        rows = list(csv.reader(file))
    assert rows[0] == ["time", *OUTPUTS] == ["time", "h", "v", "a", "contact", "contact_force", "impacts"]
    data = np.array(rows[1:], dtype=float)
    t = data[:, 0]
    np.testing.assert_array_equal(t, np.arange(8001) * 1e-3)  # the default experiment: 0 to 8 s, every 1 ms
    ball = Ball()
    solution = ExactSolution(ball, 2.0, 0.0, 0.0, 8.0)
    h, v = solution.state(t)
    np.testing.assert_allclose(data[:, 1], h, rtol=0, atol=1e-15)
    np.testing.assert_allclose(data[:, 2], v, rtol=0, atol=1e-13)
    contact = h < ball.R  # away from the events themselves, contact means below R
    away = np.abs(h - ball.R) > 1e-9
    np.testing.assert_array_equal(data[away, 4], contact[away])
    force = np.where(data[:, 4] == 1, ball.k * (ball.R - h) - ball.b * v, 0.0)
    np.testing.assert_allclose(data[:, 5], force, rtol=0, atol=1e-9)
    np.testing.assert_allclose(data[:, 3], (force - ball.m * ball.g) / ball.m, rtol=0, atol=1e-9)
    impact_times = [event.time for event in solution.events if event.kind == IMPACT]
    np.testing.assert_array_equal(data[:, 6], np.searchsorted(impact_times, t, side="right"))
    assert data[-1, 6] == 21


def test_the_reference_result_passes_bouncingball_check(fmu, capsys):
    assert main(["check", str(reference_path(fmu))]) == 0
    out = capsys.readouterr().out
    assert "points compared    8001" in out and "max |h - h_exact|  0.000e+00 m" in out


def test_the_fmi3_fmu_documentation_has_its_start_values_and_its_own_calls(fmu3):
    """The FMI 3.0 page: start values read from <Float64 start=...> (FMI 3.0 has no ScalarVariable), the
    FMI 3.0 variables, and fmi3 calls, not fmi2 ones."""
    from bouncingball.fmu.variables import FMI3_VARIABLES

    with zipfile.ZipFile(fmu3) as archive:
        page = archive.read("documentation/index.html").decode("utf-8")
    assert "<td>m</td><td>parameter</td><td>kg</td><td>1</td><td>&gt; 0</td>" in page
    ball = Ball()
    assert f"<td>R</td><td>parameter</td><td>m</td><td>{ball.R!r}</td>" in page
    for variable in FMI3_VARIABLES:
        assert f"<tr><td>{html.escape(variable.name)}</td>" in page, variable.name
    variables = page[page.index("<h2>Variables</h2>"):]
    prose = page.replace(variables[:variables.index("</table>")], "")  # the shared table says what is FMI 2.0's
    assert "fmi3DoStep" in prose and "early return" in prose and "fmi2" not in prose
