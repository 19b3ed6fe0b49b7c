"""The linear law (the default, the reference article's): a spring k and a damper b in contact; the damper may pull.

In contact the gap x = h - R obeys x'' + 2 sigma x' + w2 (x + d) = 0 (sigma = b / 2m, w2 = k / m,
d = (m g - F_ext) / k): a damped oscillator about the rest height, in closed form (equations.gap_flow_value).
Its departure is the first upward crossing of x = 0, searched on that flow (departure_time); a contact the
energy bound proves permanent is a rest (equations.rest_margin_value). The no-pull law builds on these searches.
"""

from __future__ import annotations

import math

import numpy as np

from ..equations import rest_margin_value
from ..oscillator import contact_gap_flow, sine_response, sine_response_gain
from ..rounding import hypot
from .common import BY_CVODE, IN_CLOSED_FORM, LINEAR, MIN_PHASE_SCALE, REST, SOFT_CONTACT_CAP, ContactLaw

_EPS = 2.0**-52
# The departure search on a vibrating table gives up (RuntimeError, saying where) after this many certified steps.
MAX_SINE_STEPS = 1_000_000
_SHORT_OF_ROOT = 1.0 - 1e-9  # a step to a bound's root stops just short of it: the root is computed in floats


def contact_scales(parameters, x, v, load):
    """(length [m], speed [m/s]) of a contact from (x, v): its amplitude about the rest height, and w times it.

    At most SOFT_CONTACT_CAP max(R, |x|): see phases.phase_scales.
    """
    m, k, R = parameters.m, parameters.k, parameters.R
    w = math.sqrt(k / m)
    amplitude = hypot(x + load / k, v / w)
    # Never far beyond the scene's own scale: a contact so soft that its amplitude dwarfs R (k/m = 7e-12
    # 1/s2, 6e120 m against R = 3e97 m) is left long before it gets there, and rtol times the amplitude
    # was 4e-6 of the ball's whole motion. (A cap at max(R, |x|) itself cost an R = 1 um ball, whose
    # contact swings 1.3 R, 17 times its accuracy.)
    length = min(amplitude, SOFT_CONTACT_CAP * max(R, abs(x)))
    return length, w * length


def contact_unresolved(parameters, x, v, load, resolution):
    """In a contact CVODE cannot decide: smaller than MIN_PHASE_SCALE, or resting too close to R.

    Below MIN_PHASE_SCALE its scaled state would not be representable. A rest height closer to R
    than CVODE resolves (resolution = HOP_RESOLUTION rtol, times the contact's amplitude) makes CVODE's x cross 0 or
    not by its own error: a ball creeping to a rest height 1e-23 m below R (F_ext within 2e-16 N of its
    weight), integrated to 5e-19 m, left the ground and came back.
    """
    length, speed = contact_scales(parameters, x, v, load)
    if not (length >= MIN_PHASE_SCALE and speed > 0.0):
        return True
    return abs(load / parameters.k) < resolution * length


