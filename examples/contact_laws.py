"""One drop under the three contact laws: the article's spring-damper, the same without its pull, and a rigid impact.

Needs: pip install -e '.[plot]' in the checkout (matplotlib for the figure).
Usage: python contact_laws.py [OUTPUT_DIR]   (writes contact_laws.png there; default: the current directory)

The article's ball from 2 m. The rigid ball's restitution e is the linear law's first bounce's (departure
over impact speed), so the three first bounces start alike; the exact solutions are drawn.
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import bouncingball as bb  # noqa: E402
from bouncingball.solvers.exact import ExactSolution  # noqa: E402

out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out_dir.mkdir(parents=True, exist_ok=True)
h0, t_end = 2.0, 3.0

linear = bb.Ball()
first = bb.simulate(linear, h0, 0.0, 1.0, solver="exact").events
restitution = first[1].velocity / -first[0].velocity  # the linear law's first bounce
balls = {"linear": linear, "linear-no-pull": bb.Ball(contact="linear-no-pull"),
         f"rigid, e = {restitution:.3f}": bb.Ball(contact="rigid", e=restitution)}

t = np.linspace(0.0, t_end, 300_001)  # 10 us: the first contact lasts about 30 ms
print(f"the article's ball from {h0} m, {t_end} s, exact solutions")
print(f"{'law':24s}{'impacts':>8s}{'first contact [ms]':>20s}{'least force [N]':>17s}{'1st restitution':>17s}")
solutions = {}
for label, ball in balls.items():
    exact = ExactSolution(ball, h0, 0.0, 0.0, t_end)
    h, v = exact.state(t)
    modes = exact.modes(t)
    force = np.array([ball.contact_force(*state) for state in zip(h, v, (bb.Mode(m) for m in modes), strict=True)])
    events = exact.events
    impacts = [e for e in events if e.kind == "impact"]
    departure = next((e for e in events if e.kind == "departure"), None)
    duration = "0 (instant)" if ball.rigid else f"{(departure.time - impacts[0].time) * 1e3:.3f}"
    # departure over impact speed; a rigid bounce leaves at the speed of its next impact (a parabola)
    bounce = (impacts[1].velocity / impacts[0].velocity if ball.rigid else departure.velocity / -impacts[0].velocity)
    print(f"{label:24s}{len(impacts):8d}{duration:>20s}{force.min():17.4g}{bounce:17.6f}")
    solutions[label] = (h, force)

figure, (top, bottom) = plt.subplots(2, 1, figsize=(9, 7), constrained_layout=True)
figure.suptitle(f"One drop from {h0:g} m under the three contact laws (exact solutions)")
zoom = (t >= first[0].time - 0.005) & (t <= first[0].time + 0.04)
for (label, (h, force)), style in zip(solutions.items(), ("-", "--", ":"), strict=True):
    top.plot(t, h, style, label=label)
    if not label.startswith("rigid"):  # a rigid impact is an impulse: no force to draw
        bottom.plot(t[zoom] * 1e3, force[zoom], style, label=label)
top.set(xlabel="t [s]", ylabel="h [m]", title="height of the centre")
bottom.axhline(0.0, color="grey", linewidth=0.5)
bottom.set(xlabel="t [ms]", ylabel="contact force [N]",
           title="the first contact: the linear law's damper pulls before departure, the no-pull law's does not")
top.legend()
bottom.legend()
path = out_dir / "contact_laws.png"
figure.savefig(path, dpi=110)
print(f"wrote {path}")
