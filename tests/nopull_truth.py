"""An independent solution of the no-pull contact law in mpmath: the referee of contact="linear-no-pull".

Written from the law's equations alone; it imports nothing from bouncingball. Float inputs are taken
as exact binary numbers, everything after that is done with DPS decimal digits.

The law: h is the height of the centre [m], v = dh/dt, a = g - F_ext/m the net downward acceleration
(constant). Above R the ball flies, v' = -a. Below R the ground pushes with max(0, f), f = k (R - h) - b v:
m v' = max(0, f) - m a. So below R the ball is either pressed (f > 0: m v' = f - m a, a damped linear
oscillator about R - d, d = m a / k) or free (f would be < 0: v' = -a, a parabola below R). Events:
an impact where h reaches R going down (there f = -b v >= 0: pressed); a release where f falls to 0 in the
pressed sub-mode (free from there); an engagement where f rises to 0 in the free sub-mode (pressed again);
a departure where h reaches R going up (free, since f = -b v < 0 there for b > 0; pressed only when b = 0).

Method: every piece in closed form. Pressed: y = h - (R - d) obeys y'' + 2 s y' + w^2 y = 0 (s = b / 2m,
w^2 = k / m), y = A e^(r1 t) + B e^(r2 t) with r = -s +- sqrt(s^2 - w^2) (complex where under-damped), or
(y0 + (v0 + s y0) t) e^(-s t) at critical damping; its release is the first sign change of f on a grid
of 1 / (20 (s + w)) followed by bisection to the working precision. The pressed motion never releases
once (w^2 + 4 s^2)(v^2 + w^2 y^2) < w^4 d^2: f = k (d - y) - b v = 0 needs w^2 y + 2 s v = w^2 d, which
Cauchy-Schwarz bounds by sqrt(w^2 + 4 s^2) sqrt(v^2 + w^2 y^2), an energy that (v^2 + w^2 y^2)' = -4 s v^2
never lets grow. Flight and free: parabolas, their events the roots of quadratics (f is quadratic in t
there too), chosen by the crossing's direction.
"""

from __future__ import annotations

import bisect

import mpmath

DPS = 50
mp = mpmath.MPContext()
mp.dps = DPS
FLIGHT, PRESSED, FREE = "flight", "pressed", "free"


def _mpf(value):
    return mp.mpf(float(value))


