"""The ball's equations as functions of plain floats: accelerations, load, deflection, rest margin and flow.

Each mode's acceleration, the load, the static deflection, the rest margin and the exact flow of the
linear law's modes. physics.Ball's methods call them, and the compiled CVODE engine compiles these same
functions, so the physics has one definition (solvers/engines/jit.py's rules); contact_laws/ builds each law's
on them.
"""

from __future__ import annotations

import math

from .codes import CONTACT
from .oscillator import contact_gap_flow
from .rounding import product_error


# The equations as functions of plain floats: Ball's methods call them, and the compiled CVODE
# engine compiles these same functions, so the physics has one definition.
def gap_acceleration(x, v, mode, load, m, k, b):
    """dv/dt [m/s2] in mode at the gap x = h - R [m]; load = load_value(F_ext, m, g) [N], the same for a whole phase.

    k x, not k h - k R: x is exact near R, whereas the two products of a stiff ball (k = 1e12)
    would bury its deflection in their round-off. The load, not g - F_ext/m, which rounds
    differently: a ball creeping to a rest height of exactly R felt a residual 2e-15 m/s2.
    """
    if mode != CONTACT:  # flight, or free below R under the no-pull law
        return -load / m
    return (-b * v - k * x - load) / m


def effective_gravity_value(F_ext, m, g):
    """(m g - F_ext)/m [m/s2]; see Ball.effective_gravity and load_value."""
    return load_value(F_ext, m, g) / m


def static_deflection_value(F_ext, m, k, g):
    """(m g - F_ext)/k [m]; see Ball.static_deflection and load_value."""
    return load_value(F_ext, m, g) / k


def load_value(F_ext, m, g):
    """m g - F_ext [N], the net load on the spring, with the product m g exact (Dekker's two-product).

    Its sign decides whether a contact can hold the ball. m g rounded first can land on F_ext when
    F_ext exceeds the weight by an ulp: the load came out 0, and a ball that truly rises 3.6e-16 m
    above R and leaves after 42 s was declared at rest (found by the near-critical property).
    """
    product = m * g
    if not (abs(134217729.0 * m) < 1e300 and abs(134217729.0 * g) < 1e300 and abs(product) < 1e300):
        return product - F_ext
    return (product - F_ext) + product_error(m, g, product)


def rest_margin_value(x, v, d, hop_tolerance, w2):
    """w2 d (d + 2 hop_tolerance) - (v^2 + w2 y^2) [m2/s2] at the gap x = h - R, d the static deflection.

    y = x + d is the deflection from the rest height; the d^2 terms cancel in closed form, as
    w2 (2 d hop_tolerance - x (x + 2 d)) - v^2, which keeps x's digits where d is far larger (a soft
    contact) and d's where it is far smaller than R (no R - d). See Ball.rest_margin.
    """
    return w2 * (2.0 * d * hop_tolerance - x * (x + 2.0 * d)) - v * v


def gap_flow_value(mode, x0, v0, tau, load, m, k, b):
    """The exact (x [m], v [m/s]) a time tau [s] after (x0, v0) in mode; load = load_value(F_ext, m, g) [N].

    See Ball.gap_flow. Floats or arrays; compiled by the compiled engine. Mode 2 (free below R under the
    no-pull law) is the flight's parabola.
    """
    g_eff = load / m
    if mode != CONTACT:
        return x0 + tau * (v0 - 0.5 * g_eff * tau), v0 - g_eff * tau
    return contact_gap_flow(b / (2.0 * m), k / m, g_eff, x0, v0, tau)


# --- a vibrating ground s(t) = A sin(w t + p), as the phase machine takes it (BallParameters' ground_* fields) ---
# In the ground's frame the gap x = h - R - s and the relative velocity v - s' obey the still ground's equations
# under the load m g - F_ext + m s''(t): the ground enters the machine as that load and the flows below.
_EPS = 2.0**-52
_SHORT_OF_ROOT = 1.0 - 1e-9  # a certified step stops this much short of its bound's root
MAX_TOUCH_STEPS = 100_000


def ground_value(parameters, t, order):
    """s, s', s'' or s''' (order 0 .. 3) of the ground at t [s]: A w^order sin(w t + p + order pi / 2); 0 if still."""
    if parameters.ground_amplitude == 0.0:
        return 0.0
    return sine_value(parameters.ground_amplitude, parameters.ground_omega, parameters.ground_phase, t, order)


def sine_value(amplitude, w, phase, t, order):
    """The order-th derivative (0 .. 3) at t [s] of A sin(w t + p): A w^order sin(w t + p + order pi / 2)."""
    scale = amplitude
    for _ in range(order):  # not w ** order, which numba and Python may round differently
        scale *= w
    return scale * math.sin(w * t + phase + 0.5 * math.pi * order)


