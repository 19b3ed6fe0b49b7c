"""Install hints: every message's and document's `pip install` names an extra that exists, in a form that works here.

bouncingball is not on PyPI, so `pip install 'bouncingball[plot]'` fails from a checkout ("from versions:
none"); the hint is made from how it was installed (extras.install_command), and the documents give the
checkout's form.
"""

from __future__ import annotations

import ast
import json
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from bouncingball import extras

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT_EXTRAS = set(tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))["project"]["optional-dependencies"])
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "examples").rglob("*.py")),
             ROOT / "examples" / "fmpy_cli.sh"]


def test_every_extra_the_hints_name_is_in_pyproject():
    assert set(extras.EXTRAS) <= PYPROJECT_EXTRAS
    assert PYPROJECT_EXTRAS - set(extras.EXTRAS) == {"test", "lint"}  # the developers' own, in no message
    named = set()
    for path in sorted((ROOT / "src" / "bouncingball").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text("utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "install_command":
                # the CLI's is EXTRA_OF_MODULE's, checked below
                named.update(argument.value for argument in node.args if isinstance(argument, ast.Constant))
        # no message writes its own install command
        assert path.name == "extras.py" or "pip install 'bouncingball[" not in path.read_text("utf-8"), path
    assert named == {"plot", "reference", "fmu", "fast"}
    from bouncingball.cli import EXTRA_OF_MODULE

    assert set(EXTRA_OF_MODULE.values()) <= set(extras.EXTRAS)


def test_an_unknown_extra_is_refused_by_name():
    with pytest.raises(ValueError, match="extra = 'plots' is not allowed: it must be one of plot, reference"):
        extras.install_command("plots")


def test_from_this_checkouts_editable_install_the_hint_is_the_checkouts_folder():
    command = extras.install_command("plot", "reference")
    assert command == f"{shlex.quote(sys.executable)} -m pip install -e {shlex.quote(f'{ROOT}[plot,reference]')}"


@pytest.mark.slow
def test_the_printed_hint_works_from_this_checkout():
    """What a missing extra's message prints, run (pip's --dry-run: it resolves and would install, or fails)."""
    words = shlex.split(extras.install_command("plot"))
    done = subprocess.run([*words[:4], "--dry-run", *words[4:]], capture_output=True,
                          text=True, timeout=600, cwd="/")
    assert done.returncode == 0, done.stderr[-2000:]
    assert "Would install" in done.stdout, done.stdout[-2000:]


def _fake_distribution(monkeypatch, direct_url: dict | None, requires: list[str] | None = None):
    class Distribution:
        def read_text(self, name):
            return None if direct_url is None else json.dumps(direct_url)

    monkeypatch.setattr(extras.metadata, "distribution", lambda name: Distribution())
    if requires is not None:
        monkeypatch.setattr(extras.metadata, "requires", lambda name: requires)


def test_a_wheel_that_is_still_there_is_installed_with_the_extra(monkeypatch, tmp_path):
    wheel = tmp_path / "bouncingball-1.0-py3-none-any.whl"
    wheel.write_bytes(b"")
    _fake_distribution(monkeypatch, {"url": wheel.as_uri(), "archive_info": {}})
    assert extras.install_command("fmu").endswith(f" -m pip install '{wheel}[fmu]'")


def test_a_checkout_installed_without_e_is_installed_again_from_its_folder(monkeypatch, tmp_path):
    _fake_distribution(monkeypatch, {"url": tmp_path.as_uri(), "dir_info": {}})
    assert extras.install_command("fast").endswith(f" -m pip install '{tmp_path}[fast]'")


def test_from_an_index_the_name(monkeypatch):
    _fake_distribution(monkeypatch, None)
    assert extras.install_command("sweep").endswith(" -m pip install 'bouncingball[sweep]'")


def test_where_the_source_is_gone_the_extras_own_requirements(monkeypatch, tmp_path):
    """A wheel deleted after its install: the requirements themselves, the extras an extra names resolved."""
    requires = ['numpy>=1.24', 'matplotlib>=3.7; extra == "plot"', 'scipy>=1.10; extra == "reference"',
                'fmpy>=0.3.20; extra == "fmu"', 'bouncingball[plot,reference]; extra == "bench"',
                'tqdm>=4.60; extra == "bench"']
    _fake_distribution(monkeypatch, {"url": (tmp_path / "gone.whl").as_uri(), "archive_info": {}}, requires)
    assert extras.install_command("bench").endswith(" -m pip install 'matplotlib>=3.7' 'scipy>=1.10' 'tqdm>=4.60'")


_INSTALL = re.compile(r"pip install (?P<rest>[^`\n]*)")


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda path: str(path.relative_to(ROOT)))
def test_every_install_command_in_the_documents_works_from_a_checkout(document):
    """No name pip cannot find: each `pip install` of bouncingball is the checkout's (. or -e .), with real extras."""
    for match in _INSTALL.finditer(document.read_text("utf-8")):
        rest = match["rest"]
        assert "bouncingball[" not in rest and not re.match(r"['\"]?bouncingball\b", rest), (document, rest)
        for extra_list in re.findall(r"\.\[([a-z,]+)\]", rest):
            assert set(extra_list.split(",")) <= PYPROJECT_EXTRAS, (document, rest)
