"""`bouncingball bench --quick` writes complete, consistent results; errors are recomputed from the saved h values."""

import contextlib
import csv
import dataclasses
import io
import re
import subprocess
import sys

import numpy as np
import pytest

from bouncingball import Ball
from bouncingball.bench import c_floor, pages, runners
from bouncingball.bench.stability import Case, run_case
from bouncingball.bench.work_precision import CSV_FILE, H_FILE, QUICK, solvers
from bouncingball.cli import main
from bouncingball.scenes import BUILTIN_SCENES, load_scene
from bouncingball.solvers.exact import ExactSolution
from bouncingball.solvers.forcing import ForceTable
from bouncingball.solvers.result import IMPACT, output_grid

ARTICLE = load_scene("article")


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    said, told = io.StringIO(), io.StringIO()  # what the terminal would show (FMPy's logger prints with print())
    with contextlib.redirect_stdout(said), contextlib.redirect_stderr(told):
        assert main(["bench", "--quick", "--output-dir", str(out)]) == 0
    (out / "terminal.txt").write_text(said.getvalue() + told.getvalue(), encoding="utf-8")
    return out


@pytest.fixture(scope="module")
def rows(quick):
    with open(quick / CSV_FILE, newline="", encoding="utf-8") as file:
        return list(csv.DictReader(file))


@pytest.fixture(scope="module")
def markdown(quick):
    return (quick / "benchmarks.md").read_text(encoding="utf-8")


def expected_labels(section):
    return [solver.label for solver in solvers(section, QUICK)]


@pytest.mark.slow
def test_quick_ends_with_a_headline_and_keeps_the_fmu_warnings_out_of_the_terminal(quick, markdown):
    """Every goal of the report, met or not, in the terminal's last lines; the FMU's warnings counted in one line,
    their text in the report, none printed one by one."""
    terminal = (quick / "terminal.txt").read_text(encoding="utf-8")
    assert "[WARNING]" not in terminal and "past the promise" not in terminal
    goals = re.findall(r"^- \*\*\((\w+)\)\*\* (.*?): \*\*(met|not met)\*\*", markdown, re.MULTILINE)
    lines = terminal.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("headline (a quick run"))
    shown = [re.match(r"  \((\w+)\) (met    |NOT MET)  (.*)", line).groups() for line in lines[start + 1:]
             if line.startswith("  (")]
    assert len(goals) > 5 and [(tag, state.strip().lower(), goal) for tag, state, goal in shown] == \
        [(tag, state, goal) for tag, goal, state in goals]
    kept = re.findall(r"^- (.*past the promise.*)$", markdown.split("## Warnings the FMU logged")[-1], re.MULTILINE)
    counted = re.search(r"bench: the FMU runs logged (\d+) warning\(s\), (\d+) of them", terminal)
    assert (counted is None and "## Warnings the FMU logged" not in markdown) or \
        (counted is not None and int(counted[2]) == len(kept) > 0)


