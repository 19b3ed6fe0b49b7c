"""A regression test to copy: run the BouncingBall FMU in your master, assert it matches the exact solution.

Needs: pip install -e '.[fmu]' pytest (FMPy stands in for your master here).
Usage: pytest regression_test.py      (BOUNCINGBALL_FMU=path/to/BouncingBall.fmu to test a given build;
       else the FMU is built into pytest's temporary directory)

To test your FMI importer, replace run_in_master() with a call to it: give it the start values,
let it write its result as a CSV with a time and an h column (and impacts, if it records it).
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bouncingball.check.judge import check_result

CASES = {  # name: (start values, stop time [s], communication step [s])
    "article": ({}, 8.0, 1e-3),
    "moon": ({"g": 1.62, "h": 1.0}, 6.0, 1e-2),
    "thrown up, stiff": ({"v": 3.0, "k": 1e6, "b": 50.0}, 3.0, 5e-2),  # steps longer than a contact
}


@pytest.fixture(scope="session")
def fmu(tmp_path_factory) -> Path:
    if os.environ.get("BOUNCINGBALL_FMU"):
        return Path(os.environ["BOUNCINGBALL_FMU"])
    path = tmp_path_factory.mktemp("fmu") / "BouncingBall.fmu"
    bin_dir = Path(sys.executable).parent
    subprocess.run([bin_dir / "bouncingball", "build-fmu", "-o", path], check=True)
    return path


def run_in_master(fmu: Path, start_values: dict, stop_time: float, step: float, csv_path: Path) -> Path:
    """Your master goes here. FMPy's: one communication step per output interval, written as CSV."""
    from fmpy import simulate_fmu
    from fmpy.util import write_csv

    result = simulate_fmu(str(fmu), start_values=start_values, stop_time=stop_time, output_interval=step)
    write_csv(str(csv_path), result)
    return csv_path


@pytest.mark.parametrize("case", CASES)
def test_the_master_reproduces_the_exact_solution(fmu, case, tmp_path):
    start_values, stop_time, step = CASES[case]
    csv_path = run_in_master(fmu, start_values, stop_time, step, tmp_path / "result.csv")
    # The same scene (the FMU's defaults are the article's) with the same start values, exactly.
    outcome = check_result(csv_path, "article", start_values, tolerance=1e-6)
    print(outcome.report())
    assert outcome.passed, outcome.report()
