"""CVODE against the exact solution: the article, every built-in scene, the integrator object, random balls."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import bouncingball
from bouncingball.accuracy import accuracy_of_result, height_scale
from bouncingball.physics import Ball
from bouncingball.scenes import BUILTIN_SCENES, load_scene
from bouncingball.solvers.cvode import BallIntegrator, CvodeSettings, choose_method
from bouncingball.solvers.exact import ExactSolution
from bouncingball.solvers.result import output_grid
from closed_forms import undamped_event_count
from oracle_counts import oracle_counts

README = Path(__file__).resolve().parents[1] / "README.md"


def assert_readme_quotes(quote: str) -> None:
    """The README (outside a source checkout: nothing to check) says quote, figures as the run gives them."""
    if README.is_file():
        assert quote in " ".join(README.read_text(encoding="utf-8").split()), f"README.md does not say: {quote}"


def _accuracy(result, h0, v0):
    accuracy, exact = accuracy_of_result(result, h0, v0)
    return accuracy, exact.result()


def test_article_at_default_settings():
    result = bouncingball.simulate(Ball(), 2.0, 0.0, 8.0, 1e-3)
    accuracy, exact = _accuracy(result, 2.0, 0.0)
    assert len(result.t) == 8001 and result.t[0] == 0.0 and result.t[-1] == 8.0
    assert accuracy.events_found == accuracy.events_exact == oracle_counts(Ball()).events
    assert [e.kind for e in result.events] == [e.kind for e in exact.events]
    assert accuracy.max_height_error <= 1e-6
    assert accuracy.max_event_time_error <= 1e-6


def test_article_at_tight_tolerances():
    result = bouncingball.simulate(Ball(), 2.0, 0.0, 8.0, 1e-3, rtol=1e-11, atol=1e-14)
    accuracy, _ = _accuracy(result, 2.0, 0.0)
    assert accuracy.events_found == oracle_counts(Ball()).events
    assert accuracy.max_height_error <= 1e-8
    assert accuracy.max_event_time_error <= 1e-8


@pytest.mark.parametrize("method", ["Adams", "BDF"])
def test_both_methods_reach_the_article_accuracy(method):
    result = bouncingball.simulate(Ball(), 2.0, 0.0, 8.0, 1e-3, method=method, rtol=1e-11, atol=1e-13)
    accuracy, _ = _accuracy(result, 2.0, 0.0)
    assert accuracy.events_found == oracle_counts(Ball()).events
    assert accuracy.max_height_error <= 1e-7


HEIGHT_LIMIT = {"high-drop": 1e-3}


@pytest.mark.parametrize("name", BUILTIN_SCENES)
def test_every_builtin_scene_matches_the_exact_events(name):
    scene = load_scene(name)
    result = scene.simulate()
    accuracy, exact = _accuracy(result, scene.h0, scene.v0)
    assert [e.kind for e in result.events] == [e.kind for e in exact.events]
    if name == "undamped":  # every bounce's energy kept: tests/test_long_runs.py measures it against the closed form
        ball = scene.ball
        assert len(result.events) == undamped_event_count(ball.m, ball.k, ball.R, ball.g, scene.h0, scene.t_end)
        energy = result.energy
        assert np.max(np.abs(energy - energy[0])) / energy[0] <= 1e-9
    else:
        assert accuracy.max_height_error <= HEIGHT_LIMIT.get(name, 1e-5)
        assert accuracy.max_event_time_error <= 1e-5
    if exact.rest_time is None:
        assert result.rest_time is None
    else:
        assert result.rest_time == pytest.approx(exact.rest_time, abs=1e-6)


def test_auto_method_rule():
    assert choose_method(Ball()) == "Adams"
    assert choose_method(Ball(b=0.0)) == "Adams"
    assert choose_method(Ball(k=1e12)) == "Adams"  # stiff spring, but light damping: a bounce to resolve
    for stiff in (Ball(m=1e-6), Ball(b=1e4)):  # damping ratio 50
        assert choose_method(stiff) == "BDF"


def test_integrator_advances_piece_by_piece():
    ball = Ball()
    settings = CvodeSettings(rtol=1e-11, atol=1e-14)
    integrator = BallIntegrator(ball, 2.0, 0.0, settings=settings)
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, 8.0)
    grid = np.linspace(0.0, 8.0, 161)
    h_exact, v_exact = exact.state(grid)
    impacts_exact = np.array([sum(e.kind == "impact" and e.time <= t for e in exact.events) for t in grid])
    events = []
    for i, t in enumerate(grid[1:], start=1):
        events += integrator.advance(t)
        assert integrator.t == t
        assert abs(integrator.h - h_exact[i]) <= 1e-8
        assert integrator.impacts == impacts_exact[i]
    assert len(events) == oracle_counts(ball).events
    np.testing.assert_allclose([e.time for e in events], [e.time for e in exact.events], atol=1e-8)


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_advance_stops_at_each_event_when_asked(engine):
    """stop_at_event (the FMI 3.0 early return): one event per advance, at the exact event's time."""
    ball = Ball()
    integrator = BallIntegrator(ball, 2.0, 0.0, settings=CvodeSettings(engine=engine))
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, 3.0)
    target, stops = 3.0, []
    while integrator.t < target:
        events = integrator.advance(target, stop_at_event=True)
        assert len(events) <= 1
        if events:
            assert events[0].time == integrator.t < target
            stops.append((integrator.t, str(events[0].kind)))
    assert integrator.t == target
    expected = [(e.time, str(e.kind)) for e in exact.events if e.time < target]
    assert len(expected) == 6 and [kind for _, kind in stops] == [kind for _, kind in expected]
    np.testing.assert_allclose([t for t, _ in stops], [t for t, _ in expected], rtol=0, atol=1e-9)
    h_exact, v_exact = exact.state(np.array([target]))
    assert abs(integrator.h - h_exact[0]) <= 1e-6


