"""The hunt-crossley law: Hunt and Crossley's k delta^n (1 + 3/2 alpha delta'), delta = R - h, clipped at 0.

Free (Mode.FREE, the flight's parabola below R) above the release speed 2 / (3 alpha), where the force would pull;
pressed (Mode.CONTACT) below it. alpha's range depends on the scene (limits.check_alpha): with v its largest contact
speed, 3/2 alpha v <= 1e150 (the force would overflow), and under CVODE at rtol 2 / (3 alpha) >= rtol v (a slower
release than CVODE resolves), so alpha <= min(1e150, 1 / rtol) 2 / (3 v).

No closed form: CVODE integrates every pressed contact, with the law's own right-hand side and state-dependent
Jacobian; its rest is only reported (hunt_crossley_rest_margin), and its error carried step by step
(solvers/phase_machine/error_estimate.py).

On a vibrating ground (in its frame: the deflection R - (h - s), its rate -(v - s')) the load has the ground's
acceleration in it (equations.load_at), so does the interpolant (its rate, the ground's jerk); each pressed step's
interpolant is searched for where it leaves the contact (step_exit: a departure or a release that CVODE's root
functions would miss inside one step), the free spell's ends are certified searches (sine_free_event), and no rest is
reported (its energy criterion holds for a constant load only).
"""

from __future__ import annotations

import math

from ..equations import ground_value, load_at, quintic_exit, sine_flight_flow, sine_flight_touch, sine_value
from ..oscillator import oscillator_basis
from .common import HUNT_CROSSLEY, SOFT_CONTACT_CAP, ContactLaw, surely_below

# The Hunt-Crossley law's exponent n: 1 (a linear spring) .. 2.5 (beyond Hertz's 1.5 for spheres, as fitted
# to soft and granular materials); its release speed is 2 / (3 alpha).
HC_N_RANGE = (1.0, 2.5)


def hunt_crossley_force(x, v, k, n, alpha):
    """k delta^n (1 + 3/2 alpha delta') [N], delta = -x the penetration, delta' = -v: the pressed force, unclipped.

    delta^n continued as sign(delta) |delta|^n beyond R (x > 0), where CVODE's trial steps may look past
    a departure: smooth there (for n > 1 its derivative is 0), as the linear law's k x continues.
    """
    return k * math.copysign(abs(x) ** n, -x) * (1.0 - 1.5 * alpha * v)


def hunt_crossley_acceleration(x, v, load, m, k, n, alpha):
    """dv/dt [m/s2] in the Hunt-Crossley pressed contact (Mode.CONTACT): (force - load) / m."""
    return (hunt_crossley_force(x, v, k, n, alpha) - load) / m


def hunt_crossley_partials(x, v, load, m, k, n, alpha):
    """(da/dx [1/s2], da/dv [1/s]) of hunt_crossley_acceleration: the Jacobian's second row, state-dependent."""
    power = abs(x) ** (n - 1.0)  # |x|^0 = 1 at n = 1 (and at x = 0)
    return -(k / m) * n * power * (1.0 - 1.5 * alpha * v), -(k / m) * math.copysign(abs(x) ** n, -x) * 1.5 * alpha


def hunt_crossley_rest_margin(x, v, load, m, k, n, hop):
    """g_eff (hop + delta) - v^2 / 2 - (k/m) delta^(n+1) / (n + 1) [m2/s2]: positive once it never rises hop above R.

    delta = max(-x, 0); positive once a pressed Hunt-Crossley ball can never again rise more than hop [m] above R.

    It is L hop - E per mass, with the load L = m g - F_ext (held constant) and the energy
    E = m v^2 / 2 - L delta + k delta^(n+1) / (n + 1). Proof: with delta' = -v, dE/dt = v (m v' + L - k delta^n).
    Pressed, m v' = k delta^n (1 - 3/2 alpha v) - L, so dE/dt = -3/2 alpha k delta^n v^2 <= 0; free (the force's
    clip engaged: v above the release speed 2 / (3 alpha) > 0), m v' = -L, so dE/dt = -k delta^n v < 0. So E never
    grows while delta > 0. On R (delta = 0) E = m v^2 / 2 >= 0, and a ball leaving R rising at v reaches
    v^2 / (2 g_eff) = E / L above it. Hence once E < L hop (the margin positive) the ball either never reaches
    R again, or (E in [0, L hop)) leaves it by a hop lower than hop; with hop = 0 it never leaves: E < 0 at
    delta > 0 and E >= 0 at delta = 0 cannot both hold on a path along which E does not grow. (E < 0 needs
    L delta > 0: a lifted ball, L <= 0, is never at rest.)
    """
    delta = max(-x, 0.0)
    return (load / m) * (hop + delta) - 0.5 * (v * v) - (k / m) * delta ** (n + 1.0) / (n + 1.0)


