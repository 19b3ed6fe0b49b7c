"""A piecewise-constant F_ext through simulate(): every solver, against closed forms, each other and the FMU."""

from __future__ import annotations

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.solvers.exact import ExactSolution
from bouncingball.solvers.forcing import ForceTable

BALL = bb.Ball()
TIGHT = {"cvode": {}, "exact": {}, "scipy": {"method": "DOP853", "rtol": 1e-12, "atol": 1e-12, "max_step": 0.0}}


def parabola_pieces(t, h0, v0, times, values, m, g):
    """The flight in closed form: h and v a parabola on each piece of constant force, joined continuously."""
    edges = [0.0, *[x for x in times if x > 0.0]]
    forces = [values[0], *[f for x, f in zip(times, values, strict=True) if x > 0.0]]
    h, v = np.empty_like(t), np.empty_like(t)
    start_h, start_v = h0, v0
    for i, (edge, force) in enumerate(zip(edges, forces, strict=True)):
        a = -g + force / m
        end = edges[i + 1] if i + 1 < len(edges) else np.inf
        inside = (t >= edge) & (t <= end)
        tau = t[inside] - edge
        h[inside], v[inside] = start_h + start_v * tau + 0.5 * a * tau**2, start_v + a * tau
        if np.isfinite(end):
            span = end - edge
            start_h, start_v = start_h + start_v * span + 0.5 * a * span**2, start_v + a * span
    return h, v


@pytest.mark.parametrize("solver", ["exact", "cvode", "scipy"])
def test_a_flight_under_a_force_table_is_the_parabola_of_each_piece(solver):
    times, values = [0.0, 0.4, 1.1], [3.0, 25.0, -4.0]  # thrust up over [0.4, 1.1), a push down after
    result = bb.simulate(BALL, 50.0, 3.0, 2.5, 0.01, solver, F_ext=(times, values), **TIGHT[solver])
    h, v = parabola_pieces(result.t, 50.0, 3.0, times, values, BALL.m, BALL.g)
    assert result.events == []
    np.testing.assert_allclose(result.h, h, rtol=0.0, atol=1e-9 * 50.0)
    np.testing.assert_allclose(result.v, v, rtol=0.0, atol=1e-9 * 30.0)
    # by hand: 50.6552 m, 0.276 m/s at 0.4 s; 54.56995 m, 10.909 m/s at 1.1 s; then 1.4 s at -13.81 m/s2
    assert result.h[-1] == pytest.approx(56.30875, abs=1e-9)
    assert result.F_ext == ForceTable((0.0, 0.4, 1.1), (3.0, 25.0, -4.0))


def test_the_last_value_holds_after_the_table_and_the_first_before_it():
    times, values = [0.5, 1.0], [7.0, -3.0]
    result = bb.simulate(BALL, 50.0, 0.0, 2.0, 0.01, "exact", t_start=0.0, F_ext=(times, values))
    h, _ = parabola_pieces(result.t, 50.0, 0.0, [0.0, 0.5, 1.0], [7.0, 7.0, -3.0], BALL.m, BALL.g)
    np.testing.assert_allclose(result.h, h, rtol=0.0, atol=1e-12 * 50.0)


LIFT = ([0.0, 0.2, 0.6], [0.0, 2.0 * BALL.m * BALL.g, 0.0])  # at rest, lifted by 2 m g over [0.2, 0.6), then let go
H_REST = BALL.R - BALL.static_deflection(0.0)


def test_a_table_lifting_the_ball_off_a_rest_cvode_and_exact_agree_with_the_same_events():
    exact = bb.simulate(BALL, H_REST, 0.0, 2.0, 1e-3, "exact", F_ext=LIFT)
    cvode = bb.simulate(BALL, H_REST, 0.0, 2.0, 1e-3, "cvode", F_ext=LIFT)
    scale = 1.6  # the flight's apex above R: lifted at g over 0.4 s (0.78 m), then the coast up (0.78 m)
    assert [e.kind for e in exact.events][:2] == ["departure", "impact"]
    assert [e.kind for e in cvode.events] == [e.kind for e in exact.events]
    np.testing.assert_allclose(cvode.event_times, exact.event_times, rtol=0.0, atol=1e-9)
    assert np.max(np.abs(cvode.h - exact.h)) < 1e-6 * scale
    # the first departure: from rest the contact under -g (net force up m g) reaches R in closed form
    assert exact.events[0].time > 0.2
    assert exact.h[200] == pytest.approx(H_REST, abs=1e-15)  # held at rest until the force changes
    assert len(exact.events) == 3 and exact.rest_time is None is cvode.rest_time  # it bounces on after the lift


def test_a_one_value_table_is_the_constant_bit_for_bit():
    for solver in ("exact", "cvode"):
        constant = bb.simulate(BALL, 2.0, 0.0, 3.0, 1e-3, solver, F_ext=2.5)
        table = bb.simulate(BALL, 2.0, 0.0, 3.0, 1e-3, solver, F_ext=([1.0], [2.5]))
        assert np.array_equal(constant.h, table.h) and np.array_equal(constant.v, table.v)
        assert constant.events == table.events and isinstance(constant.F_ext, float)


@pytest.mark.parametrize(("table", "message"), [
    (([0.0, 1.0], [1.0]), "F_ext table is not allowed: 2 times but 1 values"),
    (([], []), "F_ext table is not allowed: it has no value"),
    (([0.0, float("nan")], [1.0, 2.0]), "F_ext times[1] = nan s is not allowed: it must be a finite number"),
    (([0.0, 1.0], [1.0, float("inf")]), "F_ext values[1] = inf N is not allowed: it must be a finite number"),
    (([0.0, 1.0, 1.0], [1.0, 2.0, 3.0]), "F_ext times[2] = 1.0 s is not allowed: the times must increase strictly"),
    (([0.0, 1.0, 2.0],), "F_ext = ([0.0, 1.0, 2.0],) is not allowed: it must be a number [N] or a table"),
])
def test_a_bad_table_is_refused_naming_the_field(table, message):
    for solver in ("exact", "cvode", "scipy"):
        with pytest.raises(ValueError) as error:
            bb.simulate(BALL, 2.0, 0.0, 1.0, solver=solver, F_ext=table)
        assert str(error.value).startswith(message)


def test_the_fmu_driven_through_fmpy_with_the_same_input_is_the_exact_solution(fmu, tmp_path):
    fmpy = pytest.importorskip("fmpy")
    rows = np.array([(0.0, 0.0), (0.2, 0.0), (0.2, LIFT[1][1]), (0.6, LIFT[1][1]), (0.6, 0.0)],
                    dtype=[("time", float), ("F_ext", float)])
    run = fmpy.simulate_fmu(str(fmu), stop_time=2.0, output_interval=0.01, input=rows, output=["h", "F_ext"],
                            start_values={"h": H_REST})
    exact = ExactSolution(BALL, H_REST, 0.0, 0.0, 2.0, ForceTable.of(LIFT))
    h_exact, _ = exact.state(run["time"])
    assert np.max(np.abs(run["h"] - h_exact)) < 1e-6 * 1.6
    assert np.max(run["h"]) > BALL.R + 1.5  # it did fly
