"""The contact laws: one module each, their registry, and the one place (dispatch.py) that decides on the law.

- linear (the default, linear.py): the article's spring k and damper b; the damper may pull just before departure.
- rigid (rigid.py): the ball does not deform; each impact on R reverses it, v+ = -e v-, down to v_min, or to the
  Zeno time where its bounces are summed; it rests on R until F_ext lifts it.
- linear-no-pull (no_pull.py): the spring-damper whose force never pulls (Modelica's ElastoGap); below R the
  ball is pressed or free, switching where k (R - h) - b v crosses 0.
- hunt-crossley (hunt_crossley.py): k delta^n (1 + 3/2 alpha delta'), clipped at 0; no closed form: CVODE
  integrates every contact.

The contract
------------
A law's module holds what the law adds to the phase machine, as plain functions of floats (solvers/engines/jit.py's
rules: they run interpreted in the scikit-sundae engine and compiled in the other), taking Ball.parameters (a
BallParameters, read by name), the gap x = h - R [m], v [m/s] and the load m g - F_ext [N]:

1. ``contact_scales(parameters, x, v, load) -> (length [m], speed [m/s])``: the frame CVODE integrates a contact
   in, a bound on its size (phases.phase_scales).
2. ``decide_contact(parameters, x, v, load, hop, resolution) -> (answer, tau, x_event, v_event)``: how a contact
   from (x, v) is taken (common.BY_CVODE, REST or IN_CLOSED_FORM with its event tau [s] later), where hop [m] is
   the hop tolerance and resolution (HOP_RESOLUTION rtol) what CVODE resolves relative to a phase's length. A law
   with a closed-form flow takes what CVODE cannot resolve on it; one without answers BY_CVODE.
3. Where its contact differs from the linear spring-damper's: its acceleration (law_acceleration) and force
   (law_contact_force), its root functions (root_values: the terminal event first, the extremum, the rest or
   release), its flow for the polish of an event (polish_flow_mode), its free sub-mode's event (free_event), its
   rest margin, its terminal event's kind (contact_ends_in). An impact that is a jump of v with no contact phase
   (impact_is_instantaneous) takes its rebound from the law (rigid_rebound).
4. Where CVODE integrates every contact (contact_integrated: no closed form): its right-hand side and Jacobian
   (varying_jacobian), its interpolant (law_interpolant), its step's transition matrix for the error estimate
   (contact_step_transition: its force must be 0 on R, so that its events carry no saltation), its reported rest
   (reported_rest_margin), a release at the third root (third_root_releases, root_release_speed), and on a
   vibrating ground each step's exit certified on its interpolant (contact_step_exit: a graze between two of
   CVODE's steps that its root functions, seeing no change of sign, would miss).
5. Its registry entry, ``LAW = ContactLaw(...)`` in its module: its name, code (common.py), the Ball fields it
   reads, whether every phase has a closed form (the exact solver and the check take it), whether the article's
   algorithm runs it, k's unit and the sweep's damping axis, a description and a summary line; its module in
   dispatch.LAW_MODULES, which LAWS is read from (the first the default).

What the machine guarantees a law: each phase starts in one mode with the load held (a change of F_ext ends it);
an event found by CVODE is polished on the law's flow; the law is decided in dispatch.py, once per hook, never by
the machine. The dispatch is written as ``if`` on the code: numba cannot call through a table.
"""

from __future__ import annotations

