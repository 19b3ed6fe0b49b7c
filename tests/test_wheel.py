"""What a user gets from `pip install 'bouncingball[fmu,fast]'`: a wheel in a fresh virtual environment, run
from a folder that is not the checkout. One venv for the whole module (it takes ~1 minute)."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fmu_helpers import exact_at

pytestmark = pytest.mark.slow  # builds the wheel and installs it in a fresh virtual environment

ROOT = Path(__file__).resolve().parents[1]


def run(command, cwd, timeout=600) -> subprocess.CompletedProcess:
    completed = subprocess.run([str(part) for part in command], cwd=cwd, capture_output=True, text=True,
                               timeout=timeout, check=False)
    assert completed.returncode == 0, f"{command}\n{completed.stdout}\n{completed.stderr}"
    return completed


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The bin folder of a fresh venv with the wheel installed with its [fmu] and [fast] extras.

    The wheel is built by that venv's pip while it holds nothing: the build's requirements (the engine's,
    for its compiled cache) come from pip's isolated build environment alone."""
    folder = tmp_path_factory.mktemp("wheel")
    run([sys.executable, "-m", "venv", folder / "venv"], cwd=folder)
    bin_dir = folder / "venv" / "bin"
    run([bin_dir / "python", "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", folder / "dist", ROOT], cwd=folder)
    [wheel] = (folder / "dist").glob("bouncingball-*.whl")
    run([bin_dir / "python", "-m", "pip", "install", "--quiet", f"{wheel}[fmu,fast]"], cwd=folder)
    return bin_dir


def test_the_wheel_builds_and_runs_the_fmu_outside_the_checkout(installed, tmp_path):
    found = run([installed / "python", "-c", "import bouncingball; print(bouncingball.__file__)"], cwd=tmp_path)
    assert str(installed.parent) in found.stdout and str(ROOT) not in found.stdout
    built = run([installed / "bouncingball", "build-fmu", "-o", "BouncingBall.fmu"], cwd=tmp_path)
    assert "wrote BouncingBall.fmu" in built.stdout
    run([installed / "fmpy", "simulate", "BouncingBall.fmu", "--stop-time", "2", "--output-interval", "0.01",
         "--output-file", "out.csv"], cwd=tmp_path)
    with open(tmp_path / "out.csv", newline="") as table:
        rows = list(csv.DictReader(table))
    t = np.array([float(row["time"]) for row in rows])
    h = np.array([float(row["h"]) for row in rows])
    impacts = np.array([int(row["impacts"]) for row in rows])
    h_exact, _, impacts_exact = exact_at(t)
    assert t[-1] == pytest.approx(2.0) and np.max(np.abs(h - h_exact)) < 1e-7
    np.testing.assert_array_equal(impacts, impacts_exact)


_FIRST_COMPILED_RUN = """
import json
import bouncingball as bb
from bouncingball.solvers.engines import compiled
result = bb.simulate(bb.Ball(), 2.0, 0.0, 8.0, 1e-3, engine="compiled")
dispatchers = [value for value in vars(compiled).values() if hasattr(value, "stats")]
dispatchers += list(compiled._compiled.values())
print(json.dumps({"t": result.t.tolist(), "h": result.h.tolist(), "engine": result.stats.engine,
                  "misses": sum(sum(d.stats.cache_misses.values()) for d in dispatchers),
                  "hits": sum(sum(d.stats.cache_hits.values()) for d in dispatchers)}))
"""


