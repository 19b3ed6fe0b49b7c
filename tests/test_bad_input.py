"""Bad input raises a ValueError that names the field, its value and what is allowed."""

import math

import numpy as np
import pytest

import bouncingball
from bouncingball.physics import Ball

BALL = Ball()


@pytest.mark.parametrize("kwargs, message", [
    (dict(h0=math.nan), "h0 = nan m is not allowed: it must be a finite number"),
    (dict(v0=math.nan), "v0 = nan m/s is not allowed: it must be a finite number"),
    (dict(v0=math.inf), "v0 = inf m/s is not allowed"),
    (dict(t_end=0.0), "t_end = 0.0 s is not allowed: it must be > t_start = 0.0 s"),
    (dict(t_end=-1.0), "t_end = -1.0 s is not allowed"),
    (dict(output_interval=0.0), "output_interval = 0.0 s is not allowed: it must be in (0, 8]"),
    (dict(output_interval=-1e-3), "output_interval = -0.001 s is not allowed"),
    (dict(output_interval=9.0), "output_interval = 9.0 s is not allowed: it must be in (0, 8]"),
    (dict(solver="euler"), "solver = 'euler' is not allowed: it must be one of cvode, exact, scipy"),
    (dict(method="RK4"), "method = 'RK4' is not allowed: it must be one of auto, Adams, BDF"),
    (dict(solver="scipy", method="Adams"), "method = 'Adams' is not allowed: it must be one of RK45"),
    (dict(rtol=0.0), "rtol = 0.0 is not allowed: it must be in [1e-15, 1] (CVODE cannot honour"),
    (dict(rtol=1e-17), "rtol = 1e-17 is not allowed: it must be in [1e-15, 1] (CVODE cannot honour"),
    (dict(rtol=10**400), "rtol = 1e+400 is not allowed: it must be in [1e-15, 1]"),
    (dict(atol=-1.0), "atol = -1.0 m is not allowed: it must be finite and >= 0"),
    # an ulp of max(|h0|, R) = 2 m: 2**-51
    (dict(atol=1e-320), "atol = 1e-320 m is not allowed: it must be 0 (none) or finite and >= 4.440892098500626e-16"),
    (dict(atol=4.4e-16), "atol = 4.4e-16 m is not allowed: it must be 0 (none) or finite and >= 4.440892098500626e-16"),
    (dict(max_step=1e-320), "max_step = 1e-320 s is not allowed: it must be 0 (none) or finite and >= 8e-07 s"),
    (dict(max_step=7.9e-7), "max_step = 7.9e-07 s is not allowed: it must be 0 (none) or finite and >= 8e-07 s"),
    (dict(h0=10**400), "h0 = 1e+400 m is not allowed: it must be a finite number"),
    (dict(v0=-10**400), "v0 = -1e+400 m/s is not allowed: it must be a finite number"),
    (dict(t_end=10**400), "t_end = 1e+400 s is not allowed: it must be a finite number"),
    (dict(F_ext=10**400), "F_ext = 1e+400 N is not allowed"),
    (dict(max_step=-1.0), "max_step = -1.0 s is not allowed"),
    (dict(solver="exact", rtol=1e-6), "option rtol = 1e-06 is not allowed for solver 'exact': it takes no options"),
    (dict(tolerance=1e-6), "option tolerance = 1e-06 is not allowed for solver 'cvode': it takes rtol, atol"),
    (dict(t_end=1e6), "it gives 1e+09 output points, more than 5e+07; choose output_interval >= 0.02 s"),
    (dict(t_end=1e6, solver="exact"), "it gives 1e+09 output points"),
    (dict(h0=True), "h0 = True is not allowed: it must be a number"),
    (dict(v0="1"), "v0 = '1' is not allowed: it must be a number"),
])
def test_simulate_rejects_bad_input(kwargs, message):
    arguments = dict(h0=2.0, v0=0.0, t_end=8.0)
    arguments.update(kwargs)
    with pytest.raises(ValueError) as info:
        bouncingball.simulate(BALL, **arguments)
    assert message in str(info.value)