def test_result_does_not_depend_on_how_the_interval_is_cut():
    settings = CvodeSettings(rtol=1e-11, atol=1e-14)
    final = []
    for pieces in (1, 7, 800, 8000):
        integrator = BallIntegrator(Ball(), 2.0, 0.0, settings=settings)
        for t in np.linspace(0.0, 8.0, pieces + 1)[1:]:
            integrator.advance(t)
        final.append((integrator.h, integrator.v, integrator.impacts))
    for h, v, impacts in final[1:]:
        assert impacts == final[0][2]
        assert abs(h - final[0][0]) <= 1e-10 and abs(v - final[0][1]) <= 1e-8


def test_rollback_continues_bit_for_bit_in_the_same_and_a_fresh_integrator():
    ball = Ball()
    exact = ExactSolution(ball, 2.0, 0.0, 0.0, 2.0)
    integrator = BallIntegrator(ball, 2.0, 0.0)
    integrator.advance(0.65)  # inside the first contact
    saved = integrator.get_state()
    integrator.advance(1.9)
    first = (integrator.t, integrator.h, integrator.v, integrator.impacts, integrator.departures,
             integrator.steps, integrator.rhs_calls)
    assert abs(first[1] - exact.state([1.9])[0][0]) <= 1e-7
    integrator.set_state(saved)
    assert integrator.get_state() == saved
    integrator.advance(1.9)
    again = (integrator.t, integrator.h, integrator.v, integrator.impacts, integrator.departures,
             integrator.steps, integrator.rhs_calls)
    assert again == first
    fresh = BallIntegrator(Ball(), 0.0, 0.0)
    fresh.set_state(saved)
    fresh.advance(1.9)
    assert (fresh.t, fresh.h, fresh.v, fresh.impacts, fresh.departures, fresh.steps, fresh.rhs_calls) == first


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
@pytest.mark.parametrize("seed", range(4))
def test_a_restored_state_continues_bit_for_bit_whatever_the_targets_and_forces(engine, seed):
    """Random advances and F_ext changes; a state taken anywhere, restored in place and in a fresh integrator."""
    if engine == "compiled":
        pytest.importorskip("numba")
    rng = np.random.default_rng(seed)
    ball = Ball(b=float(rng.choice([0.0, 10.0, 30.0])))
    settings = CvodeSettings(engine=engine)
    targets = np.cumsum(rng.exponential(0.05, 120))
    forces = {int(i): float(rng.normal(0.0, 5.0)) for i in rng.integers(0, 120, 5)}
    taken_at = int(rng.integers(1, 60))

    def run(integrator, start):
        trace = []
        for i, t in enumerate(targets[start:], start=start):
            if i in forces:
                integrator.F_ext = forces[i]
            if i == taken_at and start == 0:
                run.saved = integrator.get_state()
            events = integrator.advance(t)
            trace.append((integrator.t, integrator.h, integrator.v, [(e.time, e.velocity) for e in events],
                          integrator.steps, integrator.rhs_calls))
        return trace

    original = BallIntegrator(ball, 2.0, 0.0, settings=settings)
    uninterrupted = run(original, 0)[taken_at:]
    assert sum(len(row[3]) for row in uninterrupted) > 0  # the continuation crosses events
    for integrator in (original, BallIntegrator(ball, 1.0, 0.0, settings=settings)):
        integrator.set_state(run.saved)
        assert run(integrator, taken_at) == uninterrupted


