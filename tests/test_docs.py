"""The shipped code and the docs stand on their own: no reference to notes or threads a reader cannot see."""

import doctest
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# The public API: numpydoc docstrings (ruff checks them, pyproject.toml), and their examples run here.
PUBLIC_MODULES = ("bouncingball.physics", "bouncingball.limits", "bouncingball.solvers", "bouncingball.solvers.result",
                  "bouncingball.solvers.cvode", "bouncingball.solvers.exact", "bouncingball.accuracy",
                  "bouncingball.capped", "bouncingball.scenes", "bouncingball.testing", "bouncingball.result_files",
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
