import math

import numpy as np
import pytest

from bouncingball.physics import Ball, Mode


def test_defaults_are_the_article():
    ball = Ball()
    assert (ball.m, ball.k, ball.b, ball.R, ball.g) == (1.0, 1e4, 10.0, 0.06, 9.81)


@pytest.mark.parametrize("field, value, allowed", [
    ("m", 0.0, "> 0"), ("m", -1.0, "> 0"), ("m", math.nan, "> 0"), ("m", math.inf, "> 0"),
    ("k", 0.0, "> 0"), ("k", math.inf, "> 0"), ("R", -0.06, "> 0"), ("R", math.nan, "> 0"),
    ("b", -1.0, ">= 0"), ("b", math.nan, ">= 0"), ("g", -9.81, ">= 0"), ("g", math.inf, ">= 0"),
])
def test_bad_parameter_names_field_value_and_range(field, value, allowed):
    with pytest.raises(ValueError) as info:
        Ball(**{field: value})
    message = str(info.value)
    assert message.startswith(f"{field} = {value!r}")
    assert allowed in message


def test_ball_is_immutable():
    ball = Ball()
    with pytest.raises(AttributeError):
        ball.m = 2.0


def test_static_deflection_and_rest_height():
    ball = Ball()
    assert ball.static_deflection() == pytest.approx(9.81e-4, rel=1e-15)
    assert ball.rest_height() == pytest.approx(0.06 - 9.81e-4, rel=1e-15)
    # at the rest height the contact acceleration vanishes
    assert abs(ball.acceleration(ball.rest_height(), 0.0, Mode.CONTACT)) < 1e-12
    # an external force m g cancels gravity: no deflection
    assert ball.static_deflection(F_ext=ball.m * ball.g) == 0.0


def test_accelerations_match_the_equations():
    ball = Ball(m=2.0, k=3e4, b=7.0)
    assert ball.acceleration(1.0, 3.0, Mode.FLIGHT) == -9.81
    assert ball.acceleration(1.0, 3.0, Mode.FLIGHT, F_ext=4.0) == pytest.approx(-9.81 + 2.0)
    h, v = 0.05, -1.5
    expected = (-7.0 * v + 3e4 * (0.06 - h)) / 2.0 - 9.81
    assert ball.acceleration(h, v, Mode.CONTACT) == pytest.approx(expected, rel=1e-14)


@pytest.mark.parametrize("mode", list(Mode))
def test_jacobian_matches_finite_differences(mode):
    ball = Ball(m=0.5, k=2e4, b=3.0)
    h, v, eps = 0.04, -0.7, 1e-6
    J = ball.jacobian(mode)
    da_dh = (ball.acceleration(h + eps, v, mode) - ball.acceleration(h - eps, v, mode)) / (2 * eps)
    da_dv = (ball.acceleration(h, v + eps, mode) - ball.acceleration(h, v - eps, mode)) / (2 * eps)
    np.testing.assert_allclose(J, [[0.0, 1.0], [da_dh, da_dv]], atol=1e-6)


def test_contact_force_and_energy():
    ball = Ball()
    assert ball.contact_force(0.05, 0.0, Mode.FLIGHT) == 0.0
    assert ball.contact_force(0.05, -1.0, Mode.CONTACT) == pytest.approx(1e4 * 0.01 + 10.0)
    # the damper pulls just before departure: the published model lets the force go negative
    assert ball.contact_force(0.0599, 2.0, Mode.CONTACT) < 0.0
    assert ball.energy(2.0, 0.0) == pytest.approx(9.81 * 2.0)
    assert ball.energy(0.05, 1.0) == pytest.approx(0.5 + 9.81 * 0.05 + 0.5 * 1e4 * 0.01**2)


def test_initial_mode():
    ball = Ball()
    assert ball.initial_mode(2.0, 0.0) == Mode.FLIGHT
    assert ball.initial_mode(0.05, 1.0) == Mode.CONTACT
    assert ball.initial_mode(0.06, 0.0) == Mode.CONTACT  # gravity pushes it in
    assert ball.initial_mode(0.06, 1.0) == Mode.FLIGHT
    assert ball.initial_mode(0.06, 0.0, F_ext=20.0) == Mode.FLIGHT  # lifted away


def test_permanent_contact_criterion():
    ball = Ball()
    assert ball.contact_is_permanent(ball.rest_height(), 0.0)
    assert not ball.contact_is_permanent(ball.R, -1.0)
    assert not Ball(g=0.0).contact_is_permanent(0.05, 0.0)  # no deflection: nothing holds it down


def test_hypot_value_rounds_as_pythons_math_hypot():
    """The phase scales' hypot, written out so that compiled code computes it too: Python's own numbers."""
    import random

    from bouncingball.rounding import hypot_value

    generator = random.Random(7)
    for _ in range(20000):
        exponent = generator.uniform(-300, 300)
        x = generator.uniform(-1.0, 1.0) * 10.0**exponent
        y = generator.uniform(-1.0, 1.0) * 10.0 ** min(300.0, exponent + generator.uniform(-20.0, 20.0))
        assert hypot_value(x, y) == math.hypot(x, y), (x, y)
    for x, y in ((0.0, 0.0), (3.0, 4.0), (1e308, 1e308), (-0.0, 5e-324), (math.inf, math.nan), (math.nan, 1.0)):
        assert hypot_value(x, y) == math.hypot(x, y) or math.isnan(math.hypot(x, y)) and math.isnan(hypot_value(x, y))
