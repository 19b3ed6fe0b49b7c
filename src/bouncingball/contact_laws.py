"""The contact laws: their codes, and each law's own formulas as functions of plain floats.

- linear (the default): the article's spring k and damper b; the damper may pull just before departure.
- rigid: the ball does not deform (k and b play no part); at each impact on R its velocity reverses,
  v+ = -e v-. With v_min = 0 and e < 1 it makes infinitely many ever smaller bounces before it rests on R
  at the Zeno time t_k + 2 v_k / (g (1 - e)) after a bounce leaving at v_k (those lower than ZENO_APEX R
  are summed as the geometric series they are); with v_min > 0 it stops on R at the first bounce that
  would leave slower than v_min (the Reference-FMUs' BouncingBall). A resting ball leaves when F_ext
  exceeds m g.
- linear-no-pull: the ground never pulls, its force max(0, k (R - h) - b v) (Modelica's ElastoGap); below
  R the ball is pressed (Mode.CONTACT) while that force is positive and free (Mode.FREE, the flight's
  parabola) where it would pull, switching where k (R - h) - b v crosses 0. With b = 0 it is the linear law.
- hunt-crossley: Hunt and Crossley's k delta^n (1 + 3/2 alpha delta'), delta = R - h, clipped at 0 (free
  above the release speed 2 / (3 alpha)); no closed form, so CVODE integrates every contact.

The functions take Ball.parameters (the law's code at [5]), a state and the load, and return floats: run
interpreted and compiled alike (solvers/jit.py's rules), they dispatch on the law where the laws differ.
"""

from __future__ import annotations

import math

from .equations import gap_acceleration, gap_flow_value, rest_margin_value

# The contact laws (Ball.contact) and the codes the phase machine knows them by (Ball.parameters).
CONTACT_LAWS = ("linear", "rigid", "linear-no-pull", "hunt-crossley")
LINEAR, RIGID, NO_PULL, HUNT_CROSSLEY = 0, 1, 2, 3
# The parameters each law reads besides the ball's m, R and g (physics.Ball's fields): another law's parameter set
# to a value other than Ball's default is refused by name (Ball, the CLI, scene files), logged by the FMU. The
# rigid law reads neither k nor b (its scales are R and the flight's); Hunt-Crossley's damping is alpha, not b.
LAW_PARAMETERS = {"linear": ("k", "b"), "rigid": ("e", "v_min"), "linear-no-pull": ("k", "b"),
                  "hunt-crossley": ("k", "n", "alpha")}
CONTACT_PARAMETERS = ("k", "b", "e", "v_min", "n", "alpha")  # every law's, in Ball's order
# The Hunt-Crossley law's exponent n: 1 (a linear spring) .. 2.5 (beyond Hertz's 1.5 for spheres, as fitted
# to soft and granular materials); its release speed is 2 / (3 alpha).
HC_N_RANGE = (1.0, 2.5)


ZENO_APEX = 2.0**-40


def rigid_rebound(parameters, v_impact, load):
    """(v_after [m/s], zeno [s]): the rigid law's bounce after an impact at v_impact < 0 on R (Ball.parameters).

    v_after = -e v_impact, or 0 where the ball stays on R: below v_min, or where the bounces from
    there rise less than ZENO_APEX R (e < 1, a load on the ground). Their infinitely many impacts then
    take zeno = 2 v / (g_eff (1 - e)) [s] in all (v = -e v_impact, g_eff = load / m), after which the
    ball rests on R: the Zeno time is the impact's time + zeno. zeno is 0 where none are summed.
    """
    return rigid_rebound_above(parameters, v_impact, load, ZENO_APEX * parameters[3])


def rigid_rebound_above(parameters, v_impact, load, apex_floor):
    """rigid_rebound, with the bounces that rise less than apex_floor [m] (rather than ZENO_APEX R) summed."""
    e, v_min = parameters[6], parameters[7]
    v_after = -e * v_impact
    if v_after < v_min:
        return 0.0, 0.0
    g_eff = load / parameters[0]
    if g_eff > 0.0 and e < 1.0 and v_after * v_after <= 2.0 * g_eff * apex_floor:
        return 0.0, 2.0 * v_after / (g_eff * (1.0 - e))
    return v_after, 0.0


def summed_bounce_state(parameters, v_first, load, tau):
    """(x [m], v [m/s]) of a rigid ball tau [s] after the impact whose bounces rigid_rebound summed (Ball.parameters).

    Its bounces leave R at v_first e^j, j = 0, 1, ..., under the constant load [N]; the j-th leaves at
    S_j = 2 v_first (1 - e^j) / (g_eff (1 - e)), and from the Zeno time S_inf on the ball rests, (0, 0). Each is
    lower than ZENO_APEX R, so the ball is taken on R while they last; this is where it truly is, for a change
    of F_ext inside that time: a lift there leaves with the bounce's speed, not from rest.
    """
    e, g_eff = parameters[6], load / parameters[0]
    scale = 2.0 * v_first / (g_eff * (1.0 - e))  # S_inf
    if not tau < scale:
        return 0.0, 0.0
    j = max(int(math.floor(math.log1p(-tau / scale) / math.log(e))), 0)  # e^j >= 1 - tau / S_inf
    while j > 0 and scale * (1.0 - e**j) > tau:  # the rounding of the logarithms, either way
        j -= 1
    while scale * (1.0 - e ** (j + 1)) <= tau:
        j += 1
    s, v_j = tau - scale * (1.0 - e**j), v_first * e**j
    return max(s * (v_j - 0.5 * g_eff * s), 0.0), v_j - g_eff * s


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


