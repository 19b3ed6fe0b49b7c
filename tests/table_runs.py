"""What the vibrating table's tests (tests/test_moving_ground.py, tests/test_moving_ground_cvode.py) set up and read
of a run: the start on the rigid law's period-1 orbit (its closed forms, tests/closed_forms.py) and the impacts."""

from __future__ import annotations

import math
import warnings

import numpy as np

import bouncingball as bb
from closed_forms import period_n_phase, period_n_takeoff_speed, table_amplitude
from table_truth import SineTableTruth


def orbit_start(e, gamma, speed_factor, frequency, g, R):
    """(ball, ground, h0, v0): on the period-1 orbit's take-off point at t = 0, speed_factor times its speed.

    The rigid ball (v_min 0) of radius R [m] under g [m/s2], the table at frequency [Hz] with Gamma = gamma, its
    phase phi at t = 0; h0 on the table (the next float up where R + s(0) rounds into it).
    """
    ground = bb.Ground.sine(table_amplitude(gamma, frequency, g), frequency, period_n_phase(1, e, gamma))
    ball = bb.Ball(R=R, g=g, contact="rigid", e=e, v_min=0.0)
    h0 = R + ground.position(0.0)
    h0 = math.nextafter(h0, math.inf) if h0 - R < ground.position(0.0) else h0
    return ball, ground, h0, speed_factor * period_n_takeoff_speed(1, frequency, g)


def impact_times(result):
    """The times [s] of a result's impacts, an array."""
    return np.array([event.time for event in result.events if event.kind == bb.EventKind.IMPACT])


def grazing_run(scene, solver, **options):
    """(bounces_before, truth, result, warned) of a grazing scene (tests/table_scenes.py's dict, left unchanged).

    truth: its SineTableTruth; result: the solver's run to its t_end, 400 output intervals, with options; warned:
    whether the run issued an AccuracyWarning.
    """
    scene = dict(scene)
    bounces_before = scene.pop("bounces_before")
    scene.pop("graze_time"), scene.pop("graze_depth")
    ball = bb.Ball(R=scene["R"], g=scene["g"], contact="rigid", e=scene["e"], v_min=scene["v_min"])
    ground = bb.Ground.sine(scene["amplitude"], scene["frequency"], scene["phase"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = bb.simulate(ball, scene["h0"], scene["v0"], scene["t_end"], scene["t_end"] / 400, solver=solver,
                             ground=ground, **options)
    warned = any(issubclass(w.category, bb.AccuracyWarning) for w in caught)
    return bounces_before, SineTableTruth(**scene), result, warned
