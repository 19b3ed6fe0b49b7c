"""`bouncingball check` of a run whose F_ext an input drove: FMPy's input file, or the result's own F_ext column."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bouncingball.check.input_files import fmpy_input_value, read_input_file
from bouncingball.check.judge import check_result
from bouncingball.check.result_files import BadResultError
from bouncingball.cli import main

fmpy = pytest.importorskip("fmpy")

# A ramp down from 0 and, at 0.5 s, a step up to 20 N (two rows at one time), held, then a ramp to 5 N.
INPUT = "time,F_ext\n0,0\n0.5,0\n0.5,20\n1.0,20\n1.3,5\n"
OTHER = "time,F_ext\n0,0\n0.6,0\n0.6,20\n1.0,20\n1.3,5\n"  # the step 0.1 s later


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def fmpy_run(fmu: Path, input_path: Path, output: list[str], interval: float = 0.01, stop: float = 2.0):
    rows = np.genfromtxt(input_path, delimiter=",", names=True)
    return fmpy.simulate_fmu(str(fmu), stop_time=stop, output_interval=interval, input=rows, output=output)


def write_result(path: Path, run, every: int = 1) -> Path:
    names = run.dtype.names
    lines = [",".join(f'"{n}"' for n in names)]
    lines += [",".join(repr(float(row[n])) if n != "impacts" else str(int(row[n])) for n in names)
              for row in run[::every]]
    path.write_text("\n".join(lines) + "\n")
    return path


def check(capsys, *args) -> tuple[int, str]:
    code = main(["check", *map(str, args)])
    return code, capsys.readouterr().out


def test_fmpy_records_in_each_row_the_F_ext_applied_over_the_step_that_ends_there(fmu, tmp_path):
    run = fmpy_run(fmu, write(tmp_path / "in.csv", INPUT), ["h", "F_ext"])
    force = dict(zip(np.round(run["time"], 9), run["F_ext"], strict=True))
    # FMPy applies the input at t_i (after a step at t_i: the later row), calls doStep, samples at t_i+1.
    assert force[0.5] == 0.0 and force[0.6] == 20.0  # the step at 0.5 is applied over [0.5, 0.6)
    assert force[1.01] == 20.0 and force[1.11] == pytest.approx(15.0, abs=1e-12)  # the ramp taken at 1.0, 1.1
    assert force[1.1] == pytest.approx(15.5, abs=1e-12)  # taken at 1.09: 20 - 15 (0.09 / 0.3)
    assert force[1.31] == 5.0  # the value at 1.3, applied over [1.3, 1.31)
    # a free fall from 2 m for 0.5 s, then the net 10.19 m/s2 up over [0.5, 0.6): by hand
    i = int(np.argmin(np.abs(run["time"] - 0.6)))
    assert run["h"][i] == pytest.approx(2.0 - 0.5 * 9.81 * 0.25 - 4.905 * 0.1 + 0.5 * 10.19 * 0.01, abs=1e-9)


def test_fmpy_input_value_is_what_fmpy_applies(tmp_path):
    from fmpy.simulation import Input

    times, values = read_input_file(write(tmp_path / "in.csv", INPUT))
    for t in (-1.0, 0.0, 0.25, 0.5, 0.7, 1.0, 1.1, 1.3, 2.0):
        expected, _ = Input.interpolate(t, times, values.reshape(1, -1), after_event=True)
        assert fmpy_input_value(times, values, t) == float(expected[0])
    assert fmpy_input_value(times, values, 0.5) == 20.0
    assert fmpy_input_value(times, values, 1.1) == pytest.approx(15.0, abs=1e-12)


def test_check_passes_an_fmpy_run_driven_through_the_input_file_and_fails_another_input(fmu, tmp_path, capsys):
    inputs = write(tmp_path / "in.csv", INPUT)
    result = write_result(tmp_path / "out.csv", fmpy_run(fmu, inputs, ["h", "v", "impacts"]))
    code, out = check(capsys, result, "--input-file", inputs)
    assert code == 0, out
    outcome = check_result(result, input_file=inputs)
    assert outcome.passed and outcome.max_height_error < 1e-8 and outcome.impacts_exact == 1
    assert "F_ext from" in out and "in.csv" in out
    code, out = check(capsys, result, "--input-file", write(tmp_path / "other.csv", OTHER))
    assert code != 0 and "FAIL" in out
    assert check_result(result, input_file=tmp_path / "other.csv").max_height_error > 0.05
    assert check_result(result).max_height_error > 1.0  # F_ext = 0 throughout: metres off


def test_a_forced_run_checked_without_its_input_is_told_of_input_file(fmu, tmp_path, capsys):
    inputs = write(tmp_path / "in.csv", INPUT)
    result = write_result(tmp_path / "out.csv", fmpy_run(fmu, inputs, ["h", "impacts"]))
    code, out = check(capsys, result)
    verdict = out.splitlines()[-1]
    assert code == 1 and "FAIL" in verdict
    assert "the file has no F_ext column: if an input drove F_ext, give its file with --input-file F.csv" in verdict
    code, out = check(capsys, result, "--input-file", write(tmp_path / "other.csv", OTHER))
    assert code == 1 and "--input-file" not in out.splitlines()[-1]  # it was given: the input is wrong, not missing
    with_column = write_result(tmp_path / "with_column.csv", fmpy_run(fmu, inputs, ["h", "F_ext"]))
    verdict = check_result(with_column, tolerance=1e-15).verdict
    assert verdict.startswith("FAIL") and "--input-file" not in verdict  # its F_ext column says what was applied
    unforced = {"time": np.array([0.0, 0.1]), "h": np.array([2.0, 2.0])}  # no fall: fails
    assert "--input-file" in check_result(unforced).verdict


def test_a_master_recording_less_often_than_it_steps_needs_its_step_size(fmu, tmp_path, capsys):
    inputs = write(tmp_path / "in.csv", INPUT)
    result = write_result(tmp_path / "out.csv", fmpy_run(fmu, inputs, ["h", "impacts"]), every=7)
    code, out = check(capsys, result, "--input-file", inputs, "--step-size", "0.01")
    assert code == 0, out
    assert check_result(result, input_file=inputs, step_size=0.01).max_height_error < 1e-8
    # taken as stepping at its recorded times (0.07 s), the ramp is held longer: the check says so
    assert not check_result(result, input_file=inputs).passed


def test_the_F_ext_column_says_what_was_applied(fmu, tmp_path, capsys):
    inputs = write(tmp_path / "in.csv", INPUT)
    result = write_result(tmp_path / "out.csv", fmpy_run(fmu, inputs, ["h", "F_ext", "impacts"]))
    code, out = check(capsys, result)
    assert code == 0, out
    assert "from the file's 'F_ext' column" in out
    assert check_result(result).max_height_error < 1e-8
    # the column shifted one row earlier (as if each row held the value applied from its time on) fails
    run = np.genfromtxt(result, delimiter=",", names=True)
    run["F_ext"][:-1] = run["F_ext"][1:]
    assert not check_result(write_result(tmp_path / "shifted.csv", run)).passed


@pytest.mark.parametrize(("text", "message"), [
    ("t,F_ext\n0,1\n", "row 1: the first column is 't'"),
    ("time,F\n0,1\n", "no 'F_ext' column in the header (it has: time, F)"),
    ("time,F_ext\n", "no data rows after the header"),
    ("time,F_ext\n0,1\n1,abc\n", "row 3, column 'F_ext': 'abc' is not a finite number"),
    ("time,F_ext\n0,1\n1,nan\n", "row 3, column 'F_ext': 'nan' is not a finite number"),
    ("time,F_ext\n0,1\n1,2\n0.5,3\n", "row 4, column 'time': 0.5 goes back in time (the row before has 1.0)"),
])
def test_a_bad_input_file_is_refused_naming_the_row_and_value(tmp_path, text, message):
    path = write(tmp_path / "bad.csv", text)
    with pytest.raises(BadResultError) as error:
        check_result({"time": np.array([0.0, 0.1]), "h": np.array([2.0, 1.95])}, input_file=path)
    assert str(error.value).startswith(f"{path}: {message}")


def test_step_size_without_an_input_file_is_refused():
    with pytest.raises(ValueError, match="step_size names the communication points of an input file"):
        check_result({"time": np.array([0.0, 0.1]), "h": np.array([2.0, 1.95])}, step_size=0.01)
