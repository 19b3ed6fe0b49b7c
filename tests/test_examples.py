"""examples/: each one run as a user runs it (a subprocess, in a temporary directory), its printed numbers checked."""

from __future__ import annotations

import contextlib
import math
import os
import re
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bouncingball.oscillator import oscillator_basis
from bouncingball.physics import Ball
from bouncingball.solvers.exact import ExactSolution
from fmu_helpers import assert_fmu_page_quotes, exact_at
from oracle_counts import oracle_counts

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
BIN = Path(sys.executable).parent
NUMBER = r"[-+]?\d+(?:\.\d*)?(?:e[-+]?\d+)?"


def run_example(args, cwd: Path, timeout: float = 300, never_says: tuple[str, ...] = (), **env) -> str:
    """Run an example in a subprocess with cwd; its stdout, after asserting that it succeeded (and that its
    stderr says none of never_says)."""
    environment = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}", "MPLBACKEND": "Agg",
                   "PYTHONDONTWRITEBYTECODE": "1", **env}  # no __pycache__ left in examples/
    completed = subprocess.run([str(arg) for arg in args], cwd=cwd, capture_output=True, text=True,
                               timeout=timeout, env=environment, check=False)
    assert completed.returncode == 0, completed.stdout[-3000:] + completed.stderr[-3000:]
    assert not [said for said in never_says if said in completed.stderr], completed.stderr[-3000:]
    return completed.stdout


def test_every_example_says_what_it_shows_and_what_it_needs():
    for path in sorted(EXAMPLES.rglob("*")):
        if path.suffix in (".py", ".sh"):
            head = path.read_text().splitlines()[:8]
            assert any("Needs:" in line for line in head), path
            assert len(path.read_text().splitlines()) <= 100, path


@pytest.mark.slow
def test_api_tour(tmp_path):
    pytest.importorskip("scipy")
    pytest.importorskip("matplotlib")
    out = run_example([sys.executable, EXAMPLES / "api_tour.py", tmp_path / "out"], tmp_path)
    exact = ExactSolution(Ball(), 2.0, 0.0, 0.0, 8.0)
    h_end, _ = exact.state(8.0)
    rows = {m[0]: [float(x) for x in m[1:]] for m in re.findall(
        rf"^(exact|cvode|scipy) +({NUMBER}) +({NUMBER}) +(\d+) +(\d+) +({NUMBER})$", out, re.M)}
    assert set(rows) == {"exact", "cvode", "scipy"}, out
    impacts = sum(event.kind == "impact" for event in exact.events)
    truth = oracle_counts(Ball())
    for name, (height_error, event_error, events, found_impacts, final_h) in rows.items():
        assert abs(final_h - h_end[0]) <= height_error + 1e-15, name  # the final point is one of those compared
        bound = 1e-2 if name == "scipy" else 1e-6  # the article's RK45 is ~3e-3 m off; CVODE within 1e-6 m
        assert height_error <= bound and event_error <= bound, name
        assert (events, found_impacts) == (len(exact.events), impacts) == (truth.events, truth.impacts), name
    assert rows["exact"][:2] == [0.0, 0.0] and rows["scipy"][0] > 1e-4  # SciPy is measurably off at its defaults
    printed = re.findall(rf"t = ({NUMBER}) s  (impact|departure) +v = ({NUMBER}) m/s", out)
    assert len(printed) == 4
    for (time, kind, velocity), event in zip(printed, exact.events, strict=False):
        assert (kind, float(time), float(velocity)) == (event.kind, pytest.approx(event.time, abs=1e-14),
                                                        pytest.approx(event.velocity, abs=1e-11))
    assert (tmp_path / "out" / "api_tour.png").stat().st_size > 10_000
    assert list(tmp_path.iterdir()) == [tmp_path / "out"]  # nothing written anywhere else