def test_writes_every_file(quick):
    for name in ("benchmarks.md", CSV_FILE, H_FILE, "work_precision.png", "floor.csv"):
        assert (quick / name).stat().st_size > 0, name
    assert (quick / "work_precision.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_the_quick_figure_says_it_is_quick(quick):
    """The figure of a real `bench --quick` run, redrawn from its CSV, is titled as quick; its points have
    QUICK's tolerances and repeats, from which the title is drawn."""
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    from bouncingball.bench import plots, tables

    points = tables.read_work_precision_csv(quick / CSV_FILE)
    assert {len(p.times) for p in points if p.times} == {QUICK.repeats}
    fig = plots.work_precision_figure(points)
    try:
        assert fig.get_suptitle().startswith("QUICK run (bouncingball bench --quick)")
    finally:
        plt.close(fig)


@pytest.mark.slow
def test_every_solver_in_every_section_of_the_csv(rows):
    for section in ("dense", "sparse"):
        found = [row["solver"] for row in rows if row["section"] == section]
        assert set(found) == set(expected_labels(section))
        for label in expected_labels(section):
            solver = next(s for s in solvers(section, QUICK) if s.label == label)
            assert found.count(label) == (len(QUICK.rtols) if solver.takes_tolerances else 1), label


@pytest.mark.parametrize("label", expected_labels("dense"))
@pytest.mark.slow
def test_every_solver_ran_and_was_timed(rows, label):
    if label == runners.C_FLOOR.label and c_floor.unavailable_reason():
        pytest.skip(c_floor.unavailable_reason())
    ok = [row for row in rows if row["solver"] == label and row["status"] == "ok"]
    assert ok, f"{label}: no run finished"
    for row in ok:
        times = [float(t) for t in row["times"].split(";")]
        assert len(times) == QUICK.repeats and all(t > 0.0 for t in times)
        assert float(row["median_time"]) == pytest.approx(float(np.median(times)))
        assert float(row["min_time"]) == min(times)


@pytest.mark.slow
def test_errors_recomputed_from_the_saved_h_values_match_csv_and_table(quick, rows, markdown):
    saved = np.load(quick / H_FILE)
    dense_md, sparse_md = markdown.split("### Sparse output grid")
    events = ExactSolution(ARTICLE.ball, ARTICLE.h0, ARTICLE.v0, 0.0, ARTICLE.t_end).events
    exact_counts = {"events": len(events), "impacts": sum(e.kind == IMPACT for e in events)}
    checked = set()
    for row in rows:
        if row["status"] != "ok" or not row["max_height_error"]:
            continue
        assert int(row["events_exact"]) == exact_counts[row["counted"]]
        if not row["h_key"]:
            continue
        t = output_grid(0.0, ARTICLE.t_end, float(row["output_interval"]))
        h = saved[row["h_key"]]
        h_exact, _ = ExactSolution(ARTICLE.ball, ARTICLE.h0, ARTICLE.v0, 0.0, ARTICLE.t_end).state(t)
        error = float(np.max(np.abs(h - h_exact)))
        assert error == pytest.approx(float(row["max_height_error"]), rel=1e-12, abs=1e-300)
        rtol = "default" if not row["rtol"] else f"{float(row['rtol']):.0e}"
        table = dense_md if row["section"] == "dense" else sparse_md
        assert f"| {row['solver']} | {rtol} | {error:.2e} |" in table
        checked.add((row["section"], row["solver"]))
    with_errors = {(row["section"], row["solver"]) for row in rows if row["max_height_error"]}
    assert checked == with_errors  # every solver that has an error has saved h values


@pytest.mark.slow
def test_cvode_is_accurate_where_it_claims(rows):
    """An independent check on the numbers: CVODE at rtol 1e-12 is within 1e-9 m of the exact solution."""
    row = next(r for r in rows if r["solver"] == runners.CVODE_AUTO.label and r["section"] == "dense"
               and r["rtol"] and float(r["rtol"]) == 1e-12)
    assert float(row["max_height_error"]) < 1e-9
    assert row["events_found"] == row["events_exact"]


@pytest.mark.slow
def test_markdown_states_machine_versions_and_every_target(markdown):
    for word in ("cores", "Python 3", "numpy", "scikit-sundae", "scipy", "FMPy", "pythonfmu", "date:"):
        assert word in markdown, word
    for tag, count in (("a", 2), ("b", 1), ("c", 1), ("d", 1), ("e", 1), ("f", 2), ("g", 1), ("h", 1), ("i", 2)):
        lines = re.findall(rf"^- \*\*\({tag}\)\*\* .*: \*\*(?:met|not met)\*\*\. \S.*$", markdown, re.M)
        assert len(lines) == count, tag


@pytest.mark.slow
def test_a_run_over_the_cap_is_killed_and_a_failure_is_reported(tmp_path):
    stiff_rest = load_scene("stiff-rest")
    short = dataclasses.replace(ARTICLE, t_end=1.0)
    finished = run_case(Case(short, runners.CVODE_AUTO), cap=30.0)
    timed_out = run_case(Case(stiff_rest, runners.scipy("RK45")), cap=0.3)
    failed = run_case(Case(short, runners.fmu(1e-3)), cap=30.0)  # no FMU built
    assert finished.status == "finished" and finished.errors.events_match and finished.errors.events_exact == 2
    assert finished.errors.max_height_error < 1e-6
    assert timed_out.status == "timed out"
    assert failed.status == "failed" and "could not be built" in failed.note
    path = pages.write_stability_md([short, stiff_rest], [finished, timed_out, failed], 0.3, True, {},
                                    tmp_path / "stability.md")
    text = path.read_text(encoding="utf-8")
    assert "| ok 2/2 |" in text and "timed out" in text and "failed" in text


def test_the_bench_package_imports_nothing_heavy():
    code = ("import sys, bouncingball.bench.studies\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('scipy', 'matplotlib', 'fmpy', 'pythonfmu', 'tqdm')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.slow
def test_fmu_steps_table_has_every_case_and_the_first_uses(markdown):
    section = markdown.split("### Per doStep, call by call")[1].split("## Stiff scenes")[0]
    for slave in ("empty pythonfmu slave", r"FMU, default engine \(auto\)", "FMU, engine sksundae",
                  "FMU, engine compiled"):
        for state in ("no", "yes"):
            assert re.search(rf"^\| {slave} \| {state} \| \d+\.\d \| \d+\.\d \| \d+\.\d\d \|  \|$", section, re.M), (
                slave, state, [line for line in section.splitlines() if "failed" in line],  # a child's failure first
                section)  # the mean and the median doStep, the mean against the empty slave's
    for slave in ("empty pythonfmu3 slave", r"FMI 3.0 FMU, default engine \(auto\)",
                  r"FMI 3.0 FMU, default engine \(auto\), early return"):
        assert re.search(rf"^\| {slave} \| no \| \d+\.\d \| \d+\.\d \| \d+\.\d\d \|  \|$", section, re.M), slave
    for engine in ("sksundae", "compiled"):
        for cache in ("cold", "warm"):
            assert re.search(rf"^\| {engine} \| {cache} \| \d+\.\d\d \|  \|$", section, re.M), (engine, cache)
    assert re.search(r"^Engine compiled(?: pays back its longer first use after [\d,]+ doSteps| did not make|'s first "
                     r"use is no longer than sksundae's here)", section, re.M)


@pytest.mark.slow
def test_the_engine_choice_rows_measure_both_engines_first_use():
    """bench/engine_choice.py: fresh processes; the compiled engine hot is the faster, its loading the dearer."""
    pytest.importorskip("numba")
    from bouncingball.bench import engine_choice

    measured = engine_choice.measure(repeats=1)
    compiled, sksundae = measured["compiled"], measured["sksundae"]
    assert compiled.steps == sksundae.steps > 1000
    assert compiled.hot < sksundae.hot and compiled.load > 0.05 and sksundae.load > 0.05
    rows = engine_choice.break_even_rows(measured)
    assert [row[0] for row in rows][-1] == "break-even once scikit-sundae is loaded [steps]"
    saving = (sksundae.hot - compiled.hot) / compiled.steps
    assert float(rows[-1][1]) == pytest.approx(compiled.load / saving, rel=1e-3)


# --- the C floor: the compiled engine's CVODE work in C ----------------------------------------------
def _floor_or_skip():
    reason = c_floor.unavailable_reason()
    if reason:
        pytest.skip(reason)


@pytest.mark.filterwarnings("ignore::bouncingball.AccuracyWarning")  # rtol 1e-6 is off the promise, knowingly
@pytest.mark.parametrize(("rtol", "method"), [(None, "auto"), (10.0**-9, "BDF"), (10.0**-6, "auto")])
def test_the_c_floor_does_the_compiled_engines_work(rtol, method):
    """The compiled engine's events to the bit, its steps and RHS calls; on the grid, its heights and the exact ones.

    rtol 1e-9 with BDF: with the C library's hypot, 1 ulp off Python's, a contact's scale moved and an event
    speed came out 1e-14 m/s off.
    """
    _floor_or_skip()
    atol = None if rtol is None else 1e-3 * rtol
    tolerances = {} if rtol is None else {"rtol": rtol, "atol": atol}
    ours = ARTICLE.simulate("cvode", engine="compiled", method=method, **tolerances)
    floor = c_floor.run(ARTICLE.ball, ARTICLE.h0, ARTICLE.v0, ARTICLE.t_end, ARTICLE.output_interval, ARTICLE.F_ext,
                        rtol, atol, method)
    assert floor.events == ours.events  # times, kinds and speeds, bit for bit
    assert (floor.steps, floor.rhs_calls) == (ours.stats.steps, ours.stats.rhs_calls)
    np.testing.assert_array_equal(floor.t, ours.t)
    # the same step ends; numpy's vectorised exp, sin and cos may round the flows differently from C's (7e-18 m)
    np.testing.assert_allclose(floor.h, ours.h, rtol=0.0, atol=1e-15)
    np.testing.assert_allclose(floor.v, ours.v, rtol=0.0, atol=1e-13)
    exact = ExactSolution(ARTICLE.ball, ARTICLE.h0, ARTICLE.v0, 0.0, ARTICLE.t_end)
    assert [e.kind for e in floor.events] == [e.kind for e in exact.events]
    if rtol is None:
        assert np.max(np.abs(floor.h - exact.state(floor.t)[0])) < 1e-9


@pytest.mark.parametrize("name", BUILTIN_SCENES)
def test_on_every_builtin_scene_the_c_floor_does_the_same_work_or_refuses(name):
    """Never a different answer: the compiled engine's events and steps, or a refusal naming the path it lacks."""
    _floor_or_skip()
    scene = load_scene(name)
    if isinstance(scene.F_ext, ForceTable):
        pytest.skip("a force table: the C floor takes a constant force")
    t_end = min(scene.t_end, 20.0)
    ours = scene.simulate("cvode", engine="compiled", t_end=t_end)
    try:
        floor = c_floor.run(scene.ball, scene.h0, scene.v0, t_end, min(scene.output_interval, t_end), scene.F_ext)
    except RuntimeError as error:
        assert "not the article's path" in str(error)
        return
    assert floor.events == ours.events
    assert (floor.steps, floor.rhs_calls) == (ours.stats.steps, ours.stats.rhs_calls)
    np.testing.assert_allclose(floor.h, ours.h, rtol=0.0, atol=1e-15 * max(1.0, scene.h0))


def test_the_c_floor_refuses_what_it_does_not_implement(monkeypatch):
    _floor_or_skip()
    with pytest.raises(RuntimeError, match="not the article's path"):  # an over-damped contact's rest
        c_floor.run(Ball(b=1e3), 2.0, 0.0, 8.0, 1e-3)
    with pytest.raises(ValueError, match="constant force"):
        c_floor.run(Ball(), 2.0, 0.0, 1.0, 1e-3, F_ext=ForceTable((0.0, 0.5), (0.0, 1.0)))
    monkeypatch.setenv("CC", "no-such-compiler-here")
    with pytest.raises(c_floor.FloorUnavailable, match="no C compiler"):
        c_floor.compiler()


def test_the_c_floors_callback_types_are_the_ones_scikit_sundae_declares():
    """The prototypes come from compiled.FUNCTIONS (checked in test_compiled); the callbacks are declared here."""
    from test_compiled import _c_type, _pxd_declarations

    declarations, typedefs = _pxd_declarations()
    for name, (restype, argtypes) in c_floor.CALLBACKS.items():
        declared_restype, declared_args = declarations[name]
        assert ([_c_type(t, typedefs) for t in (restype, *argtypes)]
                == [_c_type(t, typedefs) for t in (declared_restype, *declared_args)]), name
    assert typedefs["sunindextype"] == c_floor._BASIC["sunindextype"]


@pytest.mark.slow
def test_the_floor_section_says_the_work_was_the_same(markdown):
    if c_floor.unavailable_reason():
        pytest.skip(c_floor.unavailable_reason())
    section = markdown.split("## The C floor, and DOP853 at matched errors")[1].split("## FMU overhead")[0]
    assert "Event times bit-identical: yes; steps and RHS calls equal: yes." in section
    assert "no `gc.collect()` before a timed call; min and median" in section


def test_the_first_use_page_gives_each_case_its_min_and_median_and_what_was_said(tmp_path):
    from bouncingball.bench import first_use

    study = first_use.Study(22.4, 2_100_000, 154, 17.6, 2_440_000, (3_600_000, 1_500_000), [
        first_use.Case("simulate", [0.7, 0.6, 0.9], [0.5, 0.4, 0.8], ""),
        first_use.Case("the FMU", [1.0, 1.2, 1.1], [0.6, 0.7, 0.65], "bouncingball: numba compiles")])
    text = first_use.write_page(study, tmp_path / "first_use.md").read_text(encoding="utf-8")
    assert "built in 22 s" in text and "2.1 MB with 154 numba cache files" in text
    assert "took 18 s" in text and "the FMU is 2.4 MB, its compiled engine 3.6 MB (1.5 MB compressed)" in text
    assert "| simulate | 0.60 | 0.70 | 0.40 | 0.50 | nothing |" in text
    assert "| the FMU | 1.00 | 1.10 | 0.60 | 0.65 | bouncingball: numba compiles |" in text


def test_bench_takes_one_study_at_a_time(capsys):
    with pytest.raises(SystemExit) as raised:
        main(["bench", "--stability", "--first-use"])
    assert raised.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


@pytest.mark.slow  # a quick run of the study: a few dozen runs of 8 s of bouncing
def test_the_hunt_crossley_study_matches_both_solvers_to_the_target_against_its_reference(tmp_path):
    assert main(["bench", "--hunt-crossley", "--quick", "--output-dir", str(tmp_path)]) == 0
    page = (tmp_path / "hunt_crossley.md").read_text(encoding="utf-8")
    assert "a QUICK run" in page and "REFERENCE_RTOL" not in page
    rows = {cells[0]: cells for cells in ([c.strip() for c in line.strip("|").split("|")]
                                          for line in page.splitlines() if line.startswith("|"))}
    for label in ("CVODE auto (compiled)", "solve_ivp DOP853"):
        _, rtol, error, events, *_ = rows[label]
        assert float(error) <= 1e-6 and events == "38/38", rows[label]
    reference = re.search(r"DOP853 at rtol 2.3e-14 is within (\S+) m of it on the grid", page)
    assert reference and float(reference.group(1)) < 1e-8


def test_the_fmu_warnings_are_one_line_on_the_terminal_and_their_text_in_the_report(tmp_path, capsys, monkeypatch):
    from bouncingball.bench import _report_fmu_warnings

    kept = ["by t = 0.6 s the run's error estimate is 0.002 m, 0.001 of its height scale 2 m: past the promise of "
            "1e-06 from t = 0 s on; rtol = 0.0001 is looser than the default 1e-12, which the promise is made at: "
            "tighten rtol to 1e-12 or below"] * 3 + ["SUNDIALS something else"]
    monkeypatch.setattr(runners, "FMU_WARNINGS", kept)
    report = tmp_path / "benchmarks.md"
    report.write_text("# Benchmarks\n", encoding="utf-8")
    _report_fmu_warnings(report)
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.splitlines() == [
        f"bench: the FMU runs logged 4 warning(s), 3 of them the accuracy warning of an rtol loosened on purpose "
        f"(expected); their text at the end of {report}", "bench: warning: SUNDIALS something else"]
    text = report.read_text(encoding="utf-8")
    assert text.startswith("# Benchmarks\n\n## Warnings the FMU logged\n") and text.count("\n- ") == 4


def test_bench_ends_with_the_headline_of_its_goals(tmp_path, capsys, monkeypatch):
    from bouncingball import bench
    from bouncingball.bench import studies
    from bouncingball.bench.targets import Target

    goals = [Target("a", "CVODE beats its peers at 1e-6 m", True, "1.0x"),
             Target("b", "the FMU within 1e-6", False, "")]
    report = tmp_path / "benchmarks.md"
    report.write_text("# Benchmarks\n", encoding="utf-8")
    monkeypatch.setattr(studies, "run_benchmark", lambda output_dir, quick: ([report], goals))
    monkeypatch.setattr(runners, "FMU_WARNINGS", [])
    assert bench.bench_command(tmp_path, quick=True) == 0
    assert capsys.readouterr().out.splitlines()[-3:] == [
        f"headline (a quick run: few tolerances and repeats); the numbers in {report}:",
        "  (a) met      CVODE beats its peers at 1e-6 m", "  (b) NOT MET  the FMU within 1e-6"]
