"""A rigid ball on a vibrating table: the measured orbit against the closed forms, and a picture.

Needs: pip install -e '.[plot]' in the checkout (matplotlib for the figure; the numbers need only the core).
Usage: python vibrating_table.py [OUTPUT_DIR]   (writes vibrating_table.png there; default: the current directory)

The table moves as s(t) = A sin(w t), f = 10 Hz, Gamma = A w^2 / g its peak acceleration in g. With restitution
e, a period-1 orbit (one impact per table period) exists from Gamma_1 = pi (1 - e)/(1 + e) on; it meets the
table at the phase phi, cos(phi) = Gamma_1 / Gamma, leaves it at u = pi g / w, and doubles its period at
Gamma_pd = sqrt(Gamma_1^2 + (2 (1 + e^2)/(1 + e)^2)^2) (Holmes 1982; Luck and Mehta 1993). Below
min(1, Gamma_1) the ball chatters onto the table and rides it; at 2.5 it bounces chaotically. The exact solver's runs.
"""

import math
import sys
import warnings
from pathlib import Path

import numpy as np

import bouncingball as bb

out_dir = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
g, f, R, e = 9.81, 10.0, 0.01, 0.5
w = 2.0 * math.pi * f
gamma_1 = math.pi * (1.0 - e) / (1.0 + e)
gamma_pd = math.hypot(gamma_1, 2.0 * (1.0 + e * e) / (1.0 + e) ** 2)
ball = bb.Ball(R=R, g=g, contact="rigid", e=e, v_min=0.0)


def run(gamma, t_end, h0=R + 0.05, v0=0.0, phase=0.0):
    ground = bb.Ground.sine(gamma * g / w**2, f, phase)
    return bb.simulate(ball, h0, v0, t_end, 1e-4, solver="exact", ground=ground), ground


def near_orbit(gamma, t_end):
    """Started 1% off the period-1 orbit's take-off speed at its take-off point (the table at phi at t = 0)."""
    phi = math.acos(gamma_1 / gamma)
    h0 = R + gamma * g / w**2 * math.sin(phi)
    return run(gamma, t_end, h0=math.nextafter(h0, 1.0), v0=1.01 * math.pi * g / w, phase=phi)


def impacts(result):
    return np.array([event.time for event in result.events if event.kind == "impact"])


print(f"e = {e}, f = {f:g} Hz: Gamma_1 = {gamma_1:.6f}, Gamma_pd = {gamma_pd:.6f}")
gamma = gamma_1 + 0.5 * (gamma_pd - gamma_1)
phi, u = math.acos(gamma_1 / gamma), math.pi * g / w
result, ground = near_orbit(gamma, 25.0)
last = impacts(result)[-10:]
measured_phi = np.mod(w * last + phi, 2.0 * math.pi)
take_off = [event.time for event in result.events][-1]
speed = ground.velocity(take_off) - e * (result.events[-1].velocity - ground.velocity(take_off))
print(f"Gamma = {gamma:.6f} (period 1):  phi measured {measured_phi[-1]:.12f} rad, closed form {phi:.12f} rad; "
      f"take-off speed {speed:.12f} m/s, closed form {u:.12f} m/s; interval {np.diff(last)[-1]:.12f} s")
print(f"  its Lyapunov exponent {result.lyapunov.per_impact:.4f} per impact over {result.lyapunov.impacts} impacts "
      f"(complex multipliers of modulus e: ln(e) = {math.log(e):.4f})")
for factor in (0.97, 1.03):
    intervals = np.diff(impacts(near_orbit(factor * gamma_pd, 20.0)[0]))[-4:]
    print(f"Gamma = {factor:.2f} Gamma_pd: the last intervals between impacts {np.round(intervals, 6)} s "
          f"({'period 2' if abs(intervals[0] - intervals[1]) > 1e-4 else 'period 1'})")
with warnings.catch_warnings(action="ignore", category=bb.AccuracyWarning):  # chaos: warned from ~8 s on
    chaotic, _ = run(2.5, 60.0)
print(f"Gamma = 2.5, dropped from 5 cm: chaotic, Lyapunov exponent {chaotic.lyapunov.per_impact:+.3f} per impact, "
      f"{chaotic.lyapunov.per_second:+.3f} per second over {chaotic.lyapunov.impacts} impacts")
result, _ = run(0.9, 2.0)
print(f"Gamma = 0.9 < min(1, Gamma_1): {result.impacts} impacts, then riding the table from t = "
      f"{result.rest_time:.9f} s")

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    sys.exit(0)
panels = [(gamma, "period 1, started 1% off its orbit", near_orbit),
          (1.03 * gamma_pd, "period 2, started 1% off the unstable period-1 orbit", near_orbit),
          (1.02, "dropped from 5 cm: chatters, rides, is thrown where s'' = -g, again", run),
          (0.9, "dropped from 5 cm: chatters, then rides for good", run)]
figure, axes = plt.subplots(len(panels), 1, figsize=(10, 9), sharex=True)
for ax, (value, words, start) in zip(axes, panels, strict=True):
    result, ground = start(value, 3.0)
    inside = result.t >= 2.0
    t = result.t[inside]
    ax.fill_between(t, ground.position(t), -1.2 * ground.amplitude, color="0.75", lw=0, label="the table s(t)")
    ax.plot(t, ground.position(t) + R, color="0.4", lw=0.6, ls="--", label="R + s(t): contact")
    ax.plot(t, result.h[inside], lw=1.6, label="h, the ball's centre")
    hits = impacts(result)
    hits = hits[hits >= 2.0]
    ax.plot(hits, ground.position(hits) + R, "v", color="tab:red", ms=4, label="impacts")
    ax.set_title(f"Gamma = {value:.3f}: {words}", fontsize=10)
    ax.set_ylabel("height [m]")
axes[0].legend(loc="upper right", fontsize=8, ncol=4)
axes[-1].set_xlabel("time t [s]")
figure.suptitle(f"a rigid ball (e = {e}, R = {R} m) on a table vibrating at {f:g} Hz: the exact solution")
figure.tight_layout()
out_dir.mkdir(parents=True, exist_ok=True)
figure.savefig(out_dir / "vibrating_table.png", dpi=100)
print(f"wrote {out_dir / 'vibrating_table.png'}")
