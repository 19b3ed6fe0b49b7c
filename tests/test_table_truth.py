"""The referee of the vibrating table (issue 44), SineTableTruth, held to the published closed forms and invariants.

Holmes 1982 (J. Sound Vib. 84, 173) and Luck and Mehta 1993 (Phys. Rev. E 48, 3988): the period-1 orbit's impact
phase and take-off speed, its period doubling, the ride's end (tests/closed_forms.py); the still table's rigid
ball (tests/rigid_truth.py); the geometric chattering; grazes a naive scan steps over (tests/table_scenes.py).
"""

import math
import random

import numpy as np
import pytest

import closed_forms
import table_truth
from rigid_truth import RigidTruth
from table_scenes import grazing_family, grazing_scene
from table_truth import BOUNCE, FREE, Flight, SineTableTruth, mp

F, G, R = 10.0, 9.81, 0.01  # [Hz], [m/s^2], [m]


def _on_the_orbit(e, gamma, n_impacts):
    """The truth started 1% above the period-1 orbit's take-off speed at its take-off point (t = 0, phase phi)."""
    amplitude = closed_forms.table_amplitude(gamma, F, G)
    phi = closed_forms.period_n_phase(1, e, gamma)
    h0 = R + amplitude * math.sin(phi)
    while mp.mpf(h0) < R + amplitude * mp.sin(mp.mpf(phi)):  # on or just above the table, as floats go
        h0 = math.nextafter(h0, math.inf)
    u = closed_forms.period_n_takeoff_speed(1, F, G)
    return SineTableTruth(R, G, e, 0.0, amplitude, F, phi, h0, 1.01 * u, 1e6, max_impacts=n_impacts), phi, u


@pytest.mark.parametrize("v_min", [0.0, 0.05])
def test_a_still_table_is_the_rigid_ball(v_min):
    table = SineTableTruth(0.1, G, 0.6, v_min, 0.0, F, 0.3, 1.0, 0.5, 10.0, F_ext=-2.0, m=0.5)
    rigid = RigidTruth(0.1, G + 4.0, 0.6, v_min, 1.0, 0.5, 10.0)
    # the rigid truth sums its Zeno tail from apexes below 1e-30 R, this one from speeds below 1e-25 m/s
    assert len(table.impacts) == len(rigid.impacts) >= 10 if v_min else len(table.impacts) > len(rigid.impacts) > 50
    for (t, v_before, v_after), (t_rigid, v_rigid) in zip(table.impacts, rigid.impacts, strict=False):
        assert abs(t - t_rigid) < 1e-35 and abs(v_before - v_rigid) < 1e-35 and abs(v_after + 0.6 * v_rigid) < 1e-35
    assert len(table.rides) == 1 and table.rides[0][1] is None and abs(table.rides[0][0] - rigid.rest_time) < 1e-35
    assert table.accumulations == ([] if v_min else [table.rides[0][0]])
    for t in (0.3, 1.1, float(rigid.impacts[3][0]) + 0.01, 9.0):
        assert all(abs(x - y) < 1e-30 for x, y in zip(table.state(t), rigid.state(t), strict=True))


@pytest.mark.parametrize("e", [0.5, 0.8])
@pytest.mark.parametrize("fraction", [0.3, 0.8])
def test_period_one_orbit_is_reached_at_its_closed_form_phase_and_speed(e, fraction):
    gamma_1, gamma_pd = closed_forms.period_n_threshold(1, e), closed_forms.period_doubling_threshold(1, e)
    truth, phi, u = _on_the_orbit(e, gamma_1 + fraction * (gamma_pd - gamma_1), 200)
    assert len(truth.impacts) == 200 and truth.rides == []
    first = truth.intervals()[0]
    assert abs(first - 1 / F) > 1e-4  # started off the orbit
    for t, v_before, v_after in truth.impacts[-10:]:
        assert abs(truth.phase(t) - phi) < 1e-9 and abs(v_after - u) < 1e-9 and abs(v_before + u) < 1e-9
    assert all(abs(interval - 1 / F) < 1e-9 for interval in truth.intervals()[-10:])


@pytest.mark.parametrize("e", [0.5, 0.8])
def test_just_below_the_period_doubling_threshold_the_orbit_keeps_period_one(e):
    gamma_1, gamma_pd = closed_forms.period_n_threshold(1, e), closed_forms.period_doubling_threshold(1, e)
    truth, phi, _ = _on_the_orbit(e, 0.97 * gamma_pd, 200)
    assert 0.97 * gamma_pd > gamma_1 + 0.8 * (gamma_pd - gamma_1)  # closer to the threshold than the tests above
    assert all(abs(truth.phase(t) - phi) < 1e-9 for t, _, _ in truth.impacts[-10:])
    assert all(abs(interval - 1 / F) < 1e-9 for interval in truth.intervals()[-10:])


