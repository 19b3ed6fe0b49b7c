"""The rigid law: the ball does not deform (k and b play no part); each impact on R reverses it, v+ = -e v-.

With v_min = 0 and e < 1 it makes infinitely many ever smaller bounces before it rests on R at the Zeno time
t_k + 2 v_k / (g (1 - e)) after a bounce leaving at v_k (those lower than ZENO_APEX R are summed as the geometric
series they are); with v_min > 0 it stops on R at the first bounce that would leave slower than v_min (the
Reference-FMUs' BouncingBall). Its contact mode is the ball resting on R, which it leaves at once where F_ext
exceeds m g.
"""

from __future__ import annotations

import math

from .common import IN_CLOSED_FORM, REST, RIGID, ContactLaw

# Under the rigid law with v_min = 0, the bounces after one whose apex is below ZENO_APEX R are summed as
# the geometric series they are: their heights are below any resolution, their count without end.
ZENO_APEX = 2.0**-40


def rigid_rebound(parameters, v_impact, load):
    """(v_after [m/s], zeno [s]): the rigid law's bounce after an impact at v_impact < 0 on R (Ball.parameters).

    v_after = -e v_impact, or 0 where the ball stays on R: below v_min, or where the bounces from
    there rise less than ZENO_APEX R (e < 1, a load on the ground). Their infinitely many impacts then
    take zeno = 2 v / (g_eff (1 - e)) [s] in all (v = -e v_impact, g_eff = load / m), after which the
    ball rests on R: the Zeno time is the impact's time + zeno. zeno is 0 where none are summed.
    """
    return rigid_rebound_above(parameters, v_impact, load, ZENO_APEX * parameters.R)


def rigid_rebound_above(parameters, v_impact, load, apex_floor):
    """rigid_rebound, with the bounces that rise less than apex_floor [m] (rather than ZENO_APEX R) summed."""
    e, v_min = parameters.e, parameters.v_min
    v_after = -e * v_impact
    if v_after < v_min:
        return 0.0, 0.0
    g_eff = load / parameters.m
    if g_eff > 0.0 and e < 1.0 and v_after * v_after <= 2.0 * g_eff * apex_floor:
        return 0.0, 2.0 * v_after / (g_eff * (1.0 - e))
    return v_after, 0.0


def summed_bounce_state(parameters, v_first, load, tau):
    """(x [m], v [m/s]) of a rigid ball tau [s] after the impact whose bounces rigid_rebound summed (Ball.parameters).

    Its bounces leave R at v_first e^j, j = 0, 1, ..., under the constant load [N]; the j-th leaves at
    S_j = 2 v_first (1 - e^j) / (g_eff (1 - e)), and from the Zeno time S_inf on the ball rests, (0, 0). Each is
    lower than ZENO_APEX R, so the ball is taken on R while they last; this is where it truly is, for a change
    of F_ext inside that time: a lift there leaves with the bounce's speed, not from rest.
    """
    e, g_eff = parameters.e, load / parameters.m
    scale = 2.0 * v_first / (g_eff * (1.0 - e))  # S_inf
    if not tau < scale:
        return 0.0, 0.0
    j = max(int(math.floor(math.log1p(-tau / scale) / math.log(e))), 0)  # e^j >= 1 - tau / S_inf
    while j > 0 and scale * (1.0 - e**j) > tau:  # the rounding of the logarithms, either way
        j -= 1
    while scale * (1.0 - e ** (j + 1)) <= tau:
        j += 1
    s, v_j = tau - scale * (1.0 - e**j), v_first * e**j
    return max(s * (v_j - 0.5 * g_eff * s), 0.0), v_j - g_eff * s


def contact_scales(parameters, x, v, load):
    """(R [m], 0 [m/s]): a rigid ball resting on R is scaled by R, at rest."""
    return parameters.R, 0.0


def departure_time(parameters, x0, v0, load):
    """0 [s] where F_ext lifts a rigid ball resting on R (load < 0 [N]), else inf: it leaves at once or never."""
    return math.inf if load >= 0.0 else 0.0


def departure_speed(parameters, x0, v0, tau, load):
    """v [m/s] as a rigid ball leaves R: its own (0 at rest), never < 0; -v0 for an undamped contact from R."""
    if x0 == 0.0 and v0 < 0.0 and parameters.b == 0.0:  # contact_laws.conserved_speed
        return -v0
    return max(v0, 0.0)


def decide_contact(parameters, x, v, load, hop, resolution):
    """(answer, tau, x_event, v_event) of a rigid ball resting on R: it stays (REST), or F_ext lifts it at once."""
    tau = departure_time(parameters, x, v, load)
    if math.isinf(tau):
        return REST, 0.0, 0.0, 0.0
    return IN_CLOSED_FORM, tau, 0.0, departure_speed(parameters, x, v, tau, load)


# The law's entry in the registry (contact_laws.LAWS).
LAW = ContactLaw("rigid", RIGID, ("e", "v_min"), closed_form=True,
                 description="an instantaneous impact, v+ = -e v-, resting below v_min",
                 article_algorithm=False, crossings_only=False, k_unit=None, damping_axis=None,
                 summary="rigid contact, e = {e:g}, v_min = {v_min:g} m/s")
