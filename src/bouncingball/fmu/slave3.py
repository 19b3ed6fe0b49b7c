"""The BouncingBall FMU's slave for FMI 3.0: slave_base.BallSlave with pythonfmu3, co-simulation and model exchange.

Co-simulation: do_step returns at the first impact or departure inside the step (STOP_AT_EVENT); the
FMU's binary (bouncingball_fmu3_loader.c) reads the time reached (the independent variable time) and
either returns early to the master, or, where the master did not allow early return, steps on to the
end of the communication step.

Model exchange: the continuous states are h and v, their derivatives those of the current mode
(physics.Ball.acceleration), the one event indicator h - R, and the mode switches in
update_discrete_states. The master integrates; the FMU's CVODE is not used.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from pythonfmu3 import Boolean, Float64, Fmi3Slave, Int32, String
from pythonfmu3.enums import Fmi3Causality, Fmi3Initial, Fmi3Status, Fmi3Variability
from pythonfmu3.modelexchange import ModelExchange

from .. import validation
from ..physics import Mode
from .slave_base import BallSlave
from .variables import EVENT_INDICATOR, FMI3_VARIABLES, VARIABLES

# The namespace of the FMU's slave script (pythonfmu3 imports it once per process; kept as for pythonfmu).
SCRIPT_NAMESPACES: list[dict] = []
TYPES = {"Real": Float64, "Integer": Int32, "Boolean": Boolean, "String": String}
REFERENCES = {variable.name: i for i, variable in enumerate(VARIABLES + FMI3_VARIABLES)}


class DiscreteStatesUpdate(NamedTuple):
    """What update_discrete_states returns, with the attribute names pythonfmu3's binary reads.

    pythonfmu3 0.3.4's own Fmi3UpdateDiscreteStatesResult names two fields otherwise
    (discreteStateNeedsUpdate, nominalsOfContinuousStatesChanged) than its binary asks for
    (discreteStatesNeedUpdate, nominalContinuousStatesChanged), which then leaves the master's
    values as they were; tests/test_fmu3.py checks the names against the binary's strings.
    """

    discreteStatesNeedUpdate: bool = False
    terminateSimulation: bool = False
    nominalContinuousStatesChanged: bool = False
    valuesOfContinuousStatesChanged: bool = False
    nextEventTimeDefined: bool = False
    nextEventTime: float = 0.0


class BouncingBall(BallSlave, Fmi3Slave, ModelExchange):
    """A ball with compliant contact: co-simulation with early return at each contact, and model exchange."""

    STATUS = Fmi3Status
    CALLS = {"setup": "fmi3EnterInitializationMode", "step": "fmi3DoStep", "set_state": "fmi3SetFMUState"}
    STOP_AT_EVENT = True

    def __init__(self, **kwargs):
        self.time = 0.0
        self._exchange: list | None = None  # model exchange: [h, v, mode, impacts] once a call of it came
        super().__init__(**kwargs)
        self.author, self.description = BallSlave.author, BallSlave.description  # pythonfmu3 resets them
        getters = {"time": lambda: self._integrator.t if self._exchange is None and self._integrator else self.time,
                   "der(h)": self._v, "der(v)": self._a, "gap": self._gap}
        for variable in FMI3_VARIABLES:
            self._register(variable, getters[variable.name],
                           lambda value, name=variable.name: self._error(f"{name} cannot be set"))

    def _register(self, variable, getter, setter) -> None:
        extra = {"derivative": REFERENCES[variable.derivative]} if variable.derivative else {}
        self.register_variable(TYPES[variable.type](
            variable.name, causality=Fmi3Causality[variable.causality],
            variability=Fmi3Variability[variable.variability], description=variable.description,
            initial=Fmi3Initial[variable.initial] if variable.initial else None, getter=getter, setter=setter,
            **extra), has_event_indicator=variable.name == EVENT_INDICATOR)

    def set_time(self, time):
        """Before initialisation the start time (fmi3EnterInitializationMode's, from the binary); after, ME time."""
        self.time = time
        if self._integrator is None:
            self._start_time = time
        else:
            self._model_exchange()

    def exit_initialization_mode(self):
        super().exit_initialization_mode()
        if self._integrator is not None:
            self.time = self._integrator.t

    # --- model exchange ---------------------------------------------------------------------------
    def _model_exchange(self) -> list:
        """The model exchange state, from the initialised integrator's at the first call that needs it."""
        if self._exchange is None:
            integrator = self._integrator
            self._exchange = [integrator.h, integrator.v, integrator.mode, integrator.impacts]
        return self._exchange

    def get_continuous_states(self):
        return self._model_exchange()[:2]

    def set_continuous_states(self, values):
        state = self._model_exchange()
        try:
            state[0], state[1] = (validation.finite(name, value, unit) for name, value, unit in
                                  zip(("h", "v"), values, ("m", "m/s"), strict=True))
        except ValueError as error:
            self._error(error)

    def get_continuous_state_derivatives(self):
        return [self._v(), self._a()]

    def get_event_indicators(self):
        return [self._gap()]

    def get_nominals_of_continuous_states(self, size):
        """h: the larger of R and the start height; v: the speed of a fall from there (1 m/s without one)."""
        ball = self._integrator.ball if self._integrator else None
        R, g = (ball.R, ball.g) if ball else (self._values["R"], self._values["g"])
        h0 = abs(self._values["h"])
        speed = max(abs(self._values["v"]), math.sqrt(2.0 * abs(g) * max(abs(h0 - R), R)))
        return [max(R, h0), speed if speed > 0.0 else 1.0][:size]

    def update_discrete_states(self):
        """The mode switch: to contact where h - R has turned negative, to flight where it turned positive."""
        if self._integrator is None:
            return DiscreteStatesUpdate()
        state = self._model_exchange()
        h, v, mode, impacts = state
        x = h - self._integrator.ball.R
        if mode == Mode.FLIGHT and (x < 0.0 or (x == 0.0 and v < 0.0)):
            state[2], state[3] = Mode.CONTACT, impacts + 1
        elif mode == Mode.CONTACT and (x > 0.0 or (x == 0.0 and v > 0.0)):
            state[2] = Mode.FLIGHT
        return DiscreteStatesUpdate()

    # --- outputs: the model exchange state once there is one, else the integrator's -------------------
    def _h(self):
        return self._exchange[0] if self._exchange else super()._h()

    def _v(self):
        return self._exchange[1] if self._exchange else super()._v()

    def _a(self):
        if not self._exchange:
            return super()._a()
        h, v, mode, _ = self._exchange
        return self._integrator.ball.acceleration(h, v, mode, self._values["F_ext"])

    def _contact(self):
        return self._exchange[2] == Mode.CONTACT if self._exchange else super()._contact()

    def _contact_force(self):
        if not self._exchange:
            return super()._contact_force()
        h, v, mode, _ = self._exchange
        return self._integrator.ball.contact_force(h, v, mode)

    def _impacts(self):
        return self._exchange[3] if self._exchange else super()._impacts()

    def _gap(self):
        return self._h() - (self._integrator.ball.R if self._integrator else self._values["R"])

    # --- FMU state: the model exchange state too -----------------------------------------------------
    def _get_fmu_state(self):
        state = super()._get_fmu_state()
        exchange = self._exchange
        state["model_exchange"] = None if exchange is None else [*exchange[:2], int(exchange[2]), exchange[3],
                                                                  self.time]
        return state

    def _set_fmu_state(self, state):
        try:
            saved = state.get("model_exchange") if isinstance(state, dict) else None
            exchange = None if saved is None else [validation.finite("state h", saved[0], "m"),
                                                   validation.finite("state v", saved[1], "m/s"),
                                                   Mode(saved[2]), int(saved[3]), validation.finite("state time",
                                                                                                    saved[4], "s")]
        except (TypeError, ValueError, IndexError) as error:
            self._error(f"{self.CALLS['set_state']} failed, nothing was changed: {error}")
            return
        before = len(self.log_queue)
        super()._set_fmu_state(state)
        if any(message.status >= Fmi3Status.error for message in self.log_queue[before:]):
            return
        self._exchange = None if exchange is None else exchange[:4]
        if exchange is not None:
            self.time = exchange[4]