def test_a_restore_that_fails_changes_nothing():
    integrator = BallIntegrator(Ball(), 2.0, 0.0)
    integrator.advance(0.65)
    saved = integrator.get_state()
    integrator.advance(1.2)
    before = integrator.get_state()
    wrong = dataclasses.replace(saved, restart=dataclasses.replace(saved.restart, t=saved.t + 1.0))
    with pytest.raises(ValueError, match="state restart at t = .* is not allowed"):
        integrator.set_state(wrong)
    assert integrator.get_state() == before


def test_taking_a_state_does_not_disturb_the_run():
    plain = BallIntegrator(Ball(), 2.0, 0.0)
    observed = BallIntegrator(Ball(), 2.0, 0.0)
    for t in np.linspace(0.0, 8.0, 801)[1:]:
        plain.advance(t)
        observed.get_state()
        observed.advance(t)
    assert (observed.h, observed.v, observed.steps) == (plain.h, plain.v, plain.steps)


def test_external_force_equal_to_weight_gives_constant_velocity():
    ball = Ball()
    integrator = BallIntegrator(ball, 0.5, 3.0, F_ext=ball.m * ball.g)
    integrator.advance(2.0)
    assert integrator.v == pytest.approx(3.0, abs=1e-12)
    assert integrator.h == pytest.approx(6.5, abs=1e-10)


def test_step_change_of_external_force_matches_the_exact_solution():
    ball = Ball()
    integrator = BallIntegrator(ball, 2.0, 0.0)
    integrator.advance(1.0)
    before = ExactSolution(ball, 2.0, 0.0, 0.0, 1.0)
    h1, v1 = before.state([1.0])
    assert abs(integrator.h - h1[0]) <= 1e-7
    switch = integrator.get_state()
    integrator.F_ext = 25.0  # more than m g: lifted after the next contact
    exact = ExactSolution(ball, switch.h, switch.v, switch.t, 4.0, F_ext=25.0)
    events = integrator.advance(4.0)
    h4, _ = exact.state([4.0])
    assert [e.kind for e in events] == [e.kind for e in exact.events]
    assert abs(integrator.h - h4[0]) <= 1e-6


def test_constant_external_force_in_simulate():
    ball = Ball()
    result = bouncingball.simulate(ball, 2.0, 0.0, 8.0, F_ext=-5.0)  # pushed down
    accuracy, _ = _accuracy(result, 2.0, 0.0)
    assert accuracy.events_match and accuracy.max_height_error <= 1e-6


@pytest.mark.slow
def test_event_history_is_not_kept():
    """scikit-sundae's per-call rebuild of the event history made each event cost more than the last."""
    integrator = BallIntegrator(Ball(b=0.0), 2.0, 0.0, settings=CvodeSettings(engine="sksundae"))
    integrator.advance(1000.0)
    assert integrator.impacts + integrator.departures == undamped_event_count(1.0, 1e4, 0.06, 9.81, 2.0, 1000.0)
    for solver in integrator._solvers.values():
        assert len(solver._event._t) <= 1  # at most the root found beyond the last target


def test_solver_failure_is_a_clear_error():
    settings = CvodeSettings()
    object.__setattr__(settings, "rtol", 1e-300)  # past its floor (settings.MIN_RTOL), to reach CVODE's own failure
    integrator = BallIntegrator(Ball(), 2.0, 0.0, settings=settings)
    with pytest.raises(RuntimeError, match=r"CVODE failed at t = 0.0 s \(flight, h = 2.0 m.*accuracy"):
        integrator.advance(0.5)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    m=st.floats(0.05, 20.0), k=st.floats(1e2, 1e7), zeta=st.floats(0.0, 3.0), R=st.floats(0.01, 0.5),
    g=st.floats(0.5, 30.0), h0=st.floats(0.0, 5.0), v0=st.floats(-5.0, 5.0),
)
def test_random_balls_against_the_exact_solution(m, k, zeta, R, g, h0, v0):
    ball = Ball(m=m, k=k, b=2.0 * zeta * math.sqrt(k * m), R=R, g=g)
    exact = ExactSolution(ball, h0, v0, 0.0, 3.0)
    times = [e.time for e in exact.events]
    # A grazing contact (a peak within a hair of R) is decided by round-off, not by the solver:
    # keep the examples whose events survive moving the start by 1 um either way.
    for dh in (-1e-6, 1e-6):
        assume(len(ExactSolution(ball, h0 + dh, v0, 0.0, 3.0).events) == len(times))
    assume(all(later - earlier > 1e-4 for earlier, later in zip([0.0, *times], times, strict=False)))
    assume(all(abs(t - 3.0) > 1e-4 for t in times))
    result = bouncingball.simulate(ball, h0, v0, 3.0, 1e-3)
    accuracy, exact_on_grid = accuracy_of_result(result, h0, v0)
    exact_result = exact_on_grid.result()
    assert accuracy.events_match
    # a ball launched by a stiff spring can climb kilometres: the error bound is relative
    scale = max(1.0, float(np.max(np.abs(exact_result.h))))
    assert accuracy.max_height_error <= 1e-5 * scale



