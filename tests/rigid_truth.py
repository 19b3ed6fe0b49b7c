"""An independent solution of the rigid contact law in mpmath: the referee of contact="rigid".

Written from the law's equations alone; it imports nothing from bouncingball. Float inputs are taken
as exact binary numbers, everything after that is done with DPS decimal digits.

The law: h is the height of the centre [m], v = dh/dt. Above R the ball flies, v' = -a with
a = g - F_ext/m > 0 held constant. When h reaches R going down at v- < 0 its velocity becomes
v+ = -e v- (0 <= e <= 1). With v_min > 0 a bounce that would leave slower than v_min ends on R at rest
(the Modelica Association's Reference-FMUs BouncingBall). With v_min = 0 and e < 1 the bounces go on
for ever, each flight 2 v / a long and each e times the last: after the bounce leaving at v_k at t_k
they end at the Zeno time t_k + 2 v_k / (a (1 - e)), the sum of the geometric series, and the ball
rests on R from there.

Method: each flight is a parabola, its impact the root tau = (v + s)/a (v >= 0) or 2 (h - R)/(s - v)
(v < 0), s = sqrt(v^2 + 2 a (h - R)). Bounces are enumerated one by one until the next would rise less
than APEX_FLOOR R (then the ball is taken on R, off by less than that, and the rest starts at the series'
sum), so the heights are right to ~1e-30 R and the Zeno time to the working precision.
"""

from __future__ import annotations

import bisect

import mpmath

DPS = 40
mp = mpmath.MPContext()
mp.dps = DPS
APEX_FLOOR = mp.mpf("1e-30")


class RigidTruth:
    """The rigid ball's exact motion from (h0, v0) at t = 0 under the constant load a = g - F_ext/m > 0."""

    def __init__(self, R, a, e, v_min, h0, v0, t_end, max_events=100_000):
        R, a, e, v_min = (mp.mpf(float(x)) for x in (R, a, e, v_min))
        h, v, t = mp.mpf(float(h0)), mp.mpf(float(v0)), mp.mpf(0)
        if h < R:
            raise ValueError("a rigid ball cannot start below R")
        self.R, self.a = R, a
        self.starts = []  # (t, h, v) of each flight
        self.impacts = []  # (t, v-) of each impact
        self.rest_time = None
        if h == R and v == 0:
            self.rest_time = t
        while self.rest_time is None and t <= t_end:
            self.starts.append((t, h, v))
            s = mp.sqrt(v * v + 2 * a * (h - R))
            tau = (v + s) / a if v >= 0 else 2 * (h - R) / (s - v)
            t = t + tau
            self.impacts.append((t, -s))
            h, v = R, e * s
            if v < v_min or v == 0:
                self.rest_time = t
            elif e < 1 and v * v / (2 * a) < APEX_FLOOR * R:
                self.rest_time = t + 2 * v / (a * (1 - e))
            if len(self.impacts) > max_events:
                raise RuntimeError("more bounces than max_events")
        self._times = [start[0] for start in self.starts]

    def state(self, t):
        """(h [m], v [m/s]) at the time t [s], as mpf."""
        t = mp.mpf(float(t))
        if self.rest_time is not None and (not self.impacts or t >= self.impacts[-1][0]):
            return self.R, mp.mpf(0)  # at rest, or hopping lower than APEX_FLOOR R until the Zeno time
        i = bisect.bisect_right(self._times, t) - 1
        t0, h0, v0 = self.starts[i]
        tau = t - t0
        return h0 + tau * (v0 - self.a * tau / 2), v0 - self.a * tau

    def heights(self, times):
        """The heights [m] at the times, as floats."""
        return [float(self.state(t)[0]) for t in times]
