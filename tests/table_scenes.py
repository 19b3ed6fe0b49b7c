"""Scenes of the ball on a sine table built so that an impact grazes: the test cases of issue 44's "no impact missed".

A graze is built backwards from its end. At the construction's time 0 the table is at the phase th_m, where its
deceleration beats the ball's (A w^2 sin(th_m) > a, so the gap can have a minimum there); the ball is placed at
the table's velocity (zero relative speed) and `depth` below the table's surface (depth < 0: above it, a near
miss). Forward from there the ball leaves the table; backwards, the gap grows to 0 at the crossing time t_c ~
-sqrt(2 depth / (a_rel)), a_rel = A w^2 sin(th_m) - a: the gap dips below zero for ~2 sqrt(2 depth / a_rel) only,
a window far shorter than a naive scan's step. The ball's flight before the crossing is followed backwards
(SineTableTruth's certified flight in reversed time: the table's sine reversed is the sine of phase pi - th) to the
contact before it; there, `bounces_before` times, the restitution is undone (relative speed before = after / e)
and the flight before followed back again. The scene starts inside the earliest flight, at `start_fraction` of it;
the graze is then the impact number bounces_before + 1 (or no impact, for a near miss).
"""

from __future__ import annotations

import functools
import math
import random

from table_truth import BOUNCE, FREE, Flight, mp


def grazing_scene(R, g, e, v_min, gamma, frequency, graze_phase, depth, bounces_before=0, start_fraction=0.5,
                  periods_after=1.0):
    """The keyword arguments of SineTableTruth for a scene whose impact number bounces_before + 1 grazes.

    gamma = A w^2 / g (> 1), graze_phase th_m [rad] with gamma sin(th_m) > 1, depth [m] (> 0 the ball crosses
    into the table by that much, < 0 it misses it by -depth). The scene starts at t = 0 inside the earliest
    flight; its t_end is periods_after table periods past the graze. Returned with the extras graze_time [s]
    (the construction's minimum of the gap), graze_depth [m] and bounces_before, which SineTableTruth does not
    take: pop them first.
    """
    a, w = mp.mpf(g), 2 * mp.pi * mp.mpf(frequency)
    A = mp.mpf(gamma) * a / (w * w)
    theta_m, depth = mp.mpf(graze_phase), mp.mpf(depth)
    if not (A * w * w * mp.sin(theta_m) > a and 0 < e <= 1):
        raise ValueError("a graze needs A w^2 sin(graze_phase) > g and 0 < e <= 1")
    v_m = A * w * mp.cos(theta_m)  # at the construction's time 0: the table's velocity
    h_m = R + A * mp.sin(theta_m) - depth

    def gap(t):
        return h_m + v_m * t - a * t * t / 2 - R - A * mp.sin(w * t + theta_m)

    if depth > 0:
        a_rel = A * w * w * mp.sin(theta_m) - a
        width = mp.sqrt(2 * depth / a_rel)  # the gap's quadratic model's root
        t_c = mp.findroot(gap, (-3 * width, -width / 100), solver="anderson")  # the crossing into the table
        if not (-3 * width < t_c < 0 and gap(-3 * width) > 0):
            raise RuntimeError("the graze's crossing was not found")
        backwards = (t_c, 0, -(v_m - a * t_c - A * w * mp.cos(w * t_c + theta_m)), BOUNCE)
    else:
        t_c = mp.zero
        backwards = (t_c, -depth, mp.zero, FREE)
    h_y, v_y, t_y = h_m + v_m * t_c - a * t_c * t_c / 2, v_m - a * t_c, t_c  # the ball arriving at t_y
    for bounce in range(bounces_before + 1):
        t0, gap0, u0, start = backwards
        flight = Flight(A, w, mp.pi - (w * t0 + theta_m), a, mp.zero, gap0, u0, start)
        tau = flight.first_impact(mp.mpf(1000))
        t_x = t0 - tau
        if bounce == bounces_before:
            break
        ds = A * w * mp.cos(w * t_x + theta_m)
        u_before = flight.rate(tau) / e  # the relative speed after, -rate, undone: (v- - s') = -(v+ - s') / e
        if -e * u_before < v_min:
            raise ValueError("a bounce before the graze would start a ride: lower v_min")
        h_y, v_y, t_y = R + A * mp.sin(w * t_x + theta_m), ds + u_before, t_x
        backwards = (t_x, 0, -u_before, BOUNCE)
    t_s = t_x + mp.mpf(start_fraction) * (t_y - t_x)
    theta_s = w * t_s + theta_m
    return {"R": R, "g": g, "e": e, "v_min": v_min, "amplitude": float(A), "frequency": frequency,
            "phase": float(theta_s - 2 * mp.pi * mp.floor(theta_s / (2 * mp.pi))),
            "h0": float(h_y + v_y * (t_s - t_y) - a * (t_s - t_y) ** 2 / 2), "v0": float(v_y - a * (t_s - t_y)),
            "t_end": float(-t_s + mp.mpf(periods_after) / mp.mpf(frequency)),
            "graze_time": float(-t_s), "graze_depth": float(depth), "bounces_before": bounces_before}


def grazing_family(count=100, seed=44):
    """count scenes (grazing_scene's dicts) drawn with random.Random(seed), the same on every machine.

    Each scene: R ~ U(0.005, 0.05) m, g = 9.81, e ~ U(0.3, 0.95), v_min 0 (half) or 1e-3 m/s, f ~ U(5, 50) Hz,
    Gamma ~ U(1.2, 5), the graze's phase ~ U over the middle 90% of (asin(1/Gamma), pi - asin(1/Gamma)) (where
    the table decelerates faster than g), 0, 1 or 2 ordinary bounces before it, the start at U(0.2, 0.8) of the
    first flight; 80% cross the table by a depth ~ log-U(1e-10, 1e-5) m, capped where the crossing's window would
    be longer than 0.04 / w (a fraction 0.6% of the table's period), 20% miss it by log-U(1e-10, 1e-6) m.
    A draw whose bounce before the graze would ride (below v_min) is drawn again. A new list of new dicts each call.
    """
    return [dict(scene) for scene in _drawn(count, seed)]


@functools.lru_cache(maxsize=4)
def _drawn(count, seed):
    draw, scenes = random.Random(seed), []
    while len(scenes) < count:
        gamma = draw.uniform(1.2, 5.0)
        low = math.asin(1.0 / gamma)
        margin = 0.05 * (math.pi - 2.0 * low)
        crossing = draw.random() < 0.8
        depth = 10.0 ** draw.uniform(-10.0, -5.0) if crossing else -10.0 ** draw.uniform(-10.0, -6.0)
        frequency, graze_phase = draw.uniform(5.0, 50.0), draw.uniform(low + margin, math.pi - low - margin)
        w = 2.0 * math.pi * frequency
        depth = min(depth, 0.5 * 9.81 * (gamma * math.sin(graze_phase) - 1.0) * (0.02 / w) ** 2)
        arguments = dict(R=draw.uniform(0.005, 0.05), g=9.81, e=draw.uniform(0.3, 0.95),
                         v_min=draw.choice((0.0, 1e-3)), gamma=gamma, frequency=frequency,
                         graze_phase=graze_phase, depth=depth,
                         bounces_before=draw.choice((0, 1, 2)), start_fraction=draw.uniform(0.2, 0.8))
        try:
            scenes.append(grazing_scene(**arguments))
        except ValueError:
            continue
    return tuple(scenes)
