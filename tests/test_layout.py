"""The layout holds: every module imports on its own (no import cycle), and the layers depend one way."""

import ast
import os
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import bouncingball

PACKAGE = Path(bouncingball.__file__).parent
MODULES = sorted(m.name for m in pkgutil.walk_packages([str(PACKAGE)], "bouncingball."))
# What each layer may import from this package: codes, rounding, oscillator <- equations <- contact_laws <- physics
# (the ground beside it) <- limits <- the phase machine <- its engines <- the solvers' front-ends <- the rest.
MODEL = {"bouncingball.codes", "bouncingball.rounding", "bouncingball.oscillator", "bouncingball.equations",
         "bouncingball.contact_laws", "bouncingball.physics", "bouncingball.ground"}
LOWER_LAYERS = {
    "bouncingball.codes": set(),
    "bouncingball.rounding": set(),
    "bouncingball.oscillator": set(),
    "bouncingball.equations": {"bouncingball.codes", "bouncingball.rounding", "bouncingball.oscillator"},
    "bouncingball.contact_laws": {"bouncingball.codes", "bouncingball.rounding", "bouncingball.oscillator",
                                  "bouncingball.equations", "bouncingball.contact_laws"},
    "bouncingball.physics": {"bouncingball.codes", "bouncingball.validation", "bouncingball.equations",
                             "bouncingball.contact_laws"},
    "bouncingball.ground": {"bouncingball.validation", "bouncingball.codes", "bouncingball.rounding",
                            "bouncingball.oscillator", "bouncingball.equations"},
    "bouncingball.limits": {*MODEL, "bouncingball.validation"},
    "bouncingball.solvers.phase_machine": {*MODEL, "bouncingball.validation", "bouncingball.solvers.phase_machine"},
    "bouncingball.solvers.engines": {*MODEL, "bouncingball.validation", "bouncingball.solvers.phase_machine",
                                     "bouncingball.solvers.engines"},
    # extras: the install hint of a missing extra's message (standard library only)
    "bouncingball.solvers": {*MODEL, "bouncingball.validation", "bouncingball.limits", "bouncingball.solvers",
                             "bouncingball.extras"},
}
SINGLE_FILE_LAYERS = ("bouncingball.codes", "bouncingball.rounding", "bouncingball.oscillator",
                      "bouncingball.equations", "bouncingball.physics", "bouncingball.limits", "bouncingball.ground")


# Each module is imported in a process of its own, forked from one that holds none of this package: only the libraries
# every module needs are imported before the fork, so that each import pays for ours alone (34 s as fresh interpreters).
IMPORT_ALONE = """
import atexit, importlib, os, sys
for library in ("numpy", "scipy", "sksundae.cvode"):
    importlib.import_module(library)
assert not [name for name in sys.modules if name.startswith("bouncingball")]
for name in sys.argv[1:]:
    sys.stdout.flush()
    child = os.fork()
    if child == 0:
        try:
            importlib.import_module(name)
        except BaseException as error:
            print(name, type(error).__name__, error, flush=True)
            os._exit(1)
        # The exit handlers run, as at an interpreter's exit (a crash there is seen); the rest of the interpreter's
        # teardown, 0.2 s a module with SciPy loaded, is skipped.
        atexit._run_exitfuncs()
        os._exit(0)
    if os.waitpid(child, 0)[1] != 0:
        print(name, "failed", flush=True)
"""


@pytest.mark.slow
def test_every_module_imports_alone():
    completed = subprocess.run([sys.executable, "-c", IMPORT_ALONE, *MODULES], capture_output=True, text=True,
                               timeout=600)
    assert len(MODULES) > 20 and completed.stdout == "" and completed.returncode == 0, (completed.stdout,
                                                                                       completed.stderr)


def test_a_module_that_cannot_be_imported_alone_or_crashes_at_exit_is_named(tmp_path):
    (tmp_path / "crashes_at_exit.py").write_text("import atexit, ctypes\natexit.register(ctypes.string_at, 0)\n")
    completed = subprocess.run([sys.executable, "-c", IMPORT_ALONE, "bouncingball.codes", "bouncingball.no_such",
                                "crashes_at_exit"], capture_output=True, text=True, timeout=600,
                               env={**os.environ, "PYTHONPATH": str(tmp_path)})
    assert completed.stdout.splitlines() == [
        "bouncingball.no_such ModuleNotFoundError No module named 'bouncingball.no_such'",
        "bouncingball.no_such failed", "crashes_at_exit failed"], completed.stdout + completed.stderr


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
    folder = PACKAGE.joinpath(*layer.split(".")[1:])
    files = [folder.with_suffix(".py")] if layer in SINGLE_FILE_LAYERS else sorted(folder.glob("*.py"))
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


def test_no_two_modules_share_a_name():
    """A module's name says which it is: no two files of the package (but __init__.py) share a name."""
    names = [path.stem for path in PACKAGE.rglob("*.py") if path.name != "__init__.py"]
    assert len(names) > 40 and sorted({name for name in names if names.count(name) > 1}) == []


def _import_graph() -> dict[str, set[str]]:
    """Each module of the package and the modules it imports, at its top or inside a function."""
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path

    def module_of(name: str) -> str:  # "package.module.attribute" -> the module
        while name not in modules and "." in name:
            name = name.rsplit(".", 1)[0]
        return name

    return {module: {module_of(name) for name in _imports_of(path, module)} - {module}
            for module, path in modules.items()}


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles of graph: its strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, circles = {}, {}, [], set(), []

    def visit(module):
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for other in graph.get(module, ()):
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in on_stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            component = []
            while not component or component[-1] != module:
                component.append(stack.pop())
                on_stack.discard(component[-1])
            if len(component) > 1:
                circles.append(sorted(component))

    for module in graph:
        if module not in index:
            visit(module)
    return circles


def test_no_import_circle_even_through_an_import_inside_a_function():
    graph = _import_graph()
    assert len(graph) > 40 and _circles(graph) == []
    assert _circles({**graph, "bouncingball.fmu.build3": {"bouncingball.fmu.build"}}) == [
        ["bouncingball.fmu.build", "bouncingball.fmu.build3"]]  # the check sees one
