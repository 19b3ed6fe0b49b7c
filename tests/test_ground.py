"""The ground as a scene's part: its checks, a still ground at a height, a table of positions, scene files, `run`."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bouncingball as bb
from bouncingball import Ground
from bouncingball.cli import main
from bouncingball.scenes import load_scene, scene_from_mapping


@pytest.mark.parametrize("make, words", [
    (lambda: Ground.sine(-1e-3, 10.0), "ground amplitude = -0.001 m is not allowed: it must be finite and >= 0"),
    (lambda: Ground.sine(1e-3, 0.0), "ground frequency = 0.0 Hz is not allowed: it must be in [1e-06, 1000000] (the "
                                     "range double precision resolves)"),
    (lambda: Ground.sine(1e-3, 10.0, math.nan), "ground phase = nan rad is not allowed"),
    # review: a phase of 1e13 rad put a free fall 4e-6 m off in co-simulation; 1e-100 Hz divided by an underflow
    (lambda: Ground.sine(1e-3, 10.0, 1e13), "ground phase = 10000000000000.0 rad is not allowed: it must be in "
                                            "[-10000, 10000]"),
    (lambda: Ground.sine(1e-3, 1e-100), "ground frequency = 1e-100 Hz is not allowed: it must be in [1e-06, "),
    (lambda: Ground.sine(1e-101, 10.0), "ground amplitude = 1e-101 m is not allowed: it must be in [1e-100, "),
    (lambda: Ground.still(math.inf), "ground height = inf m is not allowed"),
    (lambda: Ground.table([0, 1, 2], [0, 0, 0]), "ground table of 3 points is not allowed: it must have from 4"),
    (lambda: Ground.table([0, 1, 1, 2], [0, 0, 0, 0]), "ground table times[2] = 1.0 s is not allowed: the times "
                                                        "must increase strictly"),
    (lambda: Ground.table([0, 1, 2, 3], [0, 0, "x", 0]), "ground table positions[2] = 'x' is not allowed"),
    (lambda: Ground.table([0, 1, 2, 3], [0, 0, 0]), "ground table is not allowed: 4 times but 3 positions"),
    (lambda: Ground(kind="banana"), "ground kind = 'banana' is not allowed: it must be one of still, sine, table"),
    (lambda: Ground(kind="sine", amplitude=1e-3), "ground frequency = 0.0 Hz is not allowed"),
    (lambda: Ground(kind="table"), "ground kind = 'table' is not allowed without its spline: make it with "
                                   "Ground.table(t, s)"),
])
def test_a_bad_ground_is_refused_by_name(make, words):
    with pytest.raises(ValueError, match=words.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")
                       .replace("]", r"\]").replace(".", r"\.")):
        make()


def test_a_moving_ground_is_refused_where_it_is_not_taken_yet():
    ground = Ground.sine(1e-3, 10.0)
    rigid = bb.Ball(contact="rigid")
    with pytest.raises(ValueError, match="is not allowed with the CVODE solver: it takes a still or a sine ground"):
        bb.simulate(rigid, 1.0, 0.0, 1.0, ground=Ground.table([0, 1, 2, 3], [0, 1e-3, 0, 0]))
    with pytest.raises(ValueError, match="contact = 'hunt-crossley' is not allowed on a moving ground .* with the "
                                         "exact solver"):
        bb.simulate(bb.Ball(contact="hunt-crossley"), 1.0, 0.0, 1.0, solver="exact", ground=ground)
    with pytest.raises(ValueError, match="contact = 'linear' is not allowed on a ground table"):
        bb.simulate(bb.Ball(), 1.0, 0.0, 1.0, solver="exact", ground=Ground.table([0, 1, 2, 3], [0, 1e-3, 0, 0]))
    with pytest.raises(ValueError, match=r"b = 0.0 N s/m is not allowed with k = 10000.0 N/m and m = 1.0 kg on "
                                         r"ground .*: the contact is so near resonance"):
        bb.simulate(bb.Ball(b=0.0), 1.0, 0.0, 1.0, solver="exact", ground=Ground.sine(1e-3, 100.0 / (2.0 * math.pi)))
    with pytest.raises(ValueError, match=r"b = 1e-09 N s/m is not allowed .* steady response, 1e\+08 m"):
        bb.simulate(bb.Ball(b=1e-9, R=0.01), 1.0, 0.0, 1.0, solver="exact",
                    ground=Ground.sine(1e-3, 100.0 / (2.0 * math.pi)))
    with pytest.raises(ValueError, match="it must be >= R \\+ s\\(t_start\\)"):
        bb.simulate(rigid, rigid.R - 1e-3, 0.0, 1.0, solver="exact", ground=ground)
    with pytest.raises(ValueError, match="ground = 3 is not allowed: it must be a bouncingball.Ground"):
        bb.simulate(rigid, 1.0, 0.0, 1.0, solver="exact", ground=3)
    table = Ground.table([0.0, 0.5, 1.0, 1.5], [0.0, 1e-3, 0.0, -1e-3])
    with pytest.raises(ValueError, match="it must cover the run"):
        bb.simulate(rigid, 1.0, 0.0, 2.0, solver="exact", ground=table)


@pytest.mark.parametrize("solver", ["exact", "cvode"])
def test_a_still_ground_at_a_height_is_the_same_run_shifted(solver):
    ball = bb.Ball(contact="rigid", e=0.7)
    base = bb.simulate(ball, 2.0, 0.0, 3.0, solver=solver)
    raised = bb.simulate(ball, 2.5, 0.0, 3.0, solver=solver, ground=Ground.still(0.5))
    np.testing.assert_array_equal(raised.h, base.h + 0.5)
    assert [event.time for event in raised.events] == [event.time for event in base.events]
    assert raised.ground == Ground.still(0.5)
    assert min(raised.h) >= 0.5 + ball.R - 1e-12


def test_no_ground_is_the_still_ground_at_zero_bit_for_bit():
    ball = bb.Ball(contact="rigid", e=0.7)
    plain = bb.simulate(ball, 2.0, 0.0, 3.0, solver="exact")
    still = bb.simulate(ball, 2.0, 0.0, 3.0, solver="exact", ground=Ground.still())
    np.testing.assert_array_equal(plain.h, still.h)
    assert plain.events == still.events and plain.error_estimate == still.error_estimate


def test_a_table_of_a_sine_gives_the_sines_impacts():
    """A spline through the sine every 0.5 ms: the same impacts within its interpolation error (~1e-11 m)."""
    amplitude, frequency = 2.0e-3, 10.0
    ball = bb.Ball(contact="rigid", e=0.5, R=0.01)
    times = np.linspace(0.0, 1.0, 2001)
    table = Ground.table(times, amplitude * np.sin(2.0 * math.pi * frequency * times))
    sine = bb.simulate(ball, 0.06, 0.0, 1.0, solver="exact", ground=Ground.sine(amplitude, frequency))
    spline = bb.simulate(ball, 0.06, 0.0, 1.0, solver="exact", ground=table)
    assert len(sine.events) == len(spline.events) >= 8
    assert max(abs(a.time - b.time) for a, b in zip(sine.events, spline.events, strict=True)) < 1e-6
    # the spline's s'' is linear between the points: each ride ends on it where it reaches -g (none here: Gamma 0.8)
    assert table.acceleration_bound == pytest.approx(amplitude * (2.0 * math.pi * frequency) ** 2, rel=1e-3)


def test_a_scene_file_takes_a_ground_table(tmp_path):
    path = tmp_path / "table.toml"
    path.write_text('contact = "rigid"\ne = 0.5\nR = 0.01\nh0 = 0.06\nt_end = 1.0\n'
                    "[ground]\namplitude = 0.002\nfrequency = 10.0\nphase = 0.5\n", encoding="utf-8")
    scene = load_scene(path)
    assert scene.ground == Ground.sine(0.002, 10.0, 0.5)
    assert scene.simulate("exact").ground == scene.ground
    for values, words in [({"ground": {"amp": 1}}, "scene key 'ground.amp' \\(= 1\\) in scene 's' is not allowed"),
                          ({"ground": {"amplitude": 1e-3, "height": 1.0}}, "are not allowed together"),
                          ({"ground": {"amplitude": 1e-3}}, "scene key 'ground.frequency' in scene 's' is missing"),
                          ({"ground": 2}, "scene key 'ground' \\(= 2\\) in scene 's' is not allowed")]:
        with pytest.raises(ValueError, match=words):
            scene_from_mapping("s", values)


def test_run_takes_a_vibrating_ground_and_says_so(capsys, tmp_path):
    table = tmp_path / "ground.csv"
    table.write_text("time,height\n" + "".join(f"{t:.4f},{1e-3 * math.sin(20 * math.pi * t):.12f}\n"
                                               for t in np.linspace(0.0, 2.0, 401)), encoding="utf-8")
    code = main(["run", "article", "--contact", "rigid", "--e", "0.5", "--solver", "exact", "--t-end", "2",
                 "--ground-amplitude", "0.002", "--ground-frequency", "10"])
    said = capsys.readouterr().out
    assert code == 0 and "ground      ground s(t) = 0.002 m sin(2 pi 10 Hz t + 0 rad)" in said
    assert "rest        riding the ground for good from t = " in said  # Gamma = 0.8: it chatters down and rides
    code = main(["run", "article", "--contact", "rigid", "--solver", "exact", "--t-end", "2", "--ground-table",
                 str(table)])
    assert code == 0 and "ground      ground through 401 points from 0 s to 2 s" in capsys.readouterr().out
    assert main(["run", "article", "--ground-amplitude", "0.002"]) == 2
    assert "--ground-frequency is missing" in capsys.readouterr().err
    code = main(["run", "article", "--contact", "rigid", "--e", "0.5", "--t-end", "2", "--ground-amplitude", "0.002",
                 "--ground-frequency", "10"])  # CVODE, the default solver, takes the rigid law there
    said = capsys.readouterr().out
    assert code == 0 and "solver      cvode" in said and "riding the ground for good from t = " in said
    code = main(["run", "article", "--t-end", "1", "--ground-amplitude", "0.002", "--ground-frequency", "10"])
    said = capsys.readouterr().out  # the article's linear law, CVODE
    assert code == 0 and "solver      cvode" in said and "ground      ground s(t) = 0.002 m" in said
    assert main(["run", "article", "--contact", "hunt-crossley", "--solver", "exact", "--ground-amplitude", "0.002",
                 "--ground-frequency", "10"]) == 2
    assert "contact = 'hunt-crossley' is not allowed on a moving ground" in capsys.readouterr().err
    code = main(["run", "article", "--contact", "hunt-crossley", "--alpha", "0.2", "--t-end", "1",
                 "--ground-amplitude", "0.002", "--ground-frequency", "15"])  # CVODE takes it
    said = capsys.readouterr().out
    assert code == 0 and "events      2 (1 impact, 1 departure)" in said and "rest        none" in said


def test_check_judges_a_result_on_a_vibrating_table(tmp_path, capsys):
    """A master's CSV of a ball on a table, judged against the exact solution on that table (not a still one)."""
    scene = tmp_path / "table.toml"
    scene.write_text('contact = "rigid"\ne = 0.5\nR = 0.01\nh0 = 0.06\nt_end = 1.0\n'
                     "[ground]\namplitude = 0.003\nfrequency = 10.0\n", encoding="utf-8")
    result = load_scene(scene).simulate("exact", output_interval=1e-3)
    still = bb.simulate(bb.Ball(contact="rigid", e=0.5, R=0.01), 0.06, 0.0, 1.0, solver="exact")
    assert np.max(np.abs(still.h - result.h)) > 1e-3  # the table makes a difference to judge
    for name, run in (("right", result), ("still", still)):
        rows = "".join(f"{t!r},{h!r}\n" for t, h in zip(run.t.tolist(), run.h.tolist(), strict=True))
        (tmp_path / f"{name}.csv").write_text("time,h\n" + rows, encoding="utf-8")
    assert main(["check", str(tmp_path / "right.csv"), str(scene)]) == 0
    assert "PASS" in capsys.readouterr().out
    assert main(["check", str(tmp_path / "still.csv"), str(scene)]) == 1
    assert "FAIL" in capsys.readouterr().out
    table = tmp_path / "points.toml"  # a ground through points: the FMU takes a still one at 0 or a sine only
    table.write_text('contact = "rigid"\nR = 0.01\nh0 = 0.06\nt_end = 1.0\n[ground]\ntimes = [0.0, 0.5, 1.0, 1.5]\n'
                     "positions = [0.0, 0.001, 0.0, -0.001]\n", encoding="utf-8")
    with pytest.raises(ValueError, match="scene 'points' on its ground .* is not allowed for the FMU: it runs on a "
                                         "still ground at 0 or a sine"):
        from bouncingball.fmu.validate import validate

        validate(str(table))
