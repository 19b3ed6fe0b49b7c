"""The shipped code and the docs stand on their own: no reference to notes or threads a reader cannot see."""

import ast
import doctest
import importlib
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.solvers.exact import ExactSolution
from fmu_helpers import FMU_PAGE, assert_fmu_page_quotes, page_figure
from oracle_counts import oracle_counts

ROOT = Path(__file__).resolve().parents[1]
# The public API: numpydoc docstrings (ruff checks them, pyproject.toml), and their examples run here.
PUBLIC_MODULES = ("bouncingball.physics", "bouncingball.limits", "bouncingball.solvers", "bouncingball.solvers.result",
                  "bouncingball.solvers.cvode", "bouncingball.solvers.exact", "bouncingball.accuracy",
                  "bouncingball.capped", "bouncingball.scenes", "bouncingball.check.judge",
                  "bouncingball.check.outcome", "bouncingball.check.result_files",
                  "bouncingball.check.printed_numbers", "bouncingball.check.input_files",
                  "bouncingball.sweep.run", "bouncingball.sweep.grid", "bouncingball.run_report",
                  "bouncingball.plotting")
PRIVATE = re.compile(r"NOTES\.md|\bthe issue\b|\bissue's\b", re.IGNORECASE)


def shipped_files() -> list[Path]:
    package = ROOT / "src" / "bouncingball"
    return [*package.rglob("*.py"), *package.rglob("*.c"), *package.rglob("*.toml"), ROOT / "README.md",
            *(ROOT / "docs").glob("*.md"), *(ROOT / "fmu").glob("*.md")]


def test_code_and_docs_cite_nothing_private():
    if not (ROOT / "pyproject.toml").is_file():
        pytest.skip("runs in a source checkout")
    files = shipped_files()
    assert len(files) > 20
    cited = [f"{path.relative_to(ROOT)}: {match.group(0)}" for path in files
             for match in PRIVATE.finditer(path.read_text(encoding="utf-8"))]
    assert cited == []


@pytest.mark.parametrize("module", PUBLIC_MODULES)
def test_public_examples_run(module):
    """The Examples sections of the public API's docstrings are true."""
    failed, attempted = doctest.testmod(importlib.import_module(module), optionflags=doctest.ELLIPSIS)
    assert failed == 0


def test_the_readme_quotes_the_engine_choice_constants():
    """The rule of engine "auto" as the code applies it (solvers/engine_selection.py), not as once typed."""
    from bouncingball.solvers import engine_selection as engines

    text = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    fresh = (engines.COMPILED_FIRST_USE - engines.SKSUNDAE_FIRST_USE) / engines.STEP_SAVING
    loaded = engines.COMPILED_FIRST_USE / engines.STEP_SAVING
    for quote in (f"costs about {engines.COMPILED_FIRST_USE:.2f} s in a fresh process",
                  f"scikit-sundae's import {engines.SKSUNDAE_FIRST_USE:.2f} s",
                  f"each CVODE step is {engines.STEP_SAVING * 1e6:g} us cheaper compiled",
                  f"fewer than about {round(fresh, -2):,.0f} steps",
                  f"({round(loaded, -3):,.0f} once scikit-sundae is loaded",
                  f"the estimate is {engines.STEPS_PER_PHASE} steps per flight or contact"):
        assert quote in text, quote


# The code that writes the generated pages: every figure in them is measured or formatted from a constant.
PAGE_WRITERS = ("bench/targets.py", "bench/pages.py", "bench/stability.py", "sweep/report.py", "fmu/documentation.py")
APPROXIMATE = re.compile(r"~\s*\d|\babout \d")
FIGURE_WITH_UNIT = re.compile(r"(?<![\w.{+-])\d+(\.\d+)?(e[-+]?\d+)? ?(us|ms|m|s|N/m|kg|m/s2|N s/m)\b")