def test_method_names_are_case_insensitive():
    result = bouncingball.simulate(BALL, 2.0, 0.0, 1.0, method="bdf")
    assert result.options["contact_method"] == "BDF"


@pytest.mark.parametrize("field", ["m", "k", "b", "R", "g"])
def test_an_int_beyond_double_precision_is_refused_by_name(field):
    with pytest.raises(ValueError, match=rf"^{field} = 1e\+400 .* is not allowed: it must be finite"):
        Ball(**{field: 10**400})


@pytest.mark.parametrize("kwargs", [dict(max_step=1e-320), dict(rtol=1e-17), dict(atol=1e-320)])
def test_settings_cvode_cannot_honour_are_refused_within_a_second(kwargs):
    """max_step = 1e-320 never returned; rtol 1e-17 and atol 1e-320 failed at t = 0 naming neither."""
    import time

    started = time.perf_counter()
    with pytest.raises(ValueError, match=rf"^{next(iter(kwargs))} = "):
        bouncingball.simulate(BALL, 2.0, 0.0, 8.0, **kwargs)
    assert time.perf_counter() - started < 1.0


def test_atol_zero_means_none():
    result = bouncingball.simulate(BALL, 2.0, 0.0, 1.0, atol=0)
    assert result.options["atol"] is None
    assert np.array_equal(result.h, bouncingball.simulate(BALL, 2.0, 0.0, 1.0).h)


# --- the stepping integrator ---------------------------------------------------------------------------
def _integrator():
    from bouncingball.solvers.cvode import BallIntegrator

    return BallIntegrator(BALL, 2.0, 0.0)


@pytest.mark.parametrize("value, message", [
    (1e300, "F_ext = 1e+300 N is not allowed for this ball (m = 1 kg, k = 10000 N/m, R = 0.06 m, g = 9.81 m/s2): "
            "it must be in [-1e+152, 1e+152] N"),
    (10**400, "F_ext = 1e+400 N is not allowed: it must be a finite number"),
    (None, "F_ext = None is not allowed: it must be a number"),
])
def test_the_integrator_refuses_an_F_ext_simulate_refuses_and_changes_nothing(value, message):
    integrator = _integrator()
    with pytest.raises(ValueError) as info:
        integrator.F_ext = value
    assert message in str(info.value)
    if value == 1e300:  # the same value and range as simulate's
        with pytest.raises(ValueError) as from_simulate:
            bouncingball.simulate(BALL, 2.0, 0.0, 1.0, F_ext=value)
        assert str(info.value) == str(from_simulate.value)
    assert integrator.F_ext == 0.0
    assert [str(e.kind) for e in integrator.advance(1.0)] == ["impact", "departure"]


@pytest.mark.parametrize("target", [None, "1", 10**400])
def test_advance_refuses_a_target_that_is_not_a_number_by_name(target):
    integrator = _integrator()
    with pytest.raises(ValueError, match=r"^t_target = .* is not allowed: it must be a"):
        integrator.advance(target)
    with pytest.raises(ValueError, match=r"^t_target = "):
        integrator.advance_within_step(target)
    if target is not None:  # t_from None: from t, wherever it is
        with pytest.raises(ValueError, match=r"^t_from = .* is not allowed: it must be a"):
            integrator.advance_within_step(0.1, target)
    assert integrator.t == 0.0 and integrator.advance(0.5) == []


def test_set_state_refuses_what_is_not_a_state_by_name():
    integrator = _integrator()
    with pytest.raises(ValueError, match=r"^state = None is not allowed: it must be an IntegratorState"):
        integrator.set_state(None)
    assert integrator.t == 0.0 and integrator.h == 2.0


