"""Where a compliant ball parts from the rigid one on a vibrating table: the period-1 orbit's impact phase as k falls.

Needs: pip install -e . in the checkout (the core; scipy, which it brings, for the damping's root).
Usage: python stiff_table.py

The rigid law (e = 0.5) on a table at f = 10 Hz, Gamma = A w^2 / g halfway from the period-1 threshold Gamma_1 to
its period doubling Gamma_pd, meets the table at phi, cos(phi) = Gamma_1 / Gamma (Holmes 1982). The linear law, its
damping b chosen so that one impact at the orbit's impact speed on a still ground leaves at e times it, settles on
a period-1 orbit too: its impact phase parts from phi by about 0.1 w times the contact's duration, since the table
accelerates during the contact. Each run is the exact solver's.
"""

import math

import bouncingball as bb

g, f, R, e = 9.81, 10.0, 0.01, 0.5
w = 2.0 * math.pi * f
gamma_1 = math.pi * (1.0 - e) / (1.0 + e)
gamma_pd = math.hypot(gamma_1, 2.0 * (1.0 + e * e) / (1.0 + e) ** 2)
gamma = gamma_1 + 0.5 * (gamma_pd - gamma_1)
phi, u = math.acos(gamma_1 / gamma), math.pi * g / w  # the impact phase, the take-off speed
ground = bb.Ground.sine(gamma * g / w**2, f, phi)  # at phi at t = 0: the ball starts at the orbit's take-off
impact_speed = (u - ground.amplitude * w * math.cos(phi)) / e  # relative to the table


def restitution_damping(k):
    """b [N s/m] giving e at one impact at impact_speed on a still ground (m = 1 kg): the linear law's e there."""
    from scipy.optimize import brentq

    def ratio(b):
        events = bb.simulate(bb.Ball(k=k, b=b, R=R, g=g), R, -impact_speed, 0.2, 1e-2, solver="exact").events
        return next((event.velocity / impact_speed for event in events if event.kind == "departure"), 0.0) - e

    return brentq(ratio, 0.02 * math.sqrt(k), 0.7 * math.sqrt(k), xtol=1e-12 * math.sqrt(k))


print(f"the rigid law's period-1 orbit: Gamma = {gamma:.6f}, impact phase phi = {phi:.9f} rad")
for k in (1e9, 1e8, 1e7, 1e6, 1e5):
    b = restitution_damping(k)
    linear = bb.simulate(bb.Ball(k=k, b=b, R=R, g=g), math.nextafter(R + ground.position(0.0), 1.0), 1.01 * u,
                         30.0, 1e-2, solver="exact", ground=ground)
    ends = [i for i, event in enumerate(linear.events) if event.kind == "departure"]
    contact = linear.events[ends[-1]].time - linear.events[ends[-1] - 1].time  # the last complete contact
    last_impact = [event.time for event in linear.events if event.kind == "impact"][-1]
    offset = math.remainder(w * last_impact, 2.0 * math.pi)  # its impact phase w t + phi, less phi
    print(f"  k = {k:.0e} N/m, b = {b:.6g} N s/m: contact {contact * 1e3:.4f} ms, impact phase - phi = "
          f"{offset:+.3e} rad")
