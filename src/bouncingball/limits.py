"""The inputs double precision can resolve: a scene outside them is refused before any work.

Every solver forms squares: the damping rate's in the oscillator's characteristic equation
(sigma^2 - k/m), the speed's and the deflection's in the rest test (v^2 + (k/m) y^2), the
amplitude's (y^2 + v^2 m/k), the energies m v^2 and k (R - h)^2. A double overflows at 1.8e308;
a scene whose squares pass it gives overflow errors, NaN or a CVODE that never ends (its root
functions are inf - inf). So a scene must keep each square below SQUARE_LIMIT = 1e300, eight
decades of headroom for the sums and small factors the solvers add, and each quantity so squared
below SCALE_LIMIT = 1e150; a height in flight, never squared, below HEIGHT_LIMIT = 1e300 m. The
bounds hold for the whole run, by the oscillator's energy, which never grows in contact, and the
flight's, which is conserved until the next impact.

The output grid needs distinct, increasing times: its spacing must be several ulps of the
largest time on it.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from . import validation
from .physics import Ball
from .validation import exact

SQUARE_LIMIT = 1e300  # any square the solvers form: [m2/s2], [1/s2], [m2], and the energies [J]
SCALE_LIMIT = 1e150  # its square root: lengths in contact [m], speeds [m/s], rates [1/s]
HEIGHT_LIMIT = 1e300  # m: a height in flight is never squared, only added to and multiplied by small factors
MIN_RATE_SQUARED = 1e-300  # k/m [1/s2] below it: m/k overflows in the amplitude y^2 + v^2 m/k
MIN_GRID_ULPS = 4.0  # output points t_start + i dt, each rounded by <= 1.5 ulps: > 3 ulps apart
# Measured with CVODE in absolute time: at the default tolerances the departure speed stayed within
# 1e-8 down to contacts of 30 ulps of t (at 10 ulps CVODE failed its error test); 1e4 keeps a margin of 300.
MIN_CONTACT_ULPS = 1e4


# CVODE's settings, by the scene's scales. An error bound of h finer than the spacing of doubles at the
# ball's height scale is not one double precision can hold (h = R + x rounds to half an ulp of h); far
# below it the state scaled by atol / rtol overflowed (atol = 1e-320: CVODE failed at t = 0). The work-
# precision benchmark's tightest, 1e-15 m on the article from 2 m, is 2.3 ulps.
MIN_ATOL_ULPS = 1.0
# A max_step asking for more steps than this over the run (1 to 20 us each: minutes to hours) is refused;
# a subnormal one never returned (CVODE divides by it, and 1 / 1e-320 overflows).
MAX_STEPS_BY_MAX_STEP = 1e7


def check_cvode_settings(ball: Ball, h0: float, atol: float | None, max_step: float, t_start: float,
                         t_end: float | None = None) -> None:
    """Raise ValueError naming atol or max_step if CVODE cannot honour it in this scene; else return None.

    atol [m]: None or 0 (none), or at least an ulp (MIN_ATOL_ULPS) of the height scale max(|h0|, R).
    max_step [s]: 0 (none), or a normal double at least MIN_GRID_ULPS ulps of |t_start| (and of |t_end|),
    and with t_end at least (t_end - t_start) / MAX_STEPS_BY_MAX_STEP. h0, t_start, t_end: checked floats.
    """
    scale = max(abs(h0), ball.R)
    validation.zero_or_at_least("atol", 0.0 if atol is None else atol, MIN_ATOL_ULPS * math.ulp(scale), "m",
                                f"the spacing of doubles at the height scale max(|h0|, R) = {scale!r} m: double "
                                "precision holds h no closer")
    latest = max(abs(t_start), abs(t_start if t_end is None else t_end))
    smallest = max(sys.float_info.min, MIN_GRID_ULPS * math.ulp(latest))
    why = f"a normal double, >= {MIN_GRID_ULPS:g} ulps of t = {latest!r} s, so that a step advances t"
    if t_end is not None and (t_end - t_start) / MAX_STEPS_BY_MAX_STEP > smallest:
        smallest = (t_end - t_start) / MAX_STEPS_BY_MAX_STEP
        why = (f"that is (t_end - t_start) / {MAX_STEPS_BY_MAX_STEP:.0e}: a smaller one asks for more than "
               f"{MAX_STEPS_BY_MAX_STEP:.0e} steps")
    validation.zero_or_at_least("max_step", max_step, smallest, "s", why)


def min_output_interval(t_start: float, t_end: float) -> float:
    """The smallest output interval [s] whose grid from t_start to t_end has distinct increasing times.

    MIN_GRID_ULPS ulps of the largest |t| on the grid: below that, t_start + i dt rounds to repeated
    or decreasing times.
    """
    return MIN_GRID_ULPS * math.ulp(max(abs(t_start), abs(t_end)))


def check_output_interval(t_start: float, t_end: float, output_interval: float) -> None:
    """Raise ValueError naming output_interval if it is below min_output_interval(t_start, t_end)."""
    smallest = min_output_interval(t_start, t_end)
    if not output_interval >= smallest:
        raise ValueError(
            f"output_interval = {output_interval!r} s is not allowed from t_start = {t_start!r} s to "
            f"t_end = {t_end!r} s: it must be >= {exact(smallest)} s ({MIN_GRID_ULPS:g} ulps of "
            f"{max(abs(t_start), abs(t_end))!r} s): double precision cannot hold distinct increasing times "
            "closer than that")


def check_scene(ball: Ball, h0: float, v0: float, F_ext: float = 0.0, t_start: float = 0.0,
                t_end: float | None = None, output_interval: float | None = None, rtol: float | None = None) -> None:
    """Raise ValueError if double precision cannot resolve this scene; else return None.

    The resolvable range, checked in this order (each bound holds given the ones before it):

    - b/(2m) <= 1e150 1/s: the damping rate sigma, squared in sigma^2 - k/m.
    - 1e-300 <= k/m <= 1e300 1/s2: the oscillator's w^2 and its inverse m/k.
    - R <= 1e150 m.
    - (g - F_ext/m)^2 m/k <= B: the oscillator's energy at R, where B = 1e300 min(1, 1/m, k/m) m2/s2
      keeps the speed^2 below 1e300 m2/s2, the energy m v^2 below 1e300 J and the contact's
      amplitude below 1e150 m. m, k and g are named together, with a bound on each that fixes it (g alone
      where m and k cannot), or F_ext if F_ext takes it out of range.
    - h0's part of the energy below B: (k/m) (h0 - R + d)^2 starting in contact (d the static
      deflection), 2 (g - F_ext/m) (h0 - R) + (k/m) d^2 falling onto the spring; h0 <= 1e300 m.
    - v0^2 plus that below B.
    - Hunt-Crossley's alpha below the bound check_alpha gives at the scene's largest contact speed
      (with rtol: also a release speed CVODE resolves).
    - With t_end: t_end - t_start finite; the ball's reach over the run (how far it can fly away with
      the speed it has, pulled up if F_ext > m g) below 1e300 m, and its speed^2 and m v^2 below 1e300.
    - With output_interval: at least MIN_GRID_ULPS ulps of max(|t_start|, |t_end|).

    Parameters
    ----------
    ball : Ball
        The ball.
    h0, v0 : float
        Height [m] and velocity [m/s] at t_start.
    F_ext : float, optional
        External force [N], finite.
    t_start : float, optional
        Start time [s].
    t_end : float, optional
        End time [s], > t_start; None (a stepping integrator): no rule on the run's length.
    output_interval : float, optional
        The output grid's spacing [s]; None: no grid.
    rtol : float, optional
        CVODE's relative tolerance, a checked float; None: no rule that depends on it.

    Raises
    ------
    ValueError
        Naming the field, its value and the range it must be in, and the quantity that breaks.

    Examples
    --------
    >>> from bouncingball import Ball
    >>> check_scene(Ball(), h0=2.0, v0=0.0, t_end=8.0, output_interval=1e-3)
    >>> check_scene(Ball(R=1e300), h0=2.0, v0=0.0)
    Traceback (most recent call last):
    ...
    ValueError: R = 1e+300 m is not allowed: it must be <= 1e+150 m ...
    >>> check_scene(Ball(b=0.0), h0=-1e200, v0=0.0)
    Traceback (most recent call last):
    ...
    ValueError: h0 = -1e+200 m is not allowed for this ball (...): it must be in [-1e+148, 5.09683995922528e+298] m; ...
    """
    h0, v0 = validation.finite("h0", h0, "m"), validation.finite("v0", v0, "m/s")
    F_ext, t_start = validation.finite("F_ext", F_ext, "N"), validation.finite("t_start", t_start, "s")
    if t_end is not None:
        t_end = validation.finite("t_end", t_end, "s")
    m, k, b, R = ball.m, ball.k, ball.b, ball.R
    about = f"m = {m:g} kg, k = {k:g} N/m, R = {R:g} m"

    # --- the ball ------------------------------------------------------------------------------
    sigma = b / (2.0 * m)
    if not sigma <= SCALE_LIMIT:
        raise ValueError(f"b = {b!r} N s/m is not allowed with m = {m!r} kg: it must be <= "
                         f"{exact(2.0 * SCALE_LIMIT * m)} N s/m (the damping rate b/(2m) = {sigma:.4g} 1/s must be "
                         f"<= {SCALE_LIMIT:g} 1/s: its square, in the contact's characteristic equation, would "
                         "overflow)")
    w2 = k / m
    if not MIN_RATE_SQUARED <= w2 <= SQUARE_LIMIT:
        raise ValueError(f"k = {k!r} N/m is not allowed with m = {m!r} kg: it must be in "
                         f"[{exact(MIN_RATE_SQUARED * m)}, {exact(SQUARE_LIMIT * m)}] N/m (k/m = {w2:.4g} 1/s2 must "
                         "be in "
                         f"[{MIN_RATE_SQUARED:g}, {SQUARE_LIMIT:g}] 1/s2, or the oscillator's w^2 or m/k overflows)")
    if not R <= SCALE_LIMIT:
        raise ValueError(f"R = {R!r} m is not allowed: it must be <= {SCALE_LIMIT:g} m (lengths are squared in the "
                         "contact's energy k (R - h)^2 and the rest test, and would overflow)")
    budget = SQUARE_LIMIT * min(1.0, 1.0 / m, w2)  # [m2/s2]; see the docstring
    why = (f"the oscillator's energy per unit mass, v^2 + (k/m) y^2, must stay <= {budget:.4g} m2/s2, so that no "
           f"speed^2, energy m v^2 [J] or amplitude^2 [m2] passes {SQUARE_LIMIT:g}")

    # --- the force --------------------------------------------------------------------------------
    g_eff = ball.g - F_ext / m
    g_max = math.sqrt(budget * w2)  # (g_eff^2 / w2 <= budget): the energy at R, (k/m) d^2
    if not abs(g_eff) <= g_max:
        rest = f"the energy at R, (g - F_ext/m)^2 m/k = {g_eff * g_eff / w2:.4g} m2/s2, is out of range: {why}"
        if F_ext == 0.0 or not ball.g <= g_max:
            raise ValueError(_weight_out_of_range(ball, F_ext, g_eff, g_max, rest))
        raise ValueError(f"F_ext = {F_ext!r} N is not allowed for this ball ({about}, g = {ball.g:g} m/s2): it must "
                         f"be in [{exact(m * (ball.g - g_max))}, {exact(m * (ball.g + g_max))}] N ({rest})")
    d = g_eff / w2  # the static deflection [m]

    # --- the start state ------------------------------------------------------------------------------
    low = R - d - math.sqrt(budget / w2)
    high = HEIGHT_LIMIT if g_eff <= 0.0 else min(HEIGHT_LIMIT, R + (budget - w2 * d * d) / (2.0 * g_eff))
    energy = _energy_of_height(ball, h0, v0, F_ext, w2, d, g_eff)
    if not (h0 <= HEIGHT_LIMIT and energy <= budget):
        raise ValueError(f"h0 = {h0!r} m is not allowed for this ball ({about}): it must be in [{exact(low)}, "
                         f"{exact(high)}] m; {why} (from h0 alone it is {_amount(energy)})")
    v_max = math.sqrt(budget - energy)
    if not abs(v0) <= v_max:
        raise ValueError(f"v0 = {v0!r} m/s is not allowed from h0 = {h0!r} m for this ball ({about}): it must be in "
                         f"[{exact(-v_max)}, {exact(v_max)}] m/s; {why}")
    check_alpha(ball, h0, v0, g_eff, rtol)

    # --- the run --------------------------------------------------------------------------------------
    if t_end is None:
        return
    span = t_end - t_start
    if not math.isfinite(span):
        raise ValueError(f"t_end = {t_end!r} s is not allowed with t_start = {t_start!r} s: t_end - t_start "
                         "must be finite (<= 1.8e308 s)")
    speed = math.sqrt(energy + v0 * v0)
    span_max = _longest_run(g_eff, speed, max(abs(h0), R), SQUARE_LIMIT * min(1.0, 1.0 / m))
    if not span <= span_max:
        raise ValueError(f"t_end = {t_end!r} s is not allowed for this scene (h0 = {h0!r} m, v0 = {v0!r} m/s, "
                         f"g - F_ext/m = {g_eff:.4g} m/s2): it must be <= t_start + {exact(span_max)} s; the ball "
                         f"flies away from the ground, and later its height would pass {HEIGHT_LIMIT:g} m or its "
                         f"speed^2 or energy m v^2 {SQUARE_LIMIT:g}")
    if output_interval is not None:
        check_output_interval(t_start, t_end, output_interval)


def largest_contact_speed(ball: Ball, h0: float, v0: float, g_eff: float) -> float:
    """A bound [m/s] on the speed of a Hunt-Crossley ball in contact, from its energy under g_eff = g - F_ext/m.

    Per unit mass, e = v^2 / 2 + g_eff (h - R) + (k/m) delta^(n+1) / (n + 1), delta = max(R - h, 0), is kept in
    flight and never grows in contact (contact_laws.hunt_crossley_rest_margin): the ball reaches R at sqrt(2 e)
    at most, and is fastest in contact at the static deflection d = (g_eff / (k/m))^(1/n), where
    v^2 = 2 e + 2 g_eff d n / (n + 1). 0 for a ball above R that never comes down (g_eff <= 0, v0 >= 0).
    """
    m, k, R, n = ball.m, ball.k, ball.R, ball.n
    if h0 >= R and g_eff <= 0.0 and v0 >= 0.0:
        return 0.0
    depth = max(R - h0, 0.0)
    twice_energy = v0 * v0 + 2.0 * g_eff * (h0 - R) + 2.0 * (k / m) * depth ** (n + 1.0) / (n + 1.0)
    if g_eff > 0.0:
        twice_energy += 2.0 * g_eff * (g_eff * m / k) ** (1.0 / n) * n / (n + 1.0)
    return math.sqrt(max(twice_energy, 0.0))


def check_alpha(ball: Ball, h0: float, v0: float, g_eff: float, rtol: float | None = None) -> None:
    """Raise ValueError naming alpha if the Hunt-Crossley law's damping cannot be resolved in this scene.

    With v the scene's largest contact speed (largest_contact_speed) and alpha > 0:

    - 3/2 alpha v <= SCALE_LIMIT: the force's factor 1 + 3/2 alpha delta', multiplied by k delta^n, would
      overflow beyond it.
    - with rtol, the release speed 2 / (3 alpha) >= rtol v: CVODE resolves a contact's speed to about rtol of
      its impact speed, so it cannot tell a slower release (where the force would pull) from a rest, nor
      integrate the contact it ends (the damping stiffer than any step CVODE can take).

    So alpha <= min(2 SCALE_LIMIT / (3 v), 2 / (3 rtol v)) s/m; other laws, and alpha = 0, have no rule.
    """
    if not (ball.hunt_crossley and ball.alpha > 0.0):
        return
    speed = largest_contact_speed(ball, h0, v0, g_eff)
    if speed == 0.0:
        return
    overflow = 2.0 * SCALE_LIMIT / (3.0 * speed)
    release = math.inf if rtol is None else 2.0 / (3.0 * rtol * speed)
    if ball.alpha <= min(overflow, release):
        return
    scene = (f"h0 = {h0!r} m, v0 = {v0!r} m/s, g - F_ext/m = {g_eff:.4g} m/s2: a contact speed up to "
             f"{speed:.4g} m/s")
    if release < overflow:
        why = (f"its release speed 2 / (3 alpha) = {2.0 / (3.0 * ball.alpha):.3g} m/s must be >= rtol = {rtol:g} "
               f"times that speed, which CVODE resolves; lower alpha, or tighten rtol (a tighter rtol resolves a "
               f"slower release)")
    else:
        why = f"3/2 alpha v must stay <= {SCALE_LIMIT:g}, or the force k delta^n (1 + 3/2 alpha v) overflows"
    raise ValueError(f"alpha = {ball.alpha!r} s/m is not allowed for this scene ({scene}): it must be in "
                     f"[0, {exact(min(overflow, release))}] s/m; {why}")


def check_forces(ball: Ball, h0: float, v0: float, forces, t_start: float = 0.0, t_end: float | None = None,
                 output_interval: float | None = None, rtol: float | None = None) -> None:
    """check_scene for each of the forces [N] a table holds (a scene per force), in time linear in their number.

    check_scene depends on the force through g_eff = g - F_ext/m alone, and every rule but the run's length
    bounds a quantity convex in g_eff (g_eff itself, the energies, the largest contact speed): where a force
    breaks one, the smallest or the largest force breaks one too, so those two are checked. The run's length
    (with t_end) is shortest at the most negative g_eff where the ball flies away, and at least
    (HEIGHT_LIMIT - max(|h0|, R)) / (the largest speed) where it comes back: only a run longer than that
    (beyond 1e140 s for realistic scenes) has every force checked.
    """
    values = np.asarray(forces, dtype=float)
    low, high = float(values.min()), float(values.max())
    for force in sorted({low, high}):
        check_scene(ball, h0, v0, force, t_start, t_end, output_interval, rtol)
    if t_end is None or t_end - t_start <= _shortest_run(ball, h0, v0, low, high):
        return
    for force in np.unique(values).tolist():
        check_scene(ball, h0, v0, force, t_start, t_end, output_interval, rtol)


def _shortest_run(ball: Ball, h0: float, v0: float, low: float, high: float) -> float:
    """A lower bound [s] on check_scene's longest run for every force in [low, high] [N] (check_forces)."""
    m, w2, start = ball.m, ball.k / ball.m, max(abs(h0), ball.R)
    g_low, g_high = ball.g - high / m, ball.g - low / m
    speed_low, speed_high = (math.sqrt(_energy_of_height(ball, h0, v0, force, w2, g_eff / w2, g_eff) + v0 * v0)
                             for force, g_eff in ((high, g_low), (low, g_high)))
    fastest = max(speed_low, speed_high)
    shortest = (HEIGHT_LIMIT - start) / fastest if fastest > 0.0 else math.inf
    if g_low <= 0.0:  # the fastest flight away, at the largest speed of the flights away
        shortest = min(shortest, _longest_run(g_low, speed_low, start, SQUARE_LIMIT * min(1.0, 1.0 / m)))
    return shortest