class NoPullTruth:
    """The no-pull ball's exact motion from (h0, v0) at t = 0 under a constant F_ext, to t_end."""

    def __init__(self, m, k, b, R, g, h0, v0, t_end, F_ext=0.0, max_events=100_000):
        m, k, b, R, g, F = (_mpf(x) for x in (m, k, b, R, g, F_ext))
        self.m, self.k, self.b, self.R = m, k, b, R
        self.a = g - F / m
        self.s, self.w2 = b / (2 * m), k / m
        self.d = m * self.a / k
        h, v, t = _mpf(h0), _mpf(v0), mp.mpf(0)
        t_end = _mpf(t_end)
        self.pieces = []  # (t, mode, h, v)
        self.events = []  # (t, kind, h, v)
        self.rest_time = None
        contact_start = t
        mode = self._initial_mode(h, v)
        while t <= t_end:
            self.pieces.append((t, mode, h, v))
            if mode == FLIGHT:
                tau = self._flight_impact(h, v)
                kind, next_mode = "impact", PRESSED
            elif mode == FREE:
                tau, kind = self._free_event(h, v)
                next_mode = FLIGHT if kind == "departure" else PRESSED
            else:
                tau = self._release(h, v, t_end - t)
                kind, next_mode = ("departure", FLIGHT) if self.b == 0 else ("release", FREE)
                if tau is None:
                    self.rest_time = contact_start
                    break
            if tau is None or t + tau > t_end:
                break
            h, v = self._flow(mode, h, v, tau)
            if kind in ("impact", "departure"):
                h = R
            t = t + tau
            self.events.append((t, kind, h, v))
            if kind == "impact":
                contact_start = t
            mode = next_mode
            if len(self.events) > max_events:
                raise RuntimeError("more events than max_events")
        self._times = [piece[0] for piece in self.pieces]

    # --- the sub-modes ----------------------------------------------------------------------------
    def _force(self, h, v):
        return self.k * (self.R - h) - self.b * v

    def _initial_mode(self, h, v):
        if h > self.R or (h == self.R and (v > 0 or (v == 0 and self.a <= 0))):
            return FLIGHT
        f = self._force(h, v)
        if self.b == 0 or f > 0:
            return PRESSED
        if f < 0:
            return FREE
        # f = 0: both sub-modes have v' = -a there, so f' = -k v + b a decides
        return FREE if -self.k * v + self.b * self.a < 0 else PRESSED

    def _flow(self, mode, h, v, tau):
        if mode != PRESSED:
            return h + tau * (v - self.a * tau / 2), v - self.a * tau
        rest = self.R - self.d
        y0 = h - rest
        s, w2 = self.s, self.w2
        disc = s * s - w2
        if disc == 0:
            e = mp.exp(-s * tau)
            c = v + s * y0
            return rest + (y0 + c * tau) * e, (c - s * (y0 + c * tau)) * e
        root = mp.sqrt(mp.mpc(disc)) if disc < 0 else mp.sqrt(disc)
        r1, r2 = -s + root, -s - root
        A = (v - r2 * y0) / (r1 - r2)
        B = y0 - A
        e1, e2 = mp.exp(r1 * tau), mp.exp(r2 * tau)
        return rest + mp.re(A * e1 + B * e2), mp.re(A * r1 * e1 + B * r2 * e2)

    def _flight_impact(self, h, v):
        x, a = h - self.R, self.a
        roots = _quadratic_roots(-a / 2, v, x)
        down = [t for t in roots if t > 0 and v - a * t < 0]
        return min(down) if down else None

    def _free_event(self, h, v):
        x, a, k, b = h - self.R, self.a, self.k, self.b
        candidates = []
        for t in _quadratic_roots(-a / 2, v, x):  # h reaching R going up
            if t >= 0 and v - a * t > 0:
                candidates.append((t, "departure"))
        # f(t) = -k x(t) - b v(t) = (k a / 2) t^2 + (b a - k v) t - k x - b v, rising through 0
        for t in _quadratic_roots(k * a / 2, b * a - k * v, -k * x - b * v):
            if t > 0 and k * a * t + b * a - k * v > 0:
                candidates.append((t, "engage"))
        if not candidates:
            return None, None
        return min(candidates)

    def _release(self, h, v, horizon):
        """The time to the first fall of f through 0 in the pressed sub-mode; None if never (or past horizon)."""
        s, w2, d, b = self.s, self.w2, self.d, self.b
        if b == 0:  # the linear law: the departure is h reaching R going up
            force = lambda tau: self.R - self._flow(PRESSED, h, v, tau)[0]  # noqa: E731
        else:
            force = lambda tau: self._force(*self._flow(PRESSED, h, v, tau))  # noqa: E731
        dt = 1 / (20 * (s + mp.sqrt(w2)))
        threshold = w2 * w2 * d * d / (w2 + 4 * s * s) if b != 0 else w2 * d * d
        i = 0
        while True:
            i += 1
            tau = i * dt
            if tau > horizon + 10 * dt:
                return None
            hh, vv = self._flow(PRESSED, h, v, tau)
            y = hh - (self.R - d)
            if force(tau) <= 0:
                lo, hi = (i - 1) * dt, tau
                for _ in range(200):
                    mid = (lo + hi) / 2
                    if force(mid) > 0:
                        lo = mid
                    else:
                        hi = mid
                    if hi - lo <= mp.eps * hi:
                        break
                return hi
            if d > 0 and vv * vv + w2 * y * y < threshold * (1 - mp.mpf("1e-30")):
                return None  # the energy bound: never again

    # --- evaluation -----------------------------------------------------------------------------
    def state(self, t):
        """(h [m], v [m/s]) at the time t [s], as mpf."""
        t = _mpf(t)
        i = max(bisect.bisect_right(self._times, t) - 1, 0)
        t0, mode, h0, v0 = self.pieces[i]
        return self._flow(mode, h0, v0, t - t0)

    def heights(self, times):
        """The heights [m] at the times, as floats."""
        return [float(self.state(t)[0]) for t in times]

    def force(self, t):
        """The ground's force [N] at t: max(0, f) below R, 0 above."""
        h, v = self.state(t)
        return max(self._force(h, v), 0) if h < self.R else mp.mpf(0)


def _quadratic_roots(A, B, C):
    """The real roots of A t^2 + B t + C = 0 (mpf), A possibly 0."""
    if A == 0:
        return [] if B == 0 else [-C / B]
    disc = B * B - 4 * A * C
    if disc < 0:
        return []
    root = mp.sqrt(disc)
    return [(-B - root) / (2 * A), (-B + root) / (2 * A)]
