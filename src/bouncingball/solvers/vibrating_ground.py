"""The CVODE engines on a vibrating ground: what they take of it, and a start relative to it.

The phase machine integrates the gap to the ground x = h - R - s and the velocity relative to it v - s', the
ground's acceleration entering as a load of its own (equations.load_at); the ground reaches the machine as three
fields of its BallParameters (ground_amplitude, ground_omega, ground_phase). BallIntegrator gives h, v and the
events' velocities in the world's frame.
"""

from __future__ import annotations

from .. import validation
from ..ground import Ground
from ..physics import Ball


def machine_ground(ball: Ball, ground: Ground):
    """The phase machine's BallParameters of ball on ground; ValueError, before any work, where CVODE cannot take it.

    A sine's amplitude, angular frequency and phase in their ground_* fields; a still ground's unchanged (its
    height is the run shifted). Refused by name: a table ground, a compliant law on a vibrating one (the exact
    solver takes both).
    """
    parameters = ball.parameters
    if ground.kind == "table":
        raise ValueError(f"ground = {ground.describe()} is not allowed with the CVODE solver: it takes a still or "
                         "a sine ground (Ground.sine); the exact solver takes the table (solver='exact')")
    if not ground.moves:
        return parameters
    if not ball.rigid:
        raise ValueError(f"ground = {ground.describe()} is not allowed with the CVODE solver and contact_law = "
                         f"{ball.contact!r}: on a vibrating ground it takes the rigid law; the exact solver "
                         "(solver='exact') takes the linear and no-pull laws there too")
    return parameters._replace(ground_amplitude=ground.amplitude, ground_omega=ground.omega,
                               ground_phase=ground.phase)


def relative_start(ball: Ball, ground: Ground, h0, v0, t0, F_ext, settings, checked_start):
    """checked_start's (h0, v0, t0, F_ext) relative to a vibrating ground at t0: (R + gap, v0 - s'(t0), t0, F_ext).

    Each value checked and named; a start within 16 ulps of the ground's surface is on it (its rounding); a rigid
    ball below it is refused.
    """
    t0 = validation.finite("t0", t0, "s")
    h0, v0 = validation.finite("h0", h0, "m"), validation.finite("v0", v0, "m/s")
    surface = float(ground.position(t0))
    gap = h0 - ball.R - surface
    if abs(gap) <= 16.0 * 2.0**-52 * (abs(h0) + ball.R + abs(surface)):
        gap = 0.0
    if ball.rigid and gap < 0.0:
        raise ValueError(f"h0 = {h0!r} m is not allowed: under the rigid contact law it must be >= R + s(t0) = "
                         f"{ball.R + surface!r} m (the ball cannot start inside the ground)")
    relative, t0, F_ext = checked_start(ball, ball.R + gap, v0 - float(ground.velocity(t0)), t0, F_ext, settings)[1:]
    return ball.R + gap, relative, t0, F_ext