def _weight_out_of_range(ball: Ball, F_ext: float, g_eff: float, g_max: float, rest: str) -> str:
    """m, k and g (with F_ext) that together put the energy at R out of range, and the bound on each that fixes it.

    Each bound keeps the other inputs as they are: |g - F_ext/m| <= g_max; with F_ext = 0, m below the
    least of the three sides of the energy's bound (per unit mass, in joules, as an amplitude); k above
    their greatest. A bound the ball's own ranges (k/m, b/(2m)) would refuse is left out.
    """
    m, k, b, g = ball.m, ball.k, ball.b, ball.g
    low, high = max(0.0, F_ext / m - g_max), F_ext / m + g_max
    fixes = [f"g <= {exact(high)} m/s2" if low == 0.0 else f"g in [{exact(low)}, {exact(high)}] m/s2"]
    if F_ext == 0.0:
        m_max = min((SQUARE_LIMIT / g) * (k / g), SCALE_LIMIT * math.sqrt(k) / g, SCALE_LIMIT * k / g)
        if m_max > 0.0 and k / m_max <= SQUARE_LIMIT and b / (2.0 * m_max) <= SCALE_LIMIT:
            fixes.append(f"m <= {exact(m_max)} kg")
    k_min = max(g_eff * g_eff * m / SQUARE_LIMIT, g_eff * g_eff * m * (m / SQUARE_LIMIT), abs(g_eff) * m / SCALE_LIMIT)
    if k_min / m <= SQUARE_LIMIT:
        fixes.append(f"k >= {exact(k_min)} N/m")
    force = f", F_ext = {F_ext!r} N" if F_ext else ""
    return (f"m = {m!r} kg, k = {k!r} N/m and g = {g!r} m/s2{force} are not allowed together (R = {ball.R:g} m): "
            f"{rest}; change one: {', '.join(fixes[:-1])} or {fixes[-1]}" if len(fixes) > 1 else
            f"g = {g!r} m/s2 is not allowed for this ball (m = {m!r} kg, k = {k!r} N/m{force}): it must be "
            f"{fixes[0][2:]} ({rest})")


