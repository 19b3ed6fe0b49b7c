"""An independent solution of the Hunt-Crossley law on a sinusoidally vibrating table in mpmath: its referee there.

Written from the law's equations alone; it imports nothing from bouncingball (from tests/table_truth.py, the rigid
truth, its sine increments). Float inputs are taken as exact binary numbers, everything after that is done with
`dps` decimal digits (DPS by default).

The model (SI units): the table s(t) = A sin(w t + p), w = 2 pi f; h the height of the ball's centre, v = h',
a = g - F_ext/m the net downward acceleration (constant). The penetration delta = R + s(t) - h (> 0: pressed into
the table) and its rate delta' = s'(t) - v.
- Flight (delta < 0): h'' = -a, delta'' = s''(t) + a: a parabola minus a sine. Impact: delta reaches 0 going up.
- Pressed (delta > 0, 1 + 3/2 alpha delta' >= 0): m h'' = F - m a, F = k delta^n (1 + 3/2 alpha delta'), so
  delta'' = s''(t) + a - (k/m) delta^n (1 + 3/2 alpha delta'). Departure: delta reaches 0 going down (F = 0 there:
  the acceleration is continuous at impact and departure). Release: delta' falls below -2/(3 alpha), where F
  would pull; it is clipped at 0 and the ball is free below the surface, delta'' = s''(t) + a as in flight, until
  delta reaches 0 (departure) or delta' rises back to -2/(3 alpha) (engage: pressed again).

Method:
- Flight and free: closed forms from (t0, delta0, delta0'), written so that a short piece keeps its relative
  precision (cos x - 1 and sin x - x, x = w tau, as in tests/table_truth.py). Their events are certified first
  roots, as table_truth.Flight's impacts: each function g > 0 whose root is sought (-delta in flight; delta and
  -(delta' + 2/(3 alpha)) when free) has |g''| <= M2 and |g'''| <= M3 (|a| + A w^2 and A w^3 for delta, A w^3 and
  A w^4 for delta'); the scan steps to the root of the lower bound g0 + g1 d - M2 d^2 / 2 (or, with g0, g1 >= 0
  < g2, to half of 3 g2 / M3), so no root, a grazing one included, is stepped over. Once g is below its rounding
  noise (64 eps of its terms) the local quadratic decides: a crossing, polished by Newton's method, or a touch at
  zero relative speed (no event: a graze shallower than the noise, ~4e-22 m at DPS = 20, is taken as a touch).
- Pressed, as tests/hunt_crossley_truth.py (delta^n is not analytic at delta = 0, where a contact starts and
  ends): the first START_FRACTION of the contact's time scale after an impact at t_i is the series
  delta = [the flight's closed form from (t_i, 0, w0)] - c w0^n tau^(n+2) / ((n+1)(n+2)), c = (k/m)(1 + 3/2 alpha
  w0), which holds the table's s'', s''', ... exactly; then mpmath.odefun (a Taylor-series integrator, one per
  pressed piece) with the time-dependent right-hand side, stepped on a grid of t_scale / 20 that never crosses
  delta = 0: each step at most half the time to the root of delta + delta' d - M d^2 / 2, M = |a| + A w^2 + twice
  the present force / m (so a short contact driven by the table, a < -s'', is followed too), scanned for the
  release at its grid points (polished by findroot). Once delta falls below END_FRACTION of the contact's depth
  the rest to delta = 0 is the force-free closed form with the table's exact s(t) (a certified root) plus the
  force's impulse with delta taken linear. A contact that never ends before t_end lasts to it.

Limits: the release is looked for at the grid points only: a dip of delta' below -2/(3 alpha) and back within one
grid step would be missed. A departure tangential within the last END_FRACTION of the depth (no root of the
force-free rest within 4 delta / |delta'|) raises RuntimeError, as does a grid step landing past delta = 0.
Accuracy and cost: odefun's tolerance is 10^(2 - dps) per series; DPS = 20 and 30 agree to ~2e-19 s in event
times and each contact's energy balance (change of m v^2/2 + m a h against the work of F) holds to ~2e-20 J; with
amplitude = 0 it agrees with tests/hunt_crossley_truth.py to ~2e-20 s, with n = 1, alpha = 0 with
tests/linear_table_truth.py (b = 0) to ~1e-19 s. About 1.3 s per n = 3/2 contact at DPS = 20 (5x that at 30).
"""

