"""The rules of engines/jit.py's docstring, checked on the syntax trees of the functions compiled_together is given.

The functions are those compiled.py passed (the keys of compiled._compiled), not a list kept here, and
the names each one reads are resolved in the globals numba compiles it with (its compiled copy's), so
that what the checks see is what compiled_together re-bound.
"""

import ast
import builtins
import importlib.util
import inspect
import math
import textwrap
from pathlib import Path
from types import FunctionType, ModuleType

import numpy as np
import pytest

compiled = pytest.importorskip("bouncingball.solvers.engines.compiled",
                               reason="the compiled engine needs numba ([fast])")
from numba.core.dispatcher import Dispatcher  # noqa: E402  (numba is there once compiled imports)

from bouncingball.contact_laws import BallParameters  # noqa: E402
from bouncingball.solvers.engines import jit  # noqa: E402
from bouncingball.solvers.phase_machine import layout  # noqa: E402

GIVEN = tuple(compiled._compiled)  # every plain function compiled.py gave compiled_together
COPY_OF = {id(copy): plain for plain, copy in compiled._compiled.items()}
COMPILED_MODULES = {function.__module__ for function in GIVEN}
ALLOWED_MODULES = (math, np)
# The builtins numba compiles (numba's "Supported Python features", built-in functions), as far as this code needs.
NUMBA_BUILTINS = {"abs", "bool", "divmod", "enumerate", "float", "int", "isinstance", "len", "max", "min", "pow",
                  "range", "round", "tuple", "zip",
                  "RuntimeError"}  # raised with a constant message (numba compiles raise, not an f-string)
ARRAY_ATTRIBUTES = {"shape", "size", "ndim", "dtype", "ctypes", "T", "copy", "fill", "sum"}
PARAMETER_FIELDS = set(BallParameters._fields)  # the ball's parameters travel as a namedtuple, read by name
STATE_FIELDS = set(layout.NAMES)  # the machine's state: a record (interpreted: a dataclass), read by name
# Nodes numba cannot compile (rule 4).
REFUSED_NODES = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef, ast.Try, ast.With, ast.Yield,
                 ast.YieldFrom, ast.Global, ast.Nonlocal, ast.JoinedStr)


def syntax_tree(function) -> ast.FunctionDef:
    return ast.parse(textwrap.dedent(inspect.getsource(function))).body[0]


def where(function, node) -> str:
    return f"{function.__module__}.{function.__name__}, line {function.__code__.co_firstlineno + node.lineno - 1}"


def global_reads(function, tree):
    """(node, name) for each name the function reads that is not its own local."""
    local = set(function.__code__.co_varnames) | set(function.__code__.co_cellvars)
    return [(node, node.id) for node in ast.walk(tree)
            if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load) and node.id not in local]


def module_attribute_calls(function, compiled_modules=COMPILED_MODULES) -> list[str]:
    """Rule 1: `module.function` where module is a compiled module (compiled_together does not re-bind it)."""
    tree = syntax_tree(function)
    found = []
    for node, name in global_reads(function, tree):
        module = function.__globals__.get(name)
        if isinstance(module, ModuleType) and module.__name__ in compiled_modules:
            for parent in ast.walk(tree):
                if isinstance(parent, ast.Attribute) and parent.value is node \
                        and callable(getattr(module, parent.attr, None)):
                    found.append(f"{where(function, parent)}: {ast.unparse(parent)} (import it: "
                                 f"from {module.__name__} import {parent.attr}, and call it by its name)")
    return found


def reached(entries) -> dict:
    """{plain function: its compiled copy} for every given function the entry points reach by the names they read."""
    seen, todo = {}, list(entries)
    while todo:
        function = todo.pop()
        if function in seen:
            continue
        copy = compiled._compiled[function]
        seen[function] = copy
        namespace = copy.py_func.__globals__
        todo += [COPY_OF[id(namespace[name])] for _, name in global_reads(function, syntax_tree(function))
                 if id(namespace.get(name)) in COPY_OF]
    return seen


def entry_points() -> list:
    """The given functions whose compiled copies compiled.py keeps (run_phases, fill_grid, the callbacks' ...)."""
    return [COPY_OF[id(value)] for value in vars(compiled).values() if id(value) in COPY_OF]


def _is_number_constant(value) -> bool:
    if isinstance(value, tuple):
        return all(_is_number_constant(item) for item in value)
    return type(value) in (int, float, bool)


def compiled_rule_violations(function, namespace) -> list[str]:
    """Rules 2 to 4 for a function numba compiles, its names resolved in namespace (its compiled copy's globals)."""
    tree = syntax_tree(function)
    found = []
    arguments = tree.args
    if arguments.kwonlyargs or arguments.vararg or arguments.kwarg:
        found.append(f"{where(function, tree)}: keyword-only or variadic parameters")
    found += [f"{where(function, node)}: {type(node).__name__} (numba cannot compile it)"
              for node in ast.walk(tree) if node is not tree and isinstance(node, REFUSED_NODES)]
    for node, name in global_reads(function, tree):
        if name not in namespace:
            if name not in NUMBA_BUILTINS or not hasattr(builtins, name):
                found.append(f"{where(function, node)}: builtin {name} (not one numba compiles)")
            continue
        value = namespace[name]
        if not (isinstance(value, Dispatcher) or _is_number_constant(value) or value in ALLOWED_MODULES
                or any(value is module for module in ALLOWED_MODULES) or value is BallParameters):
            kind = ("a plain function compiled_together was not given" if isinstance(value, FunctionType)
                    else "a module other than math and numpy" if isinstance(value, ModuleType)
                    else f"a {type(value).__name__}")
            found.append(f"{where(function, node)}: reads {name}, {kind}")
    local = set(function.__code__.co_varnames)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in local:
            if (node.attr in PARAMETER_FIELDS and node.value.id == "parameters"
                    or node.attr in STATE_FIELDS and node.value.id == "state"):
                continue
            if node.attr not in ARRAY_ATTRIBUTES and not all(hasattr(module, node.attr) for module in ALLOWED_MODULES):
                found.append(f"{where(function, node)}: {ast.unparse(node)}, an object's attribute (arguments are "
                             "floats, ints, tuples, arrays, the ball's parameters, the machine's state, or math / "
                             "numpy as xp)")
    return found