def _amount(energy: float) -> str:
    return "beyond 1.8e308: it overflows" if math.isinf(energy) else f"{energy:.4g} m2/s2"


def _energy_of_height(ball: Ball, h0: float, v0: float, F_ext: float, w2: float, d: float, g_eff: float) -> float:
    """The start height's part of the oscillator's largest energy per unit mass [m2/s2] (v0^2 to be added).

    In contact (k/m) y0^2, y0 = h0 - R + d the deflection from the rest height; in flight the energy at
    the next impact, 2 g_eff (h0 - R) + (k/m) d^2 (the fall's kinetic energy, the spring's at R).
    """
    if h0 < ball.R or ball.initial_mode(h0, v0, F_ext) == 1:  # below R (pressed or free), or Mode.CONTACT
        y0 = (h0 - ball.R) + d
        return w2 * y0 * y0 if abs(y0) <= SCALE_LIMIT else math.inf
    fall = 2.0 * g_eff * (h0 - ball.R) if g_eff > 0.0 else 0.0
    return fall + w2 * d * d


def _longest_run(g_eff: float, speed: float, start: float, speed_squared_limit: float) -> float:
    """The longest run [s] before the ball is HEIGHT_LIMIT from the ground or its speed^2 passes the limit.

    g_eff > 0: the ball comes back, its speed bounded by `speed` (energy); its height by the apex
    unless time runs out first. g_eff <= 0: it flies away, accelerating at -g_eff.
    """
    room = HEIGHT_LIMIT - start
    if g_eff > 0.0:
        if 0.5 * speed * speed / g_eff <= room:  # the apex of any flight is in range
            return math.inf
        return room / speed
    a = -g_eff
    limit = math.sqrt(speed_squared_limit)
    by_speed = math.inf if a == 0.0 else (limit - speed) / a
    if speed == 0.0 and a == 0.0:
        return math.inf
    # 0.5 a T^2 + speed T = room, without cancellation
    by_reach = 2.0 * room / (speed + math.sqrt(speed * speed + 2.0 * a * room))
    return min(by_speed, by_reach)