def searches(parameters, x, v, load, resolution):
    """(rest_by_search, in_closed_form): whether a contact's exact-flow search decides a rest, and its event.

    A critically or over-damped ball (or one with no weight on the spring) creeps towards its rest height for many
    spring time constants, which CVODE would crawl through at the spring's time scale (500,000 steps for k/m =
    8e12 1/s); such a contact has at most one extremum, so the exact flow's search decides at once whether it ever
    reaches R; so it does for a contact CVODE cannot resolve (contact_unresolved), and for one that cannot hold
    the ball (F_ext lifts more than its weight), whose event then comes from the exact flow.
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    d = load / k
    unresolved = contact_unresolved(parameters, x, v, load, resolution)
    return b / (2.0 * math.sqrt(k * m)) >= 1.0 or d <= 0.0 or unresolved, d < 0.0 or unresolved


def decide_contact(parameters, x, v, load, hop, resolution):
    """(answer, tau, x_event, v_event) of a contact from (x, v): phases.decide_phase's, for this law.

    A rest once the energy bound proves it (rest_margin_value > 0 with the hop tolerance hop [m]); else the
    exact flow's departure search where searches() says so; else CVODE.
    """
    d = load / parameters.k
    if d > 0.0 and rest_margin_value(x, v, d, hop, parameters.k / parameters.m) > 0.0:
        return REST, 0.0, 0.0, 0.0
    rest_by_search, in_closed_form = searches(parameters, x, v, load, resolution)
    if not (rest_by_search or in_closed_form):
        return BY_CVODE, 0.0, 0.0, 0.0
    tau = departure_time(parameters, x, v, load)
    if math.isinf(tau):
        return (REST if rest_by_search else BY_CVODE), 0.0, 0.0, 0.0
    if in_closed_form:
        return IN_CLOSED_FORM, tau, 0.0, departure_speed(parameters, x, v, tau, load)
    return BY_CVODE, 0.0, 0.0, 0.0


def departure_time(parameters, x0, v0, load):
    """Time [s] from the gap x0 = h0 - R [m] and v0 [m/s] in contact to the first upward crossing of h = R; inf if none.

    parameters: Ball.parameters; load: m g - F_ext [N] (equations.load_value). Plain floats, so that the
    compiled phase machine runs this very search: a bracket of the crossing (_underdamped_bracket,
    _overdamped_bracket), then Newton with bisection in it (_departure_root).
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    sigma, w2 = b / (2.0 * m), k / m
    d, g_eff = load / k, load / m
    q = sigma * v0 + w2 * x0 + g_eff  # v = v0 C - q S (q = sigma v0 + w2 y0, y0 = x0 + d the deflection from rest)
    rising = v0 > 0.0 or (v0 == 0.0 and q < 0.0)
    disc = sigma * sigma - w2
    if disc < 0.0:
        a, b, guess, at_a = _underdamped_bracket(sigma, w2, g_eff, x0, v0, q, rising, math.sqrt(-disc))
    else:
        a, b, guess, at_a = _overdamped_bracket(sigma, w2, g_eff, x0, v0, q, rising, math.sqrt(disc), d)
    if math.isinf(a):
        return math.inf
    if math.isnan(guess) and contact_gap_flow(sigma, w2, g_eff, x0, v0, b)[0] <= 0.0:
        return math.inf
    return _departure_root(sigma, w2, g_eff, x0, v0, a, b, guess, at_a)


def _underdamped_bracket(sigma, w2, g_eff, x0, v0, q, rising, omega):
    """(a, b, guess, at_a): an under-damped contact's first departure lies in [a, b] [s]; a = inf: it never departs.

    Extrema come every pi / omega; maxima are positive and decay, so the first maximum decides whether the ball
    ever leaves. guess: Newton's start where known, at_a: the gap at a where computed (NaN: not known).
    """
    guess, at_a = math.nan, math.nan
    # The phase angle of the next extremum, in [0, pi], from the quadrant that holds it: atan2(a, b)
    # - pi rounds an extremum just ahead (a minimum at v0 = -1e-38) to pi instead of ~0.
    # (|omega v0|: the sign of a zero, -0.0, would turn atan2's pi into -pi)
    tau1 = math.atan2(abs(omega * v0), q if rising else -q) / omega
    # Between two extrema v keeps its sign, so the first one is a maximum when the ball starts
    # rising and a minimum when it starts falling. Decided on the direction, never on the
    # value y(tau1): near critical damping that extremum lies many decay times away, and y(tau1)
    # is below the rounding of d.
    if rising:
        return 0.0, tau1, guess, at_a
    at_a = contact_gap_flow(sigma, w2, g_eff, x0, v0, tau1)[0]
    a, b = tau1, tau1 + math.pi / omega
    at_b = contact_gap_flow(sigma, w2, g_eff, x0, v0, b)[0]
    if at_b <= 0.0:
        return math.inf, math.inf, guess, at_a
    # Between a minimum and the next maximum y is close to half a cosine: its crossing
    # is Newton's start, a few iterations from the root when the damping is light.
    half = 0.5 * (at_b - at_a)
    if half > 0.0:  # else the ball does not move (y constant): Newton starts in the middle
        cosine = min(1.0, max(-1.0, (0.5 * (at_b + at_a)) / half))
        guess = a + (b - a) * math.acos(cosine) / math.pi
    return a, b, guess, at_a