def no_pull_rest_margin_value(x, v, d, hop_tolerance, w2, sigma):
    """w2^2 (d + hop)^2 - (w2 + 4 sigma^2)(v^2 + w2 y^2) [m2/s4]: positive once a pressed no-pull ball never leaves.

    y = x + d, the deflection from the rest height. The force is k (d - y) - b v, and it reaches 0 where
    w2 y + 2 sigma v = w2 d; by Cauchy-Schwarz w2 y + 2 sigma v <= sqrt(w2 + 4 sigma^2) sqrt(v^2 + w2 y^2),
    and the energy v^2 + w2 y^2 never grows in contact (nor in the free sub-mode), so once the margin is
    positive with hop = 0 the force stays positive for ever. hop [m] (the hop tolerance) lets the force
    dip to -k hop at most, a pull the run may merge as it merges a hop. Written as
    w2^2 (hop - x)(2 d + hop + x) - 4 sigma^2 w2 y^2 - (w2 + 4 sigma^2) v^2, which keeps x's digits.
    """
    y = x + d
    return w2 * w2 * ((hop_tolerance - x) * (2.0 * d + hop_tolerance + x)) - 4.0 * sigma * sigma * w2 * (y * y) \
        - (w2 + 4.0 * sigma * sigma) * (v * v)


def law_flow_value(parameters, mode, x0, v0, tau, load):
    """gap_flow_value under the ball's contact law (parameters: Ball.parameters): a rigid ball in contact rests.

    Under the rigid law the contact mode is the ball resting on R, where it stays (x0, v0 = 0, 0).
    """
    if mode == 1 and parameters[5] == RIGID:
        return x0 + 0.0 * tau, v0 + 0.0 * tau
    if mode == 1 and parameters[5] == HUNT_CROSSLEY:  # no closed form: never asked for (NaN if it were)
        return x0 + math.nan * tau, v0 + math.nan * tau
    return gap_flow_value(mode, x0, v0, tau, load, parameters[0], parameters[1], parameters[2])


# Under the rigid law with v_min = 0, the bounces after one whose apex is below ZENO_APEX R are summed as
# the geometric series they are: their heights are below any resolution, their count without end.
def conserved_speed(parameters, mode, x_start, v_start):
    """Whether a phase from the gap x_start [m] at v_start [m/s] in mode ends on R at -v_start exactly.

    It does where it starts on R leaving its own side (up in flight, down in contact) and its exact
    flow conserves energy (a flight; a contact with b = 0): the phase machine's polish and the exact
    solver then give the event that speed, not their flows' rounded one, which added up over many
    bounces to an energy drift. parameters: Ball.parameters.
    """
    if x_start != 0.0:
        return False
    if parameters[5] == HUNT_CROSSLEY:  # alpha = 0: the Hertz contact conserves energy, its force 0 on R
        return v_start > 0.0 if mode == 0 else (v_start < 0.0 and parameters[9] == 0.0)
    return v_start > 0.0 if mode == 0 else (v_start < 0.0 and parameters[2] == 0.0)


def pressed_gap(parameters, x, v, load):
    """(z [m], dz/dt [m/s]) of the pressed no-pull contact at the gap x [m] and v [m/s]: z = x + (b / k) v = -force / k.

    The force k (R - h) - b v = -k z reaches 0 where z crosses 0: going up the ball is released (the
    force would pull), going down it is pressed again. z obeys the pressed contact's own equation
    (z'' + 2 sigma z' + w2 z = -g_eff, as x does), so its crossing upwards is the linear law's departure
    search of (z, dz/dt) (exact.departure_time); in the free sub-mode it moves on the flight's parabola
    from (z, dz/dt) too, and its crossing downwards is an impact's. dz/dt = v + (b / k) a, with a the
    pressed contact's acceleration. parameters: Ball.parameters.
    """
    m, k, b = parameters[0], parameters[1], parameters[2]
    c = b / k
    return x + c * v, v + c * gap_acceleration(x, v, 1, load, m, k, b)


def free_gap_rate(parameters, v, load):
    """dz/dt [m/s] in the free sub-mode at v [m/s]: v - (b / k) g_eff (pressed_gap's z on the parabola)."""
    return v - (parameters[2] / parameters[1]) * (load / parameters[0])


def law_rest_margin(parameters, x, v, d, hop_tolerance):
    """The rest margin under the ball's contact law (parameters: Ball.parameters); see rest_margin_value."""
    m, k = parameters[0], parameters[1]
    if parameters[5] == NO_PULL:
        return no_pull_rest_margin_value(x, v, d, hop_tolerance, k / m, parameters[2] / (2.0 * m))
    return rest_margin_value(x, v, d, hop_tolerance, k / m)


def starts_free(parameters, x, v, load):
    """Whether a ball below R (the gap x [m] < 0, v [m/s]) starts in the free sub-mode (Mode.FREE), not pressed.

    Under the no-pull law where its force would pull, or is 0 and turning so (pressed_gap's z); under the
    Hunt-Crossley law where 1 - 3/2 alpha v < 0 (rising faster than the release speed), or = 0 with the
    load [N] < 0 (a lift past the weight: v grows past it). Never under the other laws.
    """
    if parameters[5] == HUNT_CROSSLEY:
        factor = 1.0 - 1.5 * parameters[9] * v
        return factor < 0.0 or (factor == 0.0 and load < 0.0)
    if parameters[5] != NO_PULL:
        return False
    z, rate = pressed_gap(parameters, x, v, load)
    return z > 0.0 or (z == 0.0 and rate > 0.0)
