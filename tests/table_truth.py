"""An independent solution of the rigid ball on a sinusoidally vibrating table in mpmath: the referee of issue 44.

Written from the equations alone; it imports nothing from bouncingball. Float inputs are taken as exact binary
numbers, everything after that is done with DPS decimal digits.

The model (SI units): the table's height s(t) = A sin(w t + p), w = 2 pi f. h is the height of the ball's centre,
v = dh/dt; the gap h - R - s(t) is zero in contact. In flight h'' = -a, a = g - F_ext/m > 0 constant. An impact
(the gap reaches 0 with v- - s' < 0) reverses the relative velocity: v+ - s' = -e (v- - s'). An impact whose
relative speed after, e |v- - s'|, is below v_min (or zero) starts a ride. With v_min = 0 and e < 1 impacts
accumulate (chattering): once the relative take-off speed u is below TAIL_SPEED the rest is the geometric series
of flights 2 u / a_rel, e times shorter each, a_rel = a + s'' the acceleration relative to the table, summed to
the accumulation time t + 2 u / (a_rel (1 - e)); the ball rides from there (its hops below TAIL_SPEED are taken
as on the table, off by less than TAIL_SPEED^2 / a_rel). A ride (h = R + s, v = s') lasts while s'' >= -a and
ends at the first phase where s'' falls below -a, w t + p = asin(a / (A w^2)) mod 2 pi (closed form); a ride that
would end at once is no ride: the ball leaves at zero relative speed there.

Each impact is a certified first root of the flight's gap, polished by findroot (Newton). The flight from
(t0, gap0, u0 = v0 - s'(t0)) has, in tau = t - t0 and x = w tau, the gap
    gap(tau) = gap0 + u0 tau - a tau^2 / 2 - A [sin(th0) (cos x - 1) + cos(th0) (sin x - x)],  th0 = w t0 + p,
written so that a tiny flight keeps its relative precision (cos x - 1 = -2 sin^2(x/2); sin x - x with extra
digits). The scan steps from tau where the gap is certified positive up to the first root of a lower bound of
it, so no root (a grazing one included) can be stepped over:
  - order 2 (anywhere): |gap''| <= M = a + A w^2, so gap(tau + d) >= g0 + g1 d - M d^2 / 2 > 0 up to its root;
  - order 3 (g0, g1 >= 0, g2 > 0): |gap'''| <= A w^3, so gap > g2 d^2/2 - A w^3 d^3/6 > 0 for d < 3 g2 / (A w^3);
  - a departure from a ride (gap = gap' = gap'' = 0, gap''' = A w^3 cos(th0) > 0: the gap starts cubic): order 4,
    gap > gap''' d^3/6 - A w^4 d^4/24 > 0 for d < 4 cos(th0) / w; the first step is half of that.
Near a transversal root the order-2 steps converge quadratically; once the gap is below its rounding noise the
local quadratic model decides: a crossing (real roots) is an impact, polished by findroot; no real root is a
touch at zero relative speed, which is no impact (the velocity is unchanged by the law, and there the gap's
curvature -a - s'' > 0: the table falls away faster than the ball, so it cannot ride). A crossing is a minimum
of that model below minus the gap's rounding noise (~1e-40 of the terms of the gap, below 1e-38 m here): a graze
shallower than that, at a relative speed below ~sqrt(2 a_rel 1e-38 m) ~ 1e-18 m/s, is taken as a touch.

Accuracy: each impact time to ~1e-38 s (relative to t of order 1-100 s at DPS = 40), relative speeds to about
1e-40 m/s absolute; an accumulation time to the sum of the enumerated impacts' rounding plus the tail's neglect of
the change of a_rel, (A w^3 T / a_rel) T with T the tail's length (~1e-46 s at TAIL_SPEED = 1e-25 m/s).
"""

from __future__ import annotations

import bisect

import mpmath

DPS = 40
mp = mpmath.MPContext()
mp.dps = DPS