@pytest.mark.parametrize("t, h, message", [
    (0.0, 0.01, "is not allowed in flight: it must be at or above R = 0.06 m"),
    (0.64, 1.0, "is not allowed in contact: it must be at or below R = 0.06 m"),
])
def test_set_state_refuses_a_mode_that_contradicts_the_height(t, h, message):
    """A flight below R gave a ZeroDivisionError at the next advance, a contact at 1 m a misleading "tighten rtol"."""
    from dataclasses import replace

    integrator = _integrator()
    integrator.advance(t)  # the first impact is at 0.6277 s: in contact at 0.64 s
    saved = integrator.get_state()
    for restart in (saved.restart, None):
        with pytest.raises(ValueError) as info:
            integrator.set_state(replace(saved, h=h, gap=None, restart=restart))
        assert str(info.value).startswith(f"state h = {h!r} m (h - R = {h - 0.06!r} m) {message} (within ")
        assert integrator.get_state() == saved  # nothing changed, and it goes on
    exact = bouncingball.simulate(BALL, 2.0, 0.0, 1.0, solver="exact")
    integrator.advance(1.0)
    assert integrator.h == pytest.approx(float(exact.h[-1]), abs=1e-9)


def test_set_state_takes_back_every_state_of_a_run():
    """The check of the mode against the height allows what CVODE's own steps show (a merged hop, a step end
    just past R): each state a damped run passes through, restored, continues bit for bit."""
    from bouncingball.solvers.cvode import BallIntegrator

    integrator = BallIntegrator(Ball(b=30.0), 0.5, 0.0)
    states = []
    for t in np.linspace(0.0, 3.0, 601)[1:]:
        integrator.advance(t)
        states.append(integrator.get_state())
    for saved in states[::7]:
        fresh = BallIntegrator(Ball(b=30.0), 0.5, 0.0)
        fresh.set_state(saved)
        assert fresh.get_state() == saved


@pytest.mark.parametrize("simulate_on_grid", ["simulate_cvode", "simulate_exact"])
def test_the_solvers_own_entry_points_refuse_an_end_before_the_start_by_name(simulate_on_grid):
    """bouncingball.simulate checks t_end first; its solvers' functions, called directly, are refused alike."""
    from bouncingball.solvers import cvode, exact

    function = {"simulate_cvode": cvode.simulate_cvode, "simulate_exact": exact.simulate_exact}[simulate_on_grid]
    with pytest.raises(ValueError, match=r"^t_end = 0.0 s is not allowed: it must be >= t_start = 1.0 s$"):
        function(Ball(), 2.0, 0.0, 0.0, 1e-3, t_start=1.0)
    assert len(function(Ball(), 2.0, 0.0, 1.0, 1e-3, t_start=1.0).t) == 1  # an empty span: its one point


# --- Hunt-Crossley's alpha: the range its scene allows (README, limits.check_alpha) -------------------------------
HC_BALL = dict(contact="hunt-crossley", k=1e6, n=1.5)


def _alpha_bound(h0, rtol, m=1.0, k=1e6, n=1.5, R=0.06, g=9.81):
    """The README's rule written out: min(1e150, 1 / rtol) 2 / (3 v), v the fall's speed at R and the spring's share
    down to the static deflection d = (m g / k)^(1/n)."""
    d = (m * g / k) ** (1.0 / n)
    v = math.sqrt(2.0 * g * (h0 - R) + 2.0 * g * d * n / (n + 1.0))
    return min(1e150, 1.0 / rtol) * 2.0 / (3.0 * v), v


def _bound_in(message: str) -> float:
    return float(message.split("it must be in [0, ")[1].split("]")[0])