def load_at(parameters, load, t):
    """The load [N] in the ground's frame at t [s]: load + m s''(t); the load itself on a still ground."""
    if parameters.ground_amplitude == 0.0:
        return load
    return load + parameters.m * ground_value(parameters, t, 2)


def ground_rise_value(parameters, t0, tau):
    """s(t0 + tau) - s(t0) [m] without the cancellation of two heights: 2 A cos(w (t0 + tau / 2) + p) sin(w tau / 2)."""
    return sine_rise(parameters.ground_amplitude, parameters.ground_omega, parameters.ground_phase, t0, tau)


def sine_rise(amplitude, w, phase, t0, tau):
    """ground_rise_value of amplitude sin(w t + phase)."""
    return 2.0 * amplitude * math.cos(w * (t0 + 0.5 * tau) + phase) * math.sin(0.5 * w * tau)


def ground_flight_flow(parameters, x0, v0, t0, tau, load):
    """(x [m], v [m/s]) relative to the ground tau [s] after (x0, v0) at t0 [s] in flight (or a force-free mode).

    The world's parabola less the ground's motion: x0 + v0 tau - g_eff tau^2 / 2 - (s(t0 + tau) - s(t0) - s'(t0) tau).
    """
    return sine_flight_flow(parameters.m, parameters.ground_amplitude, parameters.ground_omega,
                            parameters.ground_phase, x0, v0, t0, tau, load)


def sine_flight_flow(m, amplitude, w, phase, x0, v0, t0, tau, load):
    """ground_flight_flow above the ground amplitude sin(w t + phase), for a mass m [kg] under load [N]."""
    g_eff = load / m
    slope = sine_value(amplitude, w, phase, t0, 1)
    x = x0 + tau * (v0 - 0.5 * g_eff * tau) - (sine_rise(amplitude, w, phase, t0, tau) - slope * tau)
    return x, v0 - g_eff * tau - (sine_value(amplitude, w, phase, t0 + tau, 1) - slope)


def ride_end_value(parameters, t, g_eff):
    """The first time >= t [s] at which s'' < -g_eff [m/s2] on the ball's ground (sine_ride_end); inf if never.

    A still ground: t if g_eff < 0, else inf.
    """
    if parameters.ground_amplitude == 0.0:
        return t if g_eff < 0.0 else math.inf
    return sine_ride_end(parameters.ground_amplitude, parameters.ground_omega, parameters.ground_phase, t, g_eff)


def sine_ride_end(amplitude, w, phase, t, g_eff):
    """The first time >= t [s] at which s'' < -g_eff [m/s2] on s = amplitude sin(w t + phase) (amplitude > 0).

    Where a ball riding the ground leaves it; inf if never. s'' = -A w^2 sin(angle) < -g_eff  <=>  sin(angle) >
    g_eff / (A w^2). Ground.ride_end's and the phase machine's (ride_end_value).
    """
    c = g_eff / (amplitude * (w * w))  # Ground.ride_end's rounding: A w^2 as it was computed there
    if c >= 1.0:
        return math.inf
    angle = w * t + phase
    if c < -1.0 or math.sin(angle) > c:
        return t
    start = math.asin(c)  # where sin rises through c (cos > 0)
    turns = math.ceil((angle - start) / (2.0 * math.pi))
    # The root's angle to the ground's phase, not to t's: the same root, searched from any t before it, is the same
    # double (a restored state decides its ride again from the restart point, not from where it began).
    return max((start + 2.0 * math.pi * turns - phase) / w, t)


def flight_touch(parameters, t0, x0, v0, load, horizon, on_ground):
    """tau [s]: the first time a flight from the gap x0 [m] at t0 [s], relative speed v0 [m/s], meets the ground.

    inf if not within horizon [s]: sine_flight_touch on the ball's vibrating ground. on_ground: the flight leaves
    the ground at t0 (its gap 0 there is no touch).
    """
    return sine_flight_touch(parameters.m, parameters.ground_amplitude, parameters.ground_omega,
                             parameters.ground_phase, t0, x0, v0, load, horizon, on_ground)