def hunt_crossley_static_deflection(load, k, n):
    """(load / k)^(1/n) [m], its sign the load's: the penetration at which k delta^n carries the load [N]."""
    return math.copysign((abs(load) / k) ** (1.0 / n), load)


def hunt_crossley_rest_depth(load, m, k, n):
    """(2 (n + 1) g_eff / (k/m))^(1/n) [m], g_eff = load / m > 0: the length scale of a Hunt-Crossley contact near rest.

    A contact of energy per mass e = v^2 / 2 - g_eff delta + (k/m) delta^(n+1) / (n + 1) <= 0 (one that leaves R no
    higher than it hops, e = g_eff hop, for hop -> 0) stays shallower than this: past it the spring's energy
    (k/m) delta^(n+1) / (n + 1) exceeds 2 g_eff delta. It is (2 (n + 1))^(1/n) times the static deflection
    (hunt_crossley_static_deflection): 4 at n = 1, 2.9 at n = 3/2, 2.2 at n = 5/2. The contact's frame
    (phases.hunt_crossley_scales) is never smaller.
    """
    return (2.0 * (n + 1.0) * (load / m) / (k / m)) ** (1.0 / n)


def hunt_crossley_hop_tolerance(load, m, k, n, alpha, resolution):
    """The highest hop [m] a Hunt-Crossley run may merge: resolution (HOP_RESOLUTION rtol) hunt_crossley_rest_depth.

    From the law's energy (hunt_crossley_rest_margin): a ball leaving R rising at v hops H = v^2 / (2 g_eff) above
    it, its energy on R E = m v^2 / 2 = L H (L = m g - F_ext, the load). Near rest CVODE integrates the contact
    to rtol of its frame, whose length is at least hunt_crossley_rest_depth: its error of x, resolution times
    that, is an error of L resolution depth in E at R, that of a hop of resolution depth, which no run can tell
    from a rest. 0 where the contact never rests: undamped (alpha = 0, E kept), or a load <= 0 (lifted).
    """
    if not (alpha > 0.0 and load > 0.0):
        return 0.0
    return resolution * hunt_crossley_rest_depth(load, m, k, n)


def release_speed(alpha):
    """2 / (3 alpha) [m/s]: the speed above which the Hunt-Crossley force would pull (inf for alpha = 0)."""
    return 2.0 / (3.0 * alpha) if alpha > 0.0 else math.inf


def hunt_crossley_scales(parameters, x, v, load):
    """phase_scales of a Hunt-Crossley contact: a bound on its deepest penetration [m] and on its speed [m/s].

    With delta = -x and the energy per mass e = v^2 / 2 - g_eff delta + (k/m) delta^(n+1) / (n + 1), which
    never grows in contact, the penetration stays below the larger of ((n + 1) 2 e / (k/m))^(1/(n+1)) and
    (2 (n + 1) g_eff / (k/m))^(1/n) (past both, the spring's energy exceeds e + g_eff delta); the speed below
    sqrt(2 (e + g_eff delta_max)), and at least w delta_max with w^2 = n (k/m) delta_max^(n-1), the contact's
    own rate there.
    """
    m, k, R, n = parameters.m, parameters.k, parameters.R, parameters.n
    w2, g_eff = k / m, load / m
    depth = max(-x, 0.0)
    energy = 0.5 * (v * v) - g_eff * depth + w2 * depth ** (n + 1.0) / (n + 1.0)
    deepest = max(abs(x), (2.0 * (n + 1.0) * max(energy, 0.0) / w2) ** (1.0 / (n + 1.0)))
    if g_eff > 0.0:
        deepest = max(deepest, hunt_crossley_rest_depth(load, m, k, n))
    length = min(deepest, SOFT_CONTACT_CAP * max(R, abs(x)))
    fastest = math.sqrt(2.0 * max(energy + max(g_eff, 0.0) * length, 0.0))
    return length, max(abs(v), fastest, math.sqrt(n * w2 * length ** (n - 1.0)) * length)


