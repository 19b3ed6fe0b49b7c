"""An independent solution of the linear and no-pull laws' ball on a sinusoidally vibrating table in mpmath.

Written from the equations alone; it imports nothing from bouncingball (its flights are tests/table_truth.py's,
the rigid truth's certified flights). Float inputs are taken as exact binary numbers, everything after that is
done with table_truth.DPS decimal digits.

The model (SI units): the table s(t) = A sin(w t + p); the gap x = h - R - s(t), u = x' = v - s'(t). In flight
(x > 0) h'' = -a, a = g - F_ext/m. In contact (from the impact, where x reaches 0 going down, to the departure,
where it crosses 0 going up) the spring k and damper b act on the deflection -x and its rate:
m h'' = -k x - b u - m a, so x'' + 2 sigma u + w0^2 x = -a + A w^2 sin(w t + p), sigma = b/(2m), w0^2 = k/m.
Solved as the particular solution -a/w0^2 + Im(A w^2 e^{i(w t + p)} / (w0^2 - w^2 + 2 i sigma w)) plus
c1 e^{r1 tau} + c2 e^{r2 tau}, r1,2 the complex roots of r^2 + 2 sigma r + w0^2 (under-damped only). The departure
is found by a scan of x every SCAN_FRACTION of the shorter of the two periods, the first sign change polished by
findroot in its bracket; a contact that never crosses before t_end lasts to it.

The no-pull law (no_pull=True) clips the force k(-x) - b u at 0: pressed while -(x + (b/k) u) > 0, its release
where z = x + (b/k) u crosses 0 going up; then free below the surface (the flight's equations, h'' = -a), until x
crosses 0 going up (a departure) or z falls back to 0 (an engagement: pressed again). Each found by the same scan.
"""

from __future__ import annotations

import bisect

from table_truth import BOUNCE, FREE, Flight, mp

SCAN_FRACTION = 200  # steps per period in the departure's scan


def _mpf(value):
    return mp.mpf(float(value))


