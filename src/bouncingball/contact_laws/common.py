"""What every contact law shares: the ball's parameters by name, the laws' codes, the flight, the machine's answers.

Imported by each law's module and by the dispatch in contact_laws/__init__.py; it knows no law.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

# The codes the phase machine knows the contact laws by (BallParameters.law; contact_laws.LAWS maps names to them).
LINEAR, RIGID, NO_PULL, HUNT_CROSSLEY = 0, 1, 2, 3

# How a phase is taken (a law's decide_contact, phases.decide_phase): CVODE integrates it, the contact is a rest
# (taken on its exact flow), or its event comes from the exact flow.
BY_CVODE, REST, IN_CLOSED_FORM = range(3)
# A phase whose length scale [m] is below this (a hop or contact of 1e-200 m) is taken on the exact
# flow: its scaled state would leave the range of double precision.
MIN_PHASE_SCALE = 1e-200
SOFT_CONTACT_CAP = 1e3  # a contact's length scale is at most this many max(R, |gap|): see phases.phase_scales


class BallParameters(NamedTuple):
    """The ball as plain floats, by name, as the phase machine takes it (Ball.parameters; numba compiles it as a tuple).

    law is the contact law's code as a float (LINEAR .. HUNT_CROSSLEY); the rest are Ball's fields in SI units, and
    the ground's sine s(t) = ground_amplitude sin(ground_omega t + ground_phase) [m, rad/s, rad] (amplitude 0: a
    still ground at 0; Ground.machine_parameters sets them).
    """

    m: float
    k: float
    b: float
    R: float
    g: float
    law: float
    e: float
    v_min: float
    n: float
    alpha: float
    ground_amplitude: float = 0.0
    ground_omega: float = 0.0
    ground_phase: float = 0.0


def parameters_at(values, first):
    """The BallParameters held in values[first:first + len(BallParameters._fields)], in its fields' order.

    The compiled engine's callbacks keep the ball so, in the float block CVODE hands them (engines/compiled.py).
    """
    return BallParameters(values[first], values[first + 1], values[first + 2], values[first + 3],
                          values[first + 4], values[first + 5], values[first + 6], values[first + 7],
                          values[first + 8], values[first + 9], values[first + 10], values[first + 11],
                          values[first + 12])


def time_to_impact(height_above_contact: float, v0: float, g_eff: float) -> tuple[float, float]:
    """Flight time [s] until h falls to R, and the impact velocity [m/s]; (inf, nan) if never.

    With D = v0^2 + 2 g (h0 - R) and s = sqrt(D), t = (v0 + s)/g when rising and
    2 (h0 - R)/(s - v0) when falling, which has no cancellation; the impact speed is s.
    """
    dh = height_above_contact
    disc = v0 * v0 + 2.0 * g_eff * dh
    if v0 < 0.0 and disc >= 0.0:
        s = math.sqrt(disc)
        return 2.0 * dh / (s - v0), -s
    if v0 >= 0.0 and g_eff > 0.0:
        s = math.sqrt(disc)
        return (v0 + s) / g_eff, -s
    return math.inf, math.nan


@dataclass(frozen=True)
class ContactLaw:
    """A contact law as the front-ends see it (Ball, the FMU's variables, the sweep, the CLI).

    name: its name (Ball.contact); code: the phase machine's (BallParameters.law); parameters: the Ball fields of
    its own that it reads, beyond m, R and g; closed_form: whether every phase has a closed-form flow (the exact
    solver, and so check and validate, take it); description: one line for help texts.

    article_algorithm: whether the reference article's algorithm runs it (solvers/scipy_ref.py: solve_ivp switching
    between flight and contact where h crosses R): its contact force a function of the state (Ball.acceleration),
    its contact one phase between two crossings of R.
    crossings_only: whether its only events are the crossings of R (impacts and departures), so that the FMU's
    outputs (the impact count and the contact flag) account for every event (fmu/validate.py).
    k_unit: the unit of its stiffness k, a format string of its parameters (n); None if it has no k.
    damping_axis: how a grid of its balls (the sweep) gives its damping: "zeta", the damping ratio
    b / (2 sqrt(k m)) of its linear spring-damper; "alpha", its own parameter alpha [s/m]; None if it has no k and
    damping to map.
    summary: how `bouncingball run` describes a ball of the law, a format string of Ball's fields.
    undamped_as: the law whose run a ball of this law with b = 0 is (its code taken, the same run), or None.
    """

    name: str
    code: int
    parameters: tuple[str, ...]
    closed_form: bool
    description: str
    article_algorithm: bool
    crossings_only: bool
    k_unit: str | None
    damping_axis: str | None
    summary: str
    undamped_as: str | None = None


def surely_below(gap, rate, g_eff, amplitude):
    """A time [s] by which a flight's gap from gap [m] is below a sine ground of amplitude [m] for sure; inf: none.

    rate [m/s]: the flight's own speed in the world (the gap's rate plus the ground's speed at the start). The gap
    is at most gap + 2 |A| + rate t - g_eff t^2 / 2 (the ground moves by 2 |A| at most); its root, with a margin
    of 2: under g_eff > 0, or a weightless flight (g_eff = 0) going down. inf otherwise (it need never come down).
    """
    lift = max(gap, 0.0) + 2.0 * abs(amplitude)
    if g_eff > 0.0:
        return 2.0 * (rate + math.sqrt(rate * rate + 2.0 * g_eff * lift)) / g_eff if rate > 0.0 else \
            2.0 * lift / (math.sqrt(rate * rate + 2.0 * g_eff * lift) - rate)
    if g_eff == 0.0 and rate < 0.0:
        return 2.0 * lift / -rate
    return math.inf