def hunt_crossley_free_event(parameters, x, v, load):
    """(tau [s], x [m], v [m/s], departs): how the Hunt-Crossley free sub-mode from (x < 0, v) ends, on its parabola.

    Free, the ball rises faster than the release speed 2 / (3 alpha) (its force would pull). It departs
    on R (x = 0, at sqrt(v^2 + 2 g_eff x), energy's) unless its speed falls back to the release speed first
    (g_eff > 0): then it is pressed again there (an engagement).
    """
    g_eff = load / parameters.m
    v_release = release_speed(parameters.alpha)
    disc = v * v + 2.0 * g_eff * x
    tau_departure = -2.0 * x / (v + math.sqrt(disc)) if disc >= 0.0 and v > 0.0 else math.inf
    tau_engage = (v - v_release) / g_eff if g_eff > 0.0 else math.inf
    if tau_departure <= tau_engage:
        return tau_departure, 0.0, math.sqrt(disc), True
    tau_engage = max(tau_engage, 0.0)
    return tau_engage, min(x + (v * v - v_release * v_release) / (2.0 * g_eff), 0.0), v_release, False


def sine_free_event(parameters, x0, u0, load, t0):
    """(tau [s], x [m], u [m/s], departs): the event ending a free spell from (x0 <= 0, u0) at t0 on a vibrating ground.

    In the ground's frame (x = h - R - s, u = v - s'; BallParameters' ground_* fields) the ball flies its parabola
    below the surface, rising faster than the release speed v_r. It departs where x reaches 0 going up: a flight's
    first touch (equations.sine_flight_touch, certified) of -x above the ground -s. It is pressed again (engages)
    where u falls back to v_r: u - v_r = (u0 - v_r) - g_eff tau - (s'(t0 + tau) - s'(t0)) is a weightless flight's
    gap above the ground s' = A w sin(w t + p + pi / 2) from the rate -g_eff - s''(t0), whose first touch is found
    the same way. The first of the two, a departure on a tie; the searches end where one must have come
    (common.surely_below). A spell starting at its release (u = v_r) leaves that level.
    """
    m, amplitude, w, phase = parameters.m, parameters.ground_amplitude, parameters.ground_omega, parameters.ground_phase
    g_eff, v_release = load / m, release_speed(parameters.alpha)
    horizon = surely_below(-x0, -(u0 + sine_value(amplitude, w, phase, t0, 1)), -g_eff, amplitude)
    tau_engage = math.inf
    if v_release < math.inf:
        speed_amplitude, speed_phase, excess = amplitude * w, phase + 0.5 * math.pi, u0 - v_release
        rate = -g_eff - sine_value(speed_amplitude, w, speed_phase, t0, 1)  # of u
        if excess <= 0.0 and rate <= 0.0:  # at (or below) the release speed and not rising: pressed at once
            return 0.0, min(x0, 0.0), v_release, False
        horizon = min(horizon, surely_below(excess, -g_eff, 0.0, speed_amplitude))
        tau_engage = sine_flight_touch(m, speed_amplitude, w, speed_phase, t0, excess, rate, 0.0, horizon,
                                       excess == 0.0)
    tau_depart = sine_flight_touch(m, -amplitude, w, phase, t0, -x0, -u0, -load, min(horizon, tau_engage), False)
    if tau_depart <= tau_engage:
        u = sine_flight_flow(m, amplitude, w, phase, x0, u0, t0, tau_depart, load)[1]
        return tau_depart, 0.0, max(u, 0.0), True
    x = sine_flight_flow(m, amplitude, w, phase, x0, u0, t0, tau_engage, load)[0]
    return tau_engage, min(x, 0.0), v_release, False


def hunt_crossley_jacobian(y0, y1, length, speed, load, m, k, n, alpha):
    """(j00, j01, j10, j11): the Jacobian of scaled_rates in a Hunt-Crossley contact at (y0, y1), where it changes."""
    a_x, a_v = hunt_crossley_partials(length * y0, speed * y1, load, m, k, n, alpha)
    return 0.0, 1.0 * speed / length, a_x * length / speed, a_v


