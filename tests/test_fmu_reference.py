"""What the FMU carries besides itself: documentation/index.html, and the reference result beside it."""

from __future__ import annotations

import base64
import csv
import html
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest

from bouncingball.cli import main
from bouncingball.fmu.build import reference_path
from bouncingball.fmu.variables import SOLUTION_OUTPUTS, VARIABLES
from bouncingball.physics import Ball
from bouncingball.solvers.exact import ExactSolution
from bouncingball.solvers.result import IMPACT
from fmu_helpers import exact_at
from oracle_counts import oracle_counts

pytest.importorskip("pythonfmu", reason="the FMU tests need the [fmu] extra")


def _page(fmu) -> str:
    with zipfile.ZipFile(fmu) as archive:
        return archive.read("documentation/index.html").decode("utf-8")


def _declared(fmu) -> dict[str, dict]:
    """Each variable's type, start, min and max as the FMU's modelDescription.xml declares them (FMI 2.0 or 3.0)."""
    with zipfile.ZipFile(fmu) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    declared = {}
    for variable in root.find("ModelVariables"):
        typed = next(iter(variable)) if variable.tag == "ScalarVariable" else variable
        start = typed.get("start", "")
        if typed.find("Start") is not None:
            start = typed.find("Start").get("value")
        declared[variable.get("name")] = {"type": typed.tag, "start": start, "min": typed.get("min"),
                                          "max": typed.get("max"), "unit": typed.get("unit", "")}
    return declared


def _variable_rows(page: str) -> dict[str, list[str]]:
    table = page[page.index("<h2>Variables</h2>"):]
    table = table[:table.index("</table>")]
    rows = {}
    for row in re.findall(r"<tr>(<td>.*?)</tr>", table, flags=re.DOTALL):
        cells = [html.unescape(cell) for cell in re.findall(r"<td>(.*?)</td>", row, flags=re.DOTALL)]
        rows[cells[0]] = cells
    return rows


def _range_of(declared: dict) -> str:
    """The range as a reader writes it, from the model description's min and max."""
    low, high = declared["min"], declared["max"]
    parts = []
    if low is not None:
        parts.append("> 0" if float(low) == 5e-324 else f">= {_shortest(low)}")
    if high is not None:
        parts.append(f"<= {_shortest(high)}")
    return ", ".join(parts)


def _shortest(text: str) -> str:
    """A bound as a reader reads it back to the same double: repr's digits, no trailing ".0" (1000000, 1e-15)."""
    shortest = repr(float(text))
    return shortest[:-2] if shortest.endswith(".0") else shortest


@pytest.mark.parametrize("version", [2, 3])
def test_the_fmu_documentation_has_every_variable_as_the_model_description_declares_it(version, fmu, fmu3):
    from bouncingball.fmu.variables import FMI3_VARIABLES

    path = fmu if version == 2 else fmu3
    rows, declared = _variable_rows(_page(path)), _declared(path)
    variables = VARIABLES if version == 2 else VARIABLES + FMI3_VARIABLES
    assert set(rows) == {variable.name for variable in variables} == set(declared)
    for variable in variables:
        name, causality, variability, kind, unit, start, allowed, description = rows[variable.name]
        xml = declared[variable.name]
        assert (causality, variability, description) == (variable.causality, variable.variability,
                                                         variable.description)
        assert (kind, unit, start, allowed) == (xml["type"], xml["unit"], xml["start"], _range_of(xml)), name
    assert rows["m"][4:7] == ["kg", "1", "> 0"] and rows["rtol"][6] == ">= 1e-15, <= 1"


@pytest.mark.parametrize("version", [2, 3])
def test_the_fmu_documentation_is_for_a_masters_user_not_the_python_api(version, fmu, fmu3):
    page = _page(fmu if version == 2 else fmu3)
    api = f"fmi{version}"
    for python_only in ("ValueError", "&gt;&gt;&gt;", ">>>", "Raises", "<h3>Parameters", "----", "Arrays allowed",
                        "doctest", "float</span>"):
        assert python_only not in page, python_only
    for text in ("h' = v, v' = -g + F_ext/m", "m v' = -b v + k (R - h) - m g + F_ext", "impact", "departure",
                 f"{api}DoStep", f"{api}Error", "numpy and scikit-sundae", "numba",
                 "bouncingball check", "BouncingBall_ref.csv"):
        assert html.escape(text, quote=False) in page, text
    # The refusal quoted is the one the FMU logs, naming the value (tests/test_fmu.py checks the FMU logs it).
    assert "<pre>m = -1.0 kg is not allowed: it must be finite and &gt; 0</pre>" in page
    assert not re.search(r"\d\.\d{12,}", page)  # every value in its shortest form (no 9.999999999999999e-13)
    assert "(0.059019 m with" in page  # R - m g / k = 0.06 - 9.81 / 1e4, not 0.059018999999999995