def test_the_wheel_carries_its_compiled_engine_and_a_first_use_compiles_nothing(installed, tmp_path):
    """The wheel's build compiled the engine for any CPU of its architecture into the package: a first run with the
    compiled engine, in a fresh process with an empty user-wide cache, reads every function from it, compiles none
    and says nothing; its heights are the exact solution's."""
    import json
    import os

    site = run([installed / "python", "-c", "import bouncingball, os; print(os.path.dirname(bouncingball.__file__))"],
               cwd=tmp_path).stdout.strip()
    assert len(list(Path(site, "numba-cache").glob("*.nbi"))) > 10
    import zipfile

    [wheel] = (installed.parent.parent / "dist").glob("bouncingball-*.whl")
    assert not [name for name in zipfile.ZipFile(wheel).namelist() if "__pycache__" in name]  # the compile's bytecode
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "empty-cache")}
    env.pop("NUMBA_CACHE_DIR", None)
    completed = subprocess.run([installed / "python", "-c", _FIRST_COMPILED_RUN], cwd=tmp_path, env=env,
                               capture_output=True, text=True, timeout=300, check=False)
    assert completed.returncode == 0 and completed.stderr == "", completed.stderr
    report = json.loads(completed.stdout)
    assert report["engine"] == "compiled" and report["misses"] == 0 and report["hits"] > 0, report
    h_exact, _, _ = exact_at(np.array(report["t"]))
    assert np.max(np.abs(np.array(report["h"]) - h_exact)) < 1e-7
    assert len(list((tmp_path / "empty-cache" / "bouncingball").glob("numba-*/*.nbi"))) > 10  # kept for the next


def test_the_main_job_runs_from_the_wheel(installed, tmp_path):
    completed = run([installed / "bouncingball", "run", "article", "--output", "article.csv"], cwd=tmp_path)
    assert (tmp_path / "article.csv").is_file(), completed.stdout


def test_the_fmu_travels_to_another_python_with_numpy_and_scikit_sundae(installed, tmp_path):
    """A plain C master, the build venv moved away: the FMU finds another venv's python3 on PATH (one
    with numpy and scikit-sundae, nothing else); with none on PATH it fails in fmi2Instantiate with one
    log line that says what it needs."""
    import fmpy

    from bouncingball.fmu.build import shared_libpython
    from fmu_helpers import compile_c_master

    if shared_libpython() is None:
        pytest.skip("this Python has no shared libpython: its FMU runs only in a master that runs Python")
    master = compile_c_master(tmp_path / "fmi2_master")
    if master is None:
        pytest.skip("no C compiler (cc or gcc) to build the C master")
    run([installed / "bouncingball", "build-fmu", "-o", "BouncingBall.fmu"], cwd=tmp_path)
    unzipped = fmpy.extract(str(tmp_path / "BouncingBall.fmu"), str(tmp_path / "unzipped"))
    description = fmpy.read_model_description(unzipped)
    h_reference = {v.name: v.valueReference for v in description.modelVariables}["h"]
    other = tmp_path / "other-venv"
    run([sys.executable, "-m", "venv", other], cwd=tmp_path)
    run([other / "bin" / "python", "-m", "pip", "install", "--quiet", "numpy", "scikit-sundae"], cwd=tmp_path)

    def c_master(path: str) -> subprocess.CompletedProcess:
        return subprocess.run([master, unzipped, "BouncingBall", description.guid, "2.0", "0.01", f"o{h_reference}"],
                              env={"PATH": path}, capture_output=True, text=True, timeout=120, check=False)

    build_venv = installed.parent
    moved = build_venv.with_name("moved-away")
    build_venv.rename(moved)
    try:
        travelled = c_master(f"{other / 'bin'}:/usr/bin:/bin")
        stranded = c_master("/nonexistent")
    finally:
        moved.rename(build_venv)
    assert travelled.returncode == 0, travelled.stdout + travelled.stderr
    table = np.loadtxt(travelled.stdout.splitlines())
    h_exact, _, _ = exact_at(table[:, 0])
    assert np.max(np.abs(table[:, 1] - h_exact)) < 1e-7
    assert stranded.returncode != 0
    [line] = [line for line in stranded.stderr.splitlines() if "status 3" in line]
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    assert f"this FMU needs Python {version} with a shared libpython, numpy and scikit-sundae" in line
    assert "on PATH (/nonexistent)" in line
