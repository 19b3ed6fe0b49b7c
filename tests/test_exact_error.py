"""The judge's own error: the exact solver's error estimate against independent truths.

solver="exact" evaluates closed forms in double precision; its estimate carries their rounding through the run's
transition and saltation matrices (solvers/exact_error.py). Judged here against the mpmath solution of the linear
law (tests/mpmath_oracle.py), the rigid and no-pull truths (tests/rigid_truth.py, tests/nopull_truth.py) and the
undamped ball's periodic closed form (tests/closed_forms.py): at or above the true error in >= 99% of each
family's cases, and where the judge cannot decide, `check` says so.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.check.judge import check_result
from closed_forms import first_impact_time, undamped_heights
from nopull_truth import NoPullTruth
from rigid_truth import RigidTruth
from test_error_estimate import NEAR_WEIGHTLESS, NEAR_WEIGHTLESS_H0, near_weightless_table, random_case, true_error
from test_long_runs import bounce_period

EPS = np.finfo(float).eps


def exact_run(ball, h0, v0, t_end, dt, F_ext=0.0):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = bb.simulate(ball, h0, v0, t_end, dt, solver="exact", F_ext=F_ext)
    return result, [w for w in caught if issubclass(w.category, bb.AccuracyWarning)]


def assert_honest(ratios: list[float], share: float) -> None:
    """At least share of the estimates at or above their true error, and none below half of it."""
    ratios = np.array(ratios)
    assert np.mean(ratios >= 1.0) >= share, np.sort(ratios)[:5]
    assert np.all(ratios >= 0.5), np.sort(ratios)[:5]


# --- the linear law: random scenes (tests/test_error_estimate.py's family) ---------------------------------------
def linear_ratios(seed: int, count: int) -> list[float]:
    rng = np.random.default_rng(seed)
    ratios = []
    while len(ratios) < count:
        ball, h0, v0, t_end, dt, F_ext = random_case(rng)
        result, _ = exact_run(ball, h0, v0, t_end, dt, F_ext)
        if len(result.events) > 400:
            continue  # the oracle's time
        truth = true_error(result, h0, v0)
        ratios.append(result.error_estimate / truth if truth > 0.0 else math.inf)
    return ratios


def test_the_exact_solvers_estimate_covers_its_error_on_random_linear_scenes():
    assert_honest(linear_ratios(7, 20), 1.0)


@pytest.mark.slow
def test_the_exact_solvers_estimate_covers_its_error_on_a_hundred_random_linear_scenes():
    assert_honest(linear_ratios(2026, 120), 0.99)


# --- F_ext tables around m g: light damping, long near-weightless flights (a campaign's ill-conditioned family) ---
def near_weightless_ratios(seeds) -> list[float]:
    ratios = []
    for seed in seeds:
        result, caught = exact_run(bb.Ball(**NEAR_WEIGHTLESS), NEAR_WEIGHTLESS_H0, 0.0, 15.0, 0.015,
                                   near_weightless_table(seed))
        truth = true_error(result, NEAR_WEIGHTLESS_H0, 0.0)
        scale = max(float(np.max(np.abs(result.h))), NEAR_WEIGHTLESS["R"])
        assert not caught or result.error_estimate > 1e-6 * scale  # a warning only past the promise
        ratios.append(result.error_estimate / truth if truth > 0.0 else math.inf)
    return ratios


def test_the_exact_solvers_estimate_covers_its_error_under_forces_near_the_weight():
    assert_honest(near_weightless_ratios(range(8)), 1.0)


@pytest.mark.slow
def test_the_exact_solvers_estimate_covers_its_error_under_a_hundred_forces_near_the_weight():
    assert_honest(near_weightless_ratios(range(100, 200)), 0.99)


# --- the rigid and no-pull laws against their mpmath truths -----------------------------------------------------
def test_the_exact_solvers_estimate_covers_its_error_under_the_rigid_law():
    rng = np.random.default_rng(11)
    ratios = []
    for _ in range(12):
        R, e, drop = 10 ** rng.uniform(-3, 0), rng.uniform(0.05, 0.95), 10 ** rng.uniform(-6, 1)
        v_min = rng.choice([0.0, 10 ** rng.uniform(-3, -1)])
        ball = bb.Ball(contact="rigid", e=e, v_min=v_min, R=R)
        t_end = 4 * math.sqrt(2 * drop / 9.81)
        result, _ = exact_run(ball, R + drop, 0.0, t_end, t_end / 300)
        truth_heights = RigidTruth(R, 9.81, e, v_min, R + drop, 0.0, t_end).heights(result.t)
        truth = float(np.max(np.abs(result.h - np.array(truth_heights, dtype=float))))
        ratios.append(result.error_estimate / truth if truth > 0.0 else math.inf)
    assert_honest(ratios, 1.0)


def test_the_exact_solvers_estimate_covers_its_error_under_the_no_pull_law():
    rng = np.random.default_rng(12)
    ratios = []
    for _ in range(8):
        b, drop = 10 ** rng.uniform(0, 2.5), 10 ** rng.uniform(-3, 0.5)
        ball = bb.Ball(contact="linear-no-pull", b=b)
        t_end = 3 * math.sqrt(2 * drop / 9.81)
        result, _ = exact_run(ball, ball.R + drop, 0.0, t_end, t_end / 300)
        truth_heights = NoPullTruth(ball.m, ball.k, b, ball.R, 9.81, ball.R + drop, 0.0, t_end).heights(result.t)
        truth = float(np.max(np.abs(result.h - np.array(truth_heights, dtype=float))))
        ratios.append(result.error_estimate / truth if truth > 0.0 else math.inf)
    assert_honest(ratios, 1.0)


# --- long undamped runs: an error along the flow stays one, bounce after bounce ------------------------------
UNDAMPED = bb.Ball(b=0.0)


def undamped_ratio(bounces: int, output_interval: float) -> tuple[float, float]:
    t_end = first_impact_time(2.0, UNDAMPED.R, UNDAMPED.g) + bounces * bounce_period(UNDAMPED, 2.0) - 0.5
    result, caught = exact_run(UNDAMPED, 2.0, 0.0, t_end, output_interval)
    truth = float(np.max(np.abs(result.h - undamped_heights(UNDAMPED.m, UNDAMPED.k, UNDAMPED.R, UNDAMPED.g, 2.0,
                                                            result.t))))
    assert not caught
    return result.error_estimate / truth, result.error_estimate


@pytest.mark.parametrize("bounces, output_interval", [(1000, 0.01), (10_000, 0.1)])
def test_the_exact_solvers_estimate_covers_thousands_of_undamped_bounces(bounces, output_interval):
    ratio, estimate = undamped_ratio(bounces, output_interval)
    assert 1.0 <= ratio <= 1000.0 and estimate <= 1e-6 * 2.0


@pytest.mark.slow
def test_the_exact_solvers_estimate_covers_a_hundred_thousand_undamped_bounces():
    ratio, estimate = undamped_ratio(100_000, 1.0)
    assert 1.0 <= ratio <= 1000.0 and estimate <= 1e-6 * 2.0


# --- check: a judge that cannot decide says so ------------------------------------------------------------------
def test_check_says_undecided_where_the_judges_own_error_is_above_the_tolerance():
    article = bb.Ball()
    result = bb.simulate(article, 2.0, 0.0, 8.0, 0.01, solver="exact")
    columns = {"time": result.t, "h": result.h}
    judge_error = result.error_estimate
    assert 0.0 < judge_error < 1e-10
    decided = check_result(columns, "article", tolerance=1e-9)
    assert decided.passed and decided.verdict.startswith("PASS")
    assert f"judge's error      {judge_error:.3e} m" in decided.report()
    undecided = check_result(columns, "article", tolerance=judge_error / 10)
    assert not undecided.passed and undecided.verdict.startswith("UNDECIDED: the judge's own error estimate")
    assert f"{judge_error:.3e} m" in undecided.verdict and "loosen the tolerance above it" in undecided.verdict
    off = dict(columns, h=result.h + np.where(result.t > 4.0, 1e-6, 0.0))  # off by far more than the judge's error
    assert check_result(off, "article", tolerance=judge_error / 10).verdict.startswith("FAIL")
