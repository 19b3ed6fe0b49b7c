"""build-fmu's compile of the engine kept in the user-wide cache (solvers/engines/ahead_of_time.compile_kept).

The compile itself (about a minute, a child process) is compile_portable's, which the FMU tests run for
real; here a stand-in that writes one file per call shows when compile_kept compiles and when it
takes what it kept.
"""

import os
from pathlib import Path

import pytest

from bouncingball.solvers.engines import ahead_of_time as engine_cache


@pytest.fixture
def compiles(monkeypatch, tmp_path):
    """The list of (package, into) compile_portable was called with; the user-wide cache in tmp_path/cache."""
    calls = []

    def compile_portable(package, into, shipped_by, compiler=None):
        calls.append((package, into))
        folder = into / "bouncingball" / "numba-0123"
        folder.mkdir(parents=True)
        (folder / "machine.run_phases-1.py3.nbi").write_text(f"compile {len(calls)}")
        return folder

    monkeypatch.setattr(engine_cache, "compile_portable", compile_portable)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    return calls


def _package(folder: Path, source: str = "x = 1\n") -> Path:
    (folder / "ballpkg").mkdir(parents=True, exist_ok=True)
    (folder / "ballpkg" / "machine.py").write_text(source)
    return folder / "ballpkg"


def _compiled_by(kept: Path) -> str:
    return (kept / "machine.run_phases-1.py3.nbi").read_text()


def test_a_second_build_of_the_same_sources_takes_the_kept_compile(compiles, tmp_path):
    package = _package(tmp_path / "first")
    kept = engine_cache.compile_kept(package, tmp_path / "into1", "the FMU")
    again = engine_cache.compile_kept(package, tmp_path / "into2", "the FMU")
    assert len(compiles) == 1 and again == kept and _compiled_by(again) == "compile 1"
    assert kept.parent == Path(engine_cache.user_cache_root())
    assert [path.name for path in kept.parent.iterdir() if path.name.startswith(".portable-")] == []  # no leftovers


def test_a_changed_source_or_numba_setting_compiles_anew(compiles, tmp_path, monkeypatch):
    package = _package(tmp_path / "p")
    first = engine_cache.compile_kept(package, tmp_path / "into", "the FMU")
    (package / "machine.py").write_text("x = 2\n")
    second = engine_cache.compile_kept(package, tmp_path / "into", "the FMU")
    monkeypatch.setenv("NUMBA_OPT", "1")
    third = engine_cache.compile_kept(package, tmp_path / "into", "the FMU")
    assert len(compiles) == 3 and len({first, second, third}) == 3
    assert [_compiled_by(path) for path in (first, second, third)] == ["compile 1", "compile 2", "compile 3"]


def test_another_c_compiler_compiles_anew_and_the_same_takes_the_kept_compile(compiles, tmp_path):
    """The native engine's library is linked by the C compiler: it is part of what a kept compile is keyed by."""
    package = _package(tmp_path / "p")
    gcc = engine_cache.compile_kept(package, tmp_path / "into", "the FMU", ["gcc"])
    clang = engine_cache.compile_kept(package, tmp_path / "into", "the FMU", ["clang", "-O2"])
    again = engine_cache.compile_kept(package, tmp_path / "into", "the FMU", ["gcc"])
    assert len(compiles) == 2 and gcc != clang and again == gcc


def test_a_kept_compile_without_the_native_engine_says_why_at_each_build(compiles, tmp_path, capsys):
    """The stand-in builds no library (as a failed link): the compile kept says so again, with the first's reason."""
    package = _package(tmp_path / "p")
    engine_cache.compile_kept(package, tmp_path / "into", "the FMU", ["gcc"])  # the stand-in says nothing itself
    kept = engine_cache.compile_kept(package, tmp_path / "into", "the FMU", ["gcc"])
    assert capsys.readouterr().err == ("bouncingball: the FMU ships no native engine, which could not be built here "
                                       "(no message): it runs numba's compiled engine, which adds about 0.7 s to its "
                                       "start\n")
    (kept / engine_cache.NATIVE_FAILURE).write_text("RuntimeError: linking failed")
    engine_cache.compile_kept(package, tmp_path / "into", "the FMU", ["gcc"])
    assert "(RuntimeError: linking failed)" in capsys.readouterr().err


def test_a_failed_compile_keeps_nothing(monkeypatch, tmp_path):
    calls = []
    monkeypatch.setattr(engine_cache, "compile_portable", lambda package, into, by, compiler: calls.append(into))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    package = _package(tmp_path / "p")
    assert engine_cache.compile_kept(package, tmp_path / "into", "the FMU") is None
    assert engine_cache.compile_kept(package, tmp_path / "into", "the FMU") is None
    assert len(calls) == 2  # tried again, not taken as kept
    assert not list((tmp_path / "cache" / "bouncingball").glob("portable-*[!k]"))


def test_a_user_cache_that_cannot_be_written_compiles_into_the_builds_folder(compiles, tmp_path):
    root = Path(engine_cache.user_cache_root())
    root.parent.mkdir(parents=True)
    root.write_text("a file where the folder would be")  # unwritable even for root, unlike a mode
    cache = engine_cache.compile_kept(_package(tmp_path / "p"), tmp_path / "into", "the FMU")
    assert cache.is_relative_to(tmp_path / "into") and len(compiles) == 1


def test_only_the_most_recently_used_compiles_are_kept_and_none_used_within_the_hour_is_removed(compiles, tmp_path):
    kept = [engine_cache.compile_kept(_package(tmp_path / "p", f"x = {i}\n"), tmp_path / "into", "the FMU")
            for i in range(engine_cache.KEPT_COMPILES + 2)]
    assert all(path.is_dir() for path in kept)  # all used within the hour
    for age, path in enumerate(reversed(kept)):  # the first ones the oldest, all over an hour ago
        os.utime(path, (0, os.path.getmtime(path) - 7200 - age))
    latest = engine_cache.compile_kept(_package(tmp_path / "p", "x = 0\n"), tmp_path / "into", "the FMU")
    assert latest == kept[0]
    left = sorted(path for path in kept if path.is_dir())
    # kept[0] just used, and the next most recent KEPT_COMPILES - 1: the two oldest removed
    assert left == sorted([kept[0], *kept[-(engine_cache.KEPT_COMPILES - 1):]])


def test_a_compile_whose_lock_a_build_holds_stays_and_a_killed_builds_leftovers_go(compiles, tmp_path):
    import fcntl

    kept = [engine_cache.compile_kept(_package(tmp_path / "p", f"x = {i}\n"), tmp_path / "into", "the FMU")
            for i in range(engine_cache.KEPT_COMPILES + 1)]
    root = kept[0].parent
    leftover = root / ".portable-killed"
    leftover.mkdir()
    for path in (*kept, leftover):
        os.utime(path, (0, os.path.getmtime(path) - 7200))
    with open(f"{kept[0]}.lock", "a") as lock:  # a build of kept[0] is under way (the oldest, beyond the four)
        fcntl.flock(lock, fcntl.LOCK_EX)
        engine_cache._forget_old_compiles(root)
        assert kept[0].is_dir()
    engine_cache._forget_old_compiles(root)
    assert not kept[0].is_dir() and not leftover.exists() and all(path.is_dir() for path in kept[1:])
    assert not list(root.glob(".removed-*"))