@pytest.mark.parametrize("e", [0.5, 0.8])
def test_past_the_period_doubling_threshold_the_orbit_has_period_two(e):
    gamma_pd = closed_forms.period_doubling_threshold(1, e)
    truth, _, _ = _on_the_orbit(e, 1.02 * gamma_pd, 200)
    intervals = truth.intervals()[-10:]
    for k in range(len(intervals) - 2):
        assert abs(intervals[k] + intervals[k + 1] - 2 / F) < 1e-9 and abs(intervals[k] - intervals[k + 2]) < 1e-9
        assert abs(intervals[k] - intervals[k + 1]) > 1e-3  # 4.6 ms (e = 0.5) and 8.3 ms (e = 0.8) apart


def _dropped(gamma, t_end):
    amplitude = closed_forms.table_amplitude(gamma, F, G)
    return SineTableTruth(R, G, 0.5, 0.0, amplitude, F, 0.0, R + amplitude + 0.02, 0.0, t_end)


def test_below_one_g_the_ball_chatters_and_rides_for_good():
    truth = _dropped(0.9, 3.0)
    assert len(truth.accumulations) == 1 and truth.rides == [(truth.accumulations[0], None)]
    intervals = truth.intervals()
    ratios = [later / earlier for earlier, later in zip(intervals[-20:], intervals[-19:], strict=False)]
    assert len(ratios) == 19 and all(abs(ratio - 0.5) < 1e-9 for ratio in ratios)
    # the tail summed from the intervals, not the speeds: the last interval's e / (1 - e) = 1 times more
    t_last = truth.impacts[-1][0]
    assert abs(truth.accumulations[0] - (t_last + intervals[-1])) < 1e-30
    for t in (truth.accumulations[0] + 0.01, 2.5):
        h, v = truth.state(t)
        s, ds, _ = truth.ground(t)
        assert h == R + s and v == ds


def test_the_accumulation_time_does_not_depend_on_where_the_tail_starts(monkeypatch):
    enumerated_to_1e_25 = _dropped(0.9, 1.0).accumulations[0]
    monkeypatch.setattr(table_truth, "TAIL_SPEED", mp.mpf("1e-12"))
    summed_from_1e_12 = _dropped(0.9, 1.0)
    assert len(summed_from_1e_12.impacts) < 60 and abs(summed_from_1e_12.accumulations[0] - enumerated_to_1e_25) < 1e-22


def test_every_ride_ends_at_the_closed_form_phase_and_the_ball_leaves_freely():
    gamma = 1.02  # between 1 and Gamma_1 = pi / 3 for e = 0.5: no period-1 orbit, the ball rides and leaves
    truth = _dropped(gamma, 0.5)
    ended = [(start, end) for start, end in truth.rides if end is not None]
    theta = closed_forms.ride_end_phase(truth.A, F, G)
    assert len(ended) >= 2 and len(truth.accumulations) == len(truth.rides)
    for start, end in ended:
        assert start < end and abs(truth.phase(end) - theta) < 1e-9
        assert abs(truth.ground(end)[2] + G) < 1e-30  # s'' = -g there
        for k in range(1, 10):  # riding: s'' >= -g all along
            assert truth.ground(start + k * (end - start) / 10)[2] >= -G
        later = next(t for t, _, _ in truth.impacts if t > end)
        assert later - end > 1e-3  # the departure (a cubic start of the gap) is not taken as an impact
        for k in range(1, 10):
            t = end + k * (later - end) / 10
            assert truth.state(t)[0] - R - truth.ground(t)[0] > 0


def test_a_grazing_impact_is_found_where_a_naive_scan_steps_over_it():
    depth, gamma, theta_m = 1e-7, 3.0, math.pi / 2 + 0.3
    scene = grazing_scene(R, G, 0.5, 0.0, gamma, F, theta_m, depth, start_fraction=0.5)
    graze_time = scene.pop("graze_time")
    scene.pop("graze_depth"), scene.pop("bounces_before")
    truth = SineTableTruth(**scene)
    a_rel = G * (gamma * math.sin(theta_m) - 1.0)
    window = math.sqrt(2.0 * depth / a_rel)  # the gap is below 0 for 2 window = 0.2 ms
    t_impact, v_before, _ = truth.impacts[0]
    assert abs(t_impact - (graze_time - window)) < 1e-3 * window  # the quadratic model's crossing
    relative = v_before - truth.ground(t_impact)[1]
    assert abs(relative + math.sqrt(2.0 * depth * a_rel)) < 1e-2 * math.sqrt(2.0 * depth * a_rel)
    A, w, p = scene["amplitude"], 2 * math.pi * F, scene["phase"]

    def naive_gap(t):
        return scene["h0"] + scene["v0"] * t - G * t * t / 2 - R - A * math.sin(w * t + p)

    steps = [k * 1e-3 for k in range(int(graze_time / 1e-3) + 2)]
    assert all(naive_gap(t) > 0 for t in steps)  # a 1 ms sign-change scan sees no impact there


