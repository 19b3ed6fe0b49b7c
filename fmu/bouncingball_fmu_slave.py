"""BouncingBall: the bouncing ball as an FMI 2.0 co-simulation slave, a thin adapter for pythonfmu.

Every number comes from bouncingball's CVODE integrator (BallIntegrator); the interface is
bouncingball.fmu_build.VARIABLES. Nothing here raises: pythonfmu would turn an exception into
fmi2Fatal and release the instance. Errors are logged with status error instead, and the FMU's
binary (fmu/bouncingball_fmu_loader.c) returns fmi2Error for a call that logged one.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict

from pythonfmu import Boolean, Fmi2Slave, Integer, Real, String
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Status, Fmi2Variability

from bouncingball import validation
from bouncingball.fmu_build import VARIABLES
from bouncingball.physics import Ball, Mode
from bouncingball.scenes import BALL_KEYS, SCENE_DEFAULTS
from bouncingball.solvers.cvode import BallIntegrator, CvodeSettings, IntegratorState, SolverError

STATE_FORMAT = "bouncingball-fmu-state-1"
SETTABLE_AFTER_INITIALISATION = ("F_ext",)
TYPES = {"Real": Real, "Integer": Integer, "Boolean": Boolean, "String": String}


class BouncingBall(Fmi2Slave):
    """A ball with compliant contact, integrated by CVODE with every contact found by root-finding."""

    author = "bouncingball"
    description = ("A ball with compliant contact (spring k, damper b) over rigid ground, integrated by "
                   "SUNDIALS CVODE; every impact and departure inside a step is found by root-finding")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # The values set by the master: parameters, start values of h and v, and the input F_ext. The
        # defaults are the article's; they are not read from the package's data files, because a master
        # (FMPy) may delete the unzipped FMU whose modules this process keeps using.
        ball, settings = Ball(), CvodeSettings()
        self._values = {**{key: getattr(ball, key) for key in BALL_KEYS}, "h": SCENE_DEFAULTS["h0"],
                        "v": SCENE_DEFAULTS["v0"], "F_ext": SCENE_DEFAULTS["F_ext"], "rtol": settings.rtol,
                        "atol": settings.atol, "method": settings.method}
        self._start_time = 0.0
        self._tolerance: float | None = None
        self._integrator: BallIntegrator | None = None
        outputs = {"h": self._h, "v": self._v, "a": self._a, "contact": self._contact,
                   "contact_force": self._contact_force, "impacts": self._impacts}
        for variable in VARIABLES:
            getter = outputs.get(variable.name) or (lambda name=variable.name: self._values[name])
            self.register_variable(TYPES[variable.type](
                variable.name, causality=Fmi2Causality[variable.causality],
                variability=Fmi2Variability[variable.variability], description=variable.description,
                initial=Fmi2Initial[variable.initial] if variable.initial else None, getter=getter,
                setter=lambda value, name=variable.name: self._set(name, value)))

    # --- FMI calls ------------------------------------------------------------------------------
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._start_time = start_time
        self._tolerance = tolerance

    def exit_initialization_mode(self):
        try:
            self._integrator = self._make_integrator()
        except ValueError as error:
            self._error(error)

    def do_step(self, current_time, step_size):
        """Advance from current_time by step_size [s], resolving every contact on the way."""
        integrator = self._integrator
        if integrator is None:
            self._error("fmi2DoStep before initialisation (or after a failed one)")
            return False
        try:
            # A master's own rounding of the communication points is tolerated, a jump is not.
            if not abs(current_time - integrator.t) <= 1e-9 * max(1.0, abs(integrator.t)):
                raise ValueError(f"currentCommunicationPoint = {current_time!r} s is not allowed: "
                                 f"the FMU is at t = {integrator.t!r} s")
            if not step_size >= 0.0:
                raise ValueError(f"communicationStepSize = {step_size!r} s is not allowed: it must be >= 0")
            integrator.advance(max(current_time + step_size, integrator.t))
        except (ValueError, SolverError) as error:
            self._error(error)
            return False
        return True

    # --- FMU state: everything needed to continue exactly, in this or a fresh instance ------------
    def _get_fmu_state(self):
        integrator = None
        if self._integrator is not None:
            state = self._integrator.get_state()
            integrator = {**asdict(state), "mode": int(state.mode)}
        return {"format": STATE_FORMAT, "values": dict(self._values), "start_time": self._start_time,
                "tolerance": self._tolerance, "integrator": integrator}

    def _set_fmu_state(self, state):
        try:
            if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
                reason = state.get("invalid", "") if isinstance(state, dict) else ""
                raise ValueError(f"it is not a {self.modelName} state ({STATE_FORMAT}) {reason}")
            self._values = dict(state["values"])
            self._start_time, self._tolerance = state["start_time"], state["tolerance"]
            saved = state["integrator"]
            if saved is None:
                self._integrator = None
                return
            ball, settings = self._ball_and_settings()
            current = self._integrator
            if current is None or (current.ball, current.settings) != (ball, settings):
                current = BallIntegrator(ball, saved["h"], saved["v"], saved["t"], saved["F_ext"], settings)
            current.set_state(IntegratorState(**{**saved, "mode": Mode(saved["mode"])}))
            self._integrator = current
        except (KeyError, TypeError, ValueError) as error:
            self._error(f"fmi2SetFMUstate failed: {error}")

    @staticmethod
    def _fmu_state_from_bytes(state: bytes):
        try:
            return json.loads(state.decode("utf-8"))
        except ValueError as error:  # includes UnicodeDecodeError and JSONDecodeError
            return {"invalid": f"the serialized state cannot be read: {error}"}

    # --- variables ------------------------------------------------------------------------------
    def _set(self, name, value):
        if name in ("a", "contact", "contact_force", "impacts"):
            self._error(f"{name} is an output: it cannot be set")
        elif self._integrator is not None and name not in SETTABLE_AFTER_INITIALISATION:
            self._error(f"{name} = {value!r} is not allowed: {name} cannot change after initialisation")
        else:
            self._values[name] = value
            if name == "F_ext" and self._integrator is not None:
                try:
                    self._integrator.F_ext = value
                except ValueError as error:
                    self._error(error)

    def _h(self):
        return self._values["h"] if self._integrator is None else self._integrator.h

    def _v(self):
        return self._values["v"] if self._integrator is None else self._integrator.v

    def _a(self):
        integrator = self._integrator or self._preview()
        return math.nan if integrator is None else integrator.acceleration

    def _contact(self):
        integrator = self._integrator or self._preview()
        return integrator is not None and integrator.mode == Mode.CONTACT

    def _contact_force(self):
        integrator = self._integrator or self._preview()
        return math.nan if integrator is None else integrator.contact_force

    def _impacts(self):
        return 0 if self._integrator is None else self._integrator.impacts

    # --- helpers ----------------------------------------------------------------------------------
    def _ball_and_settings(self) -> tuple[Ball, CvodeSettings]:
        """The ball and CVODE settings from the current values; ValueError names a bad value."""
        values = self._values
        ball = Ball(**{key: values[key] for key in BALL_KEYS})
        rtol = values["rtol"]
        if self._tolerance is not None:
            rtol = validation.in_range("tolerance (fmi2SetupExperiment, used as rtol)", self._tolerance, 0.0, 1.0)
        return ball, CvodeSettings(rtol=rtol, atol=values["atol"], method=values["method"], engine="sksundae")

    def _make_integrator(self) -> BallIntegrator:
        """An integrator at the start state; ValueError names a bad value."""
        ball, settings = self._ball_and_settings()
        values = self._values
        h, v = validation.finite("h", values["h"], "m"), validation.finite("v", values["v"], "m/s")
        return BallIntegrator(ball, h, v, self._start_time, values["F_ext"], settings)

    def _preview(self) -> BallIntegrator | None:
        """Before initialisation, outputs are those of the start state (None if a value is invalid)."""
        try:
            return self._make_integrator()
        except ValueError:
            return None

    def _error(self, error) -> None:
        self.log(str(error), Fmi2Status.error)
