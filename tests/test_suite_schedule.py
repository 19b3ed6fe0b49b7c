"""The test suite's own machinery (tests/conftest.py): the modules' order from their measured times, and pytest
with or without pytest-xdist."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

import conftest

ROOT = Path(__file__).resolve().parents[1]


def _items(*names: str) -> list[SimpleNamespace]:
    return [SimpleNamespace(path=conftest.TESTS / name, name=f"{name}::{i}") for i, name in enumerate(names)]


def test_the_modules_go_longest_first_and_an_unmeasured_one_before_them(monkeypatch):
    monkeypatch.setattr(conftest, "stored_durations", lambda: {"test_a.py": 5.0, "test_b.py": 60.0})
    items = _items("test_a.py", "test_a.py", "test_b.py", "test_new.py", "test_b.py")
    conftest.pytest_collection_modifyitems(None, items)
    # each module's own tests in their order: test_b's 2 then 4, test_a's 0 then 1
    assert [item.name for item in items] == ["test_new.py::3", "test_b.py::2", "test_b.py::4", "test_a.py::0",
                                             "test_a.py::1"]


def test_the_stored_durations_are_the_modules_that_exist():
    stored = conftest.stored_durations()
    modules = {path.name for path in conftest.TESTS.glob("test_*.py")}
    assert stored, f"{conftest.DURATIONS} is missing or unreadable: run the whole suite once to write it"
    assert set(stored) <= modules and all(seconds >= 0.0 for seconds in stored.values())
    assert list(stored.values()) == sorted(stored.values(), reverse=True)


def test_a_time_is_replaced_beyond_the_noise_only():
    here = "test_suite_schedule.py"  # a module that exists; conftest drops the names of deleted ones
    assert conftest.merged({here: 100.0}, {here: 120.0}) == {here: 100.0}  # within 25 %: kept
    assert conftest.merged({here: 100.0}, {here: 130.0}) == {here: 130.0}
    assert conftest.merged({here: 100.0}, {here: 70.0}) == {here: 70.0}
    assert conftest.merged({here: 0.5}, {here: 1.4}) == {here: 0.5}  # within a second: kept
    assert conftest.merged({}, {here: 1.23}) == {here: 1.2}  # a new module
    assert conftest.merged({here: 3.0}, {}) == {here: 3.0}  # not measured in this run: kept
    assert conftest.merged({"test_deleted.py": 9.0, here: 1.0}, {"test_deleted.py": 9.0}) == {here: 1.0}


def test_the_longest_stored_first_in_the_file():
    here, other = "test_suite_schedule.py", "conftest.py"  # both exist
    assert list(conftest.merged({here: 1.0}, {other: 50.0})) == [other, here]


def _session(*args: str, **options) -> SimpleNamespace:
    """What pytest_sessionfinish reads of a session: the paths given (none: testpaths) and the selection options."""
    selection = {"keyword": "", "markexpr": "", "lf": False, "deselect": None, "maxfail": 0, "stepwise": False}
    config = SimpleNamespace(args=list(args or ["tests"]), option=SimpleNamespace(**{**selection, **options}),
                             invocation_params=SimpleNamespace(dir=ROOT))
    return SimpleNamespace(config=config)


def test_a_run_of_the_whole_suite_stores_its_times_and_a_selection_does_not(monkeypatch, tmp_path):
    here = "test_suite_schedule.py"
    monkeypatch.setattr(conftest, "DURATIONS", tmp_path / "durations.json")
    monkeypatch.setattr(conftest, "_measured", {here: 2.5})
    monkeypatch.setattr(conftest, "_said", [])
    for session, status in ((_session(), pytest.ExitCode.INTERRUPTED), (_session(markexpr="not slow"), 0),
                            (_session(keyword="cli"), 0), (_session(maxfail=1), 1),
                            (_session("tests/test_cli.py"), 0), (_session("tests::test_a"), 0)):
        conftest.pytest_sessionfinish(session, status)
        assert not conftest.DURATIONS.exists() and conftest._said == []
    # the default run (addopts' -m 'not study') is the whole suite; a failed test still took its time
    conftest.pytest_sessionfinish(_session(markexpr="not study"), pytest.ExitCode.TESTS_FAILED)
    assert conftest.stored_durations() == {here: 2.5} and len(conftest._said) == 1
    conftest.pytest_sessionfinish(_session(str(ROOT)), pytest.ExitCode.OK)  # the same again: nothing to write
    assert len(conftest._said) == 1


def _config(xdist: bool, *args: str, **options) -> SimpleNamespace:
    """What pytest_cmdline_main reads of a pytest config: the plugins, the options given, the command line."""
    given = {"numprocesses": None, "maxprocesses": None, "dist": "no", "loadscopereorder": True, **options}
    return SimpleNamespace(pluginmanager=SimpleNamespace(hasplugin=lambda name: xdist and name == "xdist"),
                           option=SimpleNamespace(**given), invocation_params=SimpleNamespace(args=args))


def test_with_xdist_the_modules_go_to_up_to_4_workers_whole_and_in_order():
    config = _config(True)
    conftest.pytest_cmdline_main(config)
    assert vars(config.option) == {"numprocesses": "auto", "maxprocesses": 4, "dist": "loadscope",
                                   "loadscopereorder": False}


def test_the_command_line_wins_over_the_xdist_defaults():
    config = _config(True, "-n", "2", "--dist", "load", "--loadscope-reorder", numprocesses=2, dist="load")
    conftest.pytest_cmdline_main(config)
    assert vars(config.option) == {"numprocesses": 2, "maxprocesses": 4, "dist": "load", "loadscopereorder": True}
    in_process = _config(True, "-n", "0", numprocesses=0)
    conftest.pytest_cmdline_main(in_process)
    assert in_process.option.dist == "no"


def test_without_xdist_no_xdist_option_is_set():
    config = _config(False)
    conftest.pytest_cmdline_main(config)
    assert vars(config.option) == vars(_config(False).option)


@pytest.mark.slow  # a pytest of its own, ~5 s
def test_pytest_runs_one_module_without_xdist_and_leaves_the_stored_times_alone():
    before = conftest.DURATIONS.read_bytes() if conftest.DURATIONS.is_file() else None
    completed = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:xdist", "-q", "tests/test_scenes.py"],
                               cwd=ROOT, capture_output=True, text=True, check=False, timeout=300)
    assert completed.returncode == 0, completed.stdout[-3000:] + completed.stderr[-3000:]
    assert " passed" in completed.stdout and "worker" not in completed.stdout
    after = conftest.DURATIONS.read_bytes() if conftest.DURATIONS.is_file() else None
    assert after == before  # one module is not the whole suite: its time is not stored