def test_the_fmu_documentation_quotes_the_error_the_fmu_measures_against_the_exact_solution(fmu):
    """The page's accuracy is the FMU's own: FMPy runs the default experiment, and its error is the page's."""
    fmpy = pytest.importorskip("fmpy")
    page = _page(fmu)
    quoted = re.search(r"max \|h - h_exact\|</td><td>(\S+) m \(at t = (\S+) s\)", page)
    impacts = re.search(r"(\d+) counted, (\d+) in the exact solution", page)
    assert quoted and impacts, page[page.index("<h2>Accuracy</h2>"):][:1500]
    # the default experiment, recorded at every communication point (FMPy alone caps it at 1000 points)
    result = fmpy.simulate_fmu(str(fmu), output_interval=1e-3, output=["h", "impacts"])
    t, h = result["time"], result["h"]
    assert len(t) == 8001 and t[-1] == 8.0
    h_exact, _, exact_impacts = exact_at(t)
    error = np.abs(h - h_exact)
    assert 0 < error.max() < 1e-9  # a real, small error: the default rtol is 1e-12
    assert float(quoted[1]) == pytest.approx(error.max(), rel=5e-3)  # printed to 3 digits
    assert float(quoted[2]) == pytest.approx(t[np.argmax(error)], abs=1e-9)
    truth = oracle_counts(Ball()).impacts
    assert (int(impacts[1]), int(impacts[2])) == (result["impacts"][-1], exact_impacts[-1]) == (truth, truth)


def test_the_fmu_documentation_shows_the_default_run_as_a_png(fmu):
    pytest.importorskip("matplotlib")
    page = _page(fmu)
    image = re.search(r'<img alt="[^"]+" src="data:image/png;base64,([^"]+)">', page)
    assert image and base64.b64decode(image[1]).startswith(b"\x89PNG\r\n\x1a\n")
    assert "No plot" not in page


@pytest.mark.slow  # a build of its own (the numba cache compiled again), in a subprocess
def test_build_fmu_without_matplotlib_writes_the_page_without_a_plot(tmp_path):
    """build-fmu must not need matplotlib: without it, no plot and a sentence that says why."""
    path = tmp_path / "BouncingBall.fmu"
    script = ("import sys; sys.modules['matplotlib'] = None\n"
              "from bouncingball.cli import main\n"
              f"code = main(['build-fmu', '-o', {str(path)!r}])\n"
              "assert 'matplotlib' not in sys.modules or sys.modules['matplotlib'] is None\n"
              "sys.exit(code)\n")
    completed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=False)
    assert completed.returncode == 0, completed.stderr
    page = _page(path)
    assert "<img" not in page and "No plot: matplotlib was not installed where this FMU was built." in page
    assert "max |h - h_exact|" in page and "<h2>Variables</h2>" in page


def test_fmpy_info_still_reads_the_fmu(fmu):
    fmpy = pytest.importorskip("fmpy")
    assert fmpy.read_model_description(str(fmu)).modelName == "BouncingBall"


def test_the_reference_result_is_the_exact_solution_of_the_default_experiment(fmu):
    path = reference_path(fmu)
    assert path == fmu.with_name("BouncingBall_ref.csv")
    with path.open(newline="") as file:
        rows = list(csv.reader(file))
    # the solution's outputs; not error_estimate, the run's own diagnosis
    assert rows[0] == ["time", *SOLUTION_OUTPUTS] == ["time", "h", "v", "a", "contact", "contact_force", "impacts"]
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
    assert data[-1, 6] == oracle_counts(ball).impacts


def test_the_reference_result_passes_bouncingball_check(fmu, capsys):
    assert main(["check", str(reference_path(fmu))]) == 0
    out = capsys.readouterr().out
    assert "points compared    8001" in out and "max |h - h_exact|  0.000e+00 m" in out


def test_the_fmi3_fmu_documentation_has_its_own_calls_and_interfaces(fmu3):
    """The FMI 3.0 page: fmi3 calls, not fmi2 ones; early return, event mode and model exchange's event indicator."""
    page = _page(fmu3)
    variables = page[page.index("<h2>Variables</h2>"):]
    prose = page.replace(variables[:variables.index("</table>")], "")  # the shared table says what is FMI 2.0's
    assert "fmi2" not in prose
    for text in ("fmi3DoStep", "early return", "earlyReturn = true", "eventHandlingNeeded", "event mode",
                 "Model exchange", "event indicator <code>gap</code>", "fmi3UpdateDiscreteStates",
                 "fmi3DoStep calls with early return at each event"):
        assert text in prose, text
