"""`bouncingball check` and bouncingball.check.judge: a master's CSV judged against the exact solution."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bouncingball.check.judge import BadResultError, check_result, read_result_csv, scene_with_start_values
from bouncingball.cli import EXIT_BAD_INPUT, EXIT_CHECK_FAILED, main
from bouncingball.physics import Ball
from bouncingball.solvers.exact import ExactSolution
from fmu_helpers import exact_at
from oracle_counts import oracle_counts

BIN = Path(sys.executable).parent


def write_csv(path: Path, header: list[str], rows, quote: bool = False) -> Path:
    with path.open("w", newline="") as file:
        writer = csv.writer(file, quoting=csv.QUOTE_NONNUMERIC if quote else csv.QUOTE_MINIMAL)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def read_rows(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open(newline="") as file:
        rows = list(csv.reader(file))
    return rows[0], rows[1:]


@pytest.fixture(scope="module")
def fmpy_results(fmu, tmp_path_factory) -> dict[str, Path]:
    """The article and a ball on the Moon, each written by `fmpy simulate` (a subprocess)."""
    pytest.importorskip("fmpy", reason="the FMPy results need the [fmu] extra")
    folder = tmp_path_factory.mktemp("fmpy_results")
    runs = {"article": [], "moon": ["--stop-time", "6", "--output-interval", "0.01", "--start-values", "g", "1.62",
                                    "h", "1.0"]}
    for name, options in runs.items():
        completed = subprocess.run([BIN / "fmpy", "simulate", fmu, "--output-file", folder / f"{name}.csv", *options],
                                   capture_output=True, text=True, check=False, timeout=120)
        assert completed.returncode == 0, completed.stdout + completed.stderr
    return {name: folder / f"{name}.csv" for name in runs}


def run_check(capsys, *args) -> tuple[int, str, str]:
    code = main(["check", *map(str, args)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_good_fmpy_result_passes(fmpy_results, capsys):
    code, out, err = run_check(capsys, fmpy_results["article"])
    assert code == 0, out + err
    header, rows = read_rows(fmpy_results["article"])
    t = np.array([float(row[0]) for row in rows])
    h = np.array([float(row[header.index("h")]) for row in rows])
    h_exact, _, impacts = exact_at(t)
    assert f"points compared    {len(t)}" in out
    assert f"max |h - h_exact|  {np.max(np.abs(h - h_exact)):.3e} m" in out
    assert f"impacts            {impacts[-1]} at the end, exact {impacts[-1]}; the count is right at every point" \
        in out
    assert impacts[-1] == oracle_counts(Ball()).impacts and "verdict            PASS" in out


def test_one_height_off_by_a_millimetre_fails_and_names_the_point(fmpy_results, tmp_path, capsys):
    header, rows = read_rows(fmpy_results["article"])
    row = rows[250]  # FMPy's default grid: 1000 intervals of the stop time, 8 ms
    row[header.index("h")] = repr(float(row[header.index("h")]) + 1e-3)
    bad = write_csv(tmp_path / "bad.csv", header, rows)
    code, out, _ = run_check(capsys, bad)
    assert code == EXIT_CHECK_FAILED == 1
    outcome = check_result(bad)
    assert outcome.worst_time == float(row[0]) == 2.0
    assert outcome.max_height_error == pytest.approx(1e-3, abs=1e-7)  # the FMU's own error is ~3e-8 m
    assert "exceeds the tolerance 1e-06 m" in out and "at t = 2.0 s" in out


def test_a_wrong_impact_count_fails_and_names_the_point(fmpy_results, tmp_path, capsys):
    header, rows = read_rows(fmpy_results["article"])
    column = header.index("impacts")
    rows[375][column] = str(int(rows[375][column]) + 1)  # t = 3 s
    bad = write_csv(tmp_path / "bad.csv", header, rows)
    code, out, _ = run_check(capsys, bad)
    assert code == 1
    _, _, impacts = exact_at(np.array([0.0, 3.0]))
    assert f"wrong at 1 points, first at t = 3.0 s ({impacts[-1] + 1}, exact {impacts[-1]})" in out


def test_the_moon_passes_with_its_start_values_and_fails_without(fmpy_results, capsys):
    moon = fmpy_results["moon"]
    code, out, err = run_check(capsys, moon, "--start-value", "g=1.62", "--start-value", "h=1.0")
    assert code == 0, out + err
    header, rows = read_rows(moon)
    t = np.array([float(row[0]) for row in rows])
    _, _, impacts = exact_at(t, Ball(g=1.62), h0=1.0)
    assert len(t) == 601 and f"exact {impacts[-1]}; the count is right" in out
    assert "printed" not in out  # FMPy writes every digit: nothing is allowed beyond the tolerance
    code, out, _ = run_check(capsys, moon, "--start-value", "h=1.0")  # g = 9.81: the wrong ball
    assert code == 1 and "FAIL: the first row is not the scene's start: a = -1.62 m/s2 where the scene's ball has " \
                         "-9.81 m/s2 there (--start-value g=1.62 would match it)" in out
    code, out, _ = run_check(capsys, moon)  # nor where it starts
    assert code == 1 and "h = 1.0 m where the scene starts at 2.0 m (--start-value h=1.0 would match it)" in out


def test_a_quoted_fmusim_header_in_another_column_order_passes(fmpy_results, tmp_path, capsys):
    header, rows = read_rows(fmpy_results["article"])
    order = [header.index(name) for name in ("impacts", "h", "v", "time")]
    quoted = write_csv(tmp_path / "fmusim.csv", ["impacts", "h", "v", "time", "extra"],
                       [[float(row[i]) for i in order] + [7.0] for row in rows], quote=True)
    assert quoted.read_text().startswith('"impacts","h","v","time","extra"\n')
    code, out, err = run_check(capsys, quoted)
    assert code == 0, out + err
    assert check_result(quoted).max_height_error == check_result(fmpy_results["article"]).max_height_error


def test_the_exact_solution_shifted_by_a_known_amount_is_measured_exactly(tmp_path):
    t = np.arange(0, 4001) * 1e-3
    h, _, impacts = exact_at(t, Ball(b=0.0), h0=1.0)
    path = write_csv(tmp_path / "exact.csv", ["time", "h", "impacts"],
                     [[repr(float(a)), repr(float(b) + 5e-7), int(c)] for a, b, c in zip(t, h, impacts, strict=True)])
    outcome = check_result(path, "article", {"b": 0, "h": 1})
    assert outcome.passed and outcome.points == 4001
    assert outcome.max_height_error == pytest.approx(5e-7, rel=1e-6)
    assert outcome.impacts_exact == impacts[-1] and not outcome.impact_mismatches
    assert not check_result(path, "article", {"b": 0, "h": 1}, tolerance=4e-7).passed


def test_check_result_takes_columns_as_fmpy_returns_them():
    t = np.linspace(0.0, 1.0, 101)
    h, _, impacts = exact_at(t)
    result = np.rec.fromarrays([t, h, impacts], names=["time", "h", "impacts"])
    outcome = check_result(result)
    assert outcome.passed and outcome.max_height_error == 0.0 and outcome.impacts_found == impacts[-1] == 1


def test_an_impact_within_a_microsecond_of_a_point_may_count_either_way():
    first = ExactSolution(Ball(), 2.0, 0.0, 0.0, 1.0).events[0].time  # the article's first impact
    t = np.array([0.0, first - 5e-7, first + 5e-7, 1.0])
    h, _, _ = exact_at(t)
    for counted in ([0, 1, 1, 1], [0, 0, 0, 1]):  # early, or late, by half a microsecond
        assert check_result({"time": t, "h": h, "impacts": np.array(counted)}).passed, counted
    t = np.array([0.0, first - 2e-6, 1.0])
    h, _, _ = exact_at(t)
    assert not check_result({"time": t, "h": h, "impacts": np.array([0, 1, 1])}).passed


def test_start_values_map_onto_the_scene():
    scene = scene_with_start_values("article", {"g": "1.62", "h": 1.0, "v": "-2", "F_ext": 0.5, "rtol": 1e-9,
                                                "method": "BDF", "engine": "compiled"})
    assert (scene.ball.g, scene.h0, scene.v0, scene.F_ext, scene.ball.m) == (1.62, 1.0, -2.0, 0.5, 1.0)
    with pytest.raises(ValueError, match="start value 'contact' is not allowed"):
        scene_with_start_values("article", {"contact": 1})
    with pytest.raises(ValueError, match="m = -1.0 kg is not allowed"):
        scene_with_start_values("article", {"m": -1})


MALFORMED = {
    "no_time.csv": ("t,h\n0,2\n", "no 'time' column in the header (it has: t, h)"),
    "no_h.csv": ('"time","height"\n0,2\n', "no 'h' column in the header (it has: time, height)"),
    "text.csv": ("time,h\n0,2\n0.001,two\n", "row 3, column 'h': 'two' is not a finite number"),
    "nan.csv": ("time,h\n0,2\n0.001,nan\n", "row 3, column 'h': 'nan' is not a finite number"),
    "short.csv": ("time,v,h\n0,0,2\n0.001,0\n", "row 3 has no 'h' cell (it has 2 cells)"),
    "back.csv": ("time,h\n0,2\n0.002,2\n0.001,2\n",
                 "row 4, column 'time': 0.001 goes back in time (the row before has 0.002)"),
    "impacts.csv": ("time,h,impacts\n0,2,0\n0.001,2,0.5\n", "row 3, column 'impacts': '0.5' is not a whole number"),
    "underscore.csv": ("time,h\n0,2\n0.001,1_0\n", "row 3, column 'h': '1_0' is not a finite number"),
    "wide.csv": ("time,h\n0,2\n0.001,2,7\n", "row 3 has 3 cells, the header 2: cell 3 ('7') has no column"),
    "twice.csv": ("time,h,v,H\n0,2,0,2\n", "row 1, column 4: 'H' duplicates column 2 ('h')"),
    "twice_typed.csv": ("time,ball::h[REAL],ball::H[INT]\n0,2,2\n",
                        "row 1, column 3: 'ball::H[INT]' duplicates column 2 ('ball::h[REAL]')"),
    "two_balls.csv": ('"time","model.root.ball.h","model.root.moon.h"\n0,2,1\n',
                      "the file holds several instances of the ball (model.root.ball, model.root.moon): pick one "
                      "with --instance NAME"),
    "sep.csv": ('"sep=;"\n"time";"h"\n', "row 1 says the separator is ';': only ',' is read"),
    "header_only.csv": ("time,h\n", "no data rows after the header"),
    "empty.csv": ("", "the file is empty"),
}


@pytest.mark.parametrize("name", MALFORMED)
def test_a_malformed_file_is_bad_input_with_one_clear_line(name, tmp_path, capsys):
    text, message = MALFORMED[name]
    path = tmp_path / name
    path.write_text(text)
    code, out, err = run_check(capsys, path)
    assert code == EXIT_BAD_INPUT == 2
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"bouncingball: error: {path}: {message}")
    with pytest.raises(BadResultError, match=str(path)):
        read_result_csv(path)


def _zip(path: Path, members: list[str]) -> Path:
    import zipfile

    with zipfile.ZipFile(path, "w") as archive:
        for member in members:
            archive.writestr(member, "<fmiModelDescription/>")
    return path


NOT_TEXT = {
    "BouncingBall.fmu": (lambda path: _zip(path, ["modelDescription.xml", "binaries/linux64/x.so"]),
                         "it is an FMU (a zip archive), not a CSV file"),
    "results.zip": (lambda path: _zip(path, ["out.csv"]), "it is a zip archive, not a CSV file"),
    "out.mat": (lambda path: path.write_bytes(b"MATLAB 5.0\x00\x01\xff") and path, "it is a binary file, not a CSV"),
    "latin1.csv": (lambda path: path.write_bytes("time,h\n0,2\n# h\xf6he\n".encode("latin-1")) and path,
                   "cannot be read: it is not UTF-8 text (it holds the byte 0xf6): save it as UTF-8"),
}


@pytest.mark.parametrize("name", NOT_TEXT)
def test_a_file_that_is_no_csv_text_is_named_as_what_it_is(name, tmp_path, capsys):
    make, message = NOT_TEXT[name]
    path = make(tmp_path / name)
    code, out, err = run_check(capsys, path)
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert err.startswith(f"bouncingball: error: {path}: {message}"), err
    assert "codec" not in err
    if "not a CSV file" in message:
        assert err.rstrip().endswith("give the CSV a master wrote (a time and an h column)"), err
    (tmp_path / "ok.csv").write_text("time,h\n0,2\n")
    code, out, err = run_check(capsys, tmp_path / "ok.csv", "--input-file", path)  # the input file too
    assert code == 2 and err.startswith(f"bouncingball: error: {path}: {message}"), err
    if "not a CSV file" in message:  # each says what it wanted instead
        assert err.rstrip().endswith("give FMPy's input file (a CSV: time,F_ext)"), err


@pytest.mark.parametrize(("args", "message"), [
    (["missing.csv"], "missing.csv: cannot be read"),
    (["ok.csv", "--start-value", "g"], "--start-value 'g' is not allowed: it must be NAME=VALUE"),
    (["ok.csv", "--start-value", "gravity=1"], "start value 'gravity' is not allowed"),
    (["ok.csv", "--start-value", "g=abc"], "start value g = 'abc' is not allowed: it must be a number"),
    (["ok.csv", "--tolerance", "0"], "tolerance = 0.0 m is not allowed"),
    (["ok.csv", "nowhere"], "scene = 'nowhere' is not allowed"),
])
def test_bad_arguments_are_bad_input(args, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ok.csv").write_text("time,h\n0,2\n")
    code, out, err = run_check(capsys, *args)
    assert code == 2 and out == "" and message in err and err.count("\n") == 1


def test_the_console_script_exits_with_the_verdict(tmp_path):
    good = write_csv(tmp_path / "good.csv", ["time", "h"], [[0.0, 2.0], [0.1, 2.0 - 0.5 * 9.81 * 0.01]])
    bad = write_csv(tmp_path / "bad.csv", ["time", "h"], [[0.0, 2.0], [0.1, 2.0]])
    codes = [subprocess.run([BIN / "bouncingball", "check", path], capture_output=True, text=True,
                            timeout=60).returncode for path in (good, bad, tmp_path / "missing.csv")]
    assert codes == [0, 1, 2]


def test_the_run_starts_at_the_start_time_whether_or_not_the_result_holds_that_point(tmp_path, capsys):
    t = np.arange(1, 3001) * 1e-3  # no row at t = 0, as libcosim's observers record it
    h, _, impacts = exact_at(t)
    path = write_csv(tmp_path / "late.csv", ["time", "h", "impacts"],
                     [[repr(float(a)), repr(float(b)), int(c)] for a, b, c in zip(t, h, impacts, strict=True)])
    assert check_result(path).max_height_error == 0.0
    shifted = write_csv(tmp_path / "shifted.csv", ["time", "h", "impacts"],
                        [[repr(float(a) + 10.0), repr(float(b)), int(c)]
                         for a, b, c in zip(t, h, impacts, strict=True)])
    code, out, _ = run_check(capsys, shifted, "--start-time", "10")  # the same run, started at t = 10 s
    assert code == 0 and f"{impacts[-1]} at the end, exact {impacts[-1]}" in out
    assert check_result(shifted, start_time=10.0).max_height_error < 1e-12
    code, out, err = run_check(capsys, shifted, "--start-time", "10.5")
    assert code == 2 and "its first time, 10.001 s, is before the start time 10.5 s" in err
