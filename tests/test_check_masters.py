"""`bouncingball check` on masters' files as they write them, built here from the exact solution.

Each writer below formats a run of bouncingball.simulate(..., solver="exact") the way that master
writes its CSV (FMPy, OMSimulator, libcosim's file observer, ecos); a right run must pass, a
wrong one (h off by 1 mm at one point, or a wrong parameter) must fail, and what check says about
the file (its instance, its parameters, its printed resolution, the hops merged into the contact,
the first row) is measured against the exact solution too.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.check.judge import check_result
from bouncingball.cli import EXIT_BAD_INPUT, EXIT_CHECK_FAILED, main
from bouncingball.physics import Ball
from bouncingball.solvers.cvode import merged_hop_limit
from bouncingball.solvers.exact import ExactSolution
from bouncingball.solvers.result import IMPACT

ARTICLE = Ball()
MOON = Ball(g=1.62)
TINY = Ball(m=1e-6, k=1e9, R=0.1)  # hops down to 1.6e-14 m before it rests at 2.53 s
OUTPUTS = ("h", "v", "a", "contact_force")
PARAMETERS = ("m", "k", "b", "R", "g")


def exact_run(ball: Ball = ARTICLE, h0: float = 2.0, t_end: float = 8.0, dt: float = 0.01,
              merged: int = 0) -> dict[str, np.ndarray]:
    """The FMU's outputs of an exact run; the impacts column lacks the last `merged` impacts."""
    result = bb.simulate(ball, h0, 0.0, t_end, dt, solver="exact")
    impact_times = np.array([e.time for e in result.events if e.kind == IMPACT])
    kept = impact_times[:len(impact_times) - merged]
    contact = result.h < ball.R
    force = np.where(contact, -ball.k * (result.h - ball.R) - ball.b * result.v, 0.0)
    return {"time": result.t, "h": result.h, "v": result.v, "a": force / ball.m - ball.g, "contact_force": force,
            "impacts": np.searchsorted(kept, result.t, side="right"), "contact": contact}


def shifted(run: dict[str, np.ndarray], index: int, dh: float = 1e-3) -> dict[str, np.ndarray]:
    """The run with h off by dh at one point."""
    h = run["h"].copy()
    h[index] += dh
    return {**run, "h": h}


def write_fmpy(path: Path, run) -> Path:
    """FMPy's write_csv: quoted names, then each value as str() writes it (shortest round trip)."""
    names = ("time", *OUTPUTS, "impacts", "contact")
    lines = [",".join(f'"{name}"' for name in names)]
    for i in range(len(run["time"])):
        lines.append(",".join(str(np.float64(run[n][i])) if n not in ("impacts", "contact") else str(run[n][i])
                              for n in names))
    path.write_text("\n".join(lines) + "\n")
    return path


def write_omsimulator(path: Path, runs: dict[str, dict]) -> Path:
    """OMSimulator: "sep=,", quoted names model.root.<instance>.<variable>, %.12g, each point twice, the last thrice."""
    names = ("h", "v", "a", "contact_force", "impacts")
    header = ['"time"'] + [f'"model.root.{instance}.{n}"' for instance in runs for n in names]
    time = next(iter(runs.values()))["time"]
    rows = []
    for i, t in enumerate(time):
        row = ", ".join([f"{t:.12g}"] + [f"{run[n][i]:.12g}" for run in runs.values() for n in names])
        rows += [row] * (3 if i == len(time) - 1 else 2)
    path.write_text('"sep=,"\n' + ",".join(header) + "\n" + "\n".join(rows) + "\n")
    return path


