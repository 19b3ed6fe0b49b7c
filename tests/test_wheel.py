"""What a user gets from `pip install 'bouncingball[fmu]'`: a wheel in a fresh virtual environment, run
from a folder that is not the checkout. One venv for the whole module (it takes ~1 minute)."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fmu_helpers import exact_at

ROOT = Path(__file__).resolve().parents[1]


def run(command, cwd, timeout=600) -> subprocess.CompletedProcess:
    completed = subprocess.run([str(part) for part in command], cwd=cwd, capture_output=True, text=True,
                               timeout=timeout, check=False)
    assert completed.returncode == 0, f"{command}\n{completed.stdout}\n{completed.stderr}"
    return completed


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The bin folder of a fresh venv with the wheel installed with its [fmu] extra."""
    folder = tmp_path_factory.mktemp("wheel")
    run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", folder / "dist", ROOT], cwd=folder)
    [wheel] = (folder / "dist").glob("bouncingball-*.whl")
    run([sys.executable, "-m", "venv", folder / "venv"], cwd=folder)
    bin_dir = folder / "venv" / "bin"
    run([bin_dir / "python", "-m", "pip", "install", "--quiet", f"{wheel}[fmu]"], cwd=folder)
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


def test_the_main_job_runs_from_the_wheel(installed, tmp_path):
    completed = run([installed / "bouncingball", "run", "article", "--output", "article.csv"], cwd=tmp_path)
    assert (tmp_path / "article.csv").is_file(), completed.stdout