@pytest.mark.parametrize("method", ["BDF", "Adams", "auto"])
def test_a_max_step_too_short_for_a_phase_is_named_as_the_cause(monkeypatch, method):
    """A flight from 2 m lasts 0.63 s, a few steps without max_step: 50 steps of 1e-6 s cover 5e-5 s of it.

    The cause is max_step, whatever the method; advising method 'BDF' (the stiffness hint), as was
    done even to a BDF run, sends the user the wrong way.
    """
    import bouncingball.solvers.integrator as integrator

    monkeypatch.setattr(integrator, "MAX_STEPS_PER_PHASE", 50)
    with pytest.raises(integrator.SolverError) as failure:
        bouncingball.simulate(Ball(), 2.0, 0.0, 1.0, 1e-3, method=method, max_step=1e-6)
    message = str(failure.value)
    assert "took more than 50 steps in one flight phase" in message
    assert "max_step = 1e-06 s lets 50 steps cover only 5e-05 s; raise max_step" in message
    assert "use method 'BDF'" not in message
    assert bouncingball.simulate(Ball(), 2.0, 0.0, 0.6, 1e-3, method=method).stats.steps < 50  # the flight alone


def test_a_method_fighting_stiffness_fails_with_a_reason(monkeypatch):
    """Past MAX_STEPS_PER_PHASE steps in one phase CVODE stops with the reason, rather than run for hours.

    Adams crept a ball out of a k = 1e12, damping ratio 100 contact lifted by F_ext = 2 m g in steps
    of ~1e-8 s. Such a lifted contact is now taken on its exact flow; the cap is shown here lowered
    to 50 steps, which Adams needs more of for one k = 1e12 contact of the article's ball.
    """
    import bouncingball.solvers.integrator as integrator

    monkeypatch.setattr(integrator, "MAX_STEPS_PER_PHASE", 50)
    with pytest.raises(integrator.SolverError, match="took more than 50 steps in one contact phase.*use method 'BDF'"):
        bouncingball.simulate(Ball(k=1e12), 2.0, 0.0, 1.0, 1e-3, method="Adams")
    ball = Ball(k=1e12, m=1.0, b=2e8)
    h0, F_ext = ball.R - 1e-3, 2.0 * ball.m * ball.g
    result = bouncingball.simulate(ball, h0, 0.0, 0.01, 1e-4, F_ext=F_ext, method="Adams")
    exact = ExactSolution(ball, h0, 0.0, 0.0, 0.01, F_ext)
    assert result.stats.steps < 50 and [e.kind for e in result.events] == ["departure"]
    assert result.events[0].time == pytest.approx(exact.events[0].time, rel=1e-12)


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
@pytest.mark.parametrize("name", BUILTIN_SCENES)
def test_advance_and_integrate_grid_agree(name, engine):
    """The FMU's path (advance to each communication point) and the grid path give the same trajectory."""
    scene = load_scene(name)
    grid = output_grid(0.0, scene.t_end, max(scene.output_interval, scene.t_end / 2000))
    settings = CvodeSettings(engine=engine)
    h_grid, v_grid, grid_events = BallIntegrator(scene.ball, scene.h0, scene.v0, settings=settings).integrate_grid(grid)
    stepped = BallIntegrator(scene.ball, scene.h0, scene.v0, settings=settings)
    events, h_step = [], [scene.h0]
    for t in grid[1:]:
        events += stepped.advance(t)
        h_step.append(stepped.h)
    assert [e.kind for e in events] == [e.kind for e in grid_events]
    scale = height_scale(h_grid, scene.ball.R)
    # each path is within ~1e-6 of the scale of the exact solution (test_every_builtin_scene...); they must
    # agree at least that well with each other
    assert np.max(np.abs(np.array(h_step) - h_grid)) <= 1e-6 * scale