def write_libcosim(path: Path, run, ball: Ball, rtol: float = 1e-12) -> Path:
    """libcosim's file observer: Time,StepCount, then every variable as name [index type causality], 6 digits.

    Every line ends in a comma; the observer records after each step, so the file starts at the first step.
    """
    reals = [(n, "parameter", getattr(ball, n)) for n in PARAMETERS] + [(n, "output", None) for n in OUTPUTS] + \
        [("F_ext", "input", 0.0), ("rtol", "parameter", rtol), ("atol", "parameter", 0.0)]
    header = "Time,StepCount," + "".join(f"{n} [{i} real {c}]," for i, (n, c, _) in enumerate(reals)) + \
        "impacts [12 integer output],contact [13 boolean output],method [14 string parameter]," \
        "engine [15 string parameter],"
    lines = [header]
    for i in range(1, len(run["time"])):
        values = [f"{run['time'][i]:g}", str(i)] + [f"{run[n][i] if v is None else v:g}" for n, _, v in reals] + \
            [str(run["impacts"][i]), str(int(run["contact"][i])), "auto", "sksundae"]
        lines.append(",".join(values) + ",")
    path.write_text("\n".join(lines) + "\n")
    return path


def write_ecos(path: Path, runs: dict[str, tuple[dict, Ball]]) -> Path:
    """ecos's csv_writer: iterations, time, then <instance>::<variable>[TYPE] for every variable, 6 decimals."""
    header = ["iterations", "time"]
    for instance in runs:
        header += [f"{instance}::{n}[REAL]" for n in (*PARAMETERS, *OUTPUTS, "F_ext", "rtol", "atol")]
        header += [f"{instance}::impacts[INT]", f"{instance}::contact[BOOL]", f"{instance}::method[STR]"]
    time = next(iter(runs.values()))[0]["time"]
    lines = [", ".join(header)]
    for i, t in enumerate(time):
        values = [str(i), f"{t:g}"]  # ecos prints its time as it comes (0.01), its variables to 6 decimals
        for run, ball in runs.values():
            values += [f"{getattr(ball, n):.6f}" for n in PARAMETERS] + [f"{run[n][i]:.6f}" for n in OUTPUTS]
            values += [f"{0.0:.6f}", f"{1e-12:.6f}", f"{0.0:.6f}", str(run["impacts"][i]), str(int(run["contact"][i])),
                       "auto"]
        lines.append(", ".join(values))
    path.write_text("\n".join(lines) + "\n")
    return path


