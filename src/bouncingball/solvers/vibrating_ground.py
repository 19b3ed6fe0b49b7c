"""The CVODE engines on a vibrating ground: what they take of it, and a start relative to it.

The phase machine integrates the gap to the ground x = h - R - s and the velocity relative to it v - s', the
ground's acceleration entering as a load of its own (equations.load_at); the ground reaches the machine as three
fields of its BallParameters (ground_amplitude, ground_omega, ground_phase). BallIntegrator gives h, v and the
events' velocities in the world's frame.
"""

from __future__ import annotations

import dataclasses

from .. import validation
from ..ground import Ground
from ..physics import Ball


def machine_ground(ball: Ball, ground: Ground):
    """The phase machine's BallParameters of ball on ground; ValueError, before any work, where CVODE cannot take it.

    A sine's amplitude, angular frequency and phase in their ground_* fields; a still ground's unchanged (its
    height is the run shifted). Refused by name: a table ground (the exact solver takes it), a contact so near
    resonance with the ground that its steady response is out of scale (exact_ground.check_moving_ground's rule).
    """
    parameters = ball.parameters
    if ground.kind == "table":
        raise ValueError(f"ground = {ground.describe()} is not allowed with the CVODE solver: it takes a still or "
                         "a sine ground (Ground.sine); the exact solver takes the table (solver='exact')")
    if not ground.moves:
        return parameters
    from .exact_ground import check_moving_ground  # the law's own limits on a moving ground, one rule for both

    if ball.contact != "hunt-crossley":  # the Hunt-Crossley contact is no linear oscillator: no resonance rule
        check_moving_ground(ball, ground)
    return parameters._replace(ground_amplitude=ground.amplitude, ground_omega=ground.omega,
                               ground_phase=ground.phase)


def relative_start(ball: Ball, ground: Ground, h0, v0, t0, F_ext, settings, checked_start):
    """checked_start's (h0, v0, t0, F_ext), relative to a vibrating ground at t0: (R + gap, v0 - s'(t0), t0, F_ext).

    Each value checked and named; a start within 16 ulps of the ground's surface is on it (its rounding); a rigid
    ball below it is refused. On a still ground checked_start's own.
    """
    if not ground.moves:
        return checked_start(ball, h0, v0, t0, F_ext, settings)
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


def relative_to(ground: Ground, t: float, h: float, v: float) -> tuple[float, float]:
    """(h - s(t) [m], v - s'(t) [m/s]): the height and velocity at t [s] relative to the ground (a still one: h, v)."""
    if not ground.moves:
        return h, v
    return h - float(ground.position(t)), v - float(ground.velocity(t))


def ground_motion(ground: Ground, t: float, order: int) -> float:
    """The ground's s, s' or s'' (order 0, 1, 2) at t [s]; 0 on a still one (a height is the run shifted)."""
    return float(ground.derivative(t, order)) if ground.moves else 0.0


def world_events(ground: Ground, events: list) -> list:
    """The machine's events, their velocities relative to a vibrating ground, with the world's velocities."""
    if not ground.moves:
        return events
    return [dataclasses.replace(event, velocity=event.velocity + ground_motion(ground, event.time, 1))
            for event in events]


def world_grid(ground: Ground, R: float, grid, x, v) -> tuple:
    """(h [m], v [m/s]) at the times grid [s] from the machine's gap x [m] and velocity v [m/s] (relative to it)."""
    if not ground.moves:
        return R + x, v
    return R + x + ground.position(grid), v + ground.velocity(grid)
