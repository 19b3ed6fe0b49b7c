"""Model exchange's equations of the ball's modes, for the FMI 3.0 slave (slave3): what a master's integrator asks of
the FMU between and at events.

The nominals of the continuous states x = h - R and v in each phase, the one event indicator of each mode, the mode an
event switches to, and the rigid law's impact as a jump of the state. Each takes the state in the ground's frame (h, v
relative to a vibrating ground, its acceleration a load of its own: slave3's _in_frame); slave3 holds the state.
"""

from __future__ import annotations

import math

from ..contact_laws import has_pressed_gap, impact_is_instantaneous, pressed_gap
from ..contact_laws.no_pull import free_gap_rate
from ..contact_laws.rigid import rigid_rebound_above
from ..equations import load_value
from ..ground import Ground
from ..physics import Ball, Mode
from ..solvers.phase_machine.phases import phase_scales
from ..solvers.vibrating_ground import relative_to
from .variables import SMALLEST_POSITIVE

# The largest nominal [m, m/s]: FMI's default, what a master assumes of a state without one. The CVODE of FMPy and
# fmusim takes atol = rtol x nominal, read once at the start (CVodeSVtolerances copies it; neither passes it again at
# a restart), so a phase's scale above 1 loosened the user's tolerance: the Reference-FMUs' scene (their nominals 1)
# had 1.0008 to 1.0063 times their error in fmusim with a nominal of v of 4.43 m/s, their run to 14 digits with 1;
# the article 1.5 to 7.6 times the error with 1.94 m and 6.17 m/s at 6 to 15 % fewer calls (docs/fmu.md, the
# nominals: every scene measured). A smaller scale is kept: 1 there was up to 63 times the error (a 2 cm drop).
NOMINAL_CAP = 1.0


def phase_nominals(ball: Ball, h: float, v: float, mode: Mode, F_ext: float) -> list[float]:
    """The nominals [m, m/s] of the states x = h - R and v for a phase starting at (h, v) in mode: its own scales, at
    most NOMINAL_CAP.

    In flight the apex height above R and the speed at impact; in contact the amplitude of the
    oscillation about the rest height and its largest speed (phases.phase_scales, the scales our own
    CVODE integrates a phase in, in x as here). Always > 0: a scale of 0 (a ball at rest at its rest
    height) is replaced by max(R, |x|) and 1 m/s. A smaller phase (a low bounce, a short contact) keeps its
    own, so a master's absolute tolerance follows it down; a larger one gets 1 (NOMINAL_CAP).
    """
    x = h - ball.R
    length, speed = phase_scales(ball.parameters, mode, x, v, load_value(F_ext, ball.m, ball.g))
    return [min(length if 0.0 < length < math.inf else max(ball.R, abs(x)), NOMINAL_CAP),
            min(speed if 0.0 < speed < math.inf else 1.0, NOMINAL_CAP)]


# Model exchange, rigid law: a bounce rising less than this many rtol R is summed (the ball rests on R from
# its impact), as is one lower than the depth below R at which the master noticed the impact. The master's
# integrator cannot follow it: FMPy's CVODE at rtol = 1e-8 located the landing of a 5e-9 m (8e-8 R) hop at
# a twentieth of its speed, then stepped over the next, lower one, and the ball fell through the ground.
UNRESOLVED_APEX_PER_RTOL = 100.0


def rigid_impact(ball: Ball, v: float, F_ext: float, impacts: int, apex_floor: float) -> list:
    """[h, v, mode, impacts] after the rigid law's impact of the ball at v [m/s] (model exchange's state jump).

    The ball is put on R and leaves at -e v (contact_laws.rigid_rebound_above). Where it would leave slower
    than v_min, or its bounce would rise less than apex_floor [m], it rests on R from now: the true ball
    then stays within apex_floor of R (its bounces summed, as the Zeno series they are). A ball found
    below R already moving up (an event located late) is put on R, v kept.
    """
    # A flight starts an ulp above R, where its event indicator h - R is > 0: at exactly 0 a master's CVODE
    # found a root every 1.5e-7 s on the way up (FMPy: 57628 events in 4 s) and FMPy's Euler, which looks
    # for a change from > 0 to <= 0, would not see the next impact.
    above = math.nextafter(ball.R, math.inf)
    if v >= 0.0:
        return [above, v, Mode.FLIGHT, impacts]
    v_after, _ = rigid_rebound_above(ball.parameters, v, load_value(F_ext, ball.m, ball.g), apex_floor)
    if v_after > 0.0:
        return [above, v_after, Mode.FLIGHT, impacts + 1]
    return [ball.R, 0.0, Mode.CONTACT, impacts + 1]