def sine_flight_touch(m, amplitude, w, phase, t0, x0, v0, load, horizon, on_ground):
    """tau [s]: the first time a flight from the gap x0 [m] at t0 [s], relative speed v0 [m/s], meets a sine ground.

    The ground amplitude sin(w t + phase) [m] (amplitude != 0, of either sign), the flight a mass m [kg] under
    load [N]; inf if not within horizon [s]. Certified: each step goes to the first root of a lower bound of the
    gap (the quadratic gap + gap' d - M d^2 / 2, M = |g_eff| + |A| w^2 >= |gap''|, or where that step is short, a
    graze or the cubic start after a ride, the quartic Taylor bound with |gap''''| <= |A| w^4), so the steps
    converge on the first root from before it and no graze is stepped over; a gap within its rounding of 0 is a
    touch. on_ground: the flight leaves the ground at t0 (its gap 0 there is no touch). Any sine will do: the
    no-pull law's free spell searches two of its own (no_pull.sine_free_event).
    """
    g_eff = load / m
    size = abs(amplitude)
    bound = abs(g_eff) + size * w * w
    rate_bound = size * w * w * w * w
    tau = 0.0
    for _ in range(MAX_TOUCH_STEPS):
        if not tau <= horizon:
            return math.inf
        t = t0 + tau
        gap, slope = sine_flight_flow(m, amplitude, w, phase, x0, v0, t0, tau, load)
        curve = -g_eff - sine_value(amplitude, w, phase, t, 2)
        jerk = -sine_value(amplitude, w, phase, t, 3)
        spread = abs(x0) + abs(v0) * tau + 0.5 * abs(g_eff) * tau * tau
        rounding = 16.0 * _EPS * (spread + size * (1.0 + abs(w * t + phase) * min(w * tau, 2.0)))
        if gap <= rounding and (tau > 0.0 or (slope < 0.0 and not on_ground)):
            return tau
        if tau == 0.0 and on_ground:
            gap, slope, curve = 0.0, max(slope, 0.0), max(curve, 0.0)  # leaving the ground: its gap's start
        gap = max(gap, 0.0)
        root = math.sqrt(slope * slope + 2.0 * bound * gap)
        step = (slope + root) / bound if slope >= 0.0 else 2.0 * gap / (root - slope) if root > slope else 0.0
        if not step * w > 1e-2:
            step = max(step, first_quartic_root(-rate_bound / 24.0, jerk / 6.0, 0.5 * curve, slope, gap))
        if not step > 0.0:
            return tau
        tau += _SHORT_OF_ROOT * step
    raise RuntimeError("the certified search for a flight's touch of the vibrating ground made MAX_TOUCH_STEPS "
                       "steps: neither a touch nor a way past one")


def first_quartic_root(c4, c3, c2, c1, c0):
    """The smallest positive root of the quartic c4 d^4 + c3 d^3 + c2 d^2 + c1 d + c0 (c4 < 0 <= c0).

    In plain floats, the same in both engines: the roots of its derivative (a cubic, whose turning points are the
    roots of a quadratic) split (0, inf) into pieces where it is monotonic; the first piece whose end is <= 0 holds
    the root, found by bisection.
    """
    turn0, turn1 = _quadratic_roots(12.0 * c4, 6.0 * c3, 2.0 * c2)
    point0, point1, point2 = _cubic_roots(4.0 * c4, 3.0 * c3, 2.0 * c2, c1, turn0, turn1)
    start, value = 0.0, c0
    for end in (point0, point1, point2, _past_roots(c4, c3, c2, c1, c0)):
        if not end > start:
            continue
        end_value = _quartic(c4, c3, c2, c1, c0, end)
        if end_value <= 0.0:
            return _bisected(c4, c3, c2, c1, c0, start, end) if value > 0.0 else start
        start, value = end, end_value
    return math.inf


def _quartic(c4, c3, c2, c1, c0, d):
    return (((c4 * d + c3) * d + c2) * d + c1) * d + c0


def _quadratic_roots(a2, a1, a0):
    """The real roots of a2 x^2 + a1 x + a0, ascending; nan where there is none."""
    if a2 == 0.0:
        return (-a0 / a1, math.nan) if a1 != 0.0 else (math.nan, math.nan)
    disc = a1 * a1 - 4.0 * a2 * a0
    if disc < 0.0:
        return math.nan, math.nan
    q = -0.5 * (a1 + math.copysign(math.sqrt(disc), a1))
    if q == 0.0:
        return 0.0, 0.0
    r0, r1 = q / a2, a0 / q
    return min(r0, r1), max(r0, r1)


def _cubic_roots(a3, a2, a1, a0, turn0, turn1):
    """The positive real roots (ascending, nan-padded to three) of the cubic a3 x^3 + a2 x^2 + a1 x + a0, a3 < 0.

    Given its turning points turn0 <= turn1 (nan: none): one bisection per monotonic piece that changes sign.
    """
    roots = [math.nan, math.nan, math.nan]
    count, start, value = 0, 0.0, a0
    for end in (turn0, turn1, 1.0 + (abs(a2) + abs(a1) + abs(a0)) / abs(a3)):
        if not end > start:
            continue
        end_value = _quartic(0.0, a3, a2, a1, a0, end)
        if value == 0.0 or (value > 0.0) != (end_value > 0.0):
            roots[count] = start if value == 0.0 else _bisected(0.0, a3, a2, a1, a0, start, end)
            count += 1
        start, value = end, end_value
    return roots[0], roots[1], roots[2]


