"""CVODE's settings and the rules that follow from its tolerance (the hops it may merge).

Kept apart from the integrator, so that reports, the sweep's grid and the check of a master's
result can read them without loading an engine.
"""

from __future__ import annotations

from dataclasses import dataclass

from ... import validation
from ...contact_laws import law_hop_tolerance
from ...equations import load_value
from ...physics import Ball, Mode

METHODS = ("auto", "Adams", "BDF")
ENGINES = ("auto", "compiled", "sksundae")
# Each contact's departure speed comes out ~20 rtol off (CVODE's local errors over its ~50 steps),
# and a ball that keeps its energy keeps those errors: event times drift with the square of the
# number of bounces. Measured with the state scaled to each phase: at 1e-11 an R = 1 um ball of
# 912 events ends 2e-5 of its height scale off; at 1e-12 5e-8, in 8% fewer steps (Adams' order
# rises); the article 1e-10 m.
DEFAULT_RTOL = 1e-12
# No absolute bound by default: CVODE integrates the gap x = h - R scaled to each phase (see
# phase_scales), so rtol is relative to the phase's own size whatever R, the drop height or the
# stiffness. An atol, where given, only tightens that rule.
DEFAULT_ATOL = None
# CVODE refuses a relative tolerance below its unit roundoff, 2.2e-16 ("too much accuracy", at t = 0);
# at that roundoff its error test passes on the rounding of the state alone. 1e-15, 4.5 of it, leaves the
# corrector's few ulps of rounding room: every built-in scene ran at 2.2e-16 .. 1e-15 on both engines,
# and the error stops following rtol there (the article 1.1e-12 of its height scale at 1e-15, 4.7e-14 at
# 2.3e-16, 1.9e-12 at 1e-14).
MIN_RTOL = 1e-15
RTOL_RANGE_WHY = "CVODE cannot honour a relative tolerance within a few ulps of double precision's 2.2e-16"
# The contact oscillator is stiff for Adams when it is strongly over-damped (fast and slow rates
# far apart). A high natural frequency alone is not: a bounce must be resolved for accuracy
# anyway, where Adams beats BDF (an undamped k = 1e8 N/m ball over 39 contacts: 1.1e-9 m in 1707
# steps against 5.7e-8 m in 3842), and a rest, where BDF's large steps paid off, is taken in
# closed form.
STIFF_DAMPING_RATIO = 2.0
# A hop whose apex is within this many rtol of the static deflection above R cannot be told from the
# contact's own error (CVODE controls the contact relative to its amplitude, ~ the deflection near rest).
HOP_RESOLUTION = 10.0
MERGED_HOP_MARGIN = 10.0
# The promise: max |h - h_true| <= PROMISE max(|h|, R) over a run. A run whose error estimate passes it
# says so (AccuracyWarning).
PROMISE = 1e-6
# CVODE's error inside a phase, where only its end is measured (error_estimate.phase_error): this many rtol the
# phase's length scale. Measured against the mpmath solution: tests/test_error_estimate.py.
ERROR_WITHIN_PHASE = 5.0
# The bound is first order in the errors (the flows are exact, the events linearised): twice it keeps it above
# the true error where second-order terms and rounding add to it (tests/test_error_estimate.py).
ESTIMATE_SAFETY = 2.0
# Under the Hunt-Crossley law a contact's error is bounded by what CVODE's error test let through at each step
# (error_estimate._contact_step): this many times the ellipse the test holds its estimate of the
# local error in, for an error it underestimated. Measured against the mpmath solution: tests/test_hunt_crossley.py.
LOCAL_ERROR_SAFETY = 2.0
ESTIMATE_CAP = 10.0  # an error estimate is at most this many times the height scale: the run is then lost


def choose_method(ball: Ball) -> str:
    """The rule behind method="auto": BDF for a stiff contact, Adams otherwise.

    Stiff means damping ratio >= 2 (over-damped, the fast and slow rates differ by >= 14x).
    Flight is never stiff.
    """
    return "BDF" if ball.damping_ratio >= STIFF_DAMPING_RATIO else "Adams"


