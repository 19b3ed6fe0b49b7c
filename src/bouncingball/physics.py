"""The bouncing ball with compliant contact: parameters, both modes' equations, events, energy.

No solver and no I/O here. States are h, the height of the ball's centre [m], and v = dh/dt [m/s].
F_ext [N] is an external vertical force on the ball (positive upwards).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from . import validation
from .oscillator import contact_gap_flow
from .rounding import product_error


class Mode(enum.IntEnum):
    """The discrete phase, held between events. Under the rigid law, CONTACT is the ball resting on R.

    FREE is the no-pull law's second sub-mode below R (CONTACT its pressed one): the contact force
    would pull, so there is none, and the ball moves on its flight's parabola below R.
    """

    FLIGHT = 0
    CONTACT = 1
    FREE = 2


# The contact laws (Ball.contact) and the codes the phase machine knows them by (Ball.parameters).
CONTACT_LAWS = ("linear", "rigid", "linear-no-pull", "hunt-crossley")
LINEAR, RIGID, NO_PULL, HUNT_CROSSLEY = 0, 1, 2, 3
# The Hunt-Crossley law's exponent n: 1 (a linear spring) .. 2.5 (beyond Hertz's 1.5 for spheres, as fitted
# to soft and granular materials); its release speed is 2 / (3 alpha).
HC_N_RANGE = (1.0, 2.5)


@dataclass(frozen=True)
class Ball:
    """A ball of mass m [kg] and radius R [m] over rigid ground; in contact a spring k [N/m] and a damper b [N s/m].

    The defaults are the reference article's. In flight (h > R) h' = v, v' = -g + F_ext / m; in
    contact m v' = -b v + k (R - h) - m g + F_ext. Contact starts when h crosses R going down and
    ends when it crosses R going up; the mode is held between those events.

    With contact = "rigid" the ball does not deform (k and b play no part): at each impact on R its
    velocity reverses, v+ = -e v-. With v_min = 0 a ball with e < 1 makes infinitely many ever smaller
    bounces before it rests on R at the Zeno time t_k + 2 v_k / (g (1 - e)) after a bounce leaving at v_k
    [m/s] (the bounces lower than about 1e-12 R are summed as the geometric series they are). With
    v_min > 0 it stops on R at the first bounce that would leave slower than v_min (the Modelica
    Association's Reference-FMUs BouncingBall). A ball resting on R leaves it when F_ext exceeds m g.

    With contact = "linear-no-pull" the ground never pulls: below R its force is max(0, k (R - h) - b v)
    (Modelica's ElastoGap). Below R the ball is pressed (Mode.CONTACT: the linear law's spring-damper)
    while that force is positive, and free (Mode.FREE: the flight's parabola below R) where it would
    pull; it switches where k (R - h) - b v crosses 0 (a release going free, an engagement pressed again),
    and a free ball reaching R flies on (a departure). With b = 0 it is the linear law.

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
        The contact law: "linear" (the spring-damper, the default), "rigid" or "linear-no-pull" (the
        spring-damper whose force never pulls).
    e : float
        The rigid law's coefficient of restitution, in [0, 1] (ignored by "linear").
    v_min : float
        The rigid law's speed [m/s] below which a bounce ends on R, finite and >= 0 (ignored by "linear").

    Raises
    ------
    ValueError
        A parameter outside its range; the message names it, its value and the allowed range.

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

    @property
    def parameters(self) -> tuple[float, float, float, float, float, float, float, float, float, float]:
        """(m, k, b, R, g, law, e, v_min, n, alpha): the ball as plain floats, as the phase machine takes it.

        law: LINEAR (0), RIGID (1), NO_PULL (2) or HUNT_CROSSLEY (3), the code of the contact law. A no-pull
        ball with b = 0 is the linear law's (its force k (R - h) never pulls below R), and has its code: the
        same run. Under the Hunt-Crossley law b is 0.0 here (its damping is alpha's: no linear damper).
        """
        if self.hunt_crossley:
            return self.m, self.k, 0.0, self.R, self.g, float(HUNT_CROSSLEY), self.e, self.v_min, self.n, self.alpha
        law = RIGID if self.rigid else (NO_PULL if self.no_pull and self.b > 0.0 else LINEAR)
        return self.m, self.k, self.b, self.R, self.g, float(law), self.e, self.v_min, self.n, self.alpha

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
        if mode == Mode.CONTACT and (self.rigid or self.no_pull or self.hunt_crossley):
            return (self.contact_force(h, v, mode, F_ext) - load_value(F_ext, self.m, self.g)) / self.m
        return mode_acceleration(h, v, mode, F_ext, self.m, self.k, self.b, self.R, self.g)

    def jacobian(self, mode: Mode) -> np.ndarray:
        """d(h', v')/d(h, v): constant in each mode."""
        if mode != Mode.CONTACT or self.rigid:
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
        if mode != Mode.CONTACT:
            return 0.0
        if self.rigid:
            return max(load_value(F_ext, self.m, self.g), 0.0)
        if self.no_pull:
            return max(self.k * (self.R - h) - self.b * v, 0.0)
        if self.hunt_crossley:
            return max(hunt_crossley_force(h - self.R, v, self.k, self.n, self.alpha), 0.0)
        return self.k * (self.R - h) - self.b * v

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
            return Mode.FREE if self._free_below_R(h0, v0, F_ext) else Mode.CONTACT
        if h0 == self.R and ((v0 < 0.0 and not self.rigid) or (v0 == 0.0 and self.effective_gravity(F_ext) > 0.0)):
            return Mode.CONTACT
        return Mode.FLIGHT

    def _free_below_R(self, h0: float, v0: float, F_ext: float) -> bool:
        """Under the no-pull law, whether a ball below R starts free: its force would pull, or is 0 and turning so.

        Under the Hunt-Crossley law: where 1 - 3/2 alpha v < 0 (rising faster than the release speed), or = 0 with
        F_ext lifting more than the weight (v grows past it).
        """
        parameters = self.parameters
        if parameters[5] == HUNT_CROSSLEY:
            factor = 1.0 - 1.5 * self.alpha * v0
            return factor < 0.0 or (factor == 0.0 and load_value(F_ext, self.m, self.g) < 0.0)
        if parameters[5] != NO_PULL:
            return False
        load = load_value(F_ext, self.m, self.g)
        z, rate = pressed_gap(parameters, h0 - self.R, v0, load)
        return z > 0.0 or (z == 0.0 and rate > 0.0)

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


# The equations as functions of plain floats: Ball's methods call them, and the compiled CVODE
# engine compiles these same functions, so the physics has one definition.
def mode_acceleration(h, v, mode, F_ext, m, k, b, R, g):
    """dv/dt [m/s2] in mode (0 or Mode.FLIGHT: flight, 1 or Mode.CONTACT: contact); see gap_acceleration."""
    return gap_acceleration(h - R, v, mode, load_value(F_ext, m, g), m, k, b)


def gap_acceleration(x, v, mode, load, m, k, b):
    """dv/dt [m/s2] in mode at the gap x = h - R [m]; load = load_value(F_ext, m, g) [N], the same for a whole phase.

    k x, not k h - k R: x is exact near R, whereas the two products of a stiff ball (k = 1e12)
    would bury its deflection in their round-off. The load, not g - F_ext/m, which rounds
    differently: a ball creeping to a rest height of exactly R felt a residual 2e-15 m/s2.
    """
    if mode != 1:  # flight, or free below R under the no-pull law
        return -load / m
    return (-b * v - k * x - load) / m


def law_flow_value(parameters, mode, x0, v0, tau, load):
    """gap_flow_value under the ball's contact law (parameters: Ball.parameters): a rigid ball in contact rests.

    Under the rigid law the contact mode is the ball resting on R, where it stays (x0, v0 = 0, 0).
    """
    if mode == 1 and parameters[5] == RIGID:
        return x0 + 0.0 * tau, v0 + 0.0 * tau
    if mode == 1 and parameters[5] == HUNT_CROSSLEY:  # no closed form: never asked for (NaN if it were)
        return x0 + math.nan * tau, v0 + math.nan * tau
    return gap_flow_value(mode, x0, v0, tau, load, parameters[0], parameters[1], parameters[2])


# Under the rigid law with v_min = 0, the bounces after one whose apex is below ZENO_APEX R are summed as
# the geometric series they are: their heights are below any resolution, their count without end.
ZENO_APEX = 2.0**-40


def rigid_rebound(parameters, v_impact, load):
    """(v_after [m/s], zeno [s]): the rigid law's bounce after an impact at v_impact < 0 on R (Ball.parameters).

    v_after = -e v_impact, or 0 where the ball stays on R: below v_min, or where the bounces from
    there rise less than ZENO_APEX R (e < 1, a load on the ground). Their infinitely many impacts then
    take zeno = 2 v / (g_eff (1 - e)) [s] in all (v = -e v_impact, g_eff = load / m), after which the
    ball rests on R: the Zeno time is the impact's time + zeno. zeno is 0 where none are summed.
    """
    return rigid_rebound_above(parameters, v_impact, load, ZENO_APEX * parameters[3])


def rigid_rebound_above(parameters, v_impact, load, apex_floor):
    """rigid_rebound, with the bounces that rise less than apex_floor [m] (rather than ZENO_APEX R) summed."""
    e, v_min = parameters[6], parameters[7]
    v_after = -e * v_impact
    if v_after < v_min:
        return 0.0, 0.0
    g_eff = load / parameters[0]
    if g_eff > 0.0 and e < 1.0 and v_after * v_after <= 2.0 * g_eff * apex_floor:
        return 0.0, 2.0 * v_after / (g_eff * (1.0 - e))
    return v_after, 0.0


def summed_bounce_state(parameters, v_first, load, tau):
    """(x [m], v [m/s]) of a rigid ball tau [s] after the impact whose bounces rigid_rebound summed (Ball.parameters).

    Its bounces leave R at v_first e^j, j = 0, 1, ..., under the constant load [N]; the j-th leaves at
    S_j = 2 v_first (1 - e^j) / (g_eff (1 - e)), and from the Zeno time S_inf on the ball rests, (0, 0). Each is
    lower than ZENO_APEX R, so the ball is taken on R while they last; this is where it truly is, for a change
    of F_ext inside that time: a lift there leaves with the bounce's speed, not from rest.
    """
    e, g_eff = parameters[6], load / parameters[0]
    scale = 2.0 * v_first / (g_eff * (1.0 - e))  # S_inf
    if not tau < scale:
        return 0.0, 0.0
    j = max(int(math.floor(math.log1p(-tau / scale) / math.log(e))), 0)  # e^j >= 1 - tau / S_inf
    while j > 0 and scale * (1.0 - e**j) > tau:  # the rounding of the logarithms, either way
        j -= 1
    while scale * (1.0 - e ** (j + 1)) <= tau:
        j += 1
    s, v_j = tau - scale * (1.0 - e**j), v_first * e**j
    return max(s * (v_j - 0.5 * g_eff * s), 0.0), v_j - g_eff * s


def conserved_speed(parameters, mode, x_start, v_start):
    """Whether a phase from the gap x_start [m] at v_start [m/s] in mode ends on R at -v_start exactly.

    It does where it starts on R leaving its own side (up in flight, down in contact) and its exact
    flow conserves energy (a flight; a contact with b = 0): the phase machine's polish and the exact
    solver then give the event that speed, not their flows' rounded one, which added up over many
    bounces to an energy drift. parameters: Ball.parameters.
    """
    if x_start != 0.0:
        return False
    if parameters[5] == HUNT_CROSSLEY:  # alpha = 0: the Hertz contact conserves energy, its force 0 on R
        return v_start > 0.0 if mode == 0 else (v_start < 0.0 and parameters[9] == 0.0)
    return v_start > 0.0 if mode == 0 else (v_start < 0.0 and parameters[2] == 0.0)


def hunt_crossley_force(x, v, k, n, alpha):
    """k delta^n (1 + 3/2 alpha delta') [N], delta = -x the penetration, delta' = -v: the pressed force, unclipped.

    delta^n continued as sign(delta) |delta|^n beyond R (x > 0), where CVODE's trial steps may look past
    a departure: smooth there (for n > 1 its derivative is 0), as the linear law's k x continues.
    """
    return k * math.copysign(abs(x) ** n, -x) * (1.0 - 1.5 * alpha * v)


def hunt_crossley_acceleration(x, v, load, m, k, n, alpha):
    """dv/dt [m/s2] in the Hunt-Crossley pressed contact (Mode.CONTACT): (force - load) / m."""
    return (hunt_crossley_force(x, v, k, n, alpha) - load) / m


def hunt_crossley_partials(x, v, load, m, k, n, alpha):
    """(da/dx [1/s2], da/dv [1/s]) of hunt_crossley_acceleration: the Jacobian's second row, state-dependent."""
    power = abs(x) ** (n - 1.0)  # |x|^0 = 1 at n = 1 (and at x = 0)
    return -(k / m) * n * power * (1.0 - 1.5 * alpha * v), -(k / m) * math.copysign(abs(x) ** n, -x) * 1.5 * alpha


def hunt_crossley_rest_margin(x, v, load, m, k, n, hop):
    """g_eff (hop + delta) - v^2 / 2 - (k/m) delta^(n+1) / (n + 1) [m2/s2]: positive once it never rises hop above R.

    delta = max(-x, 0); positive once a pressed Hunt-Crossley ball can never again rise more than hop [m] above R.

    It is L hop - E per mass, with the load L = m g - F_ext (held constant) and the energy
    E = m v^2 / 2 - L delta + k delta^(n+1) / (n + 1). Proof: with delta' = -v, dE/dt = v (m v' + L - k delta^n).
    Pressed, m v' = k delta^n (1 - 3/2 alpha v) - L, so dE/dt = -3/2 alpha k delta^n v^2 <= 0; free (the force's
    clip engaged: v above the release speed 2 / (3 alpha) > 0), m v' = -L, so dE/dt = -k delta^n v < 0. So E never
    grows while delta > 0. On R (delta = 0) E = m v^2 / 2 >= 0, and a ball leaving R rising at v reaches
    v^2 / (2 g_eff) = E / L above it. Hence once E < L hop (the margin positive) the ball either never reaches
    R again, or (E in [0, L hop)) leaves it by a hop lower than hop; with hop = 0 it never leaves: E < 0 at
    delta > 0 and E >= 0 at delta = 0 cannot both hold on a path along which E does not grow. (E < 0 needs
    L delta > 0: a lifted ball, L <= 0, is never at rest.)
    """
    delta = max(-x, 0.0)
    return (load / m) * (hop + delta) - 0.5 * (v * v) - (k / m) * delta ** (n + 1.0) / (n + 1.0)


def hunt_crossley_static_deflection(load, k, n):
    """(load / k)^(1/n) [m], its sign the load's: the penetration at which k delta^n carries the load [N]."""
    return math.copysign((abs(load) / k) ** (1.0 / n), load)


def hunt_crossley_rest_depth(load, m, k, n):
    """(2 (n + 1) g_eff / (k/m))^(1/n) [m], g_eff = load / m > 0: the length scale of a Hunt-Crossley contact near rest.

    A contact of energy per mass e = v^2 / 2 - g_eff delta + (k/m) delta^(n+1) / (n + 1) <= 0 (one that leaves R no
    higher than it hops, e = g_eff hop, for hop -> 0) stays shallower than this: past it the spring's energy
    (k/m) delta^(n+1) / (n + 1) exceeds 2 g_eff delta. It is (2 (n + 1))^(1/n) times the static deflection
    (hunt_crossley_static_deflection): 4 at n = 1, 2.9 at n = 3/2, 2.2 at n = 5/2. The contact's frame
    (phases.hunt_crossley_scales) is never smaller.
    """
    return (2.0 * (n + 1.0) * (load / m) / (k / m)) ** (1.0 / n)


def hunt_crossley_hop_tolerance(load, m, k, n, alpha, resolution):
    """The highest hop [m] a Hunt-Crossley run may merge: resolution (HOP_RESOLUTION rtol) hunt_crossley_rest_depth.

    From the law's energy (hunt_crossley_rest_margin): a ball leaving R rising at v hops H = v^2 / (2 g_eff) above
    it, its energy on R E = m v^2 / 2 = L H (L = m g - F_ext, the load). Near rest CVODE integrates the contact
    to rtol of its frame, whose length is at least hunt_crossley_rest_depth: its error of x, resolution times
    that, is an error of L resolution depth in E at R, that of a hop of resolution depth, which no run can tell
    from a rest. 0 where the contact never rests: undamped (alpha = 0, E kept), or a load <= 0 (lifted).
    """
    if not (alpha > 0.0 and load > 0.0):
        return 0.0
    return resolution * hunt_crossley_rest_depth(load, m, k, n)


def release_speed(alpha):
    """2 / (3 alpha) [m/s]: the speed above which the Hunt-Crossley force would pull (inf for alpha = 0)."""
    return 2.0 / (3.0 * alpha) if alpha > 0.0 else math.inf


def pressed_gap(parameters, x, v, load):
    """(z [m], dz/dt [m/s]) of the pressed no-pull contact at the gap x [m] and v [m/s]: z = x + (b / k) v = -force / k.

    The force k (R - h) - b v = -k z reaches 0 where z crosses 0: going up the ball is released (the
    force would pull), going down it is pressed again. z obeys the pressed contact's own equation
    (z'' + 2 sigma z' + w2 z = -g_eff, as x does), so its crossing upwards is the linear law's departure
    search of (z, dz/dt) (exact.departure_time); in the free sub-mode it moves on the flight's parabola
    from (z, dz/dt) too, and its crossing downwards is an impact's. dz/dt = v + (b / k) a, with a the
    pressed contact's acceleration. parameters: Ball.parameters.
    """
    m, k, b = parameters[0], parameters[1], parameters[2]
    c = b / k
    return x + c * v, v + c * gap_acceleration(x, v, 1, load, m, k, b)


def free_gap_rate(parameters, v, load):
    """dz/dt [m/s] in the free sub-mode at v [m/s]: v - (b / k) g_eff (pressed_gap's z on the parabola)."""
    return v - (parameters[2] / parameters[1]) * (load / parameters[0])


def no_pull_rest_margin_value(x, v, d, hop_tolerance, w2, sigma):
    """w2^2 (d + hop)^2 - (w2 + 4 sigma^2)(v^2 + w2 y^2) [m2/s4]: positive once a pressed no-pull ball never leaves.

    y = x + d, the deflection from the rest height. The force is k (d - y) - b v, and it reaches 0 where
    w2 y + 2 sigma v = w2 d; by Cauchy-Schwarz w2 y + 2 sigma v <= sqrt(w2 + 4 sigma^2) sqrt(v^2 + w2 y^2),
    and the energy v^2 + w2 y^2 never grows in contact (nor in the free sub-mode), so once the margin is
    positive with hop = 0 the force stays positive for ever. hop [m] (the hop tolerance) lets the force
    dip to -k hop at most, a pull the run may merge as it merges a hop. Written as
    w2^2 (hop - x)(2 d + hop + x) - 4 sigma^2 w2 y^2 - (w2 + 4 sigma^2) v^2, which keeps x's digits.
    """
    y = x + d
    return w2 * w2 * ((hop_tolerance - x) * (2.0 * d + hop_tolerance + x)) - 4.0 * sigma * sigma * w2 * (y * y) \
        - (w2 + 4.0 * sigma * sigma) * (v * v)


def law_rest_margin(parameters, x, v, d, hop_tolerance):
    """The rest margin under the ball's contact law (parameters: Ball.parameters); see rest_margin_value."""
    m, k = parameters[0], parameters[1]
    if parameters[5] == NO_PULL:
        return no_pull_rest_margin_value(x, v, d, hop_tolerance, k / m, parameters[2] / (2.0 * m))
    return rest_margin_value(x, v, d, hop_tolerance, k / m)


def effective_gravity_value(F_ext, m, g):
    """(m g - F_ext)/m [m/s2]; see Ball.effective_gravity and load_value."""
    return load_value(F_ext, m, g) / m


def static_deflection_value(F_ext, m, k, g):
    """(m g - F_ext)/k [m]; see Ball.static_deflection and load_value."""
    return load_value(F_ext, m, g) / k


def load_value(F_ext, m, g):
    """m g - F_ext [N], the net load on the spring, with the product m g exact (Dekker's two-product).

    Its sign decides whether a contact can hold the ball. m g rounded first can land on F_ext when
    F_ext exceeds the weight by an ulp: the load came out 0, and a ball that truly rises 3.6e-16 m
    above R and leaves after 42 s was declared at rest (found by the near-critical property).
    """
    product = m * g
    if not (abs(134217729.0 * m) < 1e300 and abs(134217729.0 * g) < 1e300 and abs(product) < 1e300):
        return product - F_ext
    return (product - F_ext) + product_error(m, g, product)


def rest_margin_value(x, v, d, hop_tolerance, w2):
    """w2 d (d + 2 hop_tolerance) - (v^2 + w2 y^2) [m2/s2] at the gap x = h - R, d the static deflection.

    y = x + d is the deflection from the rest height; the d^2 terms cancel in closed form, as
    w2 (2 d hop_tolerance - x (x + 2 d)) - v^2, which keeps x's digits where d is far larger (a soft
    contact) and d's where it is far smaller than R (no R - d). See Ball.rest_margin.
    """
    return w2 * (2.0 * d * hop_tolerance - x * (x + 2.0 * d)) - v * v


def gap_flow_value(mode, x0, v0, tau, load, m, k, b):
    """The exact (x [m], v [m/s]) a time tau [s] after (x0, v0) in mode; load = load_value(F_ext, m, g) [N].

    See Ball.gap_flow. Floats or arrays; compiled by the compiled engine. Mode 2 (free below R under the
    no-pull law) is the flight's parabola.
    """
    g_eff = load / m
    if mode != 1:
        return x0 + tau * (v0 - 0.5 * g_eff * tau), v0 - g_eff * tau
    return contact_gap_flow(b / (2.0 * m), k / m, g_eff, x0, v0, tau)