def _past_roots(c4, c3, c2, c1, c0):
    """A point beyond every real root of the quartic (Cauchy's bound)."""
    return 1.0 + (abs(c3) + abs(c2) + abs(c1) + abs(c0)) / abs(c4)


def _bisected(c4, c3, c2, c1, c0, low, high):
    """The root of the quartic between low and high, where it changes sign once, to the last bit; its low side."""
    low_side = _quartic(c4, c3, c2, c1, c0, low) > 0.0
    for _ in range(2100):
        mid = 0.5 * (low + high)
        if not low < mid < high:
            break
        if (_quartic(c4, c3, c2, c1, c0, mid) > 0.0) == low_side:
            low = mid
        else:
            high = mid
    return low


def quintic_exit(p0, p1, p2, p3, p4, p5, level, margin, to_end):
    """(s, undecided): where the quintic p0 + p1 s + .. + p5 s^5 first rises to level on (0, 1]; nan where it does not.

    Certified to rounding: its turning points (the roots of its derivative, found from those of its higher
    derivatives, each on a piece where it is monotonic) split [0, 1] into monotonic pieces, the first piece rising
    across level holds the crossing, bisected. to_end False: a crossing on the last piece (ending at 1, a root the
    caller has) is not looked for. undecided: a local maximum inside (0, 1) up to the crossing lies within margin
    of level, below or above it (a graze that the interpolated motion's error could turn either way).
    """
    turn0, turn1 = _quadratic_roots(60.0 * p5, 24.0 * p4, 6.0 * p3)  # of the third derivative
    bend0, bend1, bend2, _ = _piece_roots(2.0 * p2, 6.0 * p3, 12.0 * p4, 20.0 * p5, 0.0, 0.0,
                                          turn0, turn1, math.nan, math.nan)
    cuts = _piece_roots(p1, 2.0 * p2, 3.0 * p3, 4.0 * p4, 5.0 * p5, 0.0, bend0, bend1, bend2, math.nan)
    undecided, start, value = False, 0.0, _quintic(p0, p1, p2, p3, p4, p5, 0.0)
    for end in (cuts[0], cuts[1], cuts[2], cuts[3], 1.0):
        if not (start < end <= 1.0):
            continue
        end_value = _quintic(p0, p1, p2, p3, p4, p5, end)
        if value < level <= end_value and (to_end or end < 1.0):
            # a turn above level by less than margin: a crossing the motion's error could undo, as a turn below
            undecided = undecided or (end < 1.0 and end_value < level + margin)
            low, high = start, end
            for _ in range(1100):
                mid = 0.5 * (low + high)
                if not low < mid < high:
                    break
                if _quintic(p0, p1, p2, p3, p4, p5, mid) >= level:
                    high = mid
                else:
                    low = mid
            return high, undecided
        if end < 1.0 and value < end_value and level - margin <= end_value < level:
            undecided = True
        start, value = end, end_value
    return math.nan, undecided


def _quintic(p0, p1, p2, p3, p4, p5, s):
    return ((((p5 * s + p4) * s + p3) * s + p2) * s + p1) * s + p0


def _piece_roots(c0, c1, c2, c3, c4, c5, cut0, cut1, cut2, cut3):
    """The roots in (0, 1) of c0 + c1 s + .. + c5 s^5, monotonic between the cuts (ascending; nan: none), nan-padded.

    One bisection per piece whose ends differ in sign (> 0 against <= 0): at most one root each, ascending.
    """
    roots = [math.nan, math.nan, math.nan, math.nan]
    count, start, value = 0, 0.0, c0
    for end in (cut0, cut1, cut2, cut3, 1.0):
        if not (start < end <= 1.0) or count == 4:
            continue
        end_value = _quintic(c0, c1, c2, c3, c4, c5, end)
        if (value > 0.0) != (end_value > 0.0):
            low, high, low_side = start, end, value > 0.0
            for _ in range(1100):
                mid = 0.5 * (low + high)
                if not low < mid < high:
                    break
                if (_quintic(c0, c1, c2, c3, c4, c5, mid) > 0.0) == low_side:
                    low = mid
                else:
                    high = mid
            if high < 1.0:
                roots[count] = high
                count += 1
        start, value = end, end_value
    return roots[0], roots[1], roots[2], roots[3]
