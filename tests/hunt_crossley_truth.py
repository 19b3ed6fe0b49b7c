"""An independent solution of the Hunt-Crossley contact law in mpmath: the referee of contact="hunt-crossley".

Written from the law's equations alone; it imports nothing from bouncingball. Float inputs are taken as
exact binary numbers, everything after that is done with DPS decimal digits.

The law: h is the height of the centre [m], v = dh/dt, a = g - F_ext/m the net downward acceleration
(constant). Above R the ball flies, v' = -a: a parabola, its impact the root of a quadratic. Below R, with the
penetration delta = R - h and w = delta' = -v, the ground pushes with F = k delta^n (1 + 3/2 alpha w), clipped
at 0 where 1 + 3/2 alpha w < 0 (it never pulls): delta'' = a - F / m. F is 0 at delta = 0, so the motion is
continuous in the acceleration at impact and departure.

Method: delta^n is not analytic at delta = 0, where each contact starts and ends, so
- the first TAU_START of a contact (delta from 0) is its series delta = w0 t + a t^2 / 2
  - c w0^n t^(n+2) / ((n+1)(n+2)), c = (k/m)(1 + 3/2 alpha w0), whose next terms are (t / t_c)^(n+3) smaller;
- then mpmath.odefun (a Taylor-series integrator) at DPS digits, stepped on a grid that shrinks as delta
  approaches 0 (never across it), the last steps halving the remaining delta / |w|;
- once delta is below END_FRACTION of the contact's depth the rest to delta = 0 is a parabola plus the force's
  impulse with delta taken linear: both the force and its work are below 1e-30 of the motion there.
- Where the clip engages (w below -2 / (3 alpha): only with F_ext > m g, or a start below R rising that fast),
  its crossing is found with mpmath.findroot on the odefun solution; from there the ball is free (a parabola
  below R) until it reaches R (departure) or falls back to the release speed (pressed again).
A contact that never reaches delta = 0 again (a resting ball) is integrated to t_end.
"""

from __future__ import annotations

import bisect

import mpmath

DPS = 20  # 4.2x faster than 30, which it agrees with to 3e-20 in heights and event times (the benchmark scene)
mp = mpmath.MPContext()
mp.dps = DPS
FLIGHT, PRESSED, FREE = "flight", "pressed", "free"
START_FRACTION = mpmath.mpf("1e-9")  # the series covers this fraction of the estimated contact time
END_FRACTION = mpmath.mpf("1e-14")  # of the contact's depth scale: the rest is a parabola


def _mpf(value):
    return mp.mpf(float(value))


