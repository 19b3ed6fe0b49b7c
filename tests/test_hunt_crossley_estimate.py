"""The Hunt-Crossley law's error estimate against its independent truth (tests/hunt_crossley_truth.py).

The estimate is never below the true error (max |h - h_true| on the grid) and within 1000x of it in at least 95%
of random scenes, the undamped ones (alpha = 0) included; it does not warn where the true error is far below the
promise (1e-6 of max(|h|, R)). The truth is an mpmath Taylor integrator: 2 to 60 s a contact on a loaded 2-core
machine, so every comparison with it is slow.
"""

from __future__ import annotations

import math
import random
import warnings

import numpy as np
import pytest

from bouncingball import Ball, simulate
from bouncingball.solvers.result import AccuracyWarning
from hunt_crossley_truth import HuntCrossleyTruth

G = 9.81
PROMISE = 1e-6  # of the height scale max(|h|, R): the run's promise

# (n, alpha [s/m], k [N/m^n], m [kg], R [m], h0 [m], t_end [s]): the worst of issue 43's campaign.
# Undamped, estimated at 2.19e5x its true error: CVODE's own error of v in the contact was carried into the
# flight after it, though the departure's speed is set to the impact's.
UNDAMPED_WORST = (1.5, 0.0, 5.7158929e7, 0.5757, 0.06431, 1.6571, 2.0)
# Stiff (k = 1.4e13): warned at 3.9e-5 of its height scale where the true error is 2.3e-9 m (3.3e-9 of it); the
# error from before each contact grew 100x in v through it (the step matrices carried a shift in time inexactly).
SPURIOUS_WARNING = (1.3167643594735918, 0.002726790044536931, 13732571177168.23, 0.2810287470313335,
                    0.003706670128046131, 0.6966180751168793, 2.2085804767739177)


def _run(case, points=200):
    n, alpha, k, m, R, h0, t_end = case
    ball = Ball(m=m, k=k, R=R, contact="hunt-crossley", n=n, alpha=alpha)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = simulate(ball, h0, 0.0, t_end, t_end / points)
    return result, [w for w in caught if issubclass(w.category, AccuracyWarning)]


def _true_error(case, result) -> tuple[float, float]:
    """(max |h - h_true| [m] on the run's grid, the height scale max(|h_true|, R) [m])."""
    n, alpha, k, m, R, h0, t_end = case
    truth = HuntCrossleyTruth(m, k, n, alpha, R, G, h0, 0.0, t_end)
    h_true = np.array([float(truth.state(t)[0]) for t in result.t])
    assert [str(e.kind) for e in result.events] == [kind for _, kind, _ in truth.events]
    return float(np.max(np.abs(result.h - h_true))), max(float(np.max(np.abs(h_true))), R)


def test_the_stiff_case_that_warned_does_not_and_its_estimate_is_within_the_promise():
    """Its true error, 1.6e-9 m on this grid (the slow test below), is 2.3e-9 of its height scale."""
    result, warned = _run(SPURIOUS_WARNING)
    scale = max(float(np.max(np.abs(result.h))), SPURIOUS_WARNING[4])
    assert warned == []
    assert result.error_estimate < 0.1 * PROMISE * scale  # was 3.9e-5 of the scale; measured 4.5e-8


@pytest.mark.slow  # the truth: ~15 s (undamped) and ~80 s (stiff) on a loaded 2-core machine
@pytest.mark.parametrize("case", [UNDAMPED_WORST, SPURIOUS_WARNING], ids=["undamped-worst", "spurious-warning"])
def test_the_campaigns_worst_cases_are_honest_and_within_1000x(case):
    """Measured: undamped 9.0e-14 m true, estimate 354x it (was 2.9e5x); stiff 1.6e-9 m, 19x (was 1.7e4x)."""
    result, warned = _run(case)
    error, scale = _true_error(case, result)
    assert error <= result.error_estimate <= 1000.0 * error, (error, result.error_estimate)
    assert warned == [] and error < 0.01 * PROMISE * scale  # the stiff one's: 2.3e-9 of its scale


def random_scenes(count: int, seed: int = 7):
    """count drops of one contact each and most of the flight after it (the error a contact leaves in v shows there).

    n in [1, 2.5]; alpha 0 in 30% of them, else log-uniform in [1e-3, 1] s/m; k 1e3 .. 1e13 N/m^n, m 0.03 .. 10 kg,
    R 1 mm .. 0.3 m, drops 1 mm .. 3 m above R, all log-uniform; t_end 1.6 to 1.95 fall times.
    """
    rng = random.Random(seed)
    for _ in range(count):
        n = rng.uniform(1.0, 2.5)
        alpha = 0.0 if rng.random() < 0.3 else 10 ** rng.uniform(-3, 0)
        k, m, R = 10 ** rng.uniform(3, 13), 10 ** rng.uniform(-1.5, 1), 10 ** rng.uniform(-3, -0.5)
        h0 = R + 10 ** rng.uniform(-3, 0.5)
        yield n, alpha, k, m, R, h0, math.sqrt(2.0 * (h0 - R) / G) * rng.uniform(1.6, 1.95)


PROPERTY_SCENES = 24


def _assert_honest_and_within_1000x(cases) -> None:
    """Every estimate at or above its true error; within 1000x of it in >= 95% of the scenes whose true error is
    above rounding (64 ulps of the height scale, as tests/test_error_estimate.py judges); no warning where the true
    error is 1000x below the promise."""
    ratios, spurious = [], []
    for case in cases:
        result, warned = _run(case)
        error, scale = _true_error(case, result)
        assert error <= result.error_estimate, (case, error, result.error_estimate)
        if error > 64.0 * 2.0**-52 * scale:
            ratios.append(result.error_estimate / error)
        if warned and error < 1e-3 * PROMISE * scale:
            spurious.append(case)
    assert np.mean(np.array(ratios) <= 1000.0) >= 0.95, ratios
    assert spurious == []


@pytest.mark.slow  # the truth: ~25 s a scene (40 to 80 s loaded)
def test_the_estimate_over_every_sixth_random_scene_is_honest_and_within_1000x():
    """The test suite's share of the 24 scenes below (every sixth, 4 of them): the study is too long for it.

    Measured: scenes 0, 6, 12 and 18 at 265, 15, 21 and 41 times their true errors (every third, 8 scenes, took 320 s
    of a loaded suite's run; the study runs all 24).
    """
    _assert_honest_and_within_1000x(list(random_scenes(PROPERTY_SCENES))[::6])


@pytest.mark.slow
@pytest.mark.study  # ~10 min: `pytest -m study` runs it
def test_the_estimate_over_random_scenes_is_honest_and_within_1000x_in_95_percent():
    """All 24 scenes.

    Measured: 22 of the 24 above rounding, their ratios 13.9 to 1271 (median 35; the 8 undamped 82 to 1271), 21 of
    them (95.5%) within 1000x. Above it an undamped drop whose true error is 8.8e-15 m (1271x: phase_error's floor of
    10 rtol of the flight's length is 4.8e-12 m, the contact's own error counted from CVODE's error test 3.2e-12 m);
    at rounding two more undamped ones, 1.9e-15 m (3610x) and 1.3e-16 m (6350x). No warning. 800 s under load.
    """
    _assert_honest_and_within_1000x(random_scenes(PROPERTY_SCENES))
