"""The FMU's interface in one table: read by the build (units, min/max in the XML) and by the slave."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .. import validation
from ..contact_laws import CONTACT_LAWS, CONTACT_PARAMETERS, LAWS
from ..ground import SINE_AMPLITUDE_RANGE, SINE_FREQUENCY_RANGE, SINE_PHASE_RANGE, Ground, checked_sine
from ..solvers.phase_machine.settings import MIN_RTOL

MODEL_NAME = "BouncingBall"
SMALLEST_POSITIVE = math.ulp(0.0)  # FMI's min is inclusive: "> 0" is ">= 5e-324"

# SI units as exponents of the base units
UNITS = {
    "s": {"s": 1},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "kg": {"kg": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "s/m": {"m": -1, "s": 1},
    "Hz": {"s": -1},
    "rad": {"rad": 1},
}


@dataclass(frozen=True)
class FmuVariable:
    """One variable of the FMU's interface; the slave registers these, the build adds unit/min/max."""

    name: str
    type: str  # Real, Integer, Boolean or String
    causality: str  # parameter, input, output (FMI 3.0 also local and independent)
    variability: str  # fixed, continuous or discrete
    description: str
    unit: str = ""
    min: float | None = None
    max: float | None = None
    initial: str = ""  # "exact" for outputs whose start value is the initial state
    derivative: str = ""  # FMI 3.0 model exchange: the name of the continuous state this is the derivative of


VARIABLES = (
    FmuVariable("m", "Real", "parameter", "fixed", "mass of the ball (> 0)", "kg", SMALLEST_POSITIVE),
    FmuVariable("k", "Real", "parameter", "fixed", "contact spring stiffness (> 0; contact_law hunt-crossley: "
                "in N/m^n)", "N/m", SMALLEST_POSITIVE),
    FmuVariable("b", "Real", "parameter", "fixed", "contact damping coefficient (>= 0)", "N.s/m", 0.0),
    FmuVariable("R", "Real", "parameter", "fixed", "radius of the ball: contact while h < R (> 0)", "m",
                SMALLEST_POSITIVE),
    FmuVariable("g", "Real", "parameter", "fixed", "gravitational acceleration (>= 0)", "m/s2", 0.0),
    FmuVariable("h", "Real", "output", "continuous", "height of the ball's centre; its start value is the "
                "initial height", "m", initial="exact"),
    FmuVariable("v", "Real", "output", "continuous", "vertical velocity dh/dt, upwards positive; its start "
                "value is the initial velocity", "m/s", initial="exact"),
    FmuVariable("a", "Real", "output", "continuous", "vertical acceleration dv/dt", "m/s2"),
    FmuVariable("contact", "Boolean", "output", "discrete", "true while the ball touches the ground (contact_law "
                "rigid: while it rests on it; linear-no-pull: while the ground pushes it)"),
    FmuVariable("contact_force", "Real", "output", "continuous", "force of the ground on the ball, upwards "
                "positive (contact_law linear: the damper can pull just before departure; rigid: the load of a "
                "ball resting on the ground, 0 otherwise: an impact's impulse is not a force)", "N"),
    FmuVariable("impacts", "Integer", "output", "discrete", "number of impacts since the start", min=0),
    FmuVariable("F_ext", "Real", "input", "continuous", "external vertical force on the ball, upwards "
                "positive, held constant over each communication step", "N"),
    FmuVariable("rtol", "Real", "parameter", "fixed", "CVODE relative tolerance, in [1e-15, 1], relative to each "
                "phase's own scale; a tighter tolerance the master gives (FMI 2.0: fmi2SetupExperiment) replaces "
                "it, a looser one does not", min=MIN_RTOL, max=1.0),
    FmuVariable("atol", "Real", "parameter", "fixed", "upper bound on CVODE's absolute error of h (0, or at "
                "least an ulp of max(|h|, R)); 0, the default, for none: the error is controlled relative to each "
                "phase's own scale", "m", 0.0),
    FmuVariable("method", "String", "parameter", "fixed", "CVODE method: auto (Adams in flight, BDF for a "
                "stiff contact), Adams or BDF"),
    FmuVariable("engine", "String", "parameter", "fixed", "CVODE engine: sksundae (scikit-sundae's CVODE), "
                "compiled (the same CVODE with callbacks compiled by numba, which the Python running the FMU "
                "must have) or auto (compiled where numba is installed, else sksundae); compiled makes each "
                "doStep cheaper but its first use in a process takes seconds, so it pays only in a long "
                "co-simulation"),
    FmuVariable("error_estimate", "Real", "output", "continuous", "estimate of max |h - h_true| since the start, "
                "at or above the error already made at each communication point: co-simulation, from the run's own "
                "errors carried by its sensitivity, the current phase so far included; model exchange, the "
                "master's states measured against each phase's exact flow and carried across events (-1, unknown, "
                "under contact_law hunt-crossley, which has no closed form); above 1e-6 of the height scale the log "
                "says from when the run cannot be trusted", "m"),
    # After the seed's variables, so that theirs keep their value references.
    FmuVariable("contact_law", "String", "parameter", "fixed", "the contact law: linear (the spring k and damper "
                "b, the default), rigid (an instantaneous impact on h = R with restitution e; k and b play no "
                "part), linear-no-pull (the spring and damper whose force max(0, k (R - h) - b v) never pulls) or "
                "hunt-crossley (k delta^n (1 + 3/2 alpha delta'), delta = R - h, clipped at 0; b plays no part)"),
    FmuVariable("e", "Real", "parameter", "fixed", "contact_law rigid: coefficient of restitution, v+ = -e v- at "
                "each impact, in [0, 1]", min=0.0, max=1.0),
    FmuVariable("v_min", "Real", "parameter", "fixed", "contact_law rigid: a bounce that would leave slower "
                "than v_min ends at rest on the ground (>= 0; 0: every bounce, the infinitely many before the Zeno "
                "time summed exactly)", "m/s", 0.0),
    FmuVariable("n", "Real", "parameter", "fixed", "contact_law hunt-crossley: exponent of the penetration delta "
                "= R - h in the force, in [1, 2.5] (1.5: Hertz's sphere on a flat)", min=1.0, max=2.5),
    FmuVariable("alpha", "Real", "parameter", "fixed", "contact_law hunt-crossley: damping of the force, its "
                "restitution about 1 - alpha v at impact speed v (>= 0)", "s/m", 0.0),
    FmuVariable("ground_amplitude", "Real", "parameter", "fixed", "amplitude A of the ground's vibration s(t) = A "
                "sin(2 pi f t + p), every contact law: contact where h = R + s(t) (0, the default: a still ground at "
                "0, ground_frequency and ground_phase not read; else in [1e-100, 1e100])", "m", 0.0,
                SINE_AMPLITUDE_RANGE[1]),
    FmuVariable("ground_frequency", "Real", "parameter", "fixed", "frequency f of the ground's vibration (in [1e-6, "
                "1e6] where ground_amplitude > 0)", "Hz", 0.0, SINE_FREQUENCY_RANGE[1]),
    FmuVariable("ground_phase", "Real", "parameter", "fixed", "phase p of the ground's vibration at t = 0 (a larger "
                "one, reduced modulo 2 pi, is the same ground)", "rad", *SINE_PHASE_RANGE),
)