@pytest.mark.slow
def test_api_tour_figure_has_a_title_every_solver_on_top_and_one_colour_per_solver(tmp_path, monkeypatch):
    """The figure itself (run in this process to read it): titled, the three solvers in the top panel, each
    solver one colour in both panels and no two solvers one colour."""
    pytest.importorskip("scipy")
    pytest.importorskip("matplotlib")
    import runpy

    import matplotlib.pyplot as plt
    from matplotlib.colors import to_hex

    monkeypatch.setattr(sys, "argv", ["api_tour.py", str(tmp_path)])
    namespace = runpy.run_path(str(EXAMPLES / "api_tour.py"))
    figure, runs = namespace["figure"], namespace["runs"]
    try:
        assert figure.get_suptitle()
        colours: dict[str, set] = {}
        for ax, solvers in ((namespace["top"], {"exact", "cvode", "scipy"}), (namespace["bottom"], {"cvode", "scipy"})):
            lines = {line.get_label().split()[0]: line for line in ax.get_lines()}
            assert set(lines) == solvers
            for name, line in lines.items():
                colours.setdefault(name, set()).add(to_hex(line.get_color()))
        assert all(len(used) == 1 for used in colours.values()), colours
        assert len({next(iter(used)) for used in colours.values()}) == 3, colours
        for line in namespace["top"].get_lines():  # each line is its solver's run
            np.testing.assert_array_equal(line.get_ydata(), runs[line.get_label().split()[0]].h)
    finally:
        plt.close(figure)


@pytest.mark.slow
def test_fmpy_cli_script(tmp_path):
    pytest.importorskip("fmpy")
    pytest.importorskip("pythonfmu")
    out = run_example(["bash", EXAMPLES / "fmpy_cli.sh", "results"], tmp_path)
    assert "Model Name         BouncingBall" in out and "F_ext              input" in out  # fmpy info
    moon, reference = out.split("check results/moon.csv")[1].split("check results/BouncingBall_ref.csv")
    t = np.linspace(0.0, 6.0, 601)
    _, _, impacts = exact_at(t, Ball(g=1.62), h0=1.0)
    assert "points compared    601" in moon and f"{impacts[-1]} at the end, exact {impacts[-1]}" in moon
    assert float(re.search(rf"max \|h - h_exact\|  ({NUMBER}) m", moon)[1]) < 1e-8
    assert "verdict            PASS" in moon and "verdict            PASS" in reference
    article = oracle_counts(Ball()).impacts
    assert f"{article} at the end, exact {article}" in reference and "max |h - h_exact|  0.000e+00 m" in reference
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ["BouncingBall.fmu", "BouncingBall_ref.csv",
                                                                      "moon.csv"]


@pytest.mark.slow
def test_regression_test_example(fmu, tmp_path):
    pytest.importorskip("fmpy")
    # -o addopts=: pytest as a user runs the example, without the checkout's options (its xdist workers hid the prints)
    out = run_example([sys.executable, "-m", "pytest", "-q", "-s", "-p", "no:cacheprovider", "-o", "addopts=",
                       EXAMPLES / "regression_test.py"], tmp_path, BOUNCINGBALL_FMU=str(fmu))
    assert "3 passed" in out
    cases = {"article": (Ball(), 2.0, 0.0, 8.0, 8001), "moon": (Ball(g=1.62), 1.0, 0.0, 6.0, 601),
             "thrown": (Ball(k=1e6, b=50.0), 2.0, 3.0, 3.0, 61)}
    reports = out.split("check ")[1:]
    assert len(reports) == 3
    for report, (ball, h0, v0, t_end, points) in zip(reports, cases.values(), strict=True):
        t = np.linspace(0.0, t_end, points)
        _, _, impacts = exact_at(t, ball, h0=h0, v0=v0)
        assert f"points compared    {points}" in report
        assert f"{impacts[-1]} at the end, exact {impacts[-1]}; the count is right at every point" in report
        assert float(re.search(rf"max \|h - h_exact\|  ({NUMBER}) m", report)[1]) < 1e-8
    assert list(tmp_path.iterdir()) == []


