"""The run's largest Lyapunov exponent, from the transition and saltation matrices its error estimate carries.

A perturbation (dh, dv) of the start is carried along the run by the very matrices the error estimate uses: each
phase's transition matrix (its exact flow's linearisation) and each event's saltation matrix (on a moving ground,
the rigid law's in the ground's frame). Its log growth, renormalised after each matrix so that nothing overflows
(Benettin's algorithm for the largest exponent), divided by the run's impacts or its duration, is the largest
Lyapunov exponent of the run, per impact and per second: ln of the factor by which a small error grows per bounce.

A finite run's exponent depends on the norm the perturbation is measured in, by at most ln(cond) / impacts
(cond: the condition of the basis the motion rotates in). Its start is (1, 0) and its end is measured in the
norm sqrt(dh^2 + (T dv)^2), with T the run's mean time between impacts [s]: a speed error moves the ball by T dv
over a bounce, so both count alike. Measured at a period-1 orbit of the rigid law on a vibrating table whose
multipliers are complex (|mu| = e): within 1.4e-3 of ln(e) from 300 to 600 impacts, 7e-4 to 1000, 4e-4 to 2000.

A rest or a ride (the ball carried by the ground: where it is no longer depends on where it was) maps every
perturbation to zero: it forgets the error (counted in `forgotten`), and a fresh perturbation is carried from
where the ball flies again. The exponent is that of the run's last stretch, from `since` (its start, or the end
of the last rest or ride) to its end: a chaotic run that rode now and then is measured on its flights since; a
run that ends resting or riding has forgotten where it started, -inf. A stretch with fewer than MIN_IMPACTS
impacts is too short to say: NaN.

A finite run's positive exponent is not yet chaos: on a still ground an error along the flow grows linearly
(the bounces' times shear apart), ln(n) / n per impact after n impacts; chaos is an exponent that stays
positive as the run lengthens.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

MIN_IMPACTS = 20  # a run with fewer impacts has no exponent (NaN)


@dataclass(frozen=True)
class LyapunovExponent:
    """The largest Lyapunov exponent of a run (see bouncingball.solvers.lyapunov).

    Attributes
    ----------
    per_impact : float
        ln of the growth of a small error per impact [1/impact] since `since`; -inf where the run ends resting or
        riding (it forgot its start), NaN for fewer than MIN_IMPACTS impacts since. < 0: errors die out (a stable
        orbit, at ln(e) per impact for a period-1 orbit with complex multipliers); > 0: they grow (chaos where it
        stays so as the run lengthens).
    per_second : float
        The same per second [1/s].
    impacts : int
        The impacts since `since`.
    duration : float
        The time [s] from `since` to the run's end.
    forgotten : int
        How many times a rest or a ride forgot the error (0: the exponent is the whole run's).
    since : float
        Where the measured stretch starts [s]: the run's start, or the end of its last rest or ride.
    """

    per_impact: float
    per_second: float
    impacts: int
    duration: float
    forgotten: int = 0
    since: float = 0.0


class TangentCarry:
    """A perturbation carried through the run's matrices: apply() each, in order, then exponent().

    Parameters
    ----------
    t_start : float
        The run's start [s].
    """

    def __init__(self, t_start: float = 0.0) -> None:
        self.dh, self.dv = 1.0, 0.0  # the perturbation's direction, of Euclidean norm 1
        self.log_growth = 0.0  # ln of its norm's growth since `since`
        self.collapsed = False  # a rest or a ride mapped it to 0: a fresh one starts with the next phase
        self.forgotten = 0
        self.since = t_start

    def apply(self, m00: float, m01: float, m10: float, m11: float, t: float) -> None:
        """The perturbation mapped by the matrix [[m00, m01], [m10, m11]] (a phase's from t [s], or an event's at t)."""
        if self.collapsed:  # flying again after a rest or a ride: a fresh perturbation from here
            self.dh, self.dv, self.collapsed, self.log_growth, self.since = 1.0, 0.0, False, 0.0, t
        dh, dv = m00 * self.dh + m01 * self.dv, m10 * self.dh + m11 * self.dv
        norm = math.hypot(dh, dv)
        if norm == 0.0:
            self.forget()
            return
        if not math.isfinite(norm):  # a NaN or inf entry: no exponent
            self.log_growth = math.nan
            return
        self.log_growth += math.log(norm)
        self.dh, self.dv = dh / norm, dv / norm

    def forget(self) -> None:
        """A rest or a ride: the perturbation is forgotten (once, however long it lasts)."""
        if not self.collapsed:
            self.collapsed, self.forgotten = True, self.forgotten + 1

    def exponent(self, impacts: int, t_end: float) -> LyapunovExponent:
        """The exponent of the stretch since `since` to t_end [s], with impacts in it (see the module's docstring)."""
        duration = t_end - self.since
        if self.collapsed:
            return LyapunovExponent(-math.inf, -math.inf, impacts, duration, self.forgotten, self.since)
        if impacts < MIN_IMPACTS or not duration > 0.0:
            return LyapunovExponent(math.nan, math.nan, impacts, duration, self.forgotten, self.since)
        growth = self.log_growth + math.log(math.hypot(self.dh, duration / impacts * self.dv))
        return LyapunovExponent(growth / impacts, growth / duration, impacts, duration, self.forgotten, self.since)


__all__ = ["MIN_IMPACTS", "LyapunovExponent", "TangentCarry"]
