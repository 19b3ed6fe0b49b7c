"""The exact solver's own error: the rounding of its closed forms, carried through the run as CVODE's error is.

Each phase's end is its closed form evaluated in double precision from the phase's start: off the exact flow
by a few ulps of the terms it sums (the phase's length and speed scales, phases.phase_scales), and its event
time by a few ulps of the phase's duration plus the state's rounding over the rate the gap crosses R at. A
grazing event (that rate near 0) is ill-conditioned: its time's error is then at most the square root of the
rounding over the acceleration there, and the state's at the event follows from it. These errors, of unknown
sign, are carried as a set of (x, v) errors, an ellipse, through each phase's transition matrix and each event's
saltation matrix: those of the CVODE engines (error_estimate.law_flow_value's unit flows and event_saltation),
so a rounding that a sensitive run amplifies (a grazing rigid impact, a long flight under a force near m g, 1e5
undamped bounces) is amplified here as in the run it judges.
"""

from __future__ import annotations

import math

from ..codes import CONTACT, FLIGHT, IMPACT
from ..contact_laws import impact_is_instantaneous, law_acceleration, law_flow_value
from .lyapunov import TangentCarry
from .phase_machine.error_estimate import ellipse_image, ellipse_sum, event_saltation
from .phase_machine.phases import phase_scales
from .phase_machine.settings import ESTIMATE_CAP, PROMISE

_EPS = 2.0**-52
ULPS = 8.0  # the rounding of one closed-form evaluation, in ulps of the terms it sums (measured: 1-4)


