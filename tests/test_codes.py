"""One encoding of modes and event kinds: the machine's ints, and the enums users see, built from them."""

import ast
from pathlib import Path

import bouncingball
from bouncingball import codes
from bouncingball.physics import Mode
from bouncingball.solvers.result import EVENT_KINDS, EventKind

SOURCE = Path(bouncingball.__file__).parent


def test_every_mode_has_one_code_and_one_name():
    assert [mode.value for mode in Mode] == [codes.FLIGHT, codes.CONTACT, codes.FREE] == [0, 1, 2]
    assert [mode.name.lower() for mode in Mode] == list(codes.MODE_NAMES)


def test_every_event_kind_has_one_code_and_one_name():
    kinds = [codes.IMPACT, codes.DEPARTURE, codes.RELEASE, codes.ENGAGE]
    assert sorted(kinds) == list(range(len(EventKind))) == list(range(len(codes.EVENT_KIND_NAMES)))
    for code in kinds:
        assert EVENT_KINDS[code] == codes.EVENT_KIND_NAMES[code]
    assert set(EVENT_KINDS) == set(EventKind)


def _assignments(path):
    for node in ast.parse(path.read_text(encoding="utf-8")).body:  # module level: Mode's and EventKind's members are
        if isinstance(node, ast.Assign):                               # the codes' named faces
            for target in node.targets:
                names = target.elts if isinstance(target, ast.Tuple) else [target]
                yield from (n.id for n in names if isinstance(n, ast.Name))


def test_the_codes_and_cvodes_flags_are_defined_once():
    wanted = {"FLIGHT", "CONTACT", "FREE", "IMPACT", "DEPARTURE", "RELEASE", "ENGAGE", "CV_ROOT_RETURN", "CV_SUCCESS",
              "CV_TSTOP_RETURN"}
    where = {}
    for path in SOURCE.rglob("*.py"):
        for name in _assignments(path):
            if name in wanted:
                where.setdefault(name, []).append(path.relative_to(SOURCE).as_posix())
    # result.py's IMPACT .. ENGAGE are EventKind's members by their public names (result.IMPACT is EventKind.IMPACT)
    for name in ("IMPACT", "DEPARTURE", "RELEASE", "ENGAGE"):
        where[name].remove("solvers/result.py")
    assert {name: places for name, places in where.items() if len(places) != 1} == {}
    assert set(where) == wanted


def test_no_mode_is_compared_with_a_bare_number():
    offenders = []
    for path in SOURCE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Compare) and isinstance(node.left, ast.Name) and "mode" in node.left.id.lower():
                if any(isinstance(c, ast.Constant) and isinstance(c.value, int | float) for c in node.comparators):
                    offenders.append(f"{path.name}:{node.lineno}")
    assert offenders == []