def _overdamped_bracket(sigma, w2, g_eff, x0, v0, q, rising, mu, d):
    """(a, b, nan, nan): _underdamped_bracket's, critically or over-damped: at most one extremum, then rest at -d."""
    tau_ext = _overdamped_extremum(v0, q, mu)
    slow_rate = w2 / (sigma + mu)
    if rising and not math.isnan(tau_ext):
        return 0.0, tau_ext, math.nan, math.nan
    if not (d < 0.0 and (rising or not math.isnan(tau_ext))):
        return math.inf, math.inf, math.nan, math.nan
    a = 0.0 if rising else tau_ext
    b = a + 1.0 / slow_rate
    for _ in range(2000):
        if contact_gap_flow(sigma, w2, g_eff, x0, v0, b)[0] > 0.0:
            return a, b, math.nan, math.nan
        b = a + 2.0 * (b - a)
    return math.inf, math.inf, math.nan, math.nan


def departure_speed(parameters, x0, v0, tau, load):
    """v [m/s] where a contact from the gap x0 = h0 - R [m] and v0 ends after tau (departure_time): never < 0.

    A departure crosses R upwards; where the ball barely moves (at R with v0 = -1e-112) the flow can
    round it to a tiny downward speed, and the flight would end at once in an impact at R, and so on
    for ever. An undamped contact from R leaves at the speed it came with, exactly
    (contact_laws.conserved_speed). Arguments as departure_time's.
    """
    if x0 == 0.0 and v0 < 0.0 and parameters.b == 0.0:  # contact_laws.conserved_speed's undamped contact
        return -v0
    m, k, b = parameters.m, parameters.k, parameters.b
    return max(contact_gap_flow(b / (2.0 * m), k / m, load / m, x0, v0, tau)[1], 0.0)


def _overdamped_extremum(v0, q, mu):
    """The one time > 0 where v0 C = q S (critical or over-damped), or NaN."""
    if v0 == 0.0:
        return math.nan
    if mu == 0.0:
        tau = v0 / q if q != 0.0 else -1.0
        return tau if tau > 0.0 else math.nan
    denominator = q - v0 * mu
    if denominator == 0.0:
        return math.nan
    x = 2.0 * v0 * mu / denominator
    if not x > 0.0:
        return math.nan
    return math.log1p(x) / (2.0 * mu)


def _departure_root(sigma, w2, g_eff, x0, v0, a, b, guess, at_a):
    """The root of the gap x(tau) (contact_gap_flow, increasing on [a, b]) with x(a) <= 0 < x(b).

    Newton from guess (NaN: the middle), safeguarded by bisection of the bracket; at_a is x(a) if
    known, else NaN.
    """
    if (contact_gap_flow(sigma, w2, g_eff, x0, v0, a)[0] if math.isnan(at_a) else at_a) >= 0.0:
        return a
    tau = guess if a < guess < b else 0.5 * (a + b)
    best, best_abs = b, math.inf
    for _ in range(200):
        x, v = contact_gap_flow(sigma, w2, g_eff, x0, v0, tau)
        if abs(x) < best_abs:
            best, best_abs = tau, abs(x)
        if x == 0.0:
            return tau
        if x < 0.0:
            a = tau
        else:
            b = tau
        step = x / v if v > 0.0 else math.inf
        # Converged when Newton moves by ulps: checked before the bracket test, since such a step
        # lands on the bracket's end just moved to tau, and bisecting from there would take ~50 steps.
        if abs(step) <= 2.0 * np.spacing(tau) or b - a <= 2.0 * np.spacing(b):
            break
        tau_new = tau - step
        if not a < tau_new < b:
            tau_new = 0.5 * (a + b)
        tau = tau_new
    return best