def _page_text_literals(path: Path) -> list[tuple[int, str]]:
    """The string constants of a module (f-strings' literal parts too), its docstrings left out."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef)) and node.body
                  and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings]


@pytest.mark.parametrize("module", PAGE_WRITERS)
def test_generated_pages_type_nopage_figure(module):
    """No "~4 us", "about 4 evaluations" or "R = 0.06 m" typed into a page: measured, or formatted from the code."""
    path = ROOT / "src" / "bouncingball" / module
    typed = [(line, text) for line, text in _page_text_literals(path)
             if APPROXIMATE.search(text) or FIGURE_WITH_UNIT.search(text)]
    assert typed == []


# A passage that quotes a generated page: every number in it (code spans aside) is printed on that page.
QUOTED = re.compile(r"<!-- figures from (?P<page>\S+) -->(?P<text>.*?)<!-- end of figures -->", re.DOTALL)
NUMBER = re.compile(r"(?<![\w.-])\d+(?:,\d{3})*(?:\.\d+)?(?:e[-+]?\d+)?")


@pytest.mark.parametrize("document", ["README.md", "docs/fmu.md"])
def test_a_quoted_figure_is_the_generated_pages(document):
    """README's benchmark headlines and docs/fmu.md's costs are docs/benchmarks.md's numbers, as it prints them."""
    path = ROOT / document
    if not path.is_file():
        pytest.skip("runs in a source checkout")
    text = path.read_text(encoding="utf-8")
    passages = QUOTED.findall(text)
    assert passages and len(passages) == text.count("<!-- end of figures -->"), "a marker is malformed"
    for page, text in passages:
        generated = (ROOT / page).read_text(encoding="utf-8")
        figures = NUMBER.findall(re.sub(r"`[^`]*`", "", text))
        assert len(figures) >= 3  # a passage of figures, not a marker around prose
        missing = [figure for figure in figures
                   if not re.search(rf"(?<![\w.-]){re.escape(figure)}(?!\.?\d)", generated)]
        assert missing == [], f"{document} quotes figures {page} does not print: {missing}"


