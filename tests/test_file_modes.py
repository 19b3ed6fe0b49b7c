"""Every file the package writes gets the mode any program gives a new file: 0666 less the umask (0644 under 022).

They are all written through bouncingball.output.atomic_write (a temporary file beside the target, renamed
onto it); a temporary file from mkstemp would be 0600, which CI artifacts and shared folders cannot read.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
import subprocess
import sys
from pathlib import Path

import pytest

import bouncingball
from bouncingball.output import atomic_write

BIN = Path(sys.executable).parent
PACKAGE = Path(bouncingball.__file__).parent
PUBLIC = 0o644  # 0666 less umask 022


@contextlib.contextmanager
def umask(mask: int):
    previous = os.umask(mask)
    try:
        yield
    finally:
        os.umask(previous)


def modes(folder: Path) -> dict[str, int]:
    """Every file in folder (hidden ones too: a leftover temporary file shows) and its permission bits."""
    return {path.name: stat.S_IMODE(path.stat().st_mode) for path in sorted(folder.iterdir()) if path.is_file()}


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o077], ids=["umask022", "umask002", "umask077"])
def test_atomic_write_gives_a_new_file_the_mode_of_the_umask(tmp_path, mask):
    with umask(mask):
        with atomic_write(tmp_path / "new.csv") as temporary:
            temporary.write_text("time,h,v\n", encoding="utf-8")
        (tmp_path / "old.csv").write_text("", encoding="utf-8")
        (tmp_path / "old.csv").chmod(0o600)
        with atomic_write(tmp_path / "old.csv") as temporary:  # replaced by a new file, as the umask says
            temporary.write_text("time,h,v\n", encoding="utf-8")
        with pytest.raises(RuntimeError), atomic_write(tmp_path / "failed.csv") as temporary:
            temporary.write_text("half a fi", encoding="utf-8")
            raise RuntimeError("interrupted")
    assert modes(tmp_path) == {"new.csv": 0o666 & ~mask, "old.csv": 0o666 & ~mask}
    assert (tmp_path / "new.csv").read_text(encoding="utf-8") == "time,h,v\n"


@pytest.mark.slow
def test_run_output_events_and_plot_are_0644_under_umask_022(tmp_path):
    pytest.importorskip("matplotlib", reason="--plot needs the [plot] extra")
    completed = subprocess.run(
        [BIN / "bouncingball", "run", "article", "--output", tmp_path / "out.csv", "--events",
         tmp_path / "events.csv", "--plot", tmp_path / "h.png"], capture_output=True, text=True, umask=0o022,
        check=False)
    assert completed.returncode == 0, completed.stderr
    assert modes(tmp_path) == {"events.csv": PUBLIC, "h.png": PUBLIC, "out.csv": PUBLIC}


@pytest.mark.slow
def test_build_fmu_writes_the_fmu_and_its_reference_0644_under_umask_022(tmp_path):
    pytest.importorskip("fmpy", reason="building the FMU needs the [fmu] extra")
    pytest.importorskip("pythonfmu", reason="building the FMU needs the [fmu] extra")
    completed = subprocess.run([BIN / "bouncingball", "build-fmu", "-o", tmp_path / "BouncingBall.fmu"],
                               capture_output=True, text=True, umask=0o022, check=False)
    assert completed.returncode == 0, completed.stderr
    assert modes(tmp_path) == {"BouncingBall.fmu": PUBLIC, "BouncingBall_ref.csv": PUBLIC}


@pytest.mark.slow
def test_a_sweep_and_its_parts_are_0644_under_umask_022(tmp_path):
    pytest.importorskip("dask", reason="the sweep needs the [sweep] extra")
    completed = subprocess.run(
        [BIN / "bouncingball", "sweep", "--k", "1e2:1e3:2", "--zeta", "0.1:1:2", "--solvers", "cvode", "--t-end",
         "0.1", "--workers", "1", "--output-dir", tmp_path], capture_output=True, text=True, umask=0o022,
        timeout=240, check=False)
    assert completed.returncode == 0, completed.stderr
    assert modes(tmp_path) == {name: PUBLIC for name in (
        "stability_map.csv", "stability_map.md", "stability_map.parquet", "stability_map_cvode.png")}
    import pandas as pd

    from bouncingball.sweep import store

    rows = pd.read_parquet(tmp_path / store.TABLE).to_dict("records")
    with umask(0o022):  # a batch's part, as an interrupted sweep leaves it for --resume
        part = store.write_part(tmp_path, rows[:1])
    assert modes(part.parent) == {part.name: PUBLIC}


def test_the_bench_files_are_0644_under_umask_022(tmp_path):
    """What `bouncingball bench` writes, each writer with nothing to report (the quick bench takes minutes)."""
    pytest.importorskip("matplotlib", reason="the bench needs the [bench] extra")
    from bouncingball.bench import pages, plots, tables, work_precision
    from bouncingball.scenes import load_scene

    with umask(0o022):
        tables.write_work_precision_csv([], tmp_path / work_precision.CSV_FILE)
        tables.write_stability_csv([], tmp_path / "stability.csv")
        work_precision.save_h([], tmp_path / work_precision.H_FILE)
        plots.plot_work_precision([], tmp_path / "work_precision.png")
        pages.write_stability_md([load_scene("article")], [], 1.0, True, {}, tmp_path / "stability.md")
    assert modes(tmp_path) == {name: PUBLIC for name in (
        "stability.csv", "stability.md", "work_precision.csv", "work_precision.png", "work_precision_h.npz")}


def test_no_module_but_output_makes_a_temporary_file_to_rename():
    """The pattern that wrote 0600 files (mkstemp, then a rename) lives in atomic_write only."""
    pattern = re.compile(r"mkstemp|NamedTemporaryFile|os\.replace\(|os\.rename\(|\.rename\(")
    # sundials_log's mkstemp is SUNDIALS' own log, read back and removed within the run; jit's rename is the digest
    # of numba's cache, written by open() (mode 0666 less the umask) in numba's own cache folder: never a result;
    # ahead_of_time's renames the folder numba compiled its cache into (numba made it) into the user-wide cache
    engines = PACKAGE / "solvers" / "engines"
    allowed = {PACKAGE / "output.py", engines / "sundials_log.py", engines / "jit.py", engines / "ahead_of_time.py"}
    found = [f"{path.relative_to(PACKAGE)}:{number}: {line.strip()}" for path in sorted(PACKAGE.rglob("*.py"))
             if path not in allowed
             for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if pattern.search(line)]
    assert found == []