def test_grazes_built_behind_bounces_and_near_misses_are_what_the_truth_finds():
    for bounces, depth in ((2, 1e-9), (1, -1e-9)):
        scene = grazing_scene(R, G, 0.7, 0.0, 2.0, 20.0, 1.2, depth, bounces_before=bounces, start_fraction=0.3)
        graze_time, _, _ = scene.pop("graze_time"), scene.pop("graze_depth"), scene.pop("bounces_before")
        times = [float(t) for t, _, _ in SineTableTruth(**scene).impacts]
        before = [t for t in times if t < graze_time - 1e-3]
        assert len(before) == bounces
        near = [t for t in times if abs(t - graze_time) < 1e-3]
        assert len(near) == (1 if depth > 0 else 0)


def test_a_touch_at_zero_relative_speed_is_no_impact():
    """A flight whose gap has a double root (to 40 digits) at tau = 0.01 s: a touch, stepped past, not an impact."""
    A, w, a, theta_m = mp.mpf("0.01"), 2 * mp.pi * 10, mp.mpf(G), mp.pi / 2 + mp.mpf("0.2")
    delay = mp.mpf("0.01")  # the flight starts this long before the touch, on the table's tangent parabola
    p = theta_m - w * delay
    gap0 = A * w * mp.cos(theta_m) * (-delay) - a * delay ** 2 / 2 + A * mp.sin(theta_m) - A * mp.sin(p)
    u0 = A * w * mp.cos(theta_m) + a * delay - A * w * mp.cos(p)
    flight = Flight(A, w, p, a, mp.zero, gap0, u0, FREE)
    assert abs(flight.gap(delay)) < 1e-38 and abs(flight.rate(delay)) < 1e-36 and gap0 > 0
    later = flight.first_impact(mp.mpf(1))
    assert later is not None and later > delay + mp.mpf("1e-3")
    nudged = Flight(A, w, p, a, mp.zero, gap0 - mp.mpf("1e-20"), u0, FREE)  # crossing by 1e-20 m: an impact
    assert abs(nudged.first_impact(mp.mpf(1)) - delay) < 1e-9
    bounce = Flight(A, w, mp.zero, a, mp.zero, mp.zero, mp.mpf("1e-20"), BOUNCE)  # s'' = 0 > -a: lands again
    assert abs(bounce.first_impact(mp.mpf(1)) / (2 * mp.mpf("1e-20") / a) - 1) < 1e-15  # s''' tau / a ~ 1e-19


def test_the_grazing_family_is_seeded_and_each_graze_is_where_it_was_built():
    family = grazing_family()
    assert len(family) == 100 and family == grazing_family() and family != grazing_family(seed=45)
    assert sum(scene["graze_depth"] > 0 for scene in family) > 60 and {s["bounces_before"] for s in family} == {0, 1, 2}
    for scene in family[:8]:
        _check_graze(scene)


@pytest.mark.slow
def test_every_scene_of_the_grazing_family_grazes_as_built():  # ~12 s
    for scene in grazing_family():
        _check_graze(scene)


def _check_graze(scene):
    scene = dict(scene)
    graze_time, depth, bounces = scene.pop("graze_time"), scene.pop("graze_depth"), scene.pop("bounces_before")
    times = [float(t) for t, _, _ in SineTableTruth(**scene).impacts]
    period = 1.0 / scene["frequency"]
    assert len([t for t in times if t < graze_time - 0.01 * period]) == bounces
    assert len([t for t in times if abs(t - graze_time) < 0.01 * period]) == (1 if depth > 0 else 0), scene


def test_no_flight_of_random_scenes_dips_into_the_table_on_a_dense_float_grid():
    """Between two impacts of the truth the gap stays >= 0 on 20000 points: no impact skipped (the certificate)."""
    draw = random.Random(4401)
    for _ in range(12):
        gamma, frequency = draw.uniform(0.5, 5.0), draw.uniform(5.0, 50.0)
        amplitude = closed_forms.table_amplitude(gamma, frequency, G)
        truth = SineTableTruth(R, G, draw.uniform(0.3, 0.95), 0.0, amplitude, frequency, draw.uniform(0, 6.28),
                               R + amplitude + draw.uniform(0.0, 0.05), draw.uniform(-1.0, 1.0), 1e3, max_impacts=6)
        w, p = 2 * math.pi * frequency, float(truth.p)
        starts = [(mp.zero, None)] + [(t, v_after) for t, _, v_after in truth.impacts[:-1]]
        for (t0, _), (t1, _, _) in zip(starts, truth.impacts, strict=True):
            h0, v0 = (float(x) for x in truth.state(t0 + mp.mpf("1e-30")))
            tau = np.linspace(0.0, float(t1 - t0), 20001)[1:-1]
            gap = h0 + v0 * tau - G * tau * tau / 2 - R - amplitude * np.sin(w * (float(t0) + tau) + p)
            assert gap.min() > -1e-12, (gamma, frequency, float(t0), float(t1))
