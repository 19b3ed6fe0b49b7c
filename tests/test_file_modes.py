"""Every file the package writes gets the mode any program gives a new file: 0666 less the umask (0644 under 022).

They are all written through bouncingball.output.atomic_write (a temporary file beside the target, renamed
onto it); a temporary file from mkstemp would be 0600, which CI artifacts and shared folders cannot read.
"""

from __future__ import annotations

import contextlib
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from bouncingball.output import atomic_write

BIN = Path(sys.executable).parent
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


def test_run_output_events_and_plot_are_0644_under_umask_022(tmp_path):
    pytest.importorskip("matplotlib", reason="--plot needs the [plot] extra")
    completed = subprocess.run(
        [BIN / "bouncingball", "run", "article", "--output", tmp_path / "out.csv", "--events",
         tmp_path / "events.csv", "--plot", tmp_path / "h.png"], capture_output=True, text=True, umask=0o022,
        check=False)
    assert completed.returncode == 0, completed.stderr
    assert modes(tmp_path) == {"events.csv": PUBLIC, "h.png": PUBLIC, "out.csv": PUBLIC}


def test_build_fmu_writes_the_fmu_and_its_reference_0644_under_umask_022(tmp_path):
    pytest.importorskip("fmpy", reason="building the FMU needs the [fmu] extra")
    pytest.importorskip("pythonfmu", reason="building the FMU needs the [fmu] extra")
    completed = subprocess.run([BIN / "bouncingball", "build-fmu", "-o", tmp_path / "BouncingBall.fmu"],
                               capture_output=True, text=True, umask=0o022, check=False)
    assert completed.returncode == 0, completed.stderr
    assert modes(tmp_path) == {"BouncingBall.fmu": PUBLIC, "BouncingBall_ref.csv": PUBLIC}