def sine_increments(ctx, x):
    """(sin x, cos x - 1, sin x - x) in the mpmath context ctx, the last two to their relative precision at small x."""
    if x == 0:
        return ctx.zero, ctx.zero, ctx.zero
    if x > 1:
        sin_x, cos_x = ctx.cos_sin(x)[::-1]
        return sin_x, cos_x - 1, sin_x - x
    cos_x_1 = -2 * ctx.sin(x / 2) ** 2
    with ctx.extraprec(-2 * ctx.mag(x) + 10):
        sin_x = ctx.sin(x)
        sin_x_x = sin_x - x
    return +sin_x, cos_x_1, +sin_x_x
EPS = mp.mpf(2) ** (-mp.prec)
TAIL_SPEED = mp.mpf("1e-25")  # [m/s] chattering: below this relative take-off speed the rest is summed
MAX_SCAN_STEPS = 100_000  # in one flight
BOUNCE, LIFT, DEPARTURE, FREE = "bounce", "lift", "departure", "free"  # how a flight starts


def _mpf(value):
    return mp.mpf(float(value))


class Flight:
    """A free flight from t0 [s]: the gap [m] to the table and its first impact, certified not missed."""

    def __init__(self, A, w, p, a, t0, gap0, u0, start):
        self.A, self.w, self.a, self.t0, self.gap0, self.u0, self.start = A, w, a, t0, gap0, u0, start
        theta0 = w * t0 + p
        self.sin0, self.cos0 = mp.sin(theta0), mp.cos(theta0)
        self.M, self.B3 = a + A * w * w, A * w ** 3  # bounds of |gap''| and |gap'''|

    def derivatives(self, tau):
        """(gap [m], gap' [m/s], gap'' [m/s^2]) at t0 + tau."""
        sin_x, cos_x_1, sin_x_x = sine_increments(mp, self.w * tau if self.A != 0 else mp.zero)
        A, w, s0, c0 = self.A, self.w, self.sin0, self.cos0
        gap = self.gap0 + self.u0 * tau - self.a * tau * tau / 2 - A * (s0 * cos_x_1 + c0 * sin_x_x)
        rate = self.u0 - self.a * tau - A * w * (c0 * cos_x_1 - s0 * sin_x)
        curvature = -self.a + A * w * w * (s0 * (1 + cos_x_1) + c0 * sin_x)
        return gap, rate, curvature

    def gap(self, tau):
        return self.derivatives(tau)[0]

    def rate(self, tau):
        return self.derivatives(tau)[1]

    def _noise(self, tau):
        """The rounding noise of gap(tau) [m]: a gap below it is a contact within the working precision."""
        x = self.w * tau
        return 64 * EPS * (abs(self.gap0) + abs(self.u0) * tau + self.a * tau * tau + self.A * x * x)

    def _first_step(self):
        """A tau > 0 with the gap certified positive on (0, tau]."""
        if self.start == FREE:
            return mp.zero
        if self.start == BOUNCE:  # gap' = u0 > 0: order 2 from 0
            return 2 * self.u0 / self.M
        if self.start == LIFT:  # gap' = 0, gap'' > 0: order 3
            return 3 * self.derivatives(mp.zero)[2] / (2 * self.B3)
        return 2 * self.cos0 / self.w  # DEPARTURE: order 4, half of 4 gap''' / (A w^4)

    def first_impact(self, tau_max):
        """The first tau in (0, tau_max] where the gap reaches 0 going down, or None if there is none."""
        tau = self._first_step()
        for _ in range(MAX_SCAN_STEPS):
            if tau > tau_max:
                return None
            g0, g1, g2 = self.derivatives(tau)
            if g0 < -4 * self._noise(tau):  # a step to a lower bound's root cannot land inside the table
                raise RuntimeError(f"a scan step crossed the table, at t = {self.t0 + tau}")
            if g0 <= self._noise(tau):
                if g1 < 0 and (g2 <= 0 or g0 - g1 * g1 / (2 * g2) < -self._noise(tau)):
                    return self._polish(tau)
                if g2 <= 0:
                    raise RuntimeError(f"the gap has a non-negative maximum 0 at t = {self.t0 + tau}")
                tau += max(-g1 / g2, 0)  # a touch at zero relative speed: no impact; step past its minimum
                g0, g1, g2 = self.derivatives(tau)
                tau += 3 * g2 / (2 * self.B3) if self.B3 else 1 / self.w
                continue
            step = (g1 + mp.sqrt(g1 * g1 + 2 * self.M * g0)) / self.M
            if g1 >= 0 and g2 > 0 and self.B3:
                step = max(step, 3 * g2 / (2 * self.B3))
            tau += step
        raise RuntimeError(f"no end to the scan of the flight from t = {self.t0}")

    def _polish(self, tau):
        """The gap's root at or just after tau (where the gap is within its noise), by Newton's method."""
        tol = 64 * EPS * tau  # findroot stops when a step is below tol max(1, |root|)
        root = mp.findroot(self.gap, tau, solver="newton", df=self.rate, tol=tol, verify=False)
        if not (root > 0 and abs(self.gap(root)) <= 4 * self._noise(root) and self.rate(root) < 0):
            raise RuntimeError(f"findroot lost the impact near t = {self.t0 + tau}")
        return root