@dataclass(frozen=True)
class CvodeSettings:
    """rtol [-], atol [m] (None or 0: none), method ("auto", "Adams", "BDF"), max_step [s] (0: none), engine.

    rtol, in [MIN_RTOL, 1], is relative to each phase's own scale (see phase_scales); atol, where given,
    is an upper bound on the absolute error of h and never loosens that rule. The floors of atol and
    max_step depend on the scene: limits.check_cvode_settings.

    engine: "sksundae" (scikit-sundae's CVODE with Python callbacks), "compiled" (the same CVODE
    library driven by compiled callbacks and a compiled stepping loop, needs numba) or "auto"
    (compiled where it can run); see choose_engine.
    """

    rtol: float = DEFAULT_RTOL
    atol: float | None = DEFAULT_ATOL
    method: str = "auto"
    max_step: float = 0.0
    engine: str = "auto"

    def __post_init__(self) -> None:
        """Check every setting before the settings exist."""
        object.__setattr__(self, "rtol", validation.in_closed_range("rtol", self.rtol, MIN_RTOL, 1.0,
                                                                    why=RTOL_RANGE_WHY))
        if self.atol is not None:  # 0 is none, as the FMU's parameter and the command line's --atol 0 say
            object.__setattr__(self, "atol", validation.non_negative("atol", self.atol, "m") or None)
        object.__setattr__(self, "method", validation.choice("method", self.method, METHODS))
        object.__setattr__(self, "max_step", validation.non_negative("max_step", self.max_step, "s"))
        object.__setattr__(self, "engine", validation.choice("engine", self.engine, ENGINES))


def hop_tolerance(ball: Ball, rtol: float = DEFAULT_RTOL, atol: float | None = DEFAULT_ATOL,
                  F_ext: float = 0.0) -> float:
    """The highest hop [m] above R that CVODE may merge into the contact around it: the tolerance's one hop rule.

    Near rest CVODE controls a contact to rtol times its amplitude, which is then about the static
    deflection d, so a hop rising less than HOP_RESOLUTION rtol d above R cannot be told from that
    error: a contact that cannot lift the ball higher is taken as a rest, and a flight lower than
    that is taken in closed form. An undamped contact never comes to rest (its energy is kept), and
    neither does a lifted one (d <= 0): there the rule is 0, every hop is integrated. A rigid ball has
    no contact to merge a hop into: 0 (its bounces too low to tell are summed, contact_laws.rigid_rebound). The
    Hunt-Crossley law's is HOP_RESOLUTION rtol its contact's length scale near rest, (2 (n + 1) (m g - F_ext) / k)^(1/n)
    (contact_laws.hunt_crossley_hop_tolerance), 0 with alpha = 0. Each law's rule: contact_laws.law_hop_tolerance.
    """
    tolerance = law_hop_tolerance(ball.parameters, load_value(F_ext, ball.m, ball.g), HOP_RESOLUTION * rtol)
    return tolerance if atol is None else min(tolerance, HOP_RESOLUTION * atol)


def merged_hop_limit(ball: Ball, rtol: float = DEFAULT_RTOL, atol: float | None = DEFAULT_ATOL,
                     F_ext: float = 0.0) -> float:
    """The highest hop [m] a CVODE result may lack or add against the exact solution: MERGED_HOP_MARGIN hop_tolerance.

    CVODE decides a rest on its own state, which is off by its tolerance, so a hop a little above
    hop_tolerance may be merged too. The one rule every comparison with the exact solution uses.
    """
    return MERGED_HOP_MARGIN * hop_tolerance(ball, rtol, atol, F_ext)


def too_many_steps_cause(settings: CvodeSettings, method: str, mode, max_steps: int) -> str:
    """Why a phase in mode took more than max_steps steps with method: max_step, stiffness for Adams, or the tolerance.

    max_step caps its steps; Adams creeps through a stiff contact; else the tolerance asks for them.
    """
    causes = []
    if settings.max_step > 0.0:
        causes.append(f"max_step = {settings.max_step!r} s lets {max_steps} steps cover only "
                      f"{max_steps * settings.max_step:.3g} s; raise max_step (or set 0 for none)")
    if method == "Adams" and mode == Mode.CONTACT:
        causes.append("the problem is stiff for this method; use method 'BDF' (or 'auto')")
    return "; or ".join(causes) or "loosen rtol/atol"