class LinearTableTruth:
    """The motion from (h0, v0) at t = 0 to t_end: events [(t, "impact" or "departure")] and state(t), as mpf."""

    def __init__(self, R, g, m, k, b, amplitude, frequency, phase, h0, v0, t_end, F_ext=0.0, no_pull=False):
        R, g, m, k, b, A, f, p, F_ext = (_mpf(x) for x in (R, g, m, k, b, amplitude, frequency, phase, F_ext))
        self.R, self.A, self.w, self.p = R, A, 2 * mp.pi * f, p
        self.a, self.sigma, self.w02 = g - F_ext / m, b / (2 * m), k / m
        self.no_pull, self.c = no_pull, b / k
        if not (self.a > 0 and self.sigma ** 2 < self.w02):
            raise ValueError("needs g - F_ext/m > 0 and an under-damped contact")
        root = mp.sqrt(self.w02 - self.sigma ** 2)
        self.r1, self.r2 = mp.mpc(-self.sigma, root), mp.mpc(-self.sigma, -root)
        self.H = 1 / mp.mpc(self.w02 - self.w ** 2, 2 * self.sigma * self.w)
        self.scan = min(2 * mp.pi / root, 2 * mp.pi / self.w) / SCAN_FRACTION
        self.events, self._segments = [], []  # segments: (t0, "flight", Flight) or (t0, "contact", (c1, c2))
        t, t_end = mp.zero, _mpf(t_end)
        gap, u = _mpf(h0) - R - self.ground(t)[0], _mpf(v0) - self.ground(t)[1]
        if gap < 0 or (gap == 0 and u < 0):  # below the surface: pressed, or (no-pull) free where the force pulls
            mode = "free" if no_pull and gap < 0 and gap + self.c * u > 0 else "contact"
        else:
            mode = "flight"
        while t <= t_end:
            if mode == "free":
                end = self._free(t, gap, u, t_end)
            elif mode == "contact":
                end = self._contact(t, gap, u, t_end)
            else:
                end = self._flight(t, gap, u, t_end)
            if end is None:
                return
            t, gap, u, mode = end

    def _flight(self, t0, gap, u, t_end):
        """The flight from (gap >= 0, u) at t0: (t, 0, u, "contact") at its impact, or None past t_end."""
        flight = Flight(self.A, self.w, self.p, self.a, t0, gap, u, BOUNCE if gap == 0 else FREE)
        self._segments.append((t0, "flight", flight))
        tau = flight.first_impact(t_end - t0)
        if tau is None:
            return None
        self.events.append((t0 + tau, "impact"))
        return t0 + tau, mp.zero, flight.rate(tau), "contact"

    def ground(self, t):
        """(s [m], s' [m/s]) at t [s]."""
        theta = self.w * t + self.p
        return self.A * mp.sin(theta), self.A * self.w * mp.cos(theta)

    def _particular(self, t):
        """(x_p, u_p): the contact's periodic solution at t."""
        phasor = self.A * self.w ** 2 * self.H * mp.expj(self.w * t + self.p)
        return -self.a / self.w02 + phasor.imag, (phasor * mp.mpc(0, self.w)).imag

    def _contact_gap(self, t0, constants, tau):
        c1, c2 = constants
        x_p, u_p = self._particular(t0 + tau)
        e1, e2 = mp.exp(self.r1 * tau), mp.exp(self.r2 * tau)
        return (c1 * e1 + c2 * e2).real + x_p, (c1 * self.r1 * e1 + c2 * self.r2 * e2).real + u_p

    def _contact(self, t0, x0, u0, t_end):
        """The contact from (x0, u0) at t0: (t, x, u, next mode) at its departure (no-pull: release), or None."""
        x_p, u_p = self._particular(t0)
        X, U = x0 - x_p, u0 - u_p
        c1 = (U - self.r2 * X) / (self.r1 - self.r2)
        constants = (c1, X - c1)
        self._segments.append((t0, "contact", constants))
        def switch(s):  # x, or under the no-pull law z = x + (b/k) u: -force / k
            x, u = self._contact_gap(t0, constants, s)
            return x + self.c * u if self.no_pull else x

        tau, before = mp.zero, switch(mp.zero)
        while t0 + tau <= t_end:
            after = switch(tau + self.scan)
            if before <= 0 < after:
                root = mp.findroot(switch, (tau, tau + self.scan), solver="anderson")
                x, u = self._contact_gap(t0, constants, root)
                self.events.append((t0 + root, "release" if self.no_pull else "departure"))
                return t0 + root, (x if self.no_pull else mp.zero), u, ("free" if self.no_pull else "flight")
            tau, before = tau + self.scan, after
        return None

    def _free(self, t0, x0, u0, t_end):
        """The no-pull law's free spell from (x0 < 0, u0) at t0: (t, x, u, next mode) at its end, or None."""
        flight = Flight(self.A, self.w, self.p, self.a, t0, x0, u0, FREE)
        self._segments.append((t0, "flight", flight))

        def gap(s):
            return flight.derivatives(s)[0]

        def pressing(s):  # z = x + (b/k) u
            x, u, _ = flight.derivatives(s)
            return x + self.c * u

        tau, x_before, z_before = mp.zero, gap(mp.zero), pressing(mp.zero)
        while t0 + tau <= t_end:
            x_after, z_after = gap(tau + self.scan), pressing(tau + self.scan)
            departs, engages = x_before < 0 <= x_after, z_before > 0 >= z_after
            if departs or engages:
                bracket = (tau, tau + self.scan)
                depart_root = mp.findroot(gap, bracket, solver="anderson") if departs else mp.inf
                engage_root = mp.findroot(pressing, bracket, solver="anderson") if engages else mp.inf
                root = min(depart_root, engage_root)
                x, u, _ = flight.derivatives(root)
                kind = "departure" if depart_root <= engage_root else "engage"
                self.events.append((t0 + root, kind))
                return t0 + root, (mp.zero if kind == "departure" else x), u, \
                    ("flight" if kind == "departure" else "contact")
            tau, x_before, z_before = tau + self.scan, x_after, z_after
        return None

    def state(self, t):
        """(h [m], v [m/s]) at t [s]."""
        t = t if isinstance(t, mp.mpf) else _mpf(t)
        times = [segment[0] for segment in self._segments]
        t0, kind, data = self._segments[bisect.bisect_right(times, t) - 1]
        s, ds = self.ground(t)
        if kind == "flight":
            tau = t - t0
            h0 = self.R + data.gap0 + self.ground(t0)[0]
            return h0 + tau * (data.u0 + self.ground(t0)[1] - self.a * tau / 2), \
                data.u0 + self.ground(t0)[1] - self.a * tau
        x, u = self._contact_gap(t0, data, t - t0)
        return self.R + s + x, ds + u
