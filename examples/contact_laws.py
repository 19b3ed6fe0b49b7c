"""One drop under the four contact laws: the article's spring-damper, the same without its pull, Hunt-Crossley, rigid.

Needs: pip install -e '.[plot,reference]' in the checkout (matplotlib for the figure, SciPy's brentq to match
alpha).
Usage: python contact_laws.py [OUTPUT_DIR]   (writes contact_laws.png there; default: the current directory)

The article's ball from 2 m. The rigid ball's restitution e is the linear law's first bounce's (departure
over impact speed), and the Hunt-Crossley ball's alpha is the one that gives its first bounce that
restitution too (k = 4e4 N/m^1.5: at the linear law's largest penetration, about 6 cm, its spring pushes as
hard), so the four first bounces start alike. The linear, no-pull and rigid laws are drawn from their exact
solutions; the Hunt-Crossley law has none and is run by CVODE at rtol 1e-10.
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

import bouncingball as bb  # noqa: E402
from bouncingball.solvers.exact import ExactSolution  # noqa: E402

out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out_dir.mkdir(parents=True, exist_ok=True)
h0, t_end, step = 2.0, 3.0, 1e-5  # 10 us: the first contact lasts about 30 ms
HC_K, HC_RTOL = 4e4, 1e-10  # N/m^1.5; CVODE's tolerance for the Hunt-Crossley law


def first_restitution(events) -> float:
    """Departure over impact speed of the first bounce."""
    impact, departure = events[0], next(e for e in events if e.kind == "departure")
    return departure.velocity / -impact.velocity


def hunt_crossley(alpha: float, t_end: float, output_interval: float):
    ball = bb.Ball(contact="hunt-crossley", k=HC_K, n=1.5, alpha=alpha)
    return ball, bb.simulate(ball, h0, 0.0, t_end, output_interval, rtol=HC_RTOL, atol=1e-13)


linear = bb.Ball()
restitution = first_restitution(bb.simulate(linear, h0, 0.0, 1.0, solver="exact").events)
alpha = brentq(lambda a: first_restitution(hunt_crossley(a, 1.0, 1e-3)[1].events) - restitution, 1e-4, 1.0,
               xtol=1e-12)
t = np.linspace(0.0, t_end, round(t_end / step) + 1)
print(f"the article's ball from {h0} m, {t_end} s; exact solutions, Hunt-Crossley by CVODE at rtol {HC_RTOL:g}")
print(f"{'law':34s}{'impacts':>8s}{'first contact [ms]':>20s}{'least force [N]':>17s}{'1st restitution':>17s}")
solutions = {}
for label, ball in {"linear": linear, "linear-no-pull": bb.Ball(contact="linear-no-pull"),
                    f"hunt-crossley, alpha = {alpha:.4f} s/m": None,
                    f"rigid, e = {restitution:.3f}": bb.Ball(contact="rigid", e=restitution)}.items():
    if ball is None:
        ball, run = hunt_crossley(alpha, t_end, step)
        h, v, events = run.h, run.v, run.events
        modes = np.where(h < ball.R, bb.Mode.CONTACT, bb.Mode.FLIGHT)  # its force is 0 at h = R: clipped below
    else:
        exact = ExactSolution(ball, h0, 0.0, 0.0, t_end)
        (h, v), modes, events = exact.state(t), exact.modes(t), exact.events
    force = np.array([ball.contact_force(*state) for state in zip(h, v, (bb.Mode(m) for m in modes), strict=True)])
    impacts = [e for e in events if e.kind == "impact"]
    departure = next((e for e in events if e.kind == "departure"), None)
    duration = "0 (instant)" if ball.rigid else f"{(departure.time - impacts[0].time) * 1e3:.3f}"
    # a rigid bounce leaves at the speed of its next impact (a parabola)
    bounce = impacts[1].velocity / impacts[0].velocity if ball.rigid else first_restitution(events)
    print(f"{label:34s}{len(impacts):8d}{duration:>20s}{force.min():17.4g}{bounce:17.6f}")
    solutions[label] = (h, force)

figure, (top, bottom) = plt.subplots(2, 1, figsize=(10, 7.5), layout="constrained")
figure.suptitle(f"One drop from {h0:g} m under the four contact laws\n(exact solutions; Hunt-Crossley, which has "
                f"none: CVODE at rtol {HC_RTOL:g}; k = {HC_K:g} N/m^1.5, n = 1.5)")
impact = bb.simulate(linear, h0, 0.0, 1.0, solver="exact").events[0].time
zoom = (t >= impact - 0.005) & (t <= impact + 0.04)
styles = ({"ls": "-", "color": "C0"}, {"ls": "--", "color": "C1"}, {"ls": "-.", "color": "C2"},
          {"ls": ":", "color": "C3"})
for (label, (h, force)), style in zip(solutions.items(), styles, strict=True):
    top.plot(t, h, label=label, **style)
    if not label.startswith("rigid"):  # a rigid impact is an impulse: no force to draw
        bottom.plot(t[zoom] * 1e3, force[zoom], label=label, **style)
top.set(xlabel="t [s]", ylabel="h [m]", title="height of the centre")
bottom.axhline(0.0, color="grey", linewidth=0.5)
bottom.set(xlabel="t [ms]", ylabel="contact force [N]",
           title="the first contact: the linear law's damper pulls before departure,\n"
                 "the no-pull law's force and Hunt-Crossley's (0 at touch-down and lift-off) never do")
bottom.plot([], [], " ", label="rigid: an impulse at the\nimpact, no force to draw")
for ax in (top, bottom):
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=9, frameon=False)
path = out_dir / "contact_laws.png"
figure.savefig(path, dpi=110)
print(f"wrote {path}")