@pytest.mark.parametrize("alpha, rtol", [(1e50, 1e-12), (1e20, 1e-12), (2e8, 1e-8), (2e14, 1e-15)])
def test_an_alpha_whose_release_cvode_cannot_resolve_is_refused_by_name_before_any_work(alpha, rtol):
    """alpha = 1e50 failed in CVODE after 3 s (CV_CONV_FAILURE at the first impact), 1e20 after 500,000 steps,
    neither naming alpha."""
    bound, speed = _alpha_bound(2.0, rtol)
    with pytest.raises(ValueError) as info:
        bouncingball.simulate(Ball(alpha=alpha, **HC_BALL), 2.0, 0.0, 3.0, rtol=rtol)
    message = str(info.value)
    assert message.startswith(f"alpha = {alpha!r} s/m is not allowed for this scene (h0 = 2.0 m, v0 = 0.0 m/s, "
                              f"g - F_ext/m = 9.81 m/s2: a contact speed up to {speed:.4g} m/s): it must be in [0, ")
    assert _bound_in(message) == pytest.approx(bound, rel=1e-9)
    assert (f"its release speed 2 / (3 alpha) = {2.0 / (3.0 * alpha):.3g} m/s must be >= rtol = {rtol:g} times "
            "that speed, which CVODE resolves; lower alpha, or tighten rtol") in message


def test_the_stepping_api_and_the_fmu_refuse_the_same_alpha_with_the_same_message():
    from bouncingball.fmu.documentation import _Host
    from bouncingball.solvers.cvode import BallIntegrator

    ball = Ball(alpha=1e20, **HC_BALL)
    with pytest.raises(ValueError) as from_simulate:
        bouncingball.simulate(ball, 2.0, 0.0, 3.0)
    with pytest.raises(ValueError) as from_integrator:
        BallIntegrator(ball, 2.0, 0.0)
    assert str(from_integrator.value) == str(from_simulate.value)
    integrator = BallIntegrator(Ball(alpha=5e10, **HC_BALL), 2.0, 0.0)  # allowed: up to 1.08e11 s/m from 2 m
    with pytest.raises(ValueError, match=r"^alpha = 50000000000.0 s/m is not allowed for this scene \(h0 = 2.0 m, "
                                         r"v0 = 0.0 m/s, g - F_ext/m = 109.8 m/s2: a contact speed up to 20.65 m/s"):
        integrator.F_ext = -100.0  # pushed down: it lands faster, and alpha's bound is 3.2e10 s/m
    assert integrator.F_ext == 0.0 and integrator.t == 0.0
    slave = _Host(stop_at_event=False)
    for name, value in dict(contact_law="hunt-crossley", k=1e6, n=1.5, alpha=1e20, h=2.0).items():
        slave.setters[name](value)
    slave.setup_experiment(0.0)
    slave.exit_initialization_mode()
    assert slave._integrator is None and len(slave.errors()) == 1
    assert str(from_simulate.value) in slave.errors()[0]


def test_an_alpha_that_would_overflow_the_force_is_refused_where_no_rtol_is_known():
    """A scene file is read without a solver: its alpha is held to the overflow rule, 3/2 alpha v <= 1e150."""
    from bouncingball.scenes import scene_from_mapping

    bound, speed = _alpha_bound(2.0, 1e-300)
    with pytest.raises(ValueError) as info:
        scene_from_mapping("hc", dict(contact="hunt-crossley", k=1e6, alpha=1e160, h0=2.0))
    message = str(info.value)
    assert message.startswith("alpha = 1e+160 s/m is not allowed for this scene (h0 = 2.0 m")
    assert _bound_in(message) == pytest.approx(bound, rel=1e-9)
    assert message.endswith("3/2 alpha v must stay <= 1e+150, or the force k delta^n (1 + 3/2 alpha v) overflows")
    scene = scene_from_mapping("hc", dict(contact="hunt-crossley", k=1e6, alpha=1e20, h0=2.0))  # read; not run
    with pytest.raises(ValueError, match=r"^alpha = 1e\+20 s/m is not allowed for this scene"):
        scene.simulate()