OUTPUTS = tuple(variable.name for variable in VARIABLES if variable.causality == "output")
# The solution's outputs, which the reference result holds: not error_estimate, the run's own diagnosis.
SOLUTION_OUTPUTS = tuple(name for name in OUTPUTS if name != "error_estimate")

# A scene and the FMU's start values, name by name: the ball's parameters under their own names, the
# scene's start state and force as h, v and F_ext. The one mapping of the slave's defaults, validate,
# the bench and `check` (testing.scene_with_start_values).
# The contact laws the FMU runs, in co-simulation and in model exchange (model_exchange.py's events): every law of
# the registry, the slave running the phase machine, which takes each. A law it could not run would be left out.
FMU_CONTACT_LAWS = CONTACT_LAWS

SCENE_FIELD_OF_START_VALUE = {"m": "m", "k": "k", "b": "b", "R": "R", "g": "g", "contact_law": "contact",
                              **{name: name for name in CONTACT_PARAMETERS if name not in ("k", "b")},
                              "h": "h0", "v": "v0", "F_ext": "F_ext"}
SCENE_OWN_FIELDS = ("h0", "v0", "F_ext")  # the others are the ball's (physics.Ball's fields)
# The scene's ground (a still one at 0, or a sine) by the FMU's parameters: each a field of ground.Ground.
GROUND_FIELD_OF_START_VALUE = {"ground_amplitude": "amplitude", "ground_frequency": "frequency",
                               "ground_phase": "phase"}
TEXT_START_VALUES = ("contact_law",)  # the others are numbers