__all__ = ["HEIGHT_LIMIT", "MIN_GRID_ULPS", "SCALE_LIMIT", "SQUARE_LIMIT", "check_alpha", "check_cvode_settings",
           "check_forces", "check_output_interval", "check_scene", "largest_contact_speed", "min_output_interval"]


def contact_duration(ball: Ball) -> float:
    """pi / omega_d [s]: how long a bouncing contact lasts (inf when the contact is critically or over-damped).

    omega_d = sqrt(k/m - (b/2m)^2). At damping ratio >= 1 a contact never ends by itself.
    """
    sigma = ball.b / (2.0 * ball.m)
    omega_d2 = ball.k / ball.m - sigma * sigma
    return math.pi / math.sqrt(omega_d2) if omega_d2 > 0.0 else math.inf


def resolvable_until(ball: Ball) -> float:
    """The latest time [s] up to which double precision can resolve a contact of this ball.

    Near time t, double precision separates instants 1 ulp (~2.2e-16 t) apart. A contact shorter
    than MIN_CONTACT_ULPS ulps of t cannot be resolved: its impact and departure fall on the same
    few representable times, the exact solution's phases stop advancing t (it never ends), and
    CVODE, which located roots in absolute time, missed or invented events and gained energy.
    """
    return contact_duration(ball) / (MIN_CONTACT_ULPS * 2.0**-52)


def check_resolvable(ball: Ball, t: float) -> None:
    """Raise ValueError if a contact of this ball cannot be resolved at time t [s]."""
    t = float(t)
    limit = resolvable_until(ball)
    if abs(t) > limit:
        duration = contact_duration(ball)
        raise ValueError(
            f"k = {ball.k!r} N/m with m = {ball.m!r} kg is not allowed up to t = {t!r} s: a contact lasts "
            f"{duration:.3g} s, but double precision resolves time only to {math.ulp(t):.3g} s there "
            f"(a contact must span {MIN_CONTACT_ULPS:g} ulps of t). Shorten the run to t <= {exact(limit)} s, "
            "or lower k or raise m (a longer contact)")