def contact_roots(y0, y1, speed, own_side, alpha):
    """CVODE's three root functions in a pressed contact, in the phase's frame (phases.root_values).

    The gap (departure), v, and 3/2 alpha v - 1, whose crossing upwards is the release (the force's clip
    engaging: 1 + 3/2 alpha delta' turning negative); no rest root: CVODE integrates a contact to its end.
    """
    release = 1.5 * alpha * (speed * y1) - 1.0 if alpha > 0.0 else -1.0
    return y0 if y0 != 0.0 else own_side, y1, release


def hunt_crossley_state(parameters, load, t0, x0, v0, t1, x1, v1, t):
    """(x [m], v [m/s]) at t in a Hunt-Crossley contact's step: the quintic Hermite interpolant of its ends.

    x from (x, v, a) at both ends, v from (v, a, da/dt), with the contact's own equation for a and its
    partials for da/dt = a_x v + a_v a - (the ground's jerk, on a vibrating ground: load [N], m g - F_ext, has the
    ground's acceleration added at each end, equations.load_at): sixth order, so its error inside a step
    (~h^6 y^(6) / 46080) stays below what CVODE controlled over it. Floats.
    """
    h = t1 - t0
    if not h > 0.0:
        return x0, v0
    a0, j0, a1, j1 = _step_ends(parameters, load, t0, x0, v0, t1, x1, v1)
    s = (t - t0) / h
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    s5 = s4 * s
    b0 = 1.0 - 10.0 * s3 + 15.0 * s4 - 6.0 * s5
    b1 = h * (s - 6.0 * s3 + 8.0 * s4 - 3.0 * s5)
    b2 = 0.5 * h * h * (s2 - 3.0 * s3 + 3.0 * s4 - s5)
    b3 = 10.0 * s3 - 15.0 * s4 + 6.0 * s5
    b4 = h * (-4.0 * s3 + 7.0 * s4 - 3.0 * s5)
    b5 = 0.5 * h * h * (s3 - 2.0 * s4 + s5)
    x = b0 * x0 + b1 * v0 + b2 * a0 + b3 * x1 + b4 * v1 + b5 * a1
    v = b0 * v0 + b1 * a0 + b2 * j0 + b3 * v1 + b4 * a1 + b5 * j1
    return x, v


def _step_ends(parameters, load, t0, x0, v0, t1, x1, v1):
    """(a0, j0, a1, j1): the acceleration [m/s2] and its rate [m/s3] at a pressed step's ends, as interpolated."""
    m, k, n, alpha = parameters.m, parameters.k, parameters.n, parameters.alpha
    load0, load1 = load_at(parameters, load, t0), load_at(parameters, load, t1)
    a0 = hunt_crossley_acceleration(x0, v0, load0, m, k, n, alpha)
    a1 = hunt_crossley_acceleration(x1, v1, load1, m, k, n, alpha)
    ax0, av0 = hunt_crossley_partials(x0, v0, load0, m, k, n, alpha)
    ax1, av1 = hunt_crossley_partials(x1, v1, load1, m, k, n, alpha)
    return a0, ax0 * v0 + av0 * a0 - ground_value(parameters, t0, 3), a1, \
        ax1 * v1 + av1 * a1 - ground_value(parameters, t1, 3)


def _step_polynomials(parameters, load, t0, x0, v0, t1, x1, v1):
    """The interpolant's x and v on a step as quintics in s = (t - t0) / h, h = t1 - t0 > 0: coefficients c0 .. c5.

    The quintic Hermite basis in powers of s (x's from the ends' x, h v, h^2 a / 2; v's from v, h a, h^2 (da/dt) / 2).
    """
    h = t1 - t0
    a0, j0, a1, j1 = _step_ends(parameters, load, t0, x0, v0, t1, x1, v1)
    return _hermite(x0, h * v0, 0.5 * h * h * a0, x1, h * v1, 0.5 * h * h * a1), \
        _hermite(v0, h * a0, 0.5 * h * h * j0, v1, h * a1, 0.5 * h * h * j1)


def _horner(p, s):
    return ((((p[5] * s + p[4]) * s + p[3]) * s + p[2]) * s + p[1]) * s + p[0]