def _per_do_step_means() -> dict[tuple[str, str], str]:
    """docs/benchmarks.md's "Per doStep, call by call" table: (slave, state at every step) -> mean doStep [us]."""
    page = (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8")
    table = page.split("### Per doStep, call by call", 1)[1].split("\n\n")[2]
    rows = [[cell.strip() for cell in line.strip("|").split("|")] for line in table.splitlines()[2:]]
    return {(slave, state): mean for slave, state, mean, *_ in rows}


def test_the_fmu_pages_doStep_costs_are_the_benchmark_pages():
    """docs/fmu.md's costs per doStep, each the mean docs/benchmarks.md prints for that slave (not only somewhere)."""
    if not FMU_PAGE.is_file():
        pytest.skip("runs in a source checkout")
    means = _per_do_step_means()
    fmi2, fmi3 = means["FMU, default engine (auto)", "no"], means["FMI 3.0 FMU, default engine (auto)", "no"]
    empty2, empty3 = means["empty pythonfmu slave", "no"], means["empty pythonfmu3 slave", "no"]
    compiled, sksundae = means["FMU, engine compiled", "no"], means["FMU, engine sksundae", "no"]
    assert_fmu_page_quotes(
        f"| per doStep, 1 ms, FMPy call by call (the mean in docs/benchmarks.md, \"Per doStep, call by call\") | "
        f"{fmi2} us, against {empty2} us for an empty pythonfmu slave | {fmi3} us without early return, "
        f"{means['FMI 3.0 FMU, default engine (auto), early return', 'no']} us per communication step with it, "
        f"against {empty3} us for an empty pythonfmu3 slave |",
        f"a `doStep` costs a mean of {compiled} us with `compiled` against {sksundae} us with `sksundae` ({empty2} us "
        f"of it pythonfmu's floor; {means['FMU, engine compiled', 'yes']} against "
        f"{means['FMU, engine sksundae', 'yes']} us with `fmi2GetFMUstate` before every step)",
        f"a `doStep` takes a mean of {fmi2} us at the default engine ({sksundae} us with the scikit-sundae engine) "
        f"against {empty2} us for an empty pythonfmu slave")
    # "The FMI 3.0 doStep costs more than the FMI 2.0 one mostly by the empty slaves' difference"
    assert float(empty3) - float(empty2) > 0.5 * (float(fmi3) - float(fmi2)) > 0


def test_the_fmu_pages_build_figures_are_the_first_use_pages():
    """docs/fmu.md's build time and sizes, as docs/first_use.md (bench --first-use) measured them."""
    if not FMU_PAGE.is_file():
        pytest.skip("runs in a source checkout")
    measured = (ROOT / "docs" / "first_use.md").read_text(encoding="utf-8")
    found = re.search(r"`build-fmu` in that venv took (\d+) s, the FMU's compiled engine's compile included; the FMU "
                      r"is ([\d.]+) MB, its compiled engine ([\d.]+) MB \(([\d.]+) MB compressed\)", measured)
    assert found, measured
    seconds, size, cache, compressed = found.groups()
    assert_fmu_page_quotes(f"the build took {seconds} s and the FMU is {size} MB, its compiled engine {cache} MB "
                           f"({compressed} MB compressed)")


def test_the_readmes_first_use_figures_are_the_first_use_pages():
    """The README's first use from a wheel, as docs/first_use.md (bench --first-use) measured it."""
    page = ROOT / "docs" / "first_use.md"
    if not page.is_file():
        pytest.skip("runs in a source checkout")
    measured = page.read_text(encoding="utf-8")
    built = re.search(r"The wheel: built in (\d+) s", measured).group(1)
    rows = [row for row in measured.splitlines() if row.startswith(("| simulate", "| the FMU"))]
    simulate, fmu = (row.split(" | ")[2] for row in rows)  # each one's median over the processes
    readme = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    assert (f"the wheel built in {built} s, a whole process running the article with the compiled engine {simulate} s, "
            f"and the FMU that venv's `build-fmu` makes, run by FMPy's `simulate_fmu` over its first 1 s on a fresh "
            f"unzip, {fmu} s<!-- end of figures -->") in readme


def test_the_python_hosts_the_docs_name_are_those_tested():
    from bouncingball.fmu.host_check import TESTED_PYTHON_HOSTS

    for document in ("README.md", "docs/fmu.md"):
        text = (ROOT / document).read_text(encoding="utf-8")
        assert all(version in text for version in TESTED_PYTHON_HOSTS), document
    assert "Python of the version the FMU was built with, with numpy" not in (ROOT / "README.md").read_text()


# --- docs/fmu.md: the FMU's own figures, computed by the code that makes them -------------------------------
# The FMU's co-simulation is its slave's do_step (fmu/slave_base.py): documentation.py drives it in-process, as a
# master does, for the FMU's own page, and so do these tests. A master's integrator (model exchange) is computed again
# where its runs are (tests/test_fmu3.py, test_strict_masters.py, test_fmu_rigid.py, test_fmu_nopull.py); the masters
# that cannot be installed here (OMSimulator, fmusim) are described on the page, with no figure, said so there.
@dataclass
class _SlaveRun:
    t: np.ndarray  # the rows a master records: each communication point, and each early return's time
    max_error: float  # max |h - h_exact| over the rows
    impacts: int
    exact_impacts: int
    error_estimate: float
    early_returns: list[float]
    exact_event_times: list[float]
    h: np.ndarray


def _slave_run(step: float, tolerance: float | None = None, stop_at_event: bool = False, **start_values) -> _SlaveRun:
    """The article through the FMU's slave, one do_step per communication step (and one more per early return)."""
    from bouncingball.fmu.documentation import _Host
    from bouncingball.scenes import load_scene
    from bouncingball.solvers.result import output_grid

    scene = load_scene("article")
    slave = _Host(stop_at_event)
    for name, value in start_values.items():
        slave.setters[name](value)
    slave.setup_experiment(0.0, scene.t_end, tolerance)
    slave.exit_initialization_mode()
    rows, early_returns = [], []
    for target in output_grid(0.0, scene.t_end, step):
        while (now := slave._integrator.t) < target:
            assert slave.do_step(now, target - now), slave.errors()
            if slave._integrator.t < target:
                early_returns.append(slave._integrator.t)
            rows.append((slave._integrator.t, slave.getters["h"](), slave.getters["impacts"]()))
        if not rows or rows[-1][0] != target:
            rows.append((target, slave.getters["h"](), slave.getters["impacts"]()))
    assert slave.errors() == []
    t, h, impacts = (np.array(column) for column in zip(*rows, strict=True))
    ball = bb.Ball(**{name: value for name, value in start_values.items() if name in ("m", "k", "b", "R", "g")})
    exact = ExactSolution(ball, scene.h0, scene.v0, 0.0, scene.t_end)
    return _SlaveRun(t, float(np.max(np.abs(h - exact.state(t)[0]))), int(impacts[-1]),
                     sum(event.kind == "impact" for event in exact.events), slave.getters["error_estimate"](),
                     early_returns, [event.time for event in exact.events], h)


@pytest.mark.slow
def test_the_fmu_pages_accuracy_figures_are_the_slaves():
    """Each figure of the FMU's co-simulation that docs/fmu.md quotes, computed by the slave's do_step again."""
    at_10ms = _slave_run(0.01)
    told_1e_4, told_1e_13, told_1e_14 = (_slave_run(0.01, tolerance) for tolerance in (1e-4, 1e-13, 1e-14))
    as_rtol_1e_4, as_rtol_1e_3 = (_slave_run(0.01, rtol=rtol) for rtol in (1e-4, 1e-3))
    moon = _slave_run(0.01, g=1.62)
    early = _slave_run(0.01, stop_at_event=True)
    defaults = _slave_run(0.001)
    tight = [_slave_run(step, 1e-12, rtol=1e-11, atol=1e-14) for step in (0.001, 0.01)]
    assert told_1e_4.max_error == at_10ms.max_error  # a looser master tolerance leaves rtol as it was
    n = oracle_counts(bb.Ball()).impacts
    assert all(run.impacts == run.exact_impacts == n for run in (at_10ms, told_1e_13, told_1e_14, early, defaults))
    assert len(early.early_returns) == len(early.exact_event_times)
    event_time_error = max(abs(a - b) for a, b in zip(early.early_returns, early.exact_event_times, strict=True))
    ours, with_early_return = page_figure(at_10ms.max_error), page_figure(early.max_error)
    quotes = [
        # the master's tolerance
        f"a tolerance of 1e-4 used as rtol put the height {page_figure(as_rtol_1e_4.max_error)} m off the exact "
        f"solution, and 1e-3 put it {page_figure(as_rtol_1e_3.max_error)} m off with {as_rtol_1e_3.impacts} of "
        f"{as_rtol_1e_3.exact_impacts} impacts; kept at rtol 1e-12 both are {ours} m off with {n} impacts",
        f"A tighter one (1e-13: {page_figure(told_1e_13.max_error)} m)",
        # how far from the truth, at the defaults (1 ms)
        f"it ends at {page_figure(defaults.error_estimate)} m, against a true error of "
        f"{page_figure(defaults.max_error)} m",
        # the masters
        f"| nothing | {ours} m, {n}/{n}; with `relative_tolerance=1e-4`: the same",
        f"| nothing | {ours} m without and with early return, {n}/{n} ({len(early.early_returns)} early returns) |",
        f"{ours} m, {n}/{n} at 1e-4 (the looser tolerance logged with status warning); "
        f"{page_figure(told_1e_14.max_error)} m at 1e-14, which tightens rtol",
        f"every call OK; {ours} m without and with early return, {n}/{n} |",
        f"were {ours} m and {page_figure(moon.max_error)} m from the exact solution at every step, with {n} and "
        f"{moon.impacts} impacts, as exact",
        # the tests' tighter settings
        f"within {page_figure(tight[0].max_error)} m of the exact solution at every point at 1 ms and "
        f"{page_figure(tight[1].max_error)} m at 10 ms, with {n} of {n} impacts",
        # FMI 3.0
        f"over the 8 s, all {len(early.early_returns)} within {page_figure(event_time_error)} s",
        f"| {ours} m, {n}/{n} impacts | co-simulation {ours} m, {n}/{n} impacts, without or with early "
        f"return ({len(early.early_returns)} early returns, {len(at_10ms.t)} + {len(early.early_returns)} rows)",
        f"| this FMU, co-simulation (its own CVODE, events inside the step) | {ours} m | {n} | within "
        f"{page_figure(event_time_error)} s (early return) |",
        f"(PASS, {with_early_return} m at 10 ms)",
    ]
    assert with_early_return == ours  # the page gives one figure "without and with early return"
    assert len(early.t) == len(at_10ms.t) + len(early.early_returns)
    assert_fmu_page_quotes(*quotes)


def test_the_fmu_pages_answer_does_not_depend_on_the_communication_step():
    """docs/fmu.md: runs at 0.5 s, 0.1 s, 10 ms and 1 ms give bit-identical heights at their common times."""
    assert_fmu_page_quotes("runs at 0.5 s, 0.1 s, 10 ms and 1 ms give bit-identical heights at their common times")
    runs = [_slave_run(step) for step in (0.5, 0.1, 0.01, 0.001)]
    for run in runs[1:]:
        at_common = [int(np.argmin(np.abs(run.t - t))) for t in runs[0].t]
        assert np.allclose(run.t[at_common], runs[0].t, rtol=0.0, atol=1e-12)
        assert np.array_equal(run.h[at_common], runs[0].h)


def _without_wall_times(line: str) -> str:
    """A line `bouncingball validate` prints, its wall times (one machine's) as the page shows them: "..."."""
    line = re.sub(r" *\d+\.\d{4}(?=  )", lambda time: f"{'...':>{len(time.group(0))}}", line)
    return re.sub(r"\+ \d+\.\d+ s to load", "+ ... s to load", line)


@pytest.mark.slow
def test_the_validate_sample_on_the_fmu_page_is_what_validate_prints(validated_article, fmu):
    """docs/fmu.md's `bouncingball validate` sample, line for line: the run the FMU tests make (its accuracy
    judged there), the FMU's path and the wall times aside."""
    if not FMU_PAGE.is_file():
        pytest.skip("runs in a source checkout")
    sample = FMU_PAGE.read_text(encoding="utf-8").split("## Validate", 1)[1].split("```", 2)[1].strip("\n")
    printed = validated_article[0].replace(f"FMU {fmu},", "FMU dist/BouncingBall.fmu,", 1)
    assert sample.splitlines() == [_without_wall_times(line).rstrip() for line in printed.splitlines()]


def _range_of(variable) -> str | set[str]:
    """A variable's range as the page writes it: FMI's inclusive min of the smallest double is "> 0"."""
    from bouncingball.fmu.variables import FMU_CONTACT_LAWS, SMALLEST_POSITIVE
    from bouncingball.solvers.phase_machine.settings import ENGINES, METHODS

    if variable.name in ("method", "engine", "contact_law"):
        return set({"method": METHODS, "engine": ENGINES, "contact_law": FMU_CONTACT_LAWS}[variable.name])
    if variable.max is not None:
        return f"[{variable.min:g}, {variable.max:g}]"
    if variable.min is None:
        return ""
    return "> 0" if variable.min == SMALLEST_POSITIVE else f">= {variable.min:g}"


def test_the_fmu_pages_variable_table_is_the_fmus():
    """docs/fmu.md's Variables table: each variable of variables.VARIABLES, in order, with its causality, type, unit,
    the slave's start value and the range the model description declares."""
    from bouncingball.fmu.documentation import _Host
    from bouncingball.fmu.variables import VARIABLES

    section = FMU_PAGE.read_text(encoding="utf-8").split("## Variables", 1)[1].split("\n\n", 2)[1]
    rows = [[cell.strip() for cell in re.split(r"(?<!\\)\|", line.strip()[1:-1])] for line in section.splitlines()[2:]]
    slave = _Host(stop_at_event=False)
    assert [row[0] for row in rows] == [f"`{variable.name}`" for variable in VARIABLES]
    for (name, causality, unit, start, value_range, _), variable in zip(rows, VARIABLES, strict=True):
        kind = "" if variable.type == "Real" else f", {variable.type}"
        initial = " (initial exact)" if variable.initial == "exact" else ""
        discrete = " (discrete)" if variable.causality == "output" and variable.variability == "discrete" \
            and variable.type == "Real" else ""
        assert causality == f"{variable.causality}{initial}{discrete}{kind}", name
        assert unit == variable.unit, name
        if variable.causality != "output" or variable.initial == "exact":
            value = slave.getters[variable.name]()
            assert (start == value) if isinstance(value, str) else (float(start) == value), name
        else:
            assert start == "", name
        expected = _range_of(variable)
        assert (set(value_range.split(", ")) if isinstance(expected, set) else value_range) == expected, name


def test_the_fmu_pages_constants_are_the_codes():
    """The DefaultExperiment, FMI's smallest min, the state's format, the check's tolerance, the nominals and the
    weightless scene's impact, as the code and its scenes have them."""
    from bouncingball.check.judge import DEFAULT_TOLERANCE
    from bouncingball.equations import load_value
    from bouncingball.fmu.model_exchange import phase_nominals
    from bouncingball.fmu.saved_state import STATE_FORMAT
    from bouncingball.fmu.variables import SMALLEST_POSITIVE
    from bouncingball.physics import Mode
    from bouncingball.scenes import load_scene
    from bouncingball.solvers.phase_machine.phases import phase_scales
    from bouncingball.solvers.phase_machine.settings import CvodeSettings

    article, rtol, weightless = load_scene("article"), CvodeSettings().rtol, load_scene("zero-gravity")
    ball = article.ball
    load = load_value(0.0, ball.m, ball.g)
    flight = phase_scales(ball.parameters, Mode.FLIGHT, article.h0 - ball.R, article.v0, load)
    contact = phase_scales(ball.parameters, Mode.CONTACT, 0.0, -flight[1], load)
    flight_nominals = phase_nominals(ball, article.h0, article.v0, Mode.FLIGHT, 0.0)
    contact_nominals = phase_nominals(ball, ball.R, -flight[1], Mode.CONTACT, 0.0)
    assert_fmu_page_quotes(f'so "> 0" is written `min="{SMALLEST_POSITIVE!r}"`',
                           f"The DefaultExperiment is the article scene: 0 to {article.t_end:g} s, step "
                           f"{article.output_interval * 1e3:g} ms, tolerance {rtol:g} (the default `rtol`)",
                           f'one byte (the state machine\'s state) and JSON (`"format": "{STATE_FORMAT}"`)',
                           f"more than the default tolerance of {page_figure(DEFAULT_TOLERANCE, 1)} m",
                           f"(from {article.h0:g} m: {flight[0]:.3g} m and {flight[1]:.3g} m/s, so nominals of "
                           f"{flight_nominals[0]:g} m and {flight_nominals[1]:g} m/s)",
                           f"(the first contact: {page_figure(contact[0])} m and {contact[1]:.2g} m/s, so "
                           f"{page_figure(contact_nominals[0])} m and {contact_nominals[1]:g} m/s)",
                           # weightless, the ball falls at its start speed: a communication point of the 1 ms grid
                           f"(zero-gravity: at {(weightless.h0 - weightless.ball.R) / -weightless.v0:g} s)")