def levitation_limit(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The coupled system as the communication step goes to 0: h, v at t, and the impacts before t_on and after t_off.

    Free fall and bounces (exact solution) up to t_on; then m h'' = kp (h_set - h) - kd v, a damped
    oscillator about h_set in closed form (the ball stays far above the ground); free again from t_off.
    """
    kp, kd, h_set, t_on, t_off, m = 40.0, 12.0, 1.0, 2.25, 5.0, 1.0
    free = ExactSolution(Ball(), 2.0, 0.0, 0.0, t_on)
    h_on, v_on = (x[0] for x in free.state(t_on))
    sigma, w2 = kd / (2 * m), kp / m

    def controlled(tau):
        c, s = oscillator_basis(sigma, w2, tau)
        y0 = h_on - h_set
        return h_set + y0 * c + (v_on + sigma * y0) * s, v_on * c - (sigma * v_on + w2 * y0) * s

    h_off, v_off = (float(x) for x in controlled(np.array(t_off - t_on)))
    late = ExactSolution(Ball(), h_off, v_off, t_off, float(t[-1]))
    h, v = np.empty_like(t), np.empty_like(t)
    for part, (h_part, v_part) in ((t <= t_on, free.state(t[t <= t_on])),
                                   ((t > t_on) & (t < t_off), controlled(t[(t > t_on) & (t < t_off)] - t_on)),
                                   (t >= t_off, late.state(t[t >= t_off]))):
        h[part], v[part] = h_part, v_part
    return h, v, sum(e.kind == "impact" for e in free.events), sum(e.kind == "impact" for e in late.events)


@pytest.mark.slow
def test_cosim_levitation(tmp_path):
    pytest.importorskip("fmpy")
    pytest.importorskip("pythonfmu")
    out = run_example([sys.executable, EXAMPLES / "cosim_levitation.py", "cosim"], tmp_path)
    reference = np.loadtxt(tmp_path / "cosim" / "cosim_levitation.csv", delimiter=",", skiprows=1)
    t = reference[:, 0]
    h_limit, v_limit, impacts_before, impacts_after = levitation_limit(t)
    assert (impacts_before, impacts_after) == (2, 5)
    # The reference run (step 2^-12 s) is within first-order distance of the continuous coupled system.
    assert np.max(np.abs(reference[:, 1] - h_limit)) < 1e-5
    hovering = (t > 4.0) & (t < 5.0)
    assert np.allclose(reference[hovering, 3], 9.81, atol=1e-4) and np.all(reference[(t < 2.25) | (t >= 5.0), 3] == 0)
    rows = re.findall(rf"^ *({NUMBER}) +({NUMBER}) +(?:({NUMBER}) +)?({NUMBER}) +({NUMBER}) +(\d+) +({NUMBER}) +(\d+)"
                      rf" +({NUMBER}) +(\d+)$", out, re.M)
    assert [float(row[0]) for row in rows] == [0.125, 0.0625, 0.03125, 0.015625, 0.0078125], out
    h_off, v_off = (float(x[t == 5.0][0]) for x in (h_limit, v_limit))
    errors = []
    for step, error, ratio, h, v, impacts, free_error, free_impacts, late_error, late_impacts in rows:
        assert abs(float(h) - h_off) < 1e-6 and abs(float(v) - v_off) < 1e-5, step
        assert (int(free_impacts), int(late_impacts), int(impacts)) == (impacts_before, impacts_after, 7), step
        assert float(free_error) < 1e-8 and float(late_error) < 1e-8, step  # impacts inside steps, resolved exactly
        assert float(error) < 0.02 * float(step), step  # first order: the force is held over each step
        if ratio:
            assert 1.5 < float(ratio) < 2.2 and float(ratio) == pytest.approx(errors[-1] / float(error), rel=0.01)
        errors.append(float(error))
    assert "so at steps of 0.125 s, 0.0625 s whole contacts fall inside one step" in out
    assert sorted(p.name for p in (tmp_path / "cosim").iterdir()) == [
        "BouncingBall.fmu", "BouncingBall_ref.csv", "PDController.fmu", "cosim_levitation.csv"]


@pytest.mark.slow
def test_cosim_levitation3(tmp_path):
    """The FMI 3.0 variant: early return at each event; both cases converge at first order against the fine step."""
    pytest.importorskip("fmpy")
    pytest.importorskip("pythonfmu3")
    pytest.importorskip("tqdm")
    out = run_example([sys.executable, EXAMPLES / "cosim_levitation3.py", "cosim3"], tmp_path)
    rows = re.findall(rf"^(levitation|catch) +({NUMBER}) +({NUMBER}) +({NUMBER}) +(\d+)$", out, re.M)
    steps = [0.125, 0.0625, 0.03125, 0.015625, 0.0078125]
    for case in ("levitation", "catch"):
        table = [[float(x) for x in row[1:]] for row in rows if row[0] == case]
        assert [row[0] for row in table] == steps, out
        for column in (1, 2):  # FMI 2.0, FMI 3.0 with early return: first order in the step
            errors = [row[column] for row in table]
            assert all(1.5 < a / b < 2.3 for a, b in zip(errors, errors[1:], strict=False)), (case, errors)
        if case == "levitation":  # its 14 events all happen while the controller is off (F = 0): nothing to update
            assert all(row[1] == row[2] and row[3] == 14 for row in table), table
        else:  # 4 impacts and 4 departures under the controller's force, each updating F_ext at the event
            assert all(row[3] == 8 and row[2] <= row[1] for row in table), table
    _the_fmu_page_quotes_these_rows(rows)


def _the_fmu_page_quotes_these_rows(rows):
    """docs/fmu.md's table of this example: each row it shows is a row printed here, to the digits it shows."""
    page = Path(__file__).resolve().parents[1] / "docs" / "fmu.md"
    if not page.is_file():
        pytest.skip("runs in a source checkout")
    text = page.read_text(encoding="utf-8").split("**Early return in a coupled system.**", 1)[1]
    quoted = re.findall(rf"^\| (?:(levitation|catch)[^|]*)?\| ({NUMBER}) (s|ms) \| ({NUMBER}) m \| ({NUMBER}) m "
                        rf"\| (\d+) \|$", text, re.M)
    printed = {(case, float(step)): [float(x) for x in row] for case, step, *row in rows}
    assert len(quoted) >= 5
    case = None
    for name, step, unit, fmi2, fmi3, returns in quoted:
        case = name or case
        dt = float(step) * (1e-3 if unit == "ms" else 1.0)
        [row] = [row for (printed_case, printed_step), row in printed.items()
                 if printed_case == case and abs(printed_step - dt) < 0.01 * dt]  # 7.8 ms for 2^-7 s
        for figure, value in ((fmi2, row[0]), (fmi3, row[1])):
            digits = len(figure.split("e")[0].replace(".", "").lstrip("0"))
            assert float(figure) == float(f"{value:.{digits - 1}e}"), (case, step, figure, value)
        assert int(returns) == row[2], (case, step)
    gain = {step: 100.0 * (1.0 - row[1] / row[0]) for (case, step), row in printed.items() if case == "catch"}
    assert_fmu_page_quotes(f"helps most at long steps ({gain[0.125]:.0f} % at 0.125 s) and little at short ones "
                           f"({gain[2.0**-7]:.1f} % at 7.8 ms)")


@pytest.mark.slow
def test_libcosim_system(tmp_path):
    pytest.importorskip("pythonfmu")
    pytest.importorskip("libcosimpy", reason="libcosimpy is not installed (the [test] extra installs it)")
    out = run_example([sys.executable, EXAMPLES / "libcosim_system" / "run.py", "osp"], tmp_path)
    data = np.loadtxt(tmp_path / "osp" / "libcosim_levitation.csv", delimiter=",", skiprows=1)
    t, h, v, force, impacts = data.T
    np.testing.assert_array_equal(t, np.arange(1, 1025) / 128)  # BaseStepSize 1/128 s, to 8 s
    free = t <= 2.25
    h_free, _, impacts_free = exact_at(np.concatenate(([0.0], t[free])))
    assert np.max(np.abs(h[free] - h_free[1:])) < 1e-8
    np.testing.assert_array_equal(impacts[free], impacts_free[1:])
    # After t_off the ball is free again: the exact solution from the state libcosim reached at t_off.
    i_off = int(np.flatnonzero(t == 5.0)[0])
    late = ExactSolution(Ball(), h[i_off], v[i_off], 5.0, 8.0)
    assert np.max(np.abs(h[i_off:] - late.state(t[i_off:])[0])) < 1e-8
    impacts_late = sum(e.kind == "impact" for e in late.events)
    truth = oracle_counts(Ball(), t_end=2.25).impacts + oracle_counts(Ball(), h[i_off], v[i_off], 8.0, 5.0).impacts
    assert impacts[-1] == impacts_free[-1] + impacts_late == truth
    _, _, impacts_before, impacts_after = levitation_limit(np.array([0.0, 8.0]))
    assert (impacts_free[-1], impacts_late) == (impacts_before, impacts_after)
    assert abs(h[i_off] - 1.0) < 1e-6 and abs(force[i_off - 1] - 9.81) < 1e-4 and np.all(force[i_off:] == 0.0)
    printed = float(re.search(rf"free ball up to t_on = 2.25 s: max \|h - h_exact\| = ({NUMBER}) m", out)[1])
    assert printed == pytest.approx(np.max(np.abs(h[free] - h_free[1:])), rel=1e-3, abs=1e-15)
    assert "impacts 2 (exact 2): PASS" in out and "1024 steps of 0.0078125 s to 8 s, 7 impacts in all" in out


@pytest.mark.slow
def test_sweep_example(tmp_path):
    """Each printed cell: the exact event count recomputed here, CVODE finding it within 1e-6 m."""
    with contextlib.ExitStack() as stack:
        try:  # Dask's default HTTP port taken, as by another cluster on the machine (unless it already is)
            stack.enter_context(socket.create_server(("", 8787)))
        except OSError:
            pass
        out = run_example([sys.executable, EXAMPLES / "sweep.py", tmp_path / "sweep"], tmp_path, timeout=600,
                          never_says=("already in use", "Traceback"))
    rows = re.findall(rf"^(cvode|article)\s+({NUMBER})\s+({NUMBER})\s+(\w+)\s+(\d+)/(\d+)\s+({NUMBER})$", out, re.M)
    assert len(rows) == 12, out
    for solver, k, zeta, status, found, expected, error in rows:
        k, zeta = float(k), float(zeta)
        ball = Ball(k=k, b=2.0 * zeta * np.sqrt(k * 1.0))
        assert int(expected) == len(ExactSolution(ball, 2.0, 0.0, 0.0, 2.0).events), (k, zeta)
        if solver == "cvode":
            assert status == "finished" and found == expected and float(error) <= 1e-6, (k, zeta, error)
    assert "cvode cells outside 1e-6 m: 0 of 6" in out
    assert list((tmp_path / "sweep" / "sweep_parts").glob("*.parquet"))  # streamed to disk as it ran


def test_contact_laws_example_against_the_laws_independent_truths(tmp_path):
    """Its table (impacts in 3 s, first contact's length, least force, first restitution) from the mpmath truths;
    the Hunt-Crossley row's alpha matched to the linear law's first restitution."""
    pytest.importorskip("matplotlib")
    from mpmath_oracle import Oracle
    from nopull_truth import NoPullTruth
    from rigid_truth import RigidTruth

    out = run_example([sys.executable, EXAMPLES / "contact_laws.py", tmp_path / "out"], tmp_path)
    pattern = rf"^(linear|linear-no-pull|rigid, e = {NUMBER}) +(\d+) +(\S+(?: \(instant\))?) +({NUMBER}) +({NUMBER})$"
    rows = {m[0]: m[1:] for m in re.findall(pattern, out, re.M)}
    assert len(rows) == 3, out
    linear = Oracle(1.0, 1e4, 10.0, 0.06, 9.81, 2.0, 0.0, 3.0)
    impact, departure = linear.events[:2]
    e = float(departure.velocity / -impact.velocity)
    assert rows["linear"] == (str(sum(ev.kind == "impact" for ev in linear.events)),
                              f"{float(departure.time - impact.time) * 1e3:.3f}", rows["linear"][2], f"{e:.6f}")
    assert float(rows["linear"][2]) < -50.0  # the published damper's pull before departure
    free = NoPullTruth(1.0, 1e4, 10.0, 0.06, 9.81, 2.0, 0.0, 3.0)
    kinds = [kind for _, kind, _, _ in free.events]
    first_departure = next(event for event in free.events if event[1] == "departure")
    assert rows["linear-no-pull"] == (str(kinds.count("impact")),
                                      f"{float(first_departure[0] - free.events[0][0]) * 1e3:.3f}", "0",
                                      f"{float(first_departure[3] / -free.events[0][3]):.6f}")
    rigid = RigidTruth(0.06, 9.81, e, 0.0, 2.0, 0.0, 3.0)
    label = f"rigid, e = {e:.3f}"
    assert rows[label] == (str(sum(t <= 3.0 for t, _ in rigid.impacts)), "0 (instant)", "0", f"{e:.6f}")
    # Hunt-Crossley (no closed form): its alpha gives the first bounce the linear law's restitution, by the truth's
    hunt = re.search(rf"^hunt-crossley, alpha = ({NUMBER}) s/m +(\d+) +({NUMBER}) +({NUMBER}) +({NUMBER})$", out, re.M)
    assert hunt, out
    alpha, impacts, duration, least, bounce = hunt.groups()
    assert 0.0 < float(alpha) < 0.1 and impacts == "3" and float(least) == 0.0  # its force never pulls
    assert bounce == f"{e:.6f}" and 25.0 < float(duration) < 45.0
    assert (tmp_path / "out" / "contact_laws.png").stat().st_size > 10_000
    readme = " ".join((EXAMPLES.parent / "README.md").read_text(encoding="utf-8").split())
    assert f"first restitution, {e:.3f})" in readme and f"negative ({float(rows['linear'][2]):.0f} N)" in readme


@pytest.mark.slow  # the mpmath truth of three bounces (about 4 s each)
def test_hunt_crossley_restitution_example_against_the_truth_and_the_separable_impact(tmp_path):
    """Its table: e from simulate against the mpmath truth at three (alpha, impact speed) pairs, from gravity's
    domain to the fast end; its separable column against G(-e v) = G(v) solved here in mpmath."""
    pytest.importorskip("matplotlib")
    pytest.importorskip("scipy")
    import mpmath

    from hunt_crossley_truth import HuntCrossleyTruth

    out = run_example([sys.executable, EXAMPLES / "hunt_crossley_restitution.py", tmp_path / "out"], tmp_path)
    rows = {(float(alpha), float(v)): (float(e), float(separable), float(linear)) for alpha, v, e, separable, linear
            in re.findall(rf"^ *({NUMBER}) +({NUMBER}) +({NUMBER}) +({NUMBER}) +({NUMBER})$", out, re.M)}
    assert len(rows) == 39, out
    m, R, k, n, g = 1.0, 0.06, 1e6, 1.5, 9.81
    for alpha, v in ((0.2, 0.05), (0.05, 1.0), (0.02, 10.0)):
        truth = HuntCrossleyTruth(m, k, n, alpha, R, g, R + v * v / (2 * g), 0.0, v / g + 0.1, max_events=2)
        (_, impact, v_in), (_, departure, v_out) = truth.events
        assert (impact, departure) == ("impact", "departure")
        assert abs(rows[alpha, v][0] - float(v_out / -v_in)) < 1.5e-6, (alpha, v)
    for (alpha, v), (_, separable, linear) in rows.items():
        c = mpmath.mpf(1.5) * alpha

        def G(u, c=c):
            return u / c - mpmath.log(1 + c * u) / c**2

        with mpmath.workdps(40):  # G's two terms cancel to c v's order
            e = mpmath.findroot(lambda e, v=v, c=c: G(-e * v, c) - G(mpmath.mpf(v), c),
                                (0.0, min(1.0, 1.0 / (c * v) - 1e-12)), solver="anderson")
        assert abs(separable - float(e)) < 1.5e-6 and linear == pytest.approx(1.0 - alpha * v, abs=1e-6), (alpha, v)
    assert (tmp_path / "out" / "hunt_crossley_restitution.png").stat().st_size > 10_000


@pytest.mark.slow
def test_stiff_table_example_parts_from_the_rigid_law_as_k_falls(tmp_path):
    """Its first line's phi is the closed form's; the linear law's impact phase within 1e-3 rad of it at k = 1e9
    (a 0.1 ms contact), parting further at each softer spring."""
    from closed_forms import period_doubling_threshold, period_n_phase, period_n_threshold

    out = run_example([sys.executable, EXAMPLES / "stiff_table.py"], tmp_path)
    low, high = period_n_threshold(1, 0.5), period_doubling_threshold(1, 0.5)
    said_phi = float(re.search(rf"impact phase phi = ({NUMBER}) rad", out)[1])
    assert abs(said_phi - period_n_phase(1, 0.5, low + 0.5 * (high - low))) < 1e-9
    offsets = [float(x) for x in re.findall(rf"impact phase - phi = ({NUMBER}) rad", out)]
    assert len(offsets) == 5 and abs(offsets[0]) < 1e-3
    assert all(abs(a) < abs(b) for a, b in zip(offsets, offsets[1:], strict=False))


@pytest.mark.slow
def test_vibrating_table_example_against_the_closed_forms_and_the_truth(tmp_path):
    """Its phi, u and interval against the closed forms (tests/closed_forms.py), period 1 and 2 on either side of
    Gamma_pd, and the ride's start against the mpmath truth's accumulation time."""
    from closed_forms import period_doubling_threshold, period_n_phase, period_n_takeoff_speed, period_n_threshold
    from table_truth import SineTableTruth

    out = run_example([sys.executable, EXAMPLES / "vibrating_table.py", tmp_path / "out"], tmp_path)
    e, f, g = 0.5, 10.0, 9.81
    low, high = period_n_threshold(1, e), period_doubling_threshold(1, e)
    assert f"Gamma_1 = {low:.6f}, Gamma_pd = {high:.6f}" in out
    found = re.search(rf"phi measured ({NUMBER}) rad, closed form ({NUMBER}) rad; take-off speed ({NUMBER}) m/s, "
                      rf"closed form ({NUMBER}) m/s; interval ({NUMBER}) s", out)
    phi, u = period_n_phase(1, e, low + 0.5 * (high - low)), period_n_takeoff_speed(1, f, g)
    measured_phi, said_phi, speed, said_u, interval = (float(x) for x in found.groups())
    assert abs(measured_phi - phi) < 1e-11 and abs(said_phi - phi) < 1e-12
    assert abs(speed - u) < 1e-11 and abs(said_u - u) < 1e-12 and abs(interval - 1.0 / f) < 1e-11
    exponent = re.search(rf"its Lyapunov exponent ({NUMBER}) per impact over (\d+) impacts", out)
    assert int(exponent[2]) >= 240 and abs(float(exponent[1]) - math.log(e)) < 3e-3  # ln(e): complex multipliers
    assert float(re.search(rf"chaotic, Lyapunov exponent ({NUMBER}) per impact", out)[1]) > 0.1
    assert "0.97 Gamma_pd: the last intervals between impacts [0.1 0.1 0.1 0.1] s (period 1)" in out
    assert re.search(r"1\.03 Gamma_pd: .*\(period 2\)", out)
    amplitude = 0.9 * g / (2.0 * math.pi * f) ** 2
    truth = SineTableTruth(0.01, g, e, 0.0, amplitude, f, 0.0, 0.06, 0.0, 2.0)
    found = re.search(rf"(\d+) impacts, then riding the table from t = ({NUMBER}) s", out)
    assert abs(float(found[2]) - float(truth.accumulations[-1])) < 1e-9
    assert (tmp_path / "out" / "vibrating_table.png").stat().st_size > 10_000
