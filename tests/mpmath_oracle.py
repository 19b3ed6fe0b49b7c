"""An independent solution of the bouncing-ball model in mpmath: the referee the solvers are judged by.

Written from the model's equations alone; it imports nothing from bouncingball. The float inputs are
taken as exact binary numbers (mpf(float)) and everything after that is done with DPS decimal digits.

The model: h is the height of the centre [m], v = dh/dt. In flight (mode 0) v' = -a with
a = g - F_ext/m; in contact (mode 1) m v' = -b v + k (R - h) - m g + F_ext. An impact is h crossing R
going down (flight -> contact), a departure h crossing R going up (contact -> flight). A contact that
never again crosses R upwards is a rest.

Method
------
Flight: a parabola; the impact is the smaller positive root of h(tau) = R, taken as
tau = 2 (h - R)/(s - v) for v < 0 and (v + s)/a for v >= 0 (s = sqrt(v^2 + 2 a (h - R)), the impact
speed), so that no digits cancel.

Contact: with d = (m g - F_ext)/k and y = h - (R - d), y'' + 2 sigma y' + w2 y = 0 (sigma = b/(2m),
w2 = k/m). Its flow is the matrix exponential
    exp(A tau) = exp(-sigma tau) (cosh(mu tau) I + sinh(mu tau)/mu (A + sigma I)),  mu^2 = sigma^2 - w2,
because (A + sigma I)^2 = mu^2 I. cosh(mu tau) and sinh(mu tau)/mu are even functions of mu, so they are
real for mu^2 < 0 (cos(nu tau), sin(nu tau)/nu with nu^2 = -mu^2) and equal 1 and tau at mu = 0; mpmath
evaluates sinh(x) and sin(x) to full relative precision at small x, so nothing is lost as mu -> 0: the
flow is exact at, and continuous through, critical damping b^2 = 4 k m. (tests/test_mpmath_oracle.py
checks it against mpmath.expm and mpmath.odefun.)

Departure: the first upward crossing of y = d. The contact is cut at the zeros of v, where y is
monotone in between: for mu^2 < 0 they are the closed-form nu tau + phi = pi/2 + n pi; for mu^2 >= 0
there is at most one, tanh(mu tau)/mu = v0/(w2 y0 + sigma v0). On the first increasing piece whose end
is above d the crossing is bracketed and found by mpmath.findroot (Anderson-Bjorck, a bracketing
solver; plain bisection if that ever leaves the bracket). Rest, proven rather than guessed:
- under-damped: v^2 + w2 y^2 never grows for b >= 0; at a maximum of y (v = 0) with y <= d it is
  <= w2 d^2, so |y| <= d for ever and y reaches d at most tangentially: the contact never ends;
- critically or over-damped: after the last zero of v, y approaches 0 monotonically, so it crosses d
  upwards iff it is increasing and d < 0 (then a finite bracket is found by doubling).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import mpmath
import numpy as np

DPS = 50
# A context of its own: other tests set mpmath.mp.dps globally.
mp = mpmath.MPContext()
mp.dps = DPS

FLIGHT, CONTACT = 0, 1
IMPACT, DEPARTURE = "impact", "departure"


def _exact(x):
    """x as an mpf: a float taken as its exact binary value, an mpf as it is."""
    return x if isinstance(x, mp.mpf) else mp.mpf(float(x))


class TooManyEvents(RuntimeError):
    """More events before t_end than the oracle was allowed to compute (max_events)."""


@dataclass(frozen=True)
class OracleEvent:
    """A mode switch: time [s], kind ("impact" or "departure"), velocity there [m/s], all as mpf."""

    time: object
    kind: str
    velocity: object


@dataclass(frozen=True)
class Phase:
    """A mode held from time start [s] with state (h, v) there (mpf)."""

    mode: int
    start: object
    h: object
    v: object


class _Contact:
    """The contact oscillator's flow and its departure search, for one ball and F_ext."""

    def __init__(self, m, k, b, R, g, F):
        self.R = R
        self.sigma = b / (2 * m)
        self.w2 = k / m
        self.d = (m * g - F) / k  # R minus the rest height
        self.mu2 = self.sigma * self.sigma - self.w2
        if self.mu2 > 0:
            self.mu = mp.sqrt(self.mu2)
        elif self.mu2 < 0:
            self.nu = mp.sqrt(-self.mu2)

    def basis(self, tau):
        """(exp(-sigma tau), cosh(mu tau), sinh(mu tau)/mu)."""
        if self.mu2 > 0:
            x = self.mu * tau
            return mp.exp(-self.sigma * tau), mp.cosh(x), mp.sinh(x) / self.mu
        if self.mu2 < 0:
            x = self.nu * tau
            return mp.exp(-self.sigma * tau), mp.cos(x), mp.sin(x) / self.nu
        return mp.exp(-self.sigma * tau), mp.one, tau

    def flow(self, y0, v0, tau):
        """(y, v) after tau from (y0, v0)."""
        e, c, s = self.basis(tau)
        return (e * (y0 * c + (self.sigma * y0 + v0) * s),
                e * (v0 * c - (self.w2 * y0 + self.sigma * v0) * s))

    def _v_zeros(self, y0, v0):
        """The zeros of v at tau > 0, in order (a generator; endless if under-damped)."""
        p = self.w2 * y0 + self.sigma * v0  # v = e (v0 C - p S)
        if self.mu2 < 0:
            if v0 == 0 and p == 0:
                return
            phi = mp.atan2(p / self.nu, v0)  # v = e M cos(nu tau + phi)
            n = int(mp.ceil((phi - mp.pi / 2) / mp.pi))
            negligible = mp.mpf(10) ** (10 - DPS) / self.nu  # a zero at 0 computed a few ulps off
            while True:
                tau = (mp.pi / 2 + n * mp.pi - phi) / self.nu
                if tau > negligible:
                    yield tau
                n += 1
        if v0 == 0 or p == 0:
            return
        q = v0 / p  # S/C = tanh(mu tau)/mu = q; increasing from 0 (to 1/mu if mu > 0)
        if q <= 0:
            return
        if self.mu2 == 0:
            yield q
        elif self.mu * q < 1:
            yield mp.atanh(self.mu * q) / self.mu

    def departure(self, y0, v0):
        """(tau, v) of the first upward crossing of y = d from (y0, v0), or None if the contact never ends."""
        d = self.d
        if y0 > d or (y0 == d and v0 > 0):
            raise AssertionError(f"a contact starting above R: y0 - d = {y0 - d}, v0 = {v0}")
        if d > 0 and v0 * v0 + self.w2 * y0 * y0 <= self.w2 * d * d:
            return None  # the energy bound: |y| <= d for ever
        start = mp.zero
        zeros = self._v_zeros(y0, v0)
        for _ in range(8):  # an increasing piece comes within three; each ends the search
            end = next(zeros, None)
            if end is None:  # the last piece: y -> 0 monotonically
                _, v_after = self.flow(y0, v0, start + 1 / mp.sqrt(self.w2))
                if v_after <= 0 or d >= 0:
                    return None
                end = self._beyond(y0, v0, start)
            else:
                _, v_mid = self.flow(y0, v0, (start + end) / 2)
                if v_mid <= 0:
                    start = end
                    continue
                if self.flow(y0, v0, end)[0] <= d:
                    if self.mu2 < 0:
                        return None  # a maximum at or below d: the energy bound from here on
                    start = end  # (over-damped: a maximum below d; the approach after it decides)
                    continue
            tau = self._root(y0, v0, start, end)
            return tau, max(self.flow(y0, v0, tau)[1], mp.zero)  # a departure crosses R upwards: never v < 0
        raise AssertionError("the departure search did not end")

    def _beyond(self, y0, v0, start):
        """A time after start at which y > d (y increases to 0 > d on the last piece)."""
        step = (self.sigma + mp.sqrt(max(self.mu2, mp.zero))) / self.w2 + 1 / mp.sqrt(self.w2)
        for _ in range(4000):
            if self.flow(y0, v0, start + step)[0] > self.d:
                return start + step
            step *= 2
        raise AssertionError("no bracket for a departure on the slow approach")

    def _root(self, y0, v0, a, b):
        """The crossing of y = d in (a, b), where y(a) < d < y(b), on the bracket scaled to u in [0, 1]."""
        d = self.d
        width = b - a
        scale = max(abs(y0), abs(d), abs(v0) / mp.sqrt(self.w2))

        def f(u):
            return (self.flow(y0, v0, a + u * width)[0] - d) / scale

        assert 0 < f(mp.one), "the departure bracket does not bracket"
        if f(mp.zero) >= 0:  # y(a) = d to the working precision: at R (a start at R at -4e-294 m/s, lifted)
            return a
        try:
            u = mp.findroot(f, (mp.zero, mp.one), solver="anderson", maxsteps=400)
        except (ValueError, ZeroDivisionError):
            u = None
        if u is None or not 0 < u < 1:
            lo, hi = mp.zero, mp.one  # bisection: the bracket halves each time
            for _ in range(mp.prec + 10):
                mid = (lo + hi) / 2
                if f(mid) < 0:
                    lo = mid
                else:
                    hi = mid
            u = (lo + hi) / 2
        return a + u * width