def test_the_sksundae_adapter_still_fits_scikit_sundae():
    """engines/sksundae_events.py reads scikit-sundae's private root records: fail loudly if a release changes them."""
    from sksundae.cvode import CVODE

    from bouncingball.solvers.engines import sksundae_events

    def rhs(t, y, yp):
        yp[0] = -1.0

    def events(t, y, e):
        e[0], e[1] = y[0] - 0.5, y[0] + 5.0  # the first crosses at t = 0.5, the second never before 1

    events.terminal, events.direction = [True, False], [-1, 0]
    solver = CVODE(rhs, eventsfn=events, num_events=2)
    solution = solver.solve([0.0, 1.0], [1.0])
    assert solution.status == 2 and abs(solution.t[-1] - 0.5) < 1e-8  # stopped at the terminal root
    assert sksundae_events.roots_found(events) == [-1, 0]
    for field in ("_i", "_t", "_y", "_i_cnt"):
        assert hasattr(events, field), field
    sksundae_events.clear(events)
    assert sksundae_events.roots_found(events) == [] and not any(events._i_cnt)


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_pooled_cvode_objects_integrate_as_new_ones(engine):
    """simulate keeps its CVODE objects for the next run (solvers/engines/stepper.py): another ball between two
    runs, and a run on new objects, change no number."""
    if engine == "compiled":
        pytest.importorskip("numba")
    from bouncingball.solvers.engines import stepper

    def run(ball, h0):
        result = bouncingball.simulate(ball, h0, 0.0, 3.0, engine=engine)
        return result.h, result.v, result.events, result.stats.steps, result.stats.rhs_calls

    first = run(Ball(), 2.0)
    other = run(Ball(m=0.1, k=1e6, b=3.0, R=0.01, g=1.62), 1.0)
    again = run(Ball(), 2.0)
    stepper._pool.clear()
    fresh = run(Ball(), 2.0)
    for result in (again, fresh):
        np.testing.assert_array_equal(result[0], first[0])
        np.testing.assert_array_equal(result[1], first[1])
        assert result[2:] == first[2:]
    exact = ExactSolution(Ball(m=0.1, k=1e6, b=3.0, R=0.01, g=1.62), 1.0, 0.0, 0.0, 3.0)
    assert [e.kind for e in other[2]] == [e.kind for e in exact.events]
    assert np.max(np.abs(other[0] - exact.state(output_grid(0.0, 3.0, 1e-3))[0])) <= 1e-8


def test_a_state_its_restart_point_does_not_lead_to_continues_from_the_state():
    """A state put together by hand (another run's restart point) is not followed to where that restart
    leads: CVODE restarts at the state itself, and the run continues as one started there."""
    integrator = BallIntegrator(Ball(), 2.0, 0.0)
    integrator.advance(0.3)  # in the first fall, restarted at t = 0
    taken = integrator.get_state()
    moved = dataclasses.replace(taken, h=1.5, gap=1.5 - Ball().R, v=0.0)  # not on the fall from 2 m
    integrator.set_state(moved)
    assert (integrator.t, integrator.h, integrator.v) == (0.3, 1.5, 0.0)
    integrator.advance(2.0)
    exact = ExactSolution(Ball(), 1.5, 0.0, 0.3, 2.0)
    assert abs(integrator.h - exact.state([2.0])[0][0]) <= 1e-8
    assert integrator.impacts == sum(e.kind == "impact" for e in exact.events)


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])
def test_a_step_within_the_last_one_is_taken_only_from_the_time_the_caller_names(engine):
    """advance_within_step(t_target, t_from): nothing unless t_from is t exactly; then what advance(t_target) gives,
    bit for bit, on the exact solution."""
    from fmu_helpers import exact_at

    settings = CvodeSettings(engine=engine)
    integrator, twin = (BallIntegrator(Ball(), 2.0, 0.0, settings=settings) for _ in range(2))
    integrator.advance(0.3)
    twin.advance(0.3)
    t = integrator.t
    target = t + 1e-4  # the ball falls freely from 0.3 to 0.63 s: one CVODE step holds it
    for wrong in (math.nextafter(t, 0.0), math.nextafter(t, 1.0), 0.29, math.nan):
        assert integrator.advance_within_step(target, wrong) is False
        assert (integrator.t, integrator.h, integrator.v) == (twin.t, twin.h, twin.v)
    assert integrator.advance_within_step(target, t) is True
    twin.advance(target)
    assert (integrator.t, integrator.h, integrator.v) == (target, twin.h, twin.v)
    h_exact, _, _ = exact_at([target])
    assert abs(integrator.h - h_exact[0]) < 1e-9
    later = target + 1e-4
    assert integrator.advance_within_step(later, target) is True  # from where it now is
    assert integrator.advance_within_step(target, later) is False and integrator.t == later  # back in time: never