def check(capsys, *args) -> tuple[int, str, str]:
    code = main(["check", *map(str, args)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def exact_error(path: Path, run, ball: Ball, h0: float = 2.0, **options) -> float:
    """max |h - h_exact| of the file, the exact solution evaluated here."""
    outcome = check_result(path, "article", {**{n: getattr(ball, n) for n in PARAMETERS}, "h": h0}, **options)
    return outcome.max_height_error


@pytest.fixture(scope="module")
def article():
    return exact_run()


@pytest.fixture(scope="module")
def moon():
    return exact_run(MOON, h0=1.0)


# --- FMPy: full precision -------------------------------------------------------------------------
def test_fmpy_a_right_run_passes_and_a_wrong_one_fails(article, moon, tmp_path, capsys):
    code, out, err = check(capsys, write_fmpy(tmp_path / "right.csv", article))
    assert code == 0, out + err
    assert "max |h - h_exact|  0.000e+00 m" in out and "printed" not in out  # full precision: nothing allowed
    code, out, _ = check(capsys, write_fmpy(tmp_path / "wrong.csv", shifted(article, 300)))
    assert code == EXIT_CHECK_FAILED and "max |h - h_exact| = 1.000e-03 m at t = 3.0 s" in out
    code, out, _ = check(capsys, write_fmpy(tmp_path / "moon.csv", moon), "--start-value", "h=1")  # g = 9.81: wrong
    assert code == EXIT_CHECK_FAILED
    assert "a = -1.62 m/s2 where the scene's ball has -9.81 m/s2 there (--start-value g=1.62 would match it)" in out


def test_a_run_started_elsewhere_fails_naming_the_start_value_that_matches_the_file(moon, tmp_path, capsys):
    path = write_fmpy(tmp_path / "moon.csv", moon)
    code, out, _ = check(capsys, path)
    assert code == EXIT_CHECK_FAILED
    assert "FAIL: the first row is not the scene's start: h = 1.0 m where the scene starts at 2.0 m " \
           "(--start-value h=1.0 would match it); a = -1.62 m/s2" in out
    code, out, err = check(capsys, path, "--start-value", "h=1.0", "--start-value", "g=1.62")
    assert code == 0, out + err
    assert check_result(path, "article", {"h": 1.0, "g": 1.62}).first_row == ()


# --- OMSimulator: 12 significant digits, each point twice, instances as model.root.<instance>. ------
def test_omsimulator_one_instance(article, tmp_path, capsys):
    path = write_omsimulator(tmp_path / "right.csv", {"ball": article})
    code, out, err = check(capsys, path)
    assert code == 0, out + err
    outcome = check_result(path)
    assert outcome.points == 2 * len(article["time"]) + 1 and outcome.instance == "model.root.ball"
    assert outcome.printing == "12 significant digits"
    assert 0.0 < outcome.max_height_error <= 5e-12  # h < 2.1 m to 12 digits
    code, out, _ = check(capsys, write_omsimulator(tmp_path / "wrong.csv", {"ball": shifted(article, 300)}))
    assert code == EXIT_CHECK_FAILED and "at t = 3.0 s (1.000e-03 m" in out


def test_omsimulator_two_instances_need_instance(article, moon, tmp_path, capsys):
    path = write_omsimulator(tmp_path / "system.csv", {"ball": article, "moon": moon})
    code, out, err = check(capsys, path)
    assert code == EXIT_BAD_INPUT and out == ""
    assert err == f"bouncingball: error: {path}: the file holds several instances of the ball (model.root.ball, " \
                  "model.root.moon): pick one with --instance NAME\n"
    code, out, err = check(capsys, path, "--instance", "moon", "--start-value", "g=1.62", "--start-value", "h=1")
    assert code == 0, out + err
    assert "instance           model.root.moon" in out
    code, out, err = check(capsys, path, "--instance", "model.root.ball")
    assert code == 0, out + err
    code, out, _ = check(capsys, path, "--instance", "moon")  # the Moon's ball checked as the article's
    assert code == EXIT_CHECK_FAILED
    code, _, err = check(capsys, path, "--instance", "mars")
    assert code == EXIT_BAD_INPUT and "--instance 'mars' is none of the file's instances of the ball " \
                                      "(model.root.ball, model.root.moon)" in err


# --- libcosim: every variable, 6 significant digits, from the first step ------------------------
def test_libcosim_a_right_run_passes_within_its_printed_resolution(article, tmp_path, capsys):
    path = write_libcosim(tmp_path / "right.csv", article, ARTICLE)
    error = exact_error(path, article, ARTICLE)
    assert 1e-6 < error <= 5e-6  # 6 digits of h ~ 2 m: the tolerance is finer than the file
    code, out, err = check(capsys, path)
    assert code == 0, out + err
    assert "file's parameters  m, k, b, R, g, F_ext, rtol, atol: as the scene and the FMU's defaults have them" in out
    assert "printed            6 significant digits" in out
    assert f"PASS: max |h - h_exact| = {error:.3e} m is within the tolerance 1e-06 m plus the file's printed " \
           "resolution (6 significant digits)" in out
    code, out, _ = check(capsys, write_libcosim(tmp_path / "wrong.csv", shifted(article, 300), ARTICLE))
    assert code == EXIT_CHECK_FAILED and "exceeds the tolerance 1e-06 m plus the file's printed resolution " \
                                         "(6 significant digits) at 1 of 800 points, most at t = 3.0 s" in out


def test_libcosim_parameters_come_from_the_file(moon, tmp_path, capsys):
    right = write_libcosim(tmp_path / "moon.csv", moon, MOON)
    code, out, err = check(capsys, right, "--start-value", "h=1")  # g = 1.62 from its column
    assert code == 0, out + err
    assert "file's parameters  m, k, b, R, g, F_ext, rtol, atol: g = 1.62 (the scene has 9.81) taken from it" in out
    assert "g = 1.62 m/s2" in out
    wrong = write_libcosim(tmp_path / "wrong.csv", moon, ARTICLE)  # says g = 9.81, ran on the Moon
    code, out, _ = check(capsys, wrong, "--start-value", "h=1")
    assert code == EXIT_CHECK_FAILED


def test_a_start_value_contradicting_a_parameter_column_is_bad_input(moon, tmp_path, capsys):
    path = write_libcosim(tmp_path / "moon.csv", moon, MOON)
    code, out, err = check(capsys, path, "--start-value", "h=1", "--start-value", "g=1.6201")
    assert code == EXIT_BAD_INPUT and out == ""
    assert err == f"bouncingball: error: {path}: row 2, column 'g [4 real parameter]': g = 1.62 contradicts the " \
                  "start value g = 1.6201 (beyond its printed resolution, 5e-06)\n"
    code, out, err = check(capsys, path, "--start-value", "h=1", "--start-value", "g=1.620004")  # within 5e-6
    assert code == EXIT_CHECK_FAILED, out + err  # taken, and the heights show the run had g = 1.62
    assert check_result(path, "article", {"h": 1, "g": "1.620004"}).scene.ball.g == 1.620004


# --- ecos: iterations, time, <instance>::<variable>[TYPE], 6 decimals ----------------------------------
def test_ecos_a_right_run_passes_and_a_wrong_one_fails(article, moon, tmp_path, capsys):
    path = write_ecos(tmp_path / "right.csv", {"ball": (article, ARTICLE), "moon": (moon, MOON)})
    assert path.read_text().startswith("iterations, time, ball::m[REAL], ball::k[REAL]")
    code, out, err = check(capsys, path, "--instance", "ball")
    assert code == 0, out + err
    assert "printed            6 decimals" in out
    # rtol 1e-12 printed 0.000000, which the FMU would refuse: it changes nothing in the exact solution
    assert "rtol printed as 0.0 (refused by the FMU), read as the FMU's default 1e-12, within its printed " \
           "resolution 5e-07" in out
    assert 0.0 < exact_error(path, article, ARTICLE, instance="ball") <= 5e-7 * (1 + 1e-6)
    code, out, err = check(capsys, path, "--instance", "moon", "--start-value", "h=1")
    assert code == 0 and "g = 1.62 m/s2" in out, out + err
    wrong = write_ecos(tmp_path / "wrong.csv", {"ball": (shifted(article, 300), ARTICLE)})
    code, out, _ = check(capsys, wrong)
    assert code == EXIT_CHECK_FAILED and "most at t = 3.0 s (1.000e-03 m" in out
    wrong_g = write_ecos(tmp_path / "wrong_g.csv", {"moon": (moon, ARTICLE)})  # says g = 9.81, ran on the Moon
    code, out, _ = check(capsys, wrong_g, "--start-value", "h=1")
    assert code == EXIT_CHECK_FAILED
    assert "a = -1.62 m/s2 where the scene's ball has -9.81 m/s2 there (the file's own parameter columns do not give " \
           "the run it holds)" in out


LIGHT = Ball(m=4e-7, k=4e-3, b=4e-6)  # the article's ball scaled by 4e-7 kg: the same motion; m prints 0.000000


def test_ecos_a_physical_parameter_printed_as_a_refused_value_needs_its_start_value(article, tmp_path, capsys):
    """m = 4e-7 kg printed 0.000000: too few digits to tell it from m = 0, refused even where the scene agrees."""
    path = write_ecos(tmp_path / "light.csv", {"ball": (article, LIGHT)})
    assert ", 0.000000, 0.004000, 0.000004, " in path.read_text().splitlines()[1]
    code, _, err = check(capsys, path)  # the article's m = 1 kg contradicts the printed 0.0
    assert code == EXIT_BAD_INPUT and "--start-value m=VALUE" in err, err
    scene = tmp_path / "light.toml"
    scene.write_text("m = 4e-7\nk = 4e-3\nb = 4e-6\n")
    code, _, err = check(capsys, path, scene)  # the scene's 4e-7 is within the printed resolution: still unknown
    assert code == EXIT_BAD_INPUT
    assert "m is printed as 0.0, which the FMU refuses, to a resolution of 5e-07: too few digits to tell the value " \
           "the master set; give it with --start-value m=VALUE" in err
    code, out, err = check(capsys, path, scene, "--start-value", "m=4e-7")
    assert code == 0, out + err


# --- strict where it must be, lenient where masters differ ------------------------------------------
def test_names_are_read_whatever_their_case_and_repeated_times_are_checked_each(article, tmp_path, capsys):
    rows = [f"{float(t)!r},{float(h)!r},{n},{int(h > 1)}"
            for t, h, n in zip(article["time"], article["h"], article["impacts"], strict=True)]
    rows.insert(301, rows[300])  # t = 3 s twice
    path = tmp_path / "upper.csv"
    path.write_text("TIME,H,Impacts,StepCount\n" + "\n".join(rows) + "\n")
    code, out, err = check(capsys, path)
    assert code == 0 and "points compared    802" in out, out + err
    wrong = rows[:302] + [rows[301].replace(rows[301].split(",")[1], "2.5")] + rows[302:]  # a repeat that disagrees
    path.write_text("TIME,H,Impacts,StepCount\n" + "\n".join(wrong) + "\n")
    code, out, _ = check(capsys, path)
    assert code == EXIT_CHECK_FAILED and "at t = 3.0 s" in out


# --- hops too small to matter: one rule ----------------------------------------------------------------
def tiny_hops() -> np.ndarray:
    exact = ExactSolution(TINY, 2.0, 0.0, 0.0, 3.0)
    from bouncingball.accuracy import event_hops

    return np.array([hop for e, hop in zip(exact.events, event_hops(exact), strict=True) if e.kind == IMPACT])


def test_a_count_lacking_the_impacts_of_hops_below_the_tolerance_passes_and_says_so(tmp_path, capsys):
    hops = tiny_hops()
    assert len(hops) == 32 and 1e-14 < hops[-5:].min() and hops[-5:].max() < 1e-11
    path = write_fmpy(tmp_path / "merged.csv", exact_run(TINY, t_end=3.0, dt=1e-3, merged=5))
    code, out, err = check(capsys, path, "--start-value", "m=1e-6", "--start-value", "k=1e9", "--start-value", "R=0.1")
    assert code == 0, out + err
    limit = merged_hop_limit(TINY)
    assert f"27 at the end, exact 32; the count is right at every point; 5 hops merged into the contact: 0 no higher " \
           f"than the FMU's hop resolution {limit:.3g} m, 5 no higher than the tolerance 1e-06 m" in out
    assert "impacts counted right; 5 hops merged into the contact" in out


def test_each_class_of_merged_hop_is_counted_and_no_other_impact_may_be_missing(tmp_path):
    hops = tiny_hops()
    values = {"m": 1e-6, "k": 1e9, "R": 0.1, "rtol": 0.1}
    limit = merged_hop_limit(TINY, 0.1)
    assert np.count_nonzero(hops <= limit) == 2 and np.count_nonzero((hops > limit) & (hops <= 1e-11)) == 4
    path = write_fmpy(tmp_path / "six.csv", exact_run(TINY, t_end=3.0, dt=1e-3, merged=6))
    merged = check_result(path, "article", values, tolerance=1e-11).merged_hops
    assert (merged.by_solver, merged.by_tolerance, merged.solver_limit) == (2, 4, limit)
    path = write_fmpy(tmp_path / "seven.csv", exact_run(TINY, t_end=3.0, dt=1e-3, merged=7))  # a 2.2e-11 m hop too
    outcome = check_result(path, "article", values, tolerance=1e-11)
    assert not outcome.passed and outcome.impact_mismatches[-1][1:] == (25, 32)


def test_a_merged_hop_is_not_a_licence_to_miss_or_add_another_impact(tmp_path):
    run = exact_run(TINY, t_end=3.0, dt=1e-3, merged=5)
    values = {"m": 1e-6, "k": 1e9, "R": 0.1}
    late = run["impacts"].copy()
    first = int(np.argmax(late == 1))
    late[first] = 0  # the first impact, 2 m down, counted a point late
    outcome = check_result(write_fmpy(tmp_path / "late.csv", {**run, "impacts": late}), "article", values)
    assert [t for t, _, _ in outcome.impact_mismatches] == [run["time"][first]]
    extra = run["impacts"] + (run["time"] >= 2.9)  # one more at the end, making up for a merged one
    outcome = check_result(write_fmpy(tmp_path / "extra.csv", {**run, "impacts": extra}), "article", values)
    assert len(outcome.impact_mismatches) == np.count_nonzero(run["time"] >= 2.9)