def _hermite(y0, d0, c0, y1, d1, c1):
    """The quintic in s matching (y, dy/ds, d2y/ds2 / 2) = (y0, d0, c0) at s = 0 and (y1, d1, c1) at 1: c0 .. c5."""
    return (y0, d0, c0, -10.0 * y0 - 6.0 * d0 - 3.0 * c0 + 10.0 * y1 - 4.0 * d1 + c1,
            15.0 * y0 + 8.0 * d0 + 3.0 * c0 - 15.0 * y1 + 7.0 * d1 - 2.0 * c1,
            -6.0 * y0 - 3.0 * d0 - c0 + 6.0 * y1 - 3.0 * d1 + c1)


def step_exit(parameters, load, t0, x0, v0, t1, x1, v1, margin, to_end):
    """(tau [s], x [m], v [m/s], departs, decided): where a pressed step's interpolant first leaves the contact.

    On a vibrating ground, where the gap is certified on each of CVODE's steps: the interpolant's x rising to 0 (a
    departure, departs True) or its v to the release speed (a release below R), whichever first
    (equations.quintic_exit, exact to rounding on the interpolant), tau after t0; nan where neither within the step
    (to_end False: neither on its last monotonic piece, which ends on CVODE's own root). decided: no turn of x or
    v within margin [m] of its level, below or above it (of v: margin times the step's speed over its depth), up to
    the exit: a graze the motion's error could turn either way.
    """
    h = t1 - t0
    if not h > 0.0:
        return math.nan, x0, v0, True, True
    x_poly, v_poly = _step_polynomials(parameters, load, t0, x0, v0, t1, x1, v1)
    s_depart, x_graze = quintic_exit(x_poly[0], x_poly[1], x_poly[2], x_poly[3], x_poly[4], x_poly[5], 0.0, margin,
                                     to_end)
    s_release, v_graze = math.nan, False
    v_release = release_speed(parameters.alpha)
    if v_release < math.inf:
        rate = (abs(v0) + abs(v1)) / max(abs(x0), abs(x1), margin)
        s_release, v_graze = quintic_exit(v_poly[0], v_poly[1], v_poly[2], v_poly[3], v_poly[4], v_poly[5],
                                          v_release, margin * rate, to_end)
    decided = not (x_graze or v_graze)
    if math.isnan(s_depart) and math.isnan(s_release):
        return math.nan, x1, v1, True, decided
    if not math.isnan(s_depart) and not s_release < s_depart:  # a departure first (or on a tie)
        return s_depart * h, 0.0, max(_horner(v_poly, s_depart), 0.0), True, decided
    return s_release * h, min(_horner(x_poly, s_release), 0.0), v_release, False, decided


def step_transition(parameters, load, t0, x0, v0, t1, x1, v1, t):
    """(p00, p01, p10, p11): the transition matrix of (x, v) over a pressed contact's step, from t0 to t <= t1.

    The contact's equation linearised at the state halfway (its interpolant, hunt_crossley_state): the
    oscillator x'' + 2 sigma x' + w2 x = 0 with sigma = -a_v / 2 and w2 = -a_x (hunt_crossley_partials, both >= 0
    pressed), whose flow of the unit vectors is exact (oscillator.oscillator_basis). Second order in the step: the
    error it carries is first order itself, so a few per cent on it are within the estimate's safety factor.
    """
    m, k, n, alpha = parameters.m, parameters.k, parameters.n, parameters.alpha
    tau = t - t0
    xm, vm = hunt_crossley_state(parameters, load, t0, x0, v0, t1, x1, v1, t0 + 0.5 * tau)
    a_x, a_v = hunt_crossley_partials(xm, vm, load, m, k, n, alpha)
    sigma, w2 = max(-0.5 * a_v, 0.0), max(-a_x, 0.0)
    c, s = oscillator_basis(sigma, w2, tau)
    return c + sigma * s, s, -w2 * s, c - sigma * s


# The law's entry in the registry (contact_laws.LAWS).
LAW = ContactLaw("hunt-crossley", HUNT_CROSSLEY, ("k", "n", "alpha"), closed_form=False,
                 description="k delta^n (1 + 3/2 alpha delta'), clipped at 0",
                 article_algorithm=True, crossings_only=False, k_unit="N/m^{n:g}", damping_axis="alpha",
                 summary="Hunt-Crossley contact, k = {k:g} N/m^{n:g}, n = {n:g}, alpha = {alpha:g} s/m")
