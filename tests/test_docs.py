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
