"""The shipped code and the docs stand on their own: no reference to notes or threads a reader cannot see."""

import ast
import doctest
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# The public API: numpydoc docstrings (ruff checks them, pyproject.toml), and their examples run here.
PUBLIC_MODULES = ("bouncingball.physics", "bouncingball.limits", "bouncingball.solvers", "bouncingball.solvers.result",
                  "bouncingball.solvers.cvode", "bouncingball.solvers.exact", "bouncingball.accuracy",
                  "bouncingball.capped", "bouncingball.scenes", "bouncingball.testing", "bouncingball.check_outcome",
                  "bouncingball.result_files", "bouncingball.printed_numbers", "bouncingball.input_files",
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
    """The rule of engine "auto" as the code applies it (solvers/engines.py), not as once typed."""
    from bouncingball.solvers import engines

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
def test_generated_pages_type_no_figure(module):
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
        assert len(figures) > 5
        missing = [figure for figure in figures
                   if not re.search(rf"(?<![\w.-]){re.escape(figure)}(?!\.?\d)", generated)]
        assert missing == [], f"{document} quotes figures {page} does not print: {missing}"


def test_the_python_hosts_the_docs_name_are_those_tested():
    from bouncingball.fmu.host_check import TESTED_PYTHON_HOSTS

    for document in ("README.md", "docs/fmu.md"):
        text = (ROOT / document).read_text(encoding="utf-8")
        assert all(version in text for version in TESTED_PYTHON_HOSTS), document
    assert "Python of the version the FMU was built with, with numpy" not in (ROOT / "README.md").read_text()