def test_an_alpha_within_its_range_runs_and_one_where_the_ball_never_lands_has_no_bound():
    bound, _ = _alpha_bound(2.0, 1e-12)
    result = bouncingball.simulate(Ball(alpha=0.5 * bound, **HC_BALL), 2.0, 0.0, 1.0)
    assert len(result.events) == 1 and result.events[0].kind == "impact"  # it sticks: no departure
    assert result.h[-1] < 0.06
    lifted = Ball(alpha=1e100, **HC_BALL)  # lifted off from above R: never in contact
    assert bouncingball.simulate(lifted, 2.0, 1.0, 1.0, F_ext=20.0).events == []


# --- F_ext tables: linear time, and a limit ----------------------------------------------------------------------
def test_a_force_table_beyond_its_limit_is_refused_naming_the_limit():
    from bouncingball.solvers.forcing import MAX_TABLE_ENTRIES

    many = np.broadcast_to(0.0, (MAX_TABLE_ENTRIES + 1,))  # no memory: the size is refused before any copy
    with pytest.raises(ValueError) as info:
        bouncingball.simulate(BALL, 2.0, 0.0, 1.0, F_ext=(many, many))
    assert str(info.value) == ("F_ext table of 1000001 entries is not allowed: it must have at most 1e+06 (each is "
                               "checked before the run, up to a second for the most, and each change of force inside "
                               "the run restarts the integrator); resample it coarser, or split the run into shorter "
                               "ones (t_start, and the state at the end of the one before)")


@pytest.mark.parametrize("table, message", [
    ((np.array([0.0, 1.0, 1.0]), np.zeros(3)), "F_ext times[2] = 1.0 s is not allowed: the times must increase "
                                               "strictly (times[1] = 1.0 s)"),
    ((np.array([0.0, np.nan]), np.zeros(2)), "F_ext times[1] = nan s is not allowed: it must be a finite number"),
    (([0.0, 1.0], [0.0, "1"]), "F_ext values[1] = '1' is not allowed: it must be a number"),
    (([0.0, 1.0], [0.0, True]), "F_ext values[1] = True is not allowed: it must be a number"),
    (([0.0, 1.0], [0.0, 10**400]), "F_ext values[1] = 1e+400 N is not allowed: it must be a finite number"),
])
def test_a_force_tables_entries_are_checked_in_numpy_and_the_first_bad_one_named(table, message):
    with pytest.raises(ValueError) as info:
        bouncingball.simulate(BALL, 2.0, 0.0, 1.0, F_ext=table)
    assert str(info.value) == message


def _allows(check, scene, force) -> bool:
    ball, h0, v0, t_end, rtol = scene
    try:
        check(ball, h0, v0, force, 0.0, t_end, None, rtol)
    except ValueError:
        return False
    return True


def test_a_force_table_is_refused_exactly_where_one_of_its_forces_alone_would_be():
    """check_forces checks the smallest and largest force (each rule but the run's length is convex in g - F/m)
    and every force only where the run is long enough for its length rule to matter: the verdict of each force
    checked alone, over random tables across the range, as the oracle."""
    from bouncingball import limits

    rng = np.random.default_rng(43)
    refused = 0
    for _ in range(300):
        ball = Ball(m=10 ** rng.uniform(-3, 3), k=10 ** rng.uniform(0, 8), **(
            dict(contact="hunt-crossley", alpha=10 ** rng.uniform(-2, 12)) if rng.random() < 0.5 else {}))
        forces = ball.m * ball.g * rng.uniform(-3.0, 3.0, 5)
        if rng.random() < 0.3:
            forces[rng.integers(5)] *= 10 ** rng.uniform(0, 160)
        h0, v0 = 10 ** rng.uniform(-3, 200), rng.normal() * 10 ** rng.uniform(-3, 3)
        t_end = 10 ** rng.uniform(0, 300)
        rtol = rng.choice([None, 1e-8])
        scene = ball, h0, v0, t_end, rtol
        alone = all(_allows(limits.check_scene, scene, force) for force in forces)
        assert _allows(limits.check_forces, scene, forces) == alone, (scene, forces)
        refused += not alone
    assert 50 < refused < 250  # both verdicts sampled