class HuntCrossleyTruth:
    """The trajectory from (h0, v0) to t_end; state(t), events [(t, kind, v)], pieces."""

    def __init__(self, m, k, n, alpha, R, g, h0, v0, t_end, F_ext=0.0, max_events=200):
        self.m, self.k, self.n, self.alpha, self.R = (_mpf(x) for x in (m, k, n, alpha, R))
        self.a = _mpf(g) - _mpf(F_ext) / self.m  # net downward acceleration
        self.t_end = _mpf(t_end)
        self.w_release = 2 / (3 * self.alpha) if self.alpha > 0 else mp.inf
        self.events = []
        self.pieces = []  # (t0, t1, kind, data): data a (delta0, w0) for parabolas, an odefun solution for pressed
        t, h, v = mp.mpf(0), _mpf(h0), _mpf(v0)
        delta, w = self.R - h, -v
        if delta > 0 or (delta == 0 and (w > 0 or (w == 0 and self.a > 0))):
            mode = FREE if (w < -self.w_release or (w == -self.w_release and self.a < 0)) else PRESSED
        else:
            mode = FLIGHT
        while t < self.t_end and len(self.events) < max_events:
            if mode == FLIGHT:
                t, delta, w, mode = self._flight(t, delta, w)
            elif mode == FREE:
                t, delta, w, mode = self._free(t, delta, w)
            else:
                t, delta, w, mode = self._pressed(t, delta, w)

    # --- flight and free: parabolas in delta, delta'' = a -------------------------------------------------
    def _parabola(self, t, delta, w, kind):
        self.pieces.append([t, None, kind, (delta, w)])

    def _flight(self, t, delta, w):
        """delta < 0 (or 0 rising): the impact where delta reaches 0 going down (w > 0)."""
        self._parabola(t, delta, w, FLIGHT)
        a = self.a
        # delta + w tau + a tau^2 / 2 = 0, the later root (delta <= 0)
        if a > 0:
            tau = (-w + mp.sqrt(w * w - 2 * a * delta)) / a
        elif w > 0:
            tau = -delta / w if a == 0 else (-w + mp.sqrt(w * w - 2 * a * delta)) / a
            if a < 0 and w * w - 2 * a * delta < 0:
                tau = mp.inf
        else:
            tau = mp.inf
        return self._end_parabola(t, tau, delta, w, "impact", PRESSED)

    def _free(self, t, delta, w):
        """Below R, w < -w_release: delta reaches 0 going up (departure) or w rises to -w_release (pressed again)."""
        self._parabola(t, delta, w, FREE)
        a = self.a
        disc = w * w - 2 * a * delta
        tau_dep = (-w - mp.sqrt(disc)) / a if (a != 0 and disc >= 0) else (-delta / w if a == 0 else mp.inf)
        if a < 0 and disc >= 0:  # lifted: delta decreases for ever; the first root
            tau_dep = (-w - mp.sqrt(disc)) / a
            tau_dep = min(r for r in ((-w - mp.sqrt(disc)) / a, (-w + mp.sqrt(disc)) / a) if r >= 0)
        tau_eng = (-self.w_release - w) / a if a > 0 else mp.inf
        if tau_dep <= tau_eng:
            return self._end_parabola(t, tau_dep, delta, w, "departure", FLIGHT)
        return self._end_parabola(t, tau_eng, delta, w, "engage", PRESSED)

    def _end_parabola(self, t, tau, delta, w, kind, next_mode):
        if not t + tau < self.t_end:
            self.pieces[-1][1] = self.t_end
            return self.t_end, None, None, None
        t1 = t + tau
        self.pieces[-1][1] = t1
        delta1 = (delta + w * tau + self.a * tau * tau / 2) if kind == "engage" else mp.mpf(0)
        w1 = w + self.a * tau
        if kind == "engage":
            w1 = -self.w_release
        self.events.append((t1, kind, -w1))
        return t1, delta1, w1, next_mode

    # --- pressed: odefun ----------------------------------------------------------------------------------------
    def _accel(self, delta, w):
        return self.a - (self.k / self.m) * delta**self.n * (1 + mp.mpf(3) / 2 * self.alpha * w)

    def _depth_scale(self, delta, w):
        """An upper bound on the contact's depth (energy: see the package's hunt_crossley_scales)."""
        km, n, a = self.k / self.m, self.n, self.a
        e = w * w / 2 - a * delta + km * delta ** (n + 1) / (n + 1)
        d = max(delta, (2 * (n + 1) * max(e, 0) / km) ** (1 / (n + 1)))
        if a > 0:
            d = max(d, (2 * (n + 1) * a / km) ** (1 / n))
        return d

    def _pressed(self, t, delta, w):
        km, n, a, alpha = self.k / self.m, self.n, self.a, self.alpha
        depth = self._depth_scale(delta, w)
        speed = max(abs(w), mp.sqrt(n * km * depth ** (n - 1)) * depth)
        t_scale = depth / speed
        if delta == 0:  # from R going down: the series over its first instant
            c = km * (1 + mp.mpf(3) / 2 * alpha * w)
            ts = START_FRACTION * t_scale
            delta_s = w * ts + a * ts**2 / 2 - c * w**n * ts ** (n + 2) / ((n + 1) * (n + 2))
            w_s = w + a * ts - c * w**n * ts ** (n + 1) / (n + 1)
            t0, y0 = t + ts, [delta_s, w_s]
        else:
            t0, y0 = t, [delta, w]
        solution = mp.odefun(lambda _t, y: [y[1], self._accel(y[0], y[1])], t0, y0, tol=mp.mpf(10) ** (-DPS + 2))
        piece = [t, None, PRESSED, (t, delta, w, t0, y0, solution)]
        self.pieces.append(piece)
        step = t_scale / 20
        tc, yc = t0, y0
        end_delta = END_FRACTION * depth
        while True:
            dt = step
            if yc[1] < 0:  # rising: never past delta = 0
                dt = min(step, yc[0] / (-yc[1]) / 2)
            tn = tc + dt
            if tn >= self.t_end:
                piece[1] = self.t_end
                return self.t_end, None, None, None
            yn = solution(tn)
            if alpha > 0 and yn[1] < -self.w_release:  # the clip engages in (tc, tn)
                tr = mp.findroot(lambda s: solution(s)[1] + self.w_release, (tc, tn), solver="anderson")
                yr = solution(tr)
                piece[1] = tr
                self.events.append((tr, "release", self.w_release))
                return tr, yr[0], -self.w_release, FREE
            tc, yc = tn, yn
            if yc[1] < 0 and yc[0] < end_delta:
                break
        # the rest to delta = 0: delta0 + w tau + a tau^2 / 2 - impulse, the force's impulse with delta linear
        d0, w0 = yc
        tau = (-w0 - mp.sqrt(w0 * w0 - 2 * a * d0)) / a if a != 0 else -d0 / w0
        if a < 0:
            tau = -d0 / w0 if w0 * w0 - 2 * a * d0 < 0 else min(
                r for r in ((-w0 - mp.sqrt(w0 * w0 - 2 * a * d0)) / a, (-w0 + mp.sqrt(w0 * w0 - 2 * a * d0)) / a)
                if r >= 0)
        impulse = km * d0 ** (n + 1) / ((n + 1) * (-w0)) * (1 + mp.mpf(3) / 2 * alpha * w0)
        w1 = w0 + a * tau - impulse
        t1 = tc + tau
        piece[1] = t1
        piece[3] = piece[3] + ((tc, d0, w0),)
        if t1 >= self.t_end:
            piece[1] = self.t_end
            return self.t_end, None, None, None
        self.events.append((t1, "departure", -w1))
        return t1, mp.mpf(0), w1, FLIGHT

    # --- evaluation --------------------------------------------------------------------------------------------
    def state(self, t):
        """(h, v) at t, as mpf."""
        t = mp.mpf(t)
        starts = [p[0] for p in self.pieces]
        i = max(bisect.bisect_right(starts, t) - 1, 0)
        t0, t1, kind, data = self.pieces[i]
        if kind != PRESSED:
            delta, w = data
            tau = t - t0
            d, ww = delta + w * tau + self.a * tau * tau / 2, w + self.a * tau
        else:
            ts, delta, w, tstart, y0, solution = data[:6]
            if t < tstart:  # the series' instant
                tau = t - ts
                c = (self.k / self.m) * (1 + mp.mpf(3) / 2 * self.alpha * w)
                n = self.n
                d = w * tau + self.a * tau**2 / 2 - c * w**n * tau ** (n + 2) / ((n + 1) * (n + 2))
                ww = w + self.a * tau - c * w**n * tau ** (n + 1) / (n + 1)
            elif len(data) > 6 and t > data[6][0]:  # the last instant before departure
                tc, d0, w0 = data[6]
                tau = t - tc
                d, ww = d0 + w0 * tau + self.a * tau * tau / 2, w0 + self.a * tau
            else:
                d, ww = solution(t)
        return self.R - d, -ww

    def force(self, t):
        h, v = self.state(t)
        delta = self.R - h
        if delta <= 0:
            return mp.mpf(0)
        return max(self.k * delta**self.n * (1 - mp.mpf(3) / 2 * self.alpha * v), 0)


def hertz_contact_duration(m, k, n, v):
    """The Hertz (alpha = 0, g = 0) contact's duration: 2 (d/v) integral_0^1 du / sqrt(1 - u^(n+1)), d its depth.

    (n + 1) k d^(n+1) / ... : m v^2 / 2 = k d^(n+1) / (n + 1); the integral is sqrt(pi) Gamma(1 + p) / Gamma(1/2 + p),
    p = 1 / (n + 1). For n = 3/2 this is 3.2145... (m^2 / (k^2 v))^(1/5).
    """
    m, k, n, v = (mp.mpf(x) for x in (m, k, n, v))
    depth = ((n + 1) * m * v * v / (2 * k)) ** (1 / (n + 1))
    p = 1 / (n + 1)
    return 2 * depth / v * mp.sqrt(mp.pi) * mp.gamma(1 + p) / mp.gamma(mp.mpf(1) / 2 + p)
