"""The Hunt-Crossley ball's coefficient of restitution against impact speed, beside its analytic approximations.

Needs: pip install -e '.[plot,reference]' in the checkout (matplotlib for the figure, SciPy's brentq for the
separable impact).
Usage: python hunt_crossley_restitution.py [OUTPUT_DIR]   (writes hunt_crossley_restitution.png there)

The benchmark's ball (m = 1 kg, R = 6 cm, k = 1e6 N/m^1.5, n = 1.5) dropped so that it meets the ground at
each impact speed, for three values of alpha; e = departure speed over impact speed of its first bounce, run
by CVODE (simulate). Beside it, two approximations of an impact without gravity (the contact lasts a few ms,
so g changes the speeds by a few cm/s at most):
- separable: with c = 3/2 alpha and u = delta' the penetration rate, m u du/d delta = -k delta^n (1 + c u)
  integrates to G(u) = u/c - ln(1 + c u)/c^2 + (k/m) delta^(n+1)/(n+1) constant, so the rebound u = -e v of an
  impact at speed v solves G(-e v) = G(v): e depends on alpha v alone, not on k, n or m;
- first order in alpha v: e = 1 - alpha v (Hunt and Crossley's).
"""

import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

import bouncingball as bb  # noqa: E402

out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out_dir.mkdir(parents=True, exist_ok=True)
m, R, k, n, g = 1.0, 0.06, 1e6, 1.5, 9.81
alphas = (0.02, 0.05, 0.2)  # s/m
speeds = (0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0, 5.0, 7.0, 10.0)  # impact speeds [m/s]


def separable_restitution(alpha: float, v: float) -> float:
    """e solving G(-e v) = G(v), G(u) = u/c - ln(1 + c u)/c^2, c = 3/2 alpha: an impact without gravity."""
    c = 1.5 * alpha
    if c * v < 1e-6:  # G's two terms cancel: their series, to the first order in c v
        return 1.0 - alpha * v
    def G(u):
        return u / c - math.log1p(c * u) / (c * c)
    target = G(v)
    return brentq(lambda e: G(-e * v) - target, 0.0, min(1.0, (1.0 - 1e-15) / (c * v)), xtol=1e-15, rtol=1e-15)


def simulated_restitution(alpha: float, v: float) -> float:
    """The first bounce's departure over impact speed, from R + v^2 / (2 g) at rest, run by CVODE."""
    ball = bb.Ball(m=m, R=R, g=g, contact="hunt-crossley", k=k, n=n, alpha=alpha)
    h0 = R + v * v / (2.0 * g)
    t_impact = v / g
    contact = 3.22 * (m / k) ** 0.4 * v ** -0.2  # Hertz's contact time (n = 1.5, alpha = 0)
    events = bb.simulate(ball, h0, 0.0, t_impact + 3.0 * contact, 1e-3).events
    impact, departure = events[0], next(e for e in events if e.kind == "departure")
    return departure.velocity / -impact.velocity


print(f"the Hunt-Crossley ball, m = {m:g} kg, R = {R:g} m, k = {k:g} N/m^{n:g}, n = {n:g}; e = departure over "
      "impact speed of the first bounce")
print(f"{'alpha [s/m]':>12s}{'v [m/s]':>10s}{'e (CVODE)':>12s}{'e (separable)':>15s}{'1 - alpha v':>13s}")
table = {}
for alpha in alphas:
    rows = []
    for v in speeds:
        e, separable = simulated_restitution(alpha, v), separable_restitution(alpha, v)
        rows.append((v, e, separable, 1.0 - alpha * v))
        print(f"{alpha:12g}{v:10g}{e:12.6f}{separable:15.6f}{1.0 - alpha * v:13.6f}")
    table[alpha] = np.array(rows)

figure, axes = plt.subplots(figsize=(8, 5.5), constrained_layout=True)
fine = np.geomspace(speeds[0], speeds[-1], 400)
colours = ("tab:blue", "tab:orange", "tab:green")
for alpha, colour in zip(alphas, colours, strict=True):
    rows = table[alpha]
    axes.plot(rows[:, 0], rows[:, 1], "o", color=colour)
    axes.plot(fine, [separable_restitution(alpha, v) for v in fine], "-", color=colour, linewidth=1)
    linear = 1.0 - alpha * fine
    axes.plot(fine[linear > 0], linear[linear > 0], "--", color=colour, linewidth=1)
axes.set(xscale="log", xlabel="impact speed v [m/s]", ylabel="coefficient of restitution e", ylim=(0.0, 1.02))
# where gravity's impulse over a contact, g t_c (Hertz's t_c = 3.22 (m/k)^0.4 v^-0.2), reaches a tenth of v
gravity_matters = (10.0 * g * 3.22 * (m / k) ** 0.4) ** (1.0 / 1.2)
axes.axvspan(speeds[0] * 0.8, gravity_matters, color="0.92", zorder=0)
axes.set_title(f"Hunt-Crossley contact, k = {k:g} N/m^{n:g}, n = {n:g}, m = {m:g} kg: restitution falls with impact "
               f"speed\n(shaded: below {gravity_matters:.2g} m/s, gravity's impulse over the contact, g t_c, is over a "
               "tenth of v)", fontsize=10)
laws = axes.legend([plt.Line2D([], [], color=c, linewidth=3) for c in colours], [f"alpha = {a:g} s/m" for a in alphas],
                   loc="lower left", fontsize=8, title="damping")
axes.add_artist(laws)
axes.legend([plt.Line2D([], [], marker="o", linestyle="", color="black"), plt.Line2D([], [], color="black"),
             plt.Line2D([], [], color="black", linestyle="--")],
            ["CVODE (simulate), with gravity", "separable impact, without gravity", "1 - alpha v (first order)"],
            loc="lower center", fontsize=8, title="e from")
figure.savefig(out_dir / "hunt_crossley_restitution.png", dpi=120)
print(f"wrote {out_dir / 'hunt_crossley_restitution.png'}")
