"""The bouncing ball with compliant contact: parameters, both modes' equations, events, energy.

No solver and no I/O here. States are h, the height of the ball's centre [m], and v = dh/dt [m/s].
F_ext [N] is an external vertical force on the ball (positive upwards).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from . import codes, validation
from .contact_laws import (
    CONTACT_LAWS,
    CONTACT_PARAMETERS,
    LAW_PARAMETERS,
    BallParameters,
    ball_parameters,
    hunt_crossley_rest_margin,
    impact_is_instantaneous,
    law_contact_force,
    law_flow_value,
    law_rest_margin,
    reported_acceleration,
    starts_free,
)
from .contact_laws.hunt_crossley import HC_N_RANGE, hunt_crossley_static_deflection
from .equations import effective_gravity_value, load_value, static_deflection_value


class Mode(enum.IntEnum):
    """The discrete phase, held between events. Under the rigid law, CONTACT is the ball resting on R.

    FREE is the no-pull law's second sub-mode below R (CONTACT its pressed one): the contact force
    would pull, so there is none, and the ball moves on its flight's parabola below R.
    """

    FLIGHT = codes.FLIGHT
    CONTACT = codes.CONTACT
    FREE = codes.FREE


@dataclass(frozen=True)
class Ball:
    """A ball of mass m [kg] and radius R [m] over rigid ground; in contact a spring k [N/m] and a damper b [N s/m].

    The defaults are the reference article's. In flight (h > R) h' = v, v' = -g + F_ext / m; in
    contact m v' = -b v + k (R - h) - m g + F_ext. Contact starts when h crosses R going down and
    ends when it crosses R going up; the mode is held between those events. The other contact laws
    (rigid, linear-no-pull, hunt-crossley) are described in bouncingball.contact_laws.

    Parameters
    ----------
    m : float
        Mass [kg], finite and > 0.
    k : float
        Contact stiffness [N/m], finite and > 0.
    b : float
        Contact damping [N s/m], finite and >= 0.
    R : float
        Radius [m], finite and > 0: the height of the centre at which contact starts.
    g : float
        Gravitational acceleration [m/s2], finite and >= 0.
    contact : str
        The contact law: "linear" (the spring-damper, the default), "rigid", "linear-no-pull" (the
        spring-damper whose force never pulls) or "hunt-crossley" (k delta^n (1 + 3/2 alpha delta')).
    e : float
        The rigid law's coefficient of restitution, in [0, 1].
    v_min : float
        The rigid law's speed [m/s] below which a bounce ends on R, finite and >= 0.
    n : float
        The Hunt-Crossley law's exponent, in [1, 2.5] (1.5: Hertz; k is then in N/m^n).
    alpha : float
        The Hunt-Crossley law's damping [s/m], finite and >= 0.

    Raises
    ------
    ValueError
        A parameter outside its range; the message names it, its value and the allowed range. Or a
        parameter the contact law does not read (contact_laws.LAW_PARAMETERS: rigid reads neither k nor
        b, hunt-crossley not b) set to another value than its default, which would be silently ignored.

    Examples
    --------
    >>> from bouncingball import Ball
    >>> ball = Ball(b=0.0)
    >>> ball.natural_frequency, ball.damping_ratio
    (100.0, 0.0)
    >>> Ball(m=-1)
    Traceback (most recent call last):
    ...
    ValueError: m = -1 kg is not allowed: it must be finite and > 0
    """

    m: float = 1.0
    k: float = 1e4
    b: float = 10.0
    R: float = 0.06
    g: float = 9.81
    contact: str = "linear"
    e: float = 0.7
    v_min: float = 0.0
    n: float = 1.5
    alpha: float = 0.0

    def __post_init__(self) -> None:
        """Check every parameter before the ball exists."""
        object.__setattr__(self, "m", validation.positive("m", self.m, "kg"))
        object.__setattr__(self, "k", validation.positive("k", self.k, "N/m"))
        object.__setattr__(self, "b", validation.non_negative("b", self.b, "N s/m"))
        object.__setattr__(self, "R", validation.positive("R", self.R, "m"))
        object.__setattr__(self, "g", validation.non_negative("g", self.g, "m/s2"))
        object.__setattr__(self, "contact", validation.choice("contact", self.contact, CONTACT_LAWS))
        object.__setattr__(self, "e", validation.in_closed_range("e", self.e, 0.0, 1.0))
        object.__setattr__(self, "v_min", validation.non_negative("v_min", self.v_min, "m/s"))
        object.__setattr__(self, "n", validation.in_closed_range("n", self.n, *HC_N_RANGE))
        object.__setattr__(self, "alpha", validation.non_negative("alpha", self.alpha, "s/m"))
        unread = unread_parameters(self.contact, {name: getattr(self, name) for name in CONTACT_PARAMETERS})
        if unread:
            raise ValueError(unread_message(self.contact, unread))

    # --- derived quantities -------------------------------------------------------------
    @property
    def rigid(self) -> bool:
        """Whether the contact law is the rigid one (an instantaneous impact)."""
        return self.contact == "rigid"

    @property
    def no_pull(self) -> bool:
        """Whether the contact law is the no-pull one (the spring-damper's force clipped at 0)."""
        return self.contact == "linear-no-pull"

    @property
    def hunt_crossley(self) -> bool:
        """Whether the contact law is Hunt and Crossley's (k delta^n (1 + 3/2 alpha delta'), clipped at 0)."""
        return self.contact == "hunt-crossley"

    @cached_property
    def parameters(self) -> BallParameters:
        """BallParameters(m, k, b, R, g, law, e, v_min, n, alpha): the ball as plain floats, as the machine takes it.

        law: LINEAR (0), RIGID (1), NO_PULL (2) or HUNT_CROSSLEY (3), the code of the contact law. A no-pull
        ball with b = 0 is the linear law's (its force k (R - h) never pulls below R), and has its code: the
        same run. Under the Hunt-Crossley law b is 0.0 here (its damping is alpha's: no linear damper).
        """
        fields = ("m", "R", "g", *CONTACT_PARAMETERS)
        return ball_parameters(self.contact, {name: getattr(self, name) for name in fields})

    @property
    def natural_frequency(self) -> float:
        """w = sqrt(k/m) [rad/s] of the contact oscillator."""
        return math.sqrt(self.k / self.m)

    @property
    def damping_ratio(self) -> float:
        """zeta = b / (2 sqrt(k m)): < 1 under-damped, 1 critical, > 1 over-damped."""
        return self.b / (2.0 * math.sqrt(self.k * self.m))

    def effective_gravity(self, F_ext: float = 0.0) -> float:
        """(m g - F_ext)/m [m/s2]: the net downward acceleration in flight, the load the spring holds in contact.

        g - F_ext/m in value, from the one load_value, so that its sign, the static deflection's and
        the mode a ball starts in agree to the last bit.
        """
        return effective_gravity_value(F_ext, self.m, self.g)

    def static_deflection(self, F_ext: float = 0.0) -> float:
        """(m g - F_ext)/k [m]: how far below R the centre rests; negative if F_ext lifts the ball.

        Under the Hunt-Crossley law ((m g - F_ext)/k)^(1/n), where k delta^n carries the load (its sign kept).
        """
        if self.hunt_crossley:
            return hunt_crossley_static_deflection(load_value(F_ext, self.m, self.g), self.k, self.n)
        return static_deflection_value(F_ext, self.m, self.k, self.g)

    def rest_height(self, F_ext: float = 0.0) -> float:
        """R - (m g - F_ext)/k [m]: the equilibrium height of the centre in contact (R - static_deflection)."""
        return self.R - self.static_deflection(F_ext)

    # --- equations of motion ---------------------------------------------------------------
    def acceleration(self, h: float, v: float, mode: Mode, F_ext: float = 0.0) -> float:
        """dv/dt [m/s2] in the given mode.

        Under the rigid, no-pull and Hunt-Crossley laws, from the force their contact_force clips at 0: a rigid ball
        resting on R has 0 while the ground carries its load, (F_ext - m g)/m where F_ext lifts it.
        """
        return reported_acceleration(self.parameters, h - self.R, v, mode, load_value(F_ext, self.m, self.g))

    def jacobian(self, mode: Mode) -> np.ndarray:
        """d(h', v')/d(h, v): constant in each mode."""
        if mode != Mode.CONTACT or impact_is_instantaneous(self.parameters):
            return np.array([[0.0, 1.0], [0.0, 0.0]])
        return np.array([[0.0, 1.0], [-self.k / self.m, -self.b / self.m]])

    def flow(self, mode: Mode, h0, v0, tau, F_ext: float = 0.0):
        """The exact state (h [m], v [m/s]) a time tau [s] after (h0, v0), the mode and F_ext held.

        Both modes are linear with constant coefficients: a parabola in flight (and free below R), a damped
        oscillator about the rest height in contact (a rigid ball resting on R stays there). Arrays allowed
        (broadcast); tau may be < 0.
        """
        x, v = self.gap_flow(mode, h0 - self.R, v0, tau, F_ext)
        return self.R + x, v

    def gap_flow(self, mode: Mode, x0, v0, tau, F_ext: float = 0.0):
        """The exact (x [m], v [m/s]) a time tau [s] after (x0, v0), x = h - R the gap to the ground.

        The gap carries digits that h = R + x rounds away (a deflection of a few ulps of R); the
        integrator and the event searches work in it.
        """
        return law_flow_value(self.parameters, mode, x0, v0, tau, load_value(F_ext, self.m, self.g))

    def contact_force(self, h: float, v: float, mode: Mode, F_ext: float = 0.0) -> float:
        """Force of the ground on the ball [N], positive upwards; zero in flight.

        As published, the damper can pull (negative force) just before departure. A rigid ball resting
        on R carries its load m g - F_ext. Under the no-pull law the force is max(0, k (R - h) - b v), and
        0 in the free sub-mode.
        """
        return law_contact_force(self.parameters, h - self.R, v, mode, load_value(F_ext, self.m, self.g))

    def energy(self, h, v, F_ext: float = 0.0):
        """Kinetic + gravitational potential (zero at h = 0) + spring energy [J]; arrays allowed.

        The spring stores energy whenever h < R. A constant F_ext adds the potential -F_ext h.
        """
        h = np.asarray(h, dtype=float)
        v = np.asarray(v, dtype=float)
        compression = np.maximum(self.R - h, 0.0)
        if self.hunt_crossley:  # the spring k delta^n stores k delta^(n+1) / (n + 1)
            return 0.5 * self.m * v**2 + (self.m * self.g - F_ext) * h + self.k * compression ** (self.n + 1.0) / (
                self.n + 1.0)
        return 0.5 * self.m * v**2 + (self.m * self.g - F_ext) * h + 0.5 * self.k * compression**2

    # --- events ---------------------------------------------------------------------------------
    def event_function(self, h: float) -> float:
        """h - R [m]: impact is its downward zero crossing, departure its upward one."""
        return h - self.R

    def initial_mode(self, h0: float, v0: float, F_ext: float = 0.0) -> Mode:
        """The mode a ball starts in: contact below R, or at R when it is about to move down.

        A rigid ball cannot start below R (ValueError, naming h0), and at R moving down it starts in
        flight, its impact the first event; at R at rest with a load on the ground it rests there.
        """
        if self.rigid and h0 < self.R:
            raise ValueError(f"h0 = {validation.shown(h0)} m is not allowed: under the rigid contact law it must be "
                             f">= R = {validation.shown(self.R)} m (the ball cannot start inside the ground)")
        if h0 < self.R:
            return Mode.FREE if starts_free(self.parameters, h0 - self.R, v0, load_value(F_ext, self.m, self.g)) \
                else Mode.CONTACT
        if h0 == self.R and ((v0 < 0.0 and not self.rigid) or (v0 == 0.0 and self.effective_gravity(F_ext) > 0.0)):
            return Mode.CONTACT
        return Mode.FLIGHT

    def contact_is_permanent(self, h: float, v: float, F_ext: float = 0.0, hop_tolerance: float = 0.0) -> bool:
        """True if a ball in contact at (h, v) can never again fly higher than hop_tolerance [m] above R.

        With hop_tolerance = 0 this says the ball never reaches R. See rest_margin.
        """
        return self.static_deflection(F_ext) > 0.0 and self.rest_margin(h, v, F_ext, hop_tolerance) > 0.0

    def rest_margin(self, h: float, v: float, F_ext: float = 0.0, hop_tolerance: float = 0.0) -> float:
        """w^2 d (d + 2 hop_tolerance) - (v^2 + w^2 y^2) [m2/s2]: positive once a contact is permanent.

        The oscillator energy about the rest height, 0.5 v^2 + 0.5 w^2 y^2 with y = h - rest
        height, never grows (b >= 0); so y stays within the amplitude A, A^2 = y^2 + v^2/w^2.
        Reaching R (y = d, the static deflection) takes A > d, and the ball leaves at most at
        v^2 = w^2 (A^2 - d^2) to fly v^2 / 2 g_eff = (A^2 - d^2) / 2d above R (g_eff = w^2 d > 0).
        It only grows in contact, so it is a root function for the start of a rest. Under the no-pull law
        the margin is no_pull_rest_margin_value's (the force can never again reach 0).
        """
        if self.hunt_crossley:  # its own energy's (per mass, m2/s2)
            return hunt_crossley_rest_margin(h - self.R, v, load_value(F_ext, self.m, self.g), self.m, self.k, self.n,
                                             hop_tolerance)
        return law_rest_margin(self.parameters, h - self.R, v, self.static_deflection(F_ext), hop_tolerance)


def clipped_contact_mode(ball: Ball, mode: Mode) -> Mode:
    """The mode for an integrator whose contact's right-hand side is Ball.acceleration (FREE is CONTACT there).

    A Hunt-Crossley ball's free sub-mode is its contact there: Ball.acceleration clips the force at 0
    (contact_force's max), so that contact covers both sub-modes, ended by h crossing R alone; FREE's own
    right-hand side, the bare parabola, would never engage again. Model exchange and SciPy's solve_ivp
    integrate so; the phase machine takes the clip as events instead.
    """
    return Mode.CONTACT if ball.hunt_crossley and mode == Mode.FREE else mode


def unread_parameters(contact: str, values: Mapping[str, float]) -> dict[str, float]:
    """The parameters in values that the contact law does not read, set to other values than Ball's defaults.

    What a user set for nothing, by name; the laws' own parameters are contact_laws.LAW_PARAMETERS, and
    Ball's defaults mean "not set".

    Examples
    --------
    >>> unread_parameters("rigid", {"k": 1e12, "b": 10.0, "e": 0.5})
    {'k': 1000000000000.0}
    """
    own = LAW_PARAMETERS[contact]
    return {name: value for name, value in values.items()
            if name in CONTACT_PARAMETERS and name not in own and value != BALL_DEFAULTS[name]}


def without_unread(ball_fields: Mapping[str, object]) -> tuple[dict, dict[str, float]]:
    """(Ball's keyword arguments with the parameters their contact law does not read at Ball's defaults, those).

    What the FMU runs from a master's start values, which may set every parameter (it logs the second), and
    what `check` judges its result by. ValueError names a contact law that does not exist.
    """
    contact = validation.choice("contact", ball_fields.get("contact", "linear"), CONTACT_LAWS)
    unread = unread_parameters(contact, ball_fields)
    return {**ball_fields, "contact": contact, **{name: BALL_DEFAULTS[name] for name in unread}}, unread


def unread_message(contact: str, unread: Mapping[str, float], option: str = "", law: str = "contact",
                   verdict: str = "is not allowed") -> str:
    """What unread_parameters found, for a ValueError or the FMU's log: each name, its value and what to do.

    option: "--" names them as the command line's options (--v-min), "" as Ball's fields; law: the contact
    law's own name there (the FMU's contact_law); verdict: "is not allowed", or what the FMU does instead.
    """
    def name_of(field: str) -> str:
        return option + field.replace("_", "-") if option else field

    named = ", ".join(f"{name_of(name)} = {value!r}" for name, value in unread.items())
    defaults = ", ".join(f"{name_of(name)} = {BALL_DEFAULTS[name]!r}" for name in unread)
    readers = sorted({other for name in unread for other, own in LAW_PARAMETERS.items() if name in own})
    return (f"{named} {verdict} with {name_of(law)} = {contact!r}: that law reads only "
            f"{', '.join(name_of(name) for name in LAW_PARAMETERS[contact])} (besides m, R and g); leave it at its "
            f"default ({defaults}) or choose a contact law that reads it ({', '.join(readers)})")


# Ball's defaults: for a contact law's parameters they mean "not set" (unread_parameters).
BALL_DEFAULTS = {field.name: field.default for field in fields(Ball)}
