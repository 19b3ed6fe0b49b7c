"""The layout holds: every module imports on its own (no import cycle), and the layers depend one way."""

import ast
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import bouncingball

PACKAGE = Path(bouncingball.__file__).parent
MODULES = sorted(m.name for m in pkgutil.walk_packages([str(PACKAGE)], "bouncingball."))
# What each layer may import from this package: codes, rounding, oscillator <- equations <- contact_laws <- physics
# <- limits <- solvers <- the rest.
MODEL = {"bouncingball.codes", "bouncingball.rounding", "bouncingball.oscillator", "bouncingball.equations",
         "bouncingball.contact_laws", "bouncingball.physics"}
LOWER_LAYERS = {
    "bouncingball.codes": set(),
    "bouncingball.rounding": set(),
    "bouncingball.oscillator": set(),
    "bouncingball.equations": {"bouncingball.codes", "bouncingball.rounding", "bouncingball.oscillator"},
    "bouncingball.contact_laws": {"bouncingball.codes", "bouncingball.rounding", "bouncingball.oscillator",
                                  "bouncingball.equations", "bouncingball.contact_laws"},
    "bouncingball.physics": {"bouncingball.codes", "bouncingball.validation", "bouncingball.equations",
                             "bouncingball.contact_laws"},
    "bouncingball.limits": {*MODEL, "bouncingball.validation"},
    # extras: the install hint of a missing extra's message (standard library only)
    "bouncingball.solvers": {*MODEL, "bouncingball.validation", "bouncingball.limits", "bouncingball.solvers",
                             "bouncingball.extras"},
}
SINGLE_FILE_LAYERS = ("bouncingball.codes", "bouncingball.rounding", "bouncingball.oscillator",
                      "bouncingball.equations", "bouncingball.physics", "bouncingball.limits")


@pytest.mark.slow
def test_every_module_imports_alone():
    script = ("import importlib, subprocess, sys\n"
              f"for name in {MODULES!r}:\n"
              "    code = f'import {name}'\n"
              "    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)\n"
              "    if done.returncode:\n"
              "        print(name, done.stderr.strip().splitlines()[-1])\n")
    completed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert len(MODULES) > 20 and completed.stdout == "" and completed.returncode == 0, completed.stdout


def _imports_of(path: Path, module: str) -> set[str]:
    """The bouncingball modules a source file imports, relative imports resolved."""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            if node.module:
                found.add(".".join([*base, node.module]))
            else:  # from . import x: the module x of that package
                found.update(".".join([*base, alias.name]) for alias in node.names)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {name for name in found if name.startswith("bouncingball")}


@pytest.mark.parametrize("layer", sorted(LOWER_LAYERS))
def test_lower_layers_import_nothing_above_them(layer):
    allowed = LOWER_LAYERS[layer]
    stem = layer.split(".")[-1]
    files = [PACKAGE / f"{stem}.py"] if layer in SINGLE_FILE_LAYERS else sorted((PACKAGE / stem).glob("*.py"))
    for path in files:
        module = layer if path.stem in (stem, "__init__") else f"{layer}.{path.stem}"
        for imported in _imports_of(path, module):
            assert any(imported == a or imported.startswith(a + ".") for a in allowed), (path.name, imported)


def test_layer_check_sees_a_violation(tmp_path):
    """The import scan resolves relative imports: a solver importing the CLI would be caught."""
    source = tmp_path / "cvode.py"
    source.write_text("from ..cli import main\nfrom .result import Event\nfrom .. import scenes\nimport numpy\n")
    assert _imports_of(source, "bouncingball.solvers.cvode") == {"bouncingball.cli", "bouncingball.solvers.result",
                                                                 "bouncingball.scenes"}


MAX_MODULE_LINES, MAX_CLASS_LINES = 400, 250  # what a maintainer reads in one pass


def test_no_module_or_class_is_too_long_to_read_in_one_pass():
    sources = sorted(PACKAGE.rglob("*.py"))
    long_modules = {str(path.relative_to(PACKAGE)): n for path in sources
                    if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES}
    long_classes = {f"{path.relative_to(PACKAGE)}:{node.name}": node.end_lineno - node.lineno + 1 for path in sources
                    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
                    if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > MAX_CLASS_LINES}
    assert len(sources) > 40 and long_modules == {} and long_classes == {}