class RoundingCarry:
    """The exact solution's error bound, phase by phase: phase() for each phase, in order, then estimate.

    Parameters
    ----------
    parameters : BallParameters
        The ball's (Ball.parameters).
    """

    def __init__(self, parameters, t_start: float = 0.0) -> None:
        self.parameters = parameters
        self.p00, self.p01, self.p11 = 0.0, 0.0, 0.0  # the ellipse holding the error of (x, v) at the phase's start
        self.bound = 0.0  # on |h - h_true| [m] so far
        self.scale = parameters.R  # max(|h|, R) [m] so far
        self.untrusted_from = math.nan  # the start [s] of the first phase past the promise
        self.speed_max = 0.0  # the largest speed scale [m/s] of the phases so far
        # the events' times' errors [s], summed: an error along the flow stays one, through every phase's flow and
        # every event's saltation (S f- = f+), so it is carried apart from the ellipse, as a delay
        self.delay = 0.0
        self.tangent = TangentCarry(t_start)  # a perturbation carried through the same matrices: the Lyapunov exponent

    def phase(self, t_start: float, mode: int, x0: float, v0: float, tau: float, load: float,
              kind: int = -1, v_event: float = 0.0, v_after: float = 0.0, forced: tuple = (0.0, 0.0)) -> None:
        """The phase from the gap x0 [m] and v0 [m/s] at t_start [s] in mode, tau [s] long under load [N].

        kind: the event that ends it (IMPACT ..), where the ball is at v_event [m/s] and leaves at v_after [m/s]
        (a rigid impact's rebound); -1: none (a change of F_ext or the run's end, x and v continuous). forced: the
        (length [m], speed [m/s]) of a contact's periodic response to a vibrating ground, terms its closed form sums.
        """
        parameters, R = self.parameters, self.parameters.R
        length, speed = self._terms(mode, x0, v0, tau, load)
        length, speed = length + forced[0], speed + forced[1]
        self.speed_max = max(self.speed_max, speed)
        x_end, v_end = law_flow_value(parameters, mode, x0, v0, tau, load)
        p00, p01, p11 = self.p00, self.p01, self.p11
        start_width = self._x_width(mode, p00, p01, p11)
        # the transition over the phase (the flow of the unit vectors under no load), then its own rounding
        f00, f10 = law_flow_value(parameters, mode, 1.0, 0.0, tau, 0.0)
        f01, f11 = law_flow_value(parameters, mode, 0.0, 1.0, tau, 0.0)
        p00, p01, p11 = ellipse_image(f00, f01, f10, f11, p00, p01, p11)
        if mode == CONTACT and impact_is_instantaneous(parameters):  # a rigid ball resting on R: forgotten
            self.tangent.forget()
        else:
            self.tangent.apply(f00, f01, f10, f11, t_start)
        ex = ULPS * _EPS * (length + R + abs(x_end))
        ev = ULPS * _EPS * (speed + abs(v_end))
        if kind >= 0:
            self.delay += self._event_delay(mode, tau, load, ex, v_event)
            # on R exactly; and a phase from R that ends at the very speed it started at (a conserved speed,
            # contact_laws' conserved_speed, or a flight's sqrt(v0^2) = |v0|) adds no error but its time's
            ex = 0.0
            ev = 0.0 if x0 == 0.0 and abs(v_event) == abs(v0) and v_after == v_event else ev
        p00, p01, p11 = ellipse_sum(p00, p01, p11, 2.0 * ex * ex, 0.0, 2.0 * ev * ev)
        end_width = math.sqrt(max(p00, 0.0))
        self.bound = max(self.bound, max(start_width, end_width) + self.delay * speed)
        self.scale = max(self.scale, abs(R + x0), abs(R + x_end), R + self._flight_top(mode, x0, v0, tau, load))
        if kind >= 0:
            jump, reflection = event_saltation(parameters, kind, mode, v_event, v_after, load)
            p00, p01, p11 = ellipse_image(reflection, 0.0, jump, reflection, p00, p01, p11)
            self.tangent.apply(reflection, 0.0, jump, reflection, t_start + tau)
        self.p00, self.p01, self.p11 = p00, p01, p11
        if math.isnan(self.untrusted_from) and not self.bound <= PROMISE * self.scale:
            self.untrusted_from = t_start

    def moving_impact(self, t: float, tau: float, relative: float, rebound: float, relative_load: float,
                      rounding: float) -> None:
        """A rigid impact on a moving ground at t [s], tau [s] after its flight's start (after phase() of it).

        relative: the speed relative to the ground [m/s] it meets it at (< 0), rebound: the relative speed it leaves
        at (0: it rides, or, where relative_load < 0, leaves with the ground at once), relative_load: m (g_eff + s'')
        [N], rounding: the gap's rounding at the root [m]. The root's time error (_moving_offset) is added to the
        ellipse, then the impact's saltation matrix (the rigid law's in the ground's frame) maps it.
        """
        p00, p01, p11 = self._moving_offset(tau, relative, relative_load / self.parameters.m, rounding)
        if rebound > 0.0 or relative_load >= 0.0 or relative == 0.0:
            jump, reflection = event_saltation(self.parameters, IMPACT, FLIGHT, relative, rebound, relative_load)
        else:  # no rebound, but the ground pulls away at once: it leaves with it, as after an impact with e = 0
            jump, reflection = -(relative_load / self.parameters.m) / relative, 0.0
        self._saltation(t, jump, reflection, p00, p01, p11)

    def moving_switch(self, t: float, tau: float, kind: int, mode: int, relative: float, acceleration: float,
                      rounding: float) -> None:
        """A compliant law's impact or departure (kind) on a moving ground at t [s], ending a phase in mode tau long.

        relative: the speed relative to the ground [m/s] there, acceleration: the relative acceleration [m/s2] (for a
        grazing event's time error), rounding: the gap's rounding at the root [m]. As moving_impact, with the
        law's saltation (its field's jump -+ b/m, unchanged in the ground's frame: the ground's speed enters both
        the jump of the field and the rate the gap crosses 0 at, and cancels).
        """
        p00, p01, p11 = self._moving_offset(tau, relative, acceleration, rounding)
        jump, reflection = event_saltation(self.parameters, kind, mode, relative, relative, 0.0)
        self._saltation(t, jump, reflection, p00, p01, p11)

    def _moving_offset(self, tau: float, relative: float, acceleration: float, rounding: float):
        """The ellipse with the state error an event's time error leaves on a moving ground.

        The root's time error d (a few ulps of tau, and the rounding over the relative speed, or for a grazing
        event over the relative acceleration) leaves the ball off the ground's true meeting point by |relative| d:
        the ground has moved meanwhile, so unlike on a still ground this is no delay along the flow.
        """
        acceleration = abs(acceleration)
        delay = ULPS * _EPS * tau + min(rounding / abs(relative) if relative != 0.0 else math.inf,
                                        math.sqrt(2.0 * rounding / acceleration) if acceleration > 0.0 else math.inf)
        if not math.isfinite(delay):
            delay = ULPS * _EPS * tau
        offset = abs(relative) * delay
        return ellipse_sum(self.p00, self.p01, self.p11, offset * offset, 0.0, 0.0)

    def _saltation(self, t: float, jump: float, reflection: float, p00: float, p01: float, p11: float) -> None:
        """The ellipse (p00, p01, p11) and the tangent through an event's saltation matrix at t [s]."""
        self.p00, self.p01, self.p11 = ellipse_image(reflection, 0.0, jump, reflection, p00, p01, p11)
        self.tangent.apply(reflection, 0.0, jump, reflection, t)
        self.bound = max(self.bound, math.sqrt(max(self.p00, 0.0)))
        self._judge(t)

    def restart(self, t: float, length: float, speed: float) -> None:
        """A flight leaving a ride at t [s]: the ride forgot the errors before it; the state's own rounding is left.

        length [m], speed [m/s]: the scales of the state (R + |s|, |s'|) rounded there.
        """
        ex, ev = ULPS * _EPS * length, ULPS * _EPS * speed
        self.p00, self.p01, self.p11 = 2.0 * ex * ex, 0.0, 2.0 * ev * ev
        self.tangent.forget()  # where it leaves is the ground's doing alone
        self.speed_max = max(self.speed_max, speed)
        self._judge(t)

    def charge(self, t: float, amount: float) -> None:
        """An error of amount [m] at t [s] outside the carried ellipse (summed bounces taken on the ground)."""
        self.bound = max(self.bound, math.sqrt(max(self.p00, 0.0)) + amount)
        self._judge(t)

    def _judge(self, t: float) -> None:
        if math.isnan(self.untrusted_from) and not self.bound <= PROMISE * self.scale:
            self.untrusted_from = t

    def _terms(self, mode: int, x0: float, v0: float, tau: float, load: float) -> tuple[float, float]:
        """(length [m], speed [m/s]): the largest terms the closed form of a phase tau [s] long sums, for x and v.

        A parabola's (a flight, the no-pull law's free spell): |x0| + |v0| tau + |a| tau^2 / 2 and |v0| + |a| tau,
        not its apex, which a force near m g puts anywhere; a contact's, its oscillation's (phases.phase_scales).
        """
        if mode == CONTACT:
            length, speed = phase_scales(self.parameters, mode, x0, v0, load)
            return length + abs(x0), speed + abs(v0)
        rise = abs(load / self.parameters.m) * tau
        return abs(x0) + (abs(v0) + 0.5 * rise) * tau, abs(v0) + rise

    def _event_delay(self, mode: int, tau: float, load: float, rounding: float, v_event: float) -> float:
        """The error [s] of an event's time tau [s] after a phase whose state is rounded by rounding [m].

        A few ulps of tau, and the rounding over the rate the gap crosses R at, or, for a grazing event, over the
        acceleration there: the root of rate d + acceleration d^2 / 2 = rounding is below either term's.
        """
        rate = abs(v_event)
        acceleration = abs(law_acceleration(self.parameters, 0.0, v_event, mode, load))
        delay = ULPS * _EPS * tau
        if acceleration > 0.0:
            return delay + min(rounding / rate if rate > 0.0 else math.inf, math.sqrt(2.0 * rounding / acceleration))
        return delay + (rounding / rate if rate > 0.0 else 0.0)

    def _x_width(self, mode: int, p00: float, p01: float, p11: float) -> float:
        """The largest |x error| [m] over a phase in mode, from the ellipse at its start.

        Its x half-width there (a parabola's x error is convex in time: largest at an end), or, in a compliant
        contact, its half-width in the energy norm, which no contact's flow grows.
        """
        parameters = self.parameters
        if mode == CONTACT and not impact_is_instantaneous(parameters):
            return math.sqrt(max(p00 + p11 * parameters.m / parameters.k, 0.0))
        return math.sqrt(max(p00, 0.0))

    def _flight_top(self, mode: int, x0: float, v0: float, tau: float, load: float) -> float:
        """The highest gap [m] a flight passes within tau (its apex, if it reaches it); else 0."""
        g_eff = load / self.parameters.m
        if mode == FLIGHT and v0 > 0.0 and g_eff > 0.0 and v0 <= g_eff * tau:
            return x0 + 0.5 * v0 * (v0 / g_eff)
        return 0.0

    def estimate(self, t_end: float) -> float:
        """The bound [m] on |h - h_true| at every output point up to t_end [s].

        The carried error, and the rounding of an output's time from its phase's start (an ulp of t_end at the
        fastest phase's speed); at most ESTIMATE_CAP scales.
        """
        evaluation = ULPS * _EPS * (self.scale + abs(t_end) * self.speed_max)
        return min(2.0 * (self.bound + evaluation), ESTIMATE_CAP * self.scale)
