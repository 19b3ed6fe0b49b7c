"""The article's algorithm (solve_ivp with a restart at each terminal event) against the exact solution."""

import pytest

import bouncingball
from bouncingball.accuracy import accuracy_of_result
from bouncingball.physics import Ball


def _accuracy(result, h0, v0):
    return accuracy_of_result(result, h0, v0)[0], None


@pytest.mark.parametrize("method", ["RK45", "DOP853", "LSODA", "Radau", "BDF"])
def test_scipy_peer_runs_every_method(method):
    result = bouncingball.simulate(Ball(), 2.0, 0.0, 3.0, solver="scipy", method=method, rtol=1e-8, atol=1e-11,
                                   max_step=0.0)
    accuracy, _ = _accuracy(result, 2.0, 0.0)
    assert accuracy.events_match
    assert accuracy.max_height_error <= 1e-4


def test_scipy_peer_reproduces_the_article():
    """At the article's settings its error is ~3e-3 m: about a thousand times CVODE's default."""
    result = bouncingball.simulate(Ball(), 2.0, 0.0, 8.0, solver="scipy")
    accuracy, _ = _accuracy(result, 2.0, 0.0)
    assert result.options == {"method": "RK45", "rtol": 1e-3, "atol": 1e-6, "max_step": 0.01}
    assert 1e-3 <= accuracy.max_height_error <= 1e-2