from __future__ import annotations

import bisect

import mpmath

from table_truth import sine_increments

DPS = 20  # as tests/hunt_crossley_truth.py: odefun's cost grows fast with the digits
mp = mpmath.MPContext()
mp.dps = DPS
FLIGHT, PRESSED, FREE = "flight", "pressed", "free"
START_FRACTION = mpmath.mpf("1e-9")  # the series covers this fraction of the estimated contact time
END_FRACTION = mpmath.mpf("1e-14")  # of the contact's depth scale: the rest is force-free
MAX_SCAN_STEPS = 100_000  # in one certified search


def _mpf(value):
    return mp.mpf(float(value))


def _safe_step(g0, g1, g2, M2, M3):
    """A d > 0 with g > 0 on (0, d): the root of g0 + g1 d - M2 d^2/2, or (g0, g1 >= 0 < g2) half of 3 g2 / M3."""
    if M2 > 0:  # without cancellation either way
        root = mp.sqrt(g1 * g1 + 2 * M2 * g0)
        d = 2 * g0 / (root - g1) if g1 < 0 else (g1 + root) / M2
    else:
        d = -g0 / g1 if g1 < 0 else mp.inf
    if g1 >= 0 and g2 > 0:
        d = max(d, 3 * g2 / (2 * M3) if M3 > 0 else mp.inf)
    return d


