"""Critical damping in floats (b = 2 sqrt(k m)) and 1 +- 1e-16 .. 1e-6 of it: right to the last digits (issue 29, C).

At b = 2 sqrt(k m) rounded, sigma^2 - k/m is a few ulps of k/m either way, and mu = sqrt(sigma^2 - k/m)
is ~1e-8 sigma; the over-damped closed form's two exponentials then agreed to ~1e-8 of their size and
the contact lost half its digits (7e-9 of the height scale in random scenes). The truth is
tests/mpmath_oracle.py (50 digits, written from the equations: it shares no code with the solvers).
"""

import math
import random

import numpy as np
import pytest

import bouncingball as bb
from mpmath_oracle import Oracle

G = 9.81
DAMPING_OFFSETS = [0.0, 1e-16, -1e-16, 1e-12, -1e-12, 1e-9, -1e-9, 1e-6, -1e-6]  # damping ratio - 1
TOLERANCE = 1e-15  # of the height scale max(|h|, R)


def random_balls(count, seed):
    """(m, k, R, F_ext) drawn over a few decades each; F_ext 0, a part of the weight, or twice it (lifted)."""
    rnd = random.Random(seed)
    balls = []
    for _ in range(count):
        m, k, R = 10 ** rnd.uniform(-2, 1), 10 ** rnd.uniform(2, 6), 10 ** rnd.uniform(-3, 0)
        balls.append((m, k, R, rnd.choice([0.0, rnd.uniform(0.0, 1.0), 2.0]) * m * G))
    return balls


def falling_scenes():
    """The article from 2 m and random balls dropped or thrown from above R: flights, contacts, departures."""
    rnd = random.Random(29)
    scenes = [(1.0, 1e4, 0.06, 0.0, 2.0, 0.0)]
    for m, k, R, F_ext in random_balls(6, seed=29):
        scenes.append((m, k, R, F_ext, R * (1 + 10 ** rnd.uniform(-2, 1)), rnd.uniform(-2.0, 2.0)))
    return scenes


def resting_scenes():
    """Random balls starting in contact within the energy bound of their rest height: a rest from t = 0.

    The CVODE solver takes such a contact on the exact flow at every damping ratio, so it is judged
    to the same digits as the exact solver.
    """
    rnd = random.Random(2029)
    scenes = []
    for m, k, R, F_ext in random_balls(6, seed=2029):
        F_ext = min(F_ext, 0.9 * m * G)  # the spring holds the ball
        d = (m * G - F_ext) / k  # static deflection
        w = math.sqrt(k / m)
        y0 = d * rnd.uniform(-0.7, 0.7)  # from the rest height
        v0 = w * d * rnd.uniform(-0.7, 0.7)
        scenes.append((m, k, R, F_ext, R - d + y0, v0))
    return scenes


def worst_error(solver, scene, offset, **options):
    """max |h - h_oracle| / max(|h_oracle|, R) on a 300-point grid over the fall and 30 / w of contact."""
    m, k, R, F_ext, h0, v0 = scene
    b = 2.0 * math.sqrt(k * m) * (1.0 + offset)
    fall = math.sqrt(2.0 * max(h0 - R, 0.0) / G) if F_ext < m * G else 0.0
    t_end = fall + 30.0 / math.sqrt(k / m)
    result = bb.simulate(bb.Ball(m=m, k=k, b=b, R=R, g=G), h0, v0, t_end, t_end / 300, solver=solver,
                         F_ext=F_ext, **options)
    h_true, _ = Oracle(m, k, b, R, G, h0, v0, t_end, F_ext=F_ext).state(result.t)
    return np.max(np.abs(result.h - h_true)) / max(np.max(np.abs(h_true)), R)


@pytest.mark.parametrize("offset", DAMPING_OFFSETS)
@pytest.mark.parametrize("scene", falling_scenes() + resting_scenes())
def test_exact_solver_is_right_to_its_last_digits(scene, offset):
    assert worst_error("exact", scene, offset) <= TOLERANCE


@pytest.mark.parametrize("engine", ["sksundae", "compiled"])  # the rest's flow interpreted, and compiled by numba
@pytest.mark.parametrize("offset", DAMPING_OFFSETS)
@pytest.mark.parametrize("scene", resting_scenes())
def test_cvode_solver_is_right_to_its_last_digits_on_the_exact_flow(scene, offset, engine):
    assert worst_error("cvode", scene, offset, engine=engine) <= TOLERANCE