from .common import BY_CVODE, HUNT_CROSSLEY, IN_CLOSED_FORM, LINEAR, NO_PULL, RIGID, BallParameters, ContactLaw
from .dispatch import (
    LAW_MODULES,
    conserved_speed,
    contact_ends_in,
    contact_event,
    contact_integrated,
    contact_scales,
    contact_step_exit,
    contact_step_transition,
    decide_contact,
    departure_speed,
    departure_time,
    free_event,
    ground_contact_event,
    ground_moves,
    has_free_sub_mode,
    has_pressed_gap,
    hunt_crossley_acceleration,
    hunt_crossley_force,
    hunt_crossley_free_event,
    hunt_crossley_jacobian,
    hunt_crossley_rest_margin,
    hunt_crossley_scales,
    hunt_crossley_state,
    impact_is_instantaneous,
    jacobian_varies,
    law_acceleration,
    law_contact_force,
    law_flow_at,
    law_flow_value,
    law_hop_tolerance,
    law_interpolant,
    law_rest_margin,
    no_pull_rest_margin_value,
    own_interpolant,
    polish_flow_mode,
    pressed_gap,
    release_speed,
    release_state,
    release_time,
    reported_acceleration,
    reported_rest_margin,
    root_release_speed,
    root_values,
    side_extreme,
    starts_free,
    third_root_releases,
    varying_jacobian,
)
from .rigid import rigid_rebound

__all__ = [
    "BY_CVODE", "BallParameters", "CONTACT_LAWS", "CONTACT_PARAMETERS", "ContactLaw", "HUNT_CROSSLEY", "IN_CLOSED_FORM",
    "LAWS", "LAW_MODULES", "LAW_PARAMETERS", "LINEAR", "NO_PULL", "RIGID", "ball_parameters", "conserved_speed",
    "contact_ends_in", "contact_event", "contact_integrated", "contact_scales", "contact_step_exit",
    "contact_step_transition",
    "decide_contact", "departure_speed", "departure_time", "free_event", "ground_contact_event", "ground_moves",
    "has_free_sub_mode", "has_pressed_gap",
    "hunt_crossley_acceleration", "hunt_crossley_force", "hunt_crossley_free_event", "hunt_crossley_jacobian",
    "hunt_crossley_rest_margin", "hunt_crossley_scales", "hunt_crossley_state", "impact_is_instantaneous",
    "jacobian_varies", "law_acceleration", "law_contact_force", "law_flow_at", "law_flow_value", "law_hop_tolerance",
    "law_interpolant", "law_rest_margin", "no_pull_rest_margin_value", "own_interpolant", "polish_flow_mode",
    "pressed_gap", "release_speed", "release_state", "release_time", "reported_acceleration", "reported_rest_margin",
    "rigid_rebound", "root_release_speed", "root_values", "side_extreme", "starts_free", "third_root_releases",
    "varying_jacobian",
]


LAWS = {module.LAW.name: module.LAW for module in LAW_MODULES if hasattr(module, "LAW")}  # the default first
CONTACT_LAWS = tuple(LAWS)  # their names
# The parameters each law reads besides the ball's m, R and g, by its name: another law's parameter set to a
# value other than Ball's default is refused by name (Ball, CLI, scene files), logged by the FMU (physics.py).
LAW_PARAMETERS = {name: law.parameters for name, law in LAWS.items()}
CONTACT_PARAMETERS = tuple(dict.fromkeys(name for law in LAWS.values() for name in law.parameters))  # every law's


def ball_parameters(contact, fields):
    """BallParameters of a ball of the law named contact, from its fields (a mapping of m, R, g and CONTACT_PARAMETERS).

    A law that does not read b has no linear damper: b is 0.0 (the phase machine's saltation at an event and the
    hop rule read it). A ball with b = 0 of a law that is then another's run (ContactLaw.undamped_as: the no-pull
    law's, the linear law's) has that law's code: the same run.
    """
    law = LAWS[contact]
    b = fields["b"] if "b" in law.parameters else 0.0
    code = LAWS[law.undamped_as].code if law.undamped_as is not None and not b > 0.0 else law.code
    values = {**fields, "b": b, "law": float(code)}
    values.update(ground_amplitude=0.0, ground_omega=0.0, ground_phase=0.0)  # a still ground; the ball's own
    return BallParameters(*(values[name] for name in BallParameters._fields))
