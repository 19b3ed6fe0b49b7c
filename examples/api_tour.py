"""The Python API in one page: simulate a scene with cvode, exact and scipy, compare, plot.

Needs: pip install -e '.[reference,plot]' in the checkout (SciPy for the article's algorithm, matplotlib for the plot).
Usage: python api_tour.py [OUTPUT_DIR]      (writes api_tour.png there; default: the current directory)
"""

import sys
from pathlib import Path

import numpy as np

import bouncingball as bb

out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out_dir.mkdir(parents=True, exist_ok=True)

# The article's ball, dropped from 2 m at rest, 8 s on a 1 ms grid.
ball = bb.Ball(m=1.0, k=1e4, b=10.0, R=0.06, g=9.81)
h0, v0, t_end, dt = 2.0, 0.0, 8.0, 1e-3
runs = {solver: bb.simulate(ball, h0, v0, t_end, dt, solver=solver) for solver in ("exact", "cvode", "scipy")}
exact = runs["exact"]

print(f"ball: m = {ball.m} kg, k = {ball.k:g} N/m, b = {ball.b} N s/m, R = {ball.R} m, g = {ball.g} m/s2; "
      f"h0 = {h0} m, v0 = {v0} m/s, {t_end} s")
print(f"{'solver':8s}{'max |h - h_exact| [m]':>24s}{'max event time error [s]':>26s}{'events':>8s}"
      f"{'impacts':>9s}{'final h [m]':>24s}")
for name, run in runs.items():
    # Every solver returns the same record on the same grid: compare point by point.
    height_error = np.max(np.abs(run.h - exact.h))
    paired = zip(run.events, exact.events, strict=False)
    event_error = max((abs(a.time - b.time) for a, b in paired), default=0.0)
    print(f"{name:8s}{height_error:24.3e}{event_error:26.3e}{len(run.events):8d}{run.impacts:9d}"
          f"{run.h[-1]:24.17g}")

print("first events (exact solution):")
for event in exact.events[:4]:
    print(f"  t = {event.time:.15f} s  {event.kind:9s}  v = {event.velocity:+.12f} m/s")
rest = "never" if exact.rest_time is None else f"{exact.rest_time:.6f} s"
print(f"rest (a contact that never ends) starts: {rest}")
print(f"cvode: {runs['cvode'].stats.steps} steps, {runs['cvode'].stats.rhs_calls} right-hand-side calls")

import matplotlib  # noqa: E402  (only the plot needs it)

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt  # noqa: E402

COLOURS = {"exact": "k", "cvode": "C0", "scipy": "C1"}  # one colour per solver, in both panels
LABELS = {"exact": "exact", "cvode": "cvode", "scipy": "scipy (the article's RK45)"}
figure, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(9, 6.5), layout="constrained")
figure.suptitle(f"The article's ball from h0 = {h0:g} m: three solvers, and their error against the exact solution")
# exact last and dotted, on top: the three lines agree to the eye (the lower panel shows by how much)
for name, style, width in (("cvode", "-", 3.0), ("scipy", "--", 1.5), ("exact", ":", 1.2)):
    top.plot(runs[name].t, runs[name].h, style, lw=width, color=COLOURS[name], label=LABELS[name])
top.set_ylabel("h [m]")
top.set_title("height of the centre", fontsize=10)
top.legend()
for name in ("cvode", "scipy"):
    # + 1e-16: a log axis cannot show an error of 0 (the first fall, before any contact)
    bottom.semilogy(exact.t, np.abs(runs[name].h - exact.h) + 1e-16, color=COLOURS[name], label=LABELS[name])
bottom.set_title("|h - h_exact| (the exact solution's own error is 0)", fontsize=10)
bottom.set_xlabel("t [s]")
bottom.set_ylabel("|h - h_exact| [m]")
bottom.legend()
figure.savefig(out_dir / "api_tour.png", dpi=100)
print(f"wrote {out_dir / 'api_tour.png'}")