class HuntCrossleyGroundTruth:
    """The trajectory from (h0, v0) at t = 0 to t_end: events [(t, kind, v)], state(t), gap(t), ground(t).

    kind is "impact", "departure", "release" or "engage", v the ball's velocity h' [m/s] there; all as mpf, computed
    (and evaluated) with dps digits. pieces: [t0, t1, "flight" / "free" / "pressed", data]."""

    def __init__(self, m, k, n, alpha, R, g, amplitude, frequency, phase, h0, v0, t_end, F_ext=0.0,
                 max_events=200, dps=DPS):
        self.dps = dps
        with mp.workdps(dps):
            self.m, self.k, self.n, self.alpha, self.R = (_mpf(x) for x in (m, k, n, alpha, R))
            self.A, self.p, self.w = _mpf(amplitude), _mpf(phase), 2 * mp.pi * _mpf(frequency)
            if not (self.m > 0 and self.k > 0 and 1 <= self.n <= 2.5 and self.alpha >= 0 and self.A >= 0
                    and self.w > 0):
                raise ValueError("needs m, k, frequency > 0, 1 <= n <= 2.5, alpha >= 0, amplitude >= 0")
            self.a = _mpf(g) - _mpf(F_ext) / self.m  # net downward acceleration
            self.t_end = _mpf(t_end)
            self.w_release = 2 / (3 * self.alpha) if self.alpha > 0 else mp.inf
            A, w = self.A, self.w
            self.bounds = ((abs(self.a) + A * w**2, A * w**3), (A * w**3, A * w**4))  # (M2, M3) of delta, delta'
            self.events = []  # (t, kind, v): v the ball's velocity h' [m/s] at the event
            self.pieces = []  # [t0, t1, kind, data]: data (t0, delta0, rate0) unforced, a dict pressed
            t = mp.zero
            s, ds = self.ground(t)
            delta, rate = self.R + s - _mpf(h0), ds - _mpf(v0)
            a_rel = self.a + self._table_accel(t)
            if delta > 0 or (delta == 0 and (rate > 0 or (rate == 0 and a_rel > 0))):
                free = rate < -self.w_release or (rate == -self.w_release and a_rel < 0)
                mode = FREE if free else PRESSED
            else:
                mode = FLIGHT
            step = {FLIGHT: self._flight, FREE: self._free, PRESSED: self._pressed}
            while mode is not None and len(self.events) < max_events:
                t, delta, rate, mode = step[mode](t, delta, rate)
            self._starts = [piece[0] for piece in self.pieces]

    # --- the table and the force-free motion -------------------------------------------------------------------
    def ground(self, t):
        """(s [m], s' [m/s]) of the table at t [s], as mpf."""
        with mp.workdps(self.dps):
            theta = self.w * mp.mpf(t) + self.p
            return self.A * mp.sin(theta), self.A * self.w * mp.cos(theta)

    def _table_accel(self, t):
        return -self.A * self.w**2 * mp.sin(self.w * t + self.p)

    def _unforced(self, t0, d0, w0, tau):
        """(delta, delta', delta'', delta''') at t0 + tau with no force, from (d0, w0) at t0."""
        sin_x, cos_x_1, sin_x_x = sine_increments(mp, self.w * tau if self.A != 0 else mp.zero)
        A, w, a = self.A, self.w, self.a
        theta0 = w * t0 + self.p
        s0, c0 = mp.sin(theta0), mp.cos(theta0)
        # s(t0 + tau) - s(t0) - s'(t0) tau = A [s0 (cos x - 1) + c0 (sin x - x)]
        delta = d0 + w0 * tau + a * tau * tau / 2 + A * (s0 * cos_x_1 + c0 * sin_x_x)
        rate = w0 + a * tau + A * w * (c0 * cos_x_1 - s0 * sin_x)
        accel = a - A * w * w * (s0 * (1 + cos_x_1) + c0 * sin_x)
        jerk = -A * w**3 * (c0 * (1 + cos_x_1) - s0 * sin_x)
        return delta, rate, accel, jerk

    def _noise(self, d0, w0, tau):
        """The rounding noise of the force-free (delta, delta') at tau from (d0, w0): 64 eps of their terms."""
        x, a = self.w * tau, abs(self.a)
        offset = self.w_release if self.alpha > 0 else 0
        return (64 * mp.eps * (abs(d0) + abs(w0) * tau + a * tau * tau + self.A * x * x),
                64 * mp.eps * (abs(w0) + offset + a * tau + self.A * self.w * x))

    def _first_root(self, t0, d0, w0, roots, tau_max):
        """The first tau in [0, tau_max] where one of the roots' g = sign (y[i] + offset), y the force-free
        (delta, delta', delta'', delta''') from (d0, w0) at t0, reaches 0 going down: (tau, kind), or None.
        roots: (sign, i, offset, kind) with g > 0 (or g = 0 rising) at 0."""
        tau = mp.zero
        for _ in range(MAX_SCAN_STEPS):
            if tau > tau_max:
                return None
            y = self._unforced(t0, d0, w0, tau)
            noises = self._noise(d0, w0, tau)
            step = mp.inf
            for sign, i, offset, kind in roots:
                M2, M3 = self.bounds[i]
                g0, g1, g2 = sign * (y[i] + offset), sign * y[i + 1], sign * y[i + 2]
                if g0 <= noises[i] and (tau > 0 or g1 < 0):
                    if g1 < 0 and (g2 <= 0 or g0 - g1 * g1 / (2 * g2) < -noises[i]):  # a crossing
                        return self._polish(t0, d0, w0, tau, sign, i, offset), kind
                    if g2 <= 0:
                        raise RuntimeError(f"a {kind}'s function has a non-negative maximum 0 at t = {t0 + tau}")
                    # a touch at zero relative speed: no event; past its minimum, then an order-3 step
                    step = min(step, max(-g1 / g2, 0) + (3 * g2 / (2 * M3) if M3 > 0 else mp.inf))
                else:
                    step = min(step, _safe_step(g0, g1, g2, M2, M3))
            if not step > 0:
                raise RuntimeError(f"the certified search is stuck at t = {t0 + tau}")
            tau += step
        raise RuntimeError(f"no end to the certified search from t = {t0}")

    def _polish(self, t0, d0, w0, tau, sign, i, offset):
        """The root of g at or just after tau (where g is within its noise), by Newton's method."""
        g = lambda s: sign * (self._unforced(t0, d0, w0, s)[i] + offset)  # noqa: E731
        dg = lambda s: sign * self._unforced(t0, d0, w0, s)[i + 1]  # noqa: E731
        tol = 64 * mp.eps * max(tau, mp.eps)
        root = mp.findroot(g, tau, solver="newton", df=dg, tol=tol, verify=False)
        if not (root >= 0 and abs(g(root)) <= 4 * self._noise(d0, w0, root)[i] and dg(root) < 0):
            raise RuntimeError(f"findroot lost the root near t = {t0 + tau}")
        return root

    def _event(self, t, kind, rate):
        self.events.append((t, kind, self.ground(t)[1] - rate))

    # --- flight and free: closed forms ---------------------------------------------------------------------------
    def _flight(self, t, delta, rate):
        """delta < 0 (or 0 moving apart): the impact where delta reaches 0 going up."""
        return self._unforced_piece(t, delta, rate, FLIGHT, [(-1, 0, 0, "impact")])

    def _free(self, t, delta, rate):
        """Below the surface, delta' < -2/(3 alpha): delta reaches 0 (departure) or delta' rises (engage)."""
        roots = [(1, 0, 0, "departure"), (-1, 1, self.w_release, "engage")]
        return self._unforced_piece(t, delta, rate, FREE, roots)

    def _unforced_piece(self, t, delta, rate, kind, roots):
        piece = [t, self.t_end, kind, (t, delta, rate)]
        self.pieces.append(piece)
        found = self._first_root(t, delta, rate, roots, self.t_end - t)
        if found is None:
            return None, None, None, None
        tau, event = found
        piece[1] = t1 = t + tau
        if event == "engage":
            delta1, rate1 = self._unforced(t, delta, rate, tau)[0], -self.w_release
        else:
            delta1, rate1 = mp.zero, self._unforced(t, delta, rate, tau)[1]
        self._event(t1, event, rate1)
        return t1, delta1, rate1, FLIGHT if event == "departure" else PRESSED

    # --- pressed: a series, odefun, a force-free rest ----------------------------------------------------------
    def _accel(self, t, delta, rate):
        km = self.k / self.m
        return self.a + self._table_accel(t) - km * delta**self.n * (1 + mp.mpf(3) / 2 * self.alpha * rate)

    def _depth_scale(self, delta, rate):
        """About the contact's depth (energy, with the table's largest push |a| + A w^2 taken constant)."""
        km, n, a = self.k / self.m, self.n, abs(self.a) + self.A * self.w**2
        e = rate * rate / 2 - a * delta + km * delta ** (n + 1) / (n + 1)
        d = max(delta, (2 * (n + 1) * max(e, 0) / km) ** (1 / (n + 1)))
        return max(d, (2 * (n + 1) * a / km) ** (1 / n)) if a > 0 else d

    def _series(self, series, tau):
        """(delta, delta') at t_i + tau in a contact's first instant: the flight's closed form less the force."""
        t_i, w0, c = series
        n = self.n
        delta, rate = self._unforced(t_i, mp.zero, w0, tau)[:2]
        q = c * w0**n * tau ** (n + 1) / (n + 1)
        return delta - q * tau / (n + 2), rate - q

    def _pressed(self, t, delta, rate):
        km, n, alpha = self.k / self.m, self.n, self.alpha
        depth = self._depth_scale(delta, rate)
        t_scale = depth / max(abs(rate), mp.sqrt(n * km * depth ** (n - 1)) * depth)
        data = {"series": None, "t0": t, "rest": None}
        if delta == 0:  # from the surface going in: the series over its first instant
            data["series"] = (t, rate, km * (1 + mp.mpf(3) / 2 * alpha * rate))
            data["t0"] = t + START_FRACTION * t_scale
            y0 = list(self._series(data["series"], data["t0"] - t))
        else:
            y0 = [delta, rate]
        tol, degree = mp.mpf(10) ** (2 - mp.dps), 4 + 3 * mp.dps // 5  # odefun's own 3 + 1.5 dps: 2.5x slower
        data["solution"] = solution = mp.odefun(lambda s, y: [y[1], self._accel(s, y[0], y[1])], data["t0"], y0,
                                                tol=tol, degree=degree)
        piece = [t, self.t_end, PRESSED, data]
        self.pieces.append(piece)
        step, end_delta = t_scale / 20, END_FRACTION * depth
        tc, yc = data["t0"], y0
        bound = abs(self.a) + self.A * self.w**2  # of |delta''| but for the force
        while not (yc[1] < 0 and yc[0] < end_delta):
            # never past delta = 0: half the time to the root of delta + delta' d - M d^2 / 2, M a bound of |delta''|
            # with the force's growth over the step taken as at most 2x (a short contact driven by the table too)
            M = bound + 2 * km * yc[0] ** n * (1 + mp.mpf(3) / 2 * alpha * max(yc[1], 0))
            tn = tc + min(step, _safe_step(yc[0], yc[1], 0, M, 0) / 2)
            if tn >= self.t_end:
                return None, None, None, None
            yn = solution(tn)
            if not (isinstance(yn[0], mp.mpf) and yn[0] > 0):
                raise RuntimeError(f"a grid step in the contact from t = {t} crossed the surface, at t = {tn}")
            if yn[1] < -self.w_release:  # the clip engages in (tc, tn)
                tr = mp.findroot(lambda s: solution(s)[1] + self.w_release, (tc, tn), solver="anderson")
                piece[1] = tr
                self._event(tr, "release", -self.w_release)
                return tr, solution(tr)[0], -self.w_release, FREE
            tc, yc = tn, yn
        # the rest to delta = 0: force-free (the table's s exact), plus the force's impulse with delta linear
        d0, w0 = yc
        data["rest"] = (tc, d0, w0)
        found = self._first_root(tc, d0, w0, [(1, 0, 0, "departure")], min(self.t_end - tc, 4 * d0 / -w0))
        if found is None:
            if tc + 4 * d0 / -w0 >= self.t_end:
                return None, None, None, None
            raise RuntimeError(f"a tangential departure near t = {tc}: no root of the force-free rest")
        tau = found[0]
        impulse = km * d0 ** (n + 1) / ((n + 1) * -w0) * (1 + mp.mpf(3) / 2 * alpha * w0)
        rate1 = self._unforced(tc, d0, w0, tau)[1] - impulse
        piece[1] = t1 = tc + tau
        self._event(t1, "departure", rate1)
        return t1, mp.zero, rate1, FLIGHT

    # --- evaluation --------------------------------------------------------------------------------------------
    def _penetration(self, t):
        """(delta, delta') at t."""
        i = max(bisect.bisect_right(self._starts, t) - 1, 0)
        _, _, kind, data = self.pieces[i]
        if kind != PRESSED or (data["rest"] is not None and t > data["rest"][0]):  # force-free
            t0, d0, w0 = data if kind != PRESSED else data["rest"]
            return self._unforced(t0, d0, w0, t - t0)[:2]
        if data["series"] is not None and t < data["t0"]:
            return self._series(data["series"], t - data["series"][0])
        return tuple(data["solution"](t))

    def state(self, t):
        """(h [m], v [m/s]) at t [s], as mpf."""
        with mp.workdps(self.dps):
            t = mp.mpf(t)
            delta, rate = self._penetration(t)
            s, ds = self.ground(t)
            return self.R + s - delta, ds - rate

    def gap(self, t):
        """h - R - s(t) [m] at t [s], as mpf: minus the penetration."""
        with mp.workdps(self.dps):
            return -self._penetration(mp.mpf(t))[0]