class SineTableTruth:
    """The rigid ball's exact motion on the table s(t) = A sin(2 pi f t + p) from (h0, v0) at t = 0 to t_end.

    Attributes: impacts, a list of (t [s], v- [m/s], v+ [m/s]) (absolute velocities); rides, a list of
    (start [s], end [s] or None if it lasts past t_end) of positive length; accumulations, the chattering's
    accumulation times [s]; t_known, the time up to which the motion is known (t_end, or the last impact's
    time when max_impacts stopped it). All as mpf.
    """

    def __init__(self, R, g, e, v_min, amplitude, frequency, phase, h0, v0, t_end, F_ext=0.0, m=1.0,
                 max_impacts=100_000):
        R, g, e, v_min, A, f, p, F_ext, m = (_mpf(x) for x in (R, g, e, v_min, amplitude, frequency, phase, F_ext,
                                                               m))
        self.R, self.A, self.w, self.p, self.e, self.v_min = R, A, 2 * mp.pi * f, p, e, v_min
        self.a = g - F_ext / m
        if not (self.a > 0 and 0 <= e <= 1 and v_min >= 0 and A >= 0 and f > 0):
            raise ValueError("needs g - F_ext/m > 0, 0 <= e <= 1, v_min >= 0, amplitude >= 0, frequency > 0")
        h0, v0, t_end = _mpf(h0), _mpf(v0), _mpf(t_end)
        self.impacts, self.rides, self.accumulations = [], [], []
        self._segments = []  # (start time, kind, h0, v0): kind "flight" (h0, v0 at the start), "ride" or "chatter"
        gap0, u0 = h0 - R - self.ground(0)[0], v0 - self.ground(0)[1]
        if gap0 < 0:
            raise ValueError(f"the ball starts {float(-gap0)} m inside the table")
        if gap0 > 0 or u0 > 0:
            action = ("flight", mp.zero, h0, v0, gap0, u0, FREE if gap0 > 0 else BOUNCE)
        else:  # on the table: moving into it is an impact at once, with it a ride
            action = ("impact", mp.zero, v0, u0) if u0 < 0 else ("ride", mp.zero)
        self.t_known = t_end
        while action is not None:  # each step returns the next: a flight ends in an impact, an impact starts a
            kind, *arguments = action  # flight or a ride, a ride ends in a flight; None past t_end
            if kind == "flight":
                action = self._flight(*arguments, t_end)
            elif kind == "impact":
                action = self._impact(*arguments, max_impacts)
            else:
                action = self._ride(*arguments, t_end)
        self._times = [segment[0] for segment in self._segments]

    def ground(self, t):
        """(s [m], s' [m/s], s'' [m/s^2]) of the table at the time t [s]."""
        theta = self.w * (t if isinstance(t, mp.mpf) else _mpf(t)) + self.p
        A, w = self.A, self.w
        return A * mp.sin(theta), A * w * mp.cos(theta), -A * w * w * mp.sin(theta)

    def _flight(self, t0, h0, v0, gap0, u0, start, t_end):
        self._segments.append((t0, "flight", h0, v0))
        flight = Flight(self.A, self.w, self.p, self.a, t0, gap0, u0, start)
        tau = flight.first_impact(t_end - t0)
        return None if tau is None else ("impact", t0 + tau, v0 - self.a * tau, flight.rate(tau))

    def _impact(self, t, v_before, u_before, max_impacts):
        """Record the impact at t [s] with the relative velocity u_before < 0; what follows."""
        s, ds, dds = self.ground(t)
        u_after = -self.e * u_before
        self.impacts.append((t, v_before, ds + u_after))
        if len(self.impacts) >= max_impacts:
            self.t_known = t
            return None
        if u_after == 0 or u_after < self.v_min:
            return "ride", t
        a_rel = self.a + dds
        if self.v_min == 0 and self.e < 1 and u_after < TAIL_SPEED and a_rel > self.a * mp.mpf("1e-10"):
            self._segments.append((t, "chatter", None, None))
            accumulation = t + 2 * u_after / (a_rel * (1 - self.e))
            self.accumulations.append(accumulation)
            return "ride", accumulation
        return "flight", t, self.R + s, ds + u_after, mp.zero, u_after, BOUNCE

    def _ride(self, t, t_end):
        """The ride from t [s], recorded if it has a length; the departing flight (None past t_end)."""
        if t > t_end:
            return None
        end, leaving = self._ride_end(t)
        if end is None or end > t:
            self._segments.append((t, "ride", None, None))
            self.rides.append((t, end if end is not None and end <= t_end else None))
            if end is None or end > t_end:
                return None
        s, ds, _ = self.ground(end)  # a ride that would end at once is none: the ball leaves at zero speed
        return "flight", end, self.R + s, ds, mp.zero, mp.zero, leaving

    def _ride_end(self, t):
        """(the time the ride from t ends [s] or None if never, how the ball leaves: LIFT at once or DEPARTURE)."""
        q = self.a / (self.A * self.w ** 2) if self.A > 0 else mp.inf
        if q >= 1:
            return None, None
        theta, theta1 = self.w * t + self.p, mp.asin(q)
        r = theta - 2 * mp.pi * mp.floor(theta / (2 * mp.pi))
        if theta1 < r < mp.pi - theta1:
            return t, LIFT
        if r == theta1:
            return t, DEPARTURE
        return (theta1 + 2 * mp.pi * mp.ceil((theta - theta1) / (2 * mp.pi)) - self.p) / self.w, DEPARTURE

    def state(self, t):
        """(h [m], v [m/s]) at the time t [s], as mpf."""
        t = t if isinstance(t, mp.mpf) else _mpf(t)
        if t < 0:
            raise ValueError("the motion starts at t = 0")
        if t > self.t_known:
            raise ValueError(f"the motion is known up to t = {float(self.t_known)} s only")
        t0, kind, h0, v0 = self._segments[bisect.bisect_right(self._times, t) - 1]
        if kind != "flight":  # riding, or hopping slower than TAIL_SPEED towards the accumulation time
            s, ds, _ = self.ground(t)
            return self.R + s, ds
        tau = t - t0
        return h0 + tau * (v0 - self.a * tau / 2), v0 - self.a * tau

    def phase(self, t):
        """The table's phase w t + p at t [s], reduced to [0, 2 pi)."""
        theta = self.w * t + self.p
        return theta - 2 * mp.pi * mp.floor(theta / (2 * mp.pi))

    def impact_phases(self):
        return [self.phase(t) for t, _, _ in self.impacts]

    def intervals(self):
        """The times between successive impacts [s]."""
        return [later[0] - earlier[0] for earlier, later in zip(self.impacts, self.impacts[1:], strict=False)]