class Oracle:
    """The solution from (h0, v0) at t_start to t_end [s]: events, rest time and h, v at any time.

    Parameters are floats (taken as exact binary values) of the ball (m, k, b, R, g), the start
    state (floats, or mpf values kept whole) and the constant upward force F_ext. Events in
    (t_start, t_end] are computed; more than max_events raise TooManyEvents.

    Attributes
    ----------
    events : list of OracleEvent
    rest_time : mpf or None
        Start of the contact that never ends, if it starts at or before t_end.
    next_event : OracleEvent or None
        The first event after t_end, if the last phase ends.
    phases : list of Phase
    """

    def __init__(self, m, k, b, R, g, h0, v0, t_end, t_start=0.0, F_ext=0.0, max_events=100_000):
        m, k, b, R, g, F = (mp.mpf(float(x)) for x in (m, k, b, R, g, F_ext))
        self.m, self.k, self.b, self.R, self.g, self.F = m, k, b, R, g, F
        self.a = g - F / m  # downward acceleration in flight
        self.contact = _Contact(m, k, b, R, g, F)
        self.t_start, self.t_end = _exact(t_start), _exact(t_end)
        h, v = _exact(h0), _exact(v0)  # an mpf start (a state carried over from another piece) is kept whole
        if h < R or (h == R and (v < 0 or (v == 0 and self.a > 0))):
            mode = CONTACT
        else:
            mode = FLIGHT
        self.events: list[OracleEvent] = []
        self.phases: list[Phase] = []
        self.rest_time = None
        self.next_event = None  # the first event after t_end, if there is one
        t = self.t_start
        while True:
            self.phases.append(Phase(mode, t, h, v))
            if mode == FLIGHT:
                switch = self._impact(h, v)
                if switch is None:
                    break  # never comes down
            else:
                switch = self.contact.departure(h - R + self.contact.d, v)
                if switch is None:
                    self.rest_time = t
                    break
            tau, v = switch
            if t + tau > self.t_end:
                self.next_event = OracleEvent(t + tau, IMPACT if mode == FLIGHT else DEPARTURE, v)
                break
            if len(self.events) >= max_events:
                raise TooManyEvents(f"more than {max_events} events before t = {float(self.t_end)} s")
            t = t + tau
            self.events.append(OracleEvent(t, IMPACT if mode == FLIGHT else DEPARTURE, v))
            mode, h = 1 - mode, R
        self._starts = [phase.start for phase in self.phases]

    def _impact(self, h, v):
        """(tau, velocity) of the next downward crossing of R in flight from (h, v), or None."""
        a, dh = self.a, h - self.R
        disc = v * v + 2 * a * dh
        if disc < 0:
            return None
        s = mp.sqrt(disc)  # the impact speed
        if v >= 0:
            if a <= 0:
                return None
            return (v + s) / a, -s
        if s == 0:
            return None  # touches R tangentially (a < 0)
        return 2 * dh / (s - v), -s

    def state_mp(self, t):
        """(h, v) at time t (mpf or float, >= t_start), as mpf."""
        t = mp.mpf(t)
        i = max(bisect.bisect_right(self._starts, t) - 1, 0)
        phase = self.phases[i]
        tau = t - phase.start
        if phase.mode == FLIGHT:
            return phase.h + phase.v * tau - self.a * tau * tau / 2, phase.v - self.a * tau
        d = self.contact.d
        y, v = self.contact.flow(phase.h - self.R + d, phase.v, tau)
        return self.R + (y - d), v

    def state(self, times):
        """h, v at the float times as numpy arrays (rounded once from DPS digits)."""
        hv = [self.state_mp(float(t)) for t in np.asarray(times, dtype=float)]
        return (np.array([float(h) for h, _ in hv], dtype=float),
                np.array([float(v) for _, v in hv], dtype=float))

    def hop_height(self, event):
        """How high [m, mpf] the flight after a departure event rises above R (inf if it never comes down)."""
        v = event.velocity
        return v * v / (2 * self.a) if self.a > 0 else mp.inf