def start_values_of(scene) -> dict[str, float | str]:
    """The FMU's start values that run scene (a scenes.Scene, fmu_ground_scene's), by SCENE_FIELD_OF_START_VALUE and
    GROUND_FIELD_OF_START_VALUE (a ground the FMU does not run gives a still one's: 0)."""
    return {**{name: getattr(scene if field in SCENE_OWN_FIELDS else scene.ball, field)
               for name, field in SCENE_FIELD_OF_START_VALUE.items()},
            **{name: getattr(scene.ground, field) for name, field in GROUND_FIELD_OF_START_VALUE.items()}}


def ground_of(start_values) -> Ground:
    """The ground of the FMU's start values (a mapping that has GROUND_FIELD_OF_START_VALUE's): still at 0 where
    ground_amplitude is 0, else the sine; ValueError names a value out of its range."""
    amplitude = validation.non_negative("ground_amplitude", start_values["ground_amplitude"], "m")
    if amplitude == 0.0:
        return Ground()
    frequency = start_values["ground_frequency"]
    if not validation.finite("ground_frequency", frequency, "Hz") > 0.0:
        raise ValueError(f"ground_frequency = {frequency!r} Hz is not allowed with ground_amplitude = {amplitude!r} m: "
                         "it must be > 0 (ground_amplitude = 0 for a still ground)")
    return Ground.sine(*checked_sine(amplitude, frequency, start_values["ground_phase"],
                                     names=("ground_amplitude", "ground_frequency", "ground_phase")))


def fmu_scene(scene):
    """The scene (a scenes.Scene), if the FMU runs its contact law (FMU_CONTACT_LAWS); else ValueError naming it."""
    if scene.ball.contact not in FMU_CONTACT_LAWS:
        raise ValueError(f"scene {scene.name!r} has contact = {scene.ball.contact!r}: the FMU models the contact laws "
                         f"{', '.join(FMU_CONTACT_LAWS)}; run the scene with `bouncingball run`")
    return scene


def fmu_ground_scene(scene):
    """The scene (fmu_scene's), if the FMU also runs its ground: still at 0 or a sine; else ValueError saying so."""
    ground = fmu_scene(scene).ground
    if ground.kind == "table" or ground.height != 0.0:
        raise ValueError(f"scene {scene.name!r} on its ground ({ground.describe()}) is not allowed for the FMU: it "
                         "runs on a still ground at 0 or a sine (ground_amplitude, ground_frequency, ground_phase); "
                         "run the scene with `bouncingball run --solver exact`, or judge a master's result of it "
                         "with `bouncingball check`")
    return scene


def judged_scene(scene, judge: str):
    """The scene (fmu_scene's), if the exact solution can judge a run of it; else ValueError saying why (judge: who).

    Every law the FMU runs has one but Hunt and Crossley's, whose contact has no closed form.
    """
    contact = fmu_scene(scene).ball.contact
    if not LAWS[contact].closed_form:
        raise ValueError(f"{judge} judges a run against the exact solution, and contact_law = {contact!r} has none "
                         "(its contact has no closed form); compare the run with bouncingball.simulate at a tight "
                         "rtol (1e-13) instead")
    return scene


def ball_fields_of(start_values) -> dict[str, float | str]:
    """physics.Ball's keyword arguments from the FMU's start values (a mapping that has all of them)."""
    return {field: start_values[name] for name, field in SCENE_FIELD_OF_START_VALUE.items()
            if field not in SCENE_OWN_FIELDS}

# FMI 3.0 only, after the shared table, so that every variable above keeps its value reference: the
# independent variable, the derivatives of model exchange's continuous states x = h - R and v, the event
# indicator, and x itself (last: the variables before it kept their references when it came).
FMI3_VARIABLES = (
    FmuVariable("time", "Real", "independent", "continuous", "simulation time", "s"),
    FmuVariable("der(x)", "Real", "local", "continuous", "dx/dt = v, the derivative of the continuous state x "
                "(model exchange)", "m/s", derivative="x"),
    FmuVariable("der(v)", "Real", "local", "continuous", "dv/dt, the derivative of the continuous state v "
                "(model exchange)", "m/s2", derivative="v"),
    FmuVariable("gap", "Real", "local", "continuous", "the event indicator, >= 0 out of contact and <= 0 in it, "
                "crossing 0 at each event: h - R [m] in flight and in the linear law's contact (an impact where it "
                "crosses 0 downwards, a departure upwards); linear-no-pull: h - R + (b/k) v [m] pressed, the least "
                "of that and R - h free; rigid, resting on the ground: F_ext/m - g [m/s2]"),
    FmuVariable("x", "Real", "local", "continuous", "h - R, the height of the ball's bottom above the ground's rest "
                "level: model exchange's continuous state (with v), 0 where the ball touches a still ground", "m"),
)
EVENT_INDICATOR = "gap"