def test_the_rules_are_checked_on_what_compiled_py_gives():
    """The functions come from compiled.py as it is: the machine and the callbacks' functions among them."""
    from bouncingball.solvers.phase_machine import dense_output, drivers, phases

    assert {drivers.run_phases, dense_output.fill_grid, phases.scaled_rates} <= set(entry_points())
    assert len(reached(entry_points())) > 20


def test_no_compiled_function_is_called_through_its_module():
    """Rule 1, on every function compiled_together is given (reached by the entry points or not yet)."""
    found = [violation for function in GIVEN for violation in module_attribute_calls(function)]
    assert found == []


@pytest.mark.parametrize("function", sorted(reached(entry_points()), key=lambda f: (f.__module__, f.__name__)),
                         ids=lambda f: f"{f.__module__.rsplit('.', 1)[-1]}.{f.__name__}")
def test_each_function_numba_compiles_follows_the_rules(function):
    """Rules 2 to 4 on each function the entry points reach, as numba sees it (its copy's re-bound globals)."""
    assert compiled_rule_violations(function, compiled._compiled[function].py_func.__globals__) == []


def _digest_modules() -> list[str]:
    """The modules whose sources jit.engine_sources gives cache_allowed (compiled.py's call), by their names."""
    package = Path(compiled.__file__).parents[2]
    return [".".join((package.name, *Path(file).relative_to(package).with_suffix("").parts)).removesuffix(".__init__")
            for file in jit.engine_sources()]


def _origin_of(module_name: str, name: str) -> str:
    """The module a module-level name of module_name comes from: its `from X import name`, or itself."""
    module = importlib.import_module(module_name)
    for node in ast.parse(Path(module.__file__).read_text(encoding="utf-8")).body:
        if isinstance(node, ast.ImportFrom) and any((alias.asname or alias.name) == name for alias in node.names):
            return importlib.util.resolve_name("." * node.level + (node.module or ""), module.__package__)
    return module_name


def test_every_source_the_compiled_code_reads_is_in_the_cache_digest():
    """Rule 5: the module of each compiled function and of each constant it reads is in cache_allowed's digest."""
    digest = set(_digest_modules())
    sources = {}
    for function, copy in reached(entry_points()).items():
        sources.setdefault(function.__module__, where(function, syntax_tree(function)))
        for node, name in global_reads(function, syntax_tree(function)):
            if _is_number_constant(copy.py_func.__globals__.get(name)):
                sources.setdefault(_origin_of(function.__module__, name), f"{where(function, node)}: {name}")
    assert {module: reader for module, reader in sources.items() if module not in digest} == {}


# --- the checks themselves find a violation ---------------------------------------------------------
def test_the_checks_find_a_call_through_a_module_and_an_object_read():
    """A function as an engineer might write it: each check names its line."""
    from bouncingball import equations, physics
    from bouncingball.solvers.phase_machine import phases

    namespace = {"equations": equations, "Ball": physics.Ball, "math": math, "LIMIT": 2.0}
    source = textwrap.dedent('''
        def flow(x, v, tau, ball, *rest):
            if ball.m > LIMIT:
                return equations.gap_flow_value(0, x, v, tau, 9.81, 1.0, 1e4, 10.0)
            return Ball(), math.sqrt(x), f"{x}"
    ''')
    function = _function_from(source, namespace)
    assert module_attribute_calls(function, {"bouncingball.equations"}) == [
        "bouncingball.solvers.phase_machine.phases.flow, line 4: equations.gap_flow_value (import it: from "
        "bouncingball.equations "
        "import gap_flow_value, and call it by its name)"]
    violations = "\n".join(compiled_rule_violations(function, namespace))
    for expected in ("line 2: keyword-only or variadic", "line 5: JoinedStr", "line 5: reads Ball, a type",
                     "line 4: reads equations, a module other than math", "line 3: ball.m, an object's attribute"):
        assert expected in violations
    assert "reads LIMIT" not in violations and "reads math" not in violations
    assert len(violations.splitlines()) == 5
    assert phases.__name__ in COMPILED_MODULES


def test_the_state_is_read_by_its_fields_names_alone():
    """Rule 3 lets the machine read its state's fields (layout.NAMES), nothing else of it: a misspelt one is found."""
    source = textwrap.dedent('''
        def flow(state, parameters):
            state.rs_t = state.t + parameters.m
            return state.rs_tt
    ''')
    violations = compiled_rule_violations(_function_from(source, {}), {})
    assert violations == ["bouncingball.solvers.phase_machine.phases.flow, line 4: state.rs_tt, an object's attribute "
                          "(arguments are floats, ints, tuples, arrays, the ball's parameters, the machine's state, "
                          "or math / numpy as xp)"]


def _function_from(source: str, namespace: dict):
    """A function defined from source in namespace, its source findable by inspect, as if in phases.py."""
    import linecache

    filename = "<jit-rules-example>"
    linecache.cache[filename] = (len(source), None, source.splitlines(True), filename)
    exec(compile(source, filename, "exec"), namespace)  # noqa: S102
    function = namespace["flow"]
    function.__module__ = "bouncingball.solvers.phase_machine.phases"
    return function