def event_indicator(ball: Ball, h: float, v: float, mode: Mode, F_ext: float) -> float:
    """Model exchange's event indicator in mode: >= 0 out of contact, <= 0 in it, crossing 0 where the mode ends.

    In flight and in the linear law's contact h - R [m] (a rigid ball rising: at least the smallest double,
    SMALLEST_POSITIVE). In the no-pull law's pressed contact
    z = h - R + (b / k) v = -force / k [m] (it is released where z turns positive); in its free sub-mode
    min(z, R - h) [m] (pressed again where z, departing where R - h, reaches 0). For a rigid ball resting
    on R, F_ext / m - g [m/s2] (it lifts where that turns positive). The FMU's binary tells a master's
    step over an event by that sign against the output contact.
    """
    x = h - ball.R
    if mode == Mode.FLIGHT:
        # A rigid ball rising from R (put there by its impact) is out of contact even where a master's integrator
        # error puts it a few ulps below R: at 0 or below, its CVODE found a root every 2e-10 s (31,582 events
        # in FMPy at rtol 1e-4), each putting the ball back on R, while the bounce was below its tolerance.
        return max(x, SMALLEST_POSITIVE) if impact_is_instantaneous(ball.parameters) and v > 0.0 else x
    if impact_is_instantaneous(ball.parameters):
        return -load_value(F_ext, ball.m, ball.g) / ball.m
    if not has_pressed_gap(ball.parameters):
        return x
    z = x + (ball.b / ball.k) * v
    return z if mode == Mode.CONTACT else min(z, -x)


def switched_mode(ball: Ball, h: float, v: float, mode: Mode, F_ext: float) -> Mode | None:
    """The mode a model-exchange event at (h [m], v [m/s]) switches the linear or no-pull ball to; None: none.

    An impact where h - R has turned negative (or is 0 going down); a departure where it turned positive.
    Under the no-pull law a release where the pressed contact's force has turned negative, an
    engagement where the free ball's would turn positive (contact_laws.pressed_gap's z).
    """
    x = h - ball.R
    up, down = x > 0.0 or (x == 0.0 and v > 0.0), x < 0.0 or (x == 0.0 and v < 0.0)
    if mode == Mode.FLIGHT:
        return Mode.CONTACT if down else None
    parameters = ball.parameters
    if not has_pressed_gap(parameters):
        return Mode.FLIGHT if up else None
    load = load_value(F_ext, ball.m, ball.g)
    if mode == Mode.CONTACT:
        z, rate = pressed_gap(parameters, x, v, load)
        return Mode.FREE if z > 0.0 or (z == 0.0 and rate > 0.0) else None
    if up:
        return Mode.FLIGHT
    z, rate = x + (ball.b / ball.k) * v, free_gap_rate(parameters, v, load)
    return Mode.CONTACT if z < 0.0 or (z == 0.0 and rate < 0.0) else None


def in_frame(ground: Ground, m: float, t: float, h: float, v: float, F_ext: float) -> tuple[float, float, float]:
    """(h [m], v [m/s], F_ext [N]) at t [s] in the frame of a ball of mass m [kg] on ground: h - s, v - s' and
    F_ext - m s'' (the ground's acceleration as a load of its own); on a still ground h, v and F_ext."""
    if not ground.moves:
        return h, v, F_ext
    return *relative_to(ground, t, h, v), F_ext - m * float(ground.derivative(t, 2))


def in_world(ground: Ground, t: float, h: float, v: float) -> list[float]:
    """[h [m], v [m/s]] in the world's frame from the ground's at t [s] (in_frame's inverse)."""
    if not ground.moves:
        return [h, v]
    return [h + float(ground.position(t)), v + float(ground.velocity(t))]
