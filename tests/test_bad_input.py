"""Bad input raises a ValueError that names the field, its value and what is allowed."""

import math

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
    (dict(rtol=0.0), "rtol = 0.0 is not allowed: it must be in (0, 1]"),
    (dict(atol=-1.0), "atol = -1.0 m is not allowed: it must be finite and > 0"),
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
