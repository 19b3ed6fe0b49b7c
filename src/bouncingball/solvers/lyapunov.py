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
perturbation to zero: the exponent is then -inf. A run with fewer than MIN_IMPACTS impacts is too short to say: NaN.
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
        ln of the growth of a small error per impact [1/impact]; -inf after a rest or a ride (the error is
        forgotten), NaN for a run with fewer than MIN_IMPACTS impacts. < 0: errors die out (a stable orbit, at
        ln(e) per impact for a period-1 orbit with complex multipliers); > 0: they grow (chaos).
    per_second : float
        The same per unit time [1/s].
    impacts : int
        The run's impacts.
    duration : float
        The run's duration [s].
    """

    per_impact: float
    per_second: float
    impacts: int
    duration: float


class TangentCarry:
    """A perturbation of the run's start carried through its matrices: apply() each, in order, then exponent()."""

    def __init__(self) -> None:
        self.dh, self.dv = 1.0, 0.0  # the perturbation's direction, of Euclidean norm 1
        self.log_growth = 0.0  # ln of its norm's growth so far

    def apply(self, m00: float, m01: float, m10: float, m11: float) -> None:
        """The perturbation mapped by the matrix [[m00, m01], [m10, m11]] (a transition or a saltation matrix)."""
        if math.isinf(self.log_growth):
            return
        dh, dv = m00 * self.dh + m01 * self.dv, m10 * self.dh + m11 * self.dv
        norm = math.hypot(dh, dv)
        if norm == 0.0 or not math.isfinite(norm):  # forgotten (a rest or a ride); inf: a NaN or inf entry
            self.log_growth = -math.inf if norm == 0.0 else math.nan
            return
        self.log_growth += math.log(norm)
        self.dh, self.dv = dh / norm, dv / norm

    def exponent(self, impacts: int, duration: float) -> LyapunovExponent:
        """The run's exponent after impacts over duration [s] (see the module's docstring for the norm)."""
        if impacts < MIN_IMPACTS or not duration > 0.0:
            return LyapunovExponent(math.nan, math.nan, impacts, duration)
        growth = self.log_growth
        if math.isfinite(growth):
            interval = duration / impacts
            growth += math.log(math.hypot(self.dh, interval * self.dv))
        return LyapunovExponent(growth / impacts, growth / duration, impacts, duration)


__all__ = ["MIN_IMPACTS", "LyapunovExponent", "TangentCarry"]