# --- on a sinusoidally vibrating ground s = A sin(theta), theta = w t + p: the contact in the ground's frame ---
# x = h - R - s and u = v - s' obey x'' + 2 sigma x' + w2 x = -g_eff + A w^2 sin(theta): the still ground's contact
# (contact_gap_flow) plus the periodic response to the ground's acceleration (oscillator.sine_response).
def sine_ground_flow(parameters, x0, u0, tau, load, forcing, w, theta0):
    """(x [m], u [m/s]) relative to a vibrating ground, tau [s] after (x0, u0) in contact at the ground's angle theta0.

    forcing = A w^2 [m/s2] (the ground's peak acceleration), w [rad/s]; tau a float or an array (x0, u0 may be
    arrays of its shape). The homogeneous flow from the start less the periodic response there, plus the
    periodic response at the end.
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    sigma, w2 = b / (2.0 * m), k / m
    x_p0, u_p0 = sine_response(sigma, w2, forcing, w, theta0)
    x_p1, u_p1 = sine_response(sigma, w2, forcing, w, theta0 + w * tau)
    x, u = contact_gap_flow(sigma, w2, load / m, x0 - x_p0, u0 - u_p0, tau)
    return x + x_p1, u + u_p1


def sine_ground_departure(parameters, x0, u0, load, forcing, w, theta0, horizon):
    """(tau [s], u [m/s]): the first upward crossing of x = 0 of sine_ground_flow from (x0 <= 0, u0); (inf, 0) if none.

    Certified, never a crossing stepped over: the motion is the periodic response plus a homogeneous one whose
    energy E = y'^2 + w2 y^2 never grows (y = x - x_p + g_eff / w2), so |x''| <= M = (2 sigma + sqrt(w2)) sqrt(E) +
    forcing w^2 |H| from any point on, and x stays below x + u d + M d^2 / 2: each step goes to that bound's first
    root, converging on the first crossing from before it (the last steps as Newton's). Once even
    -g_eff / w2 + sqrt(E / w2) + forcing |H| < 0 the ball can never reach the ground's surface again: none. A
    crossing within the rounding of x at no upward speed is a touch, not a departure. None within horizon [s]:
    (tau, 0) with tau > horizon, the first certified point past it.
    """
    m, k, b = parameters.m, parameters.k, parameters.b
    sigma, w2 = b / (2.0 * m), k / m
    omega0, d, gain = math.sqrt(w2), load / k, sine_response_gain(sigma, w2, w)
    steady = forcing * gain  # the periodic response's amplitude [m]
    tau, x, u, tau_before = 0.0, x0, u0, 0.0
    for _ in range(MAX_SINE_STEPS):
        x_p, u_p = sine_response(sigma, w2, forcing, w, theta0 + w * tau)
        y, y_rate = x - x_p + d, u - u_p
        swing = hypot(y, y_rate / omega0)  # sqrt(E / w2): the homogeneous part's amplitude bound
        noise = 16.0 * _EPS * (abs(x) + abs(d) + steady + swing)
        if swing + steady - d < -noise:  # never again at the surface
            return math.inf, 0.0
        if x >= -noise and u > 0.0 and tau > 0.0:
            return _sine_polish(parameters, x0, u0, load, forcing, w, theta0, tau_before, tau, x, u)
        bound = (2.0 * sigma + omega0) * swing * omega0 + forcing * w * w * gain
        depth = max(-x, noise)
        root = math.sqrt(u * u + 2.0 * bound * depth)
        step = 2.0 * depth / (u + root) if u > 0.0 else (root - u) / bound
        tau_before, tau = tau, tau + _SHORT_OF_ROOT * step
        if not tau <= horizon:  # none within it: a certified point past it
            return tau, 0.0
        x, u = sine_ground_flow(parameters, x0, u0, tau, load, forcing, w, theta0)
    # a plain message: the compiled engine raises it too (numba formats no f-string)
    raise RuntimeError("the departure search on the vibrating ground made MAX_SINE_STEPS (1e6) steps: neither a "
                       "departure nor a way past a touch")


def _sine_polish(parameters, x0, u0, load, forcing, w, theta0, tau_before, tau, x, u):
    """(tau, u) at the crossing a certified step to tau ended within the rounding of x.

    Newton on sine_ground_flow from (x0, u0), kept after tau_before, where the gap was certified below the surface.
    """
    best = (tau, u)
    for _ in range(4):
        tau -= x / u
        if not (tau_before < tau and math.isfinite(tau)):
            break
        x, u = sine_ground_flow(parameters, x0, u0, tau, load, forcing, w, theta0)
        if not u > 0.0:
            break
        best = (tau, u)
        if abs(x) <= 2.0 * _EPS * abs(u) * tau:
            break
    return best[0], max(best[1], 0.0)

# The law's entry in the registry (contact_laws.LAWS).
LAW = ContactLaw("linear", LINEAR, ("k", "b"), closed_form=True,
                 description="the spring-damper k, b (the damper may pull)",
                 article_algorithm=True, crossings_only=True, k_unit="N/m", damping_axis="zeta",
                 summary="k = {k:g} N/m, b = {b:g} N s/m")
