"""The BouncingBall FMU's slave for FMI 3.0: slave_base.BallSlave with pythonfmu3, co-simulation and model exchange.

Co-simulation: do_step returns at the first impact or departure inside the step (STOP_AT_EVENT); the
FMU's binary (bouncingball_fmu3_loader.c) reads the time reached (the independent variable time) and
either returns early to the master, or, where the master did not allow early return, steps on to the
end of the communication step.

Model exchange: the continuous states are x = h - R (the bottom's height: 0 where the ball touches a still ground,
as the state of the Reference-FMUs' ball, so that a master's CVODE restarts after an impact as from their 0 and not
from R, model_exchange.py) and v, their derivatives those of the current mode
(physics.Ball.acceleration), the one event indicator h - R, and the mode switches in
update_discrete_states. The master integrates; the FMU's CVODE is not used. On a vibrating ground each is taken
in the table's frame (model_exchange.in_frame: h - s, v - s', the table's acceleration a load of its own), as the phase
machine takes it.
"""

from __future__ import annotations

from typing import NamedTuple

from pythonfmu3 import Boolean, Float64, Fmi3Slave, Fmi3StepResult, Int32, String
from pythonfmu3.enums import Fmi3Causality, Fmi3Initial, Fmi3Status, Fmi3Variability
from pythonfmu3.modelexchange import ModelExchange

from .. import validation
from ..contact_laws import impact_is_instantaneous
from ..equations import load_value
from ..physics import Mode, clipped_contact_mode
from ..solvers.vibrating_ground import ground_motion, relative_to
from .master_error import UNKNOWN, MasterError, MeasuredMaster
from .model_exchange import (
    UNRESOLVED_APEX_PER_RTOL,
    event_indicator,
    in_frame,
    in_world,
    phase_nominals,
    rigid_impact,
    switched_mode,
)
from .saved_state import exchange_fields, saved_exchange
from .slave_base import BallSlave
from .variables import EVENT_INDICATOR, FMI3_VARIABLES, VARIABLES

TYPES = {"Real": Float64, "Integer": Int32, "Boolean": Boolean, "String": String}
REFERENCES = {variable.name: i for i, variable in enumerate(VARIABLES + FMI3_VARIABLES)}
_TIME_ONLY = [REFERENCES["time"]]
# The binary's call after each fmi3CompletedIntegratorStep (bouncingball_fmu3_loader.c's completed_step): time twice.
_COMPLETED_STEP = [REFERENCES["time"], REFERENCES["time"]]


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


class BouncingBall(MeasuredMaster, BallSlave, Fmi3Slave, ModelExchange):
    """A ball with compliant contact: co-simulation with early return at each contact, and model exchange."""

    STATUS = Fmi3Status
    CALLS = {"setup": "fmi3EnterInitializationMode", "step": "fmi3DoStep", "set_state": "fmi3SetFMUState"}
    STOP_AT_EVENT = True
    VERSION_GETTERS = {"time": "_time", "der(x)": "_v", "der(v)": "_a", "gap": "_gap", "x": "_x"}
    # Made once: pythonfmu3's binary reads status and terminateSimulation off what do_step returns, and off a bool
    # each is an attribute lookup that fails (an AttributeError raised and cleared) on every doStep.
    STEPPED, REFUSED = Fmi3StepResult(Fmi3Status.ok), Fmi3StepResult(Fmi3Status.discard)

    def __init__(self, **kwargs):
        self.time = 0.0
        self._exchange: list | None = None  # model exchange (_model_exchange) once a call of it came
        self._fell_through = False  # said once: a master stepped over an impact unseen (get_event_indicators)
        self._master_error: MasterError | None = None  # model exchange: the master's error (master_error.py)
        super().__init__(**kwargs)
        self.author, self.description = BallSlave.author, BallSlave.description  # pythonfmu3 resets them

    def _register(self, variable, getter, setter) -> None:
        extra = {"derivative": REFERENCES[variable.derivative]} if variable.derivative else {}
        self.register_variable(TYPES[variable.type](
            variable.name, causality=Fmi3Causality[variable.causality],
            variability=Fmi3Variability[variable.variability], description=variable.description,
            initial=Fmi3Initial[variable.initial] if variable.initial else None, getter=getter, setter=setter,
            **extra), has_event_indicator=variable.name == EVENT_INDICATOR)

    def _time(self):
        return self._integrator.t if self._exchange is None and self._integrator else self.time

    def get_float64(self, vrs):
        # The binary reads time alone after every doStep (bouncingball_fmu3_loader.c's slave_time): without
        # pythonfmu3's loop over the variables, each checked for its type and dimensions.
        if vrs == _TIME_ONLY:
            return [self._time()]
        if vrs == _COMPLETED_STEP:
            self._completed_step()
            return [self._time()] * 2
        return super().get_float64(vrs)

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
        """The model exchange state [h, v, mode, impacts, nominal of x = h - R, nominal of v], from the initialised
        integrator's at the first call that needs it."""
        if self._exchange is None:
            integrator = self._integrator
            h, v, F_ext = self._in_frame(integrator.h, integrator.v)
            self._exchange = [integrator.h, integrator.v, clipped_contact_mode(integrator.ball, integrator.mode),
                              integrator.impacts, *phase_nominals(integrator.ball, h, v, integrator.mode, F_ext)]
            self._master_error = MasterError(integrator.ball, self.time, *self._exchange[:3], self._values["F_ext"],
                                             integrator.ground)
        return self._exchange

    def _in_frame(self, h: float, v: float, time: float | None = None) -> tuple[float, float, float]:
        """model_exchange.in_frame's (h, v, F_ext) at time [s], by default the model-exchange time."""
        integrator = self._integrator
        return in_frame(integrator.ground, integrator.ball.m, self.time if time is None else time, h, v,
                        self._values["F_ext"])

    def get_continuous_states(self):
        """[x, v]: x = h - R (exact, by Sterbenz, where h is within a factor 2 of R, as near the ground)."""
        return [self._model_exchange()[0] - self._integrator.ball.R, self._exchange[1]]

    def set_continuous_states(self, values):
        state = self._model_exchange()
        try:
            x, v = (validation.finite(name, value, unit) for name, value, unit in
                    zip(("x", "v"), values, ("m", "m/s"), strict=True))
        except ValueError as error:
            self._error(error)
            return
        state[0], state[1] = x + self._integrator.ball.R, v

    def get_continuous_state_derivatives(self):
        return [self._v(), self._a()]

    def get_event_indicators(self):
        state = self._model_exchange()
        ball = self._integrator.ball
        h, v, F_ext = self._in_frame(*state[:2])
        if state[2] == Mode.FLIGHT and h < 0.0 and not self._fell_through:
            # A master stepped over an impact unseen (one that calls fmi3CompletedIntegratorStep is told). Said once.
            self._fell_through = True
            if self._master_error is not None:
                self._master_error.lost = True
            self.log(f"h = {state[0]!r} m at t = {self.time!r} s: below the ground in flight, so the master stepped "
                     "over an impact without an event, and the results from here on are wrong", self.STATUS.warning)
        return [event_indicator(ball, h, v, state[2], F_ext)]

    def get_nominals_of_continuous_states(self, size):
        """The nominals of x [m] and v [m/s] of the current phase (phase_nominals); fixed between events."""
        if self._exchange is not None:
            return self._exchange[4:6][:size]
        if (integrator := self._integrator) is not None:
            h, v, F_ext = self._in_frame(integrator.h, integrator.v)
            return phase_nominals(integrator.ball, h, v, integrator.mode, F_ext)[:size]
        # Before initialisation: from the start values, as a flight (the mode is decided at initialisation).
        values = self._values
        try:
            ball, _, ground = self._ball_and_settings()
            h, v = relative_to(ground, self._start_time, values["h"], values["v"])
            return phase_nominals(ball, h, v, Mode.FLIGHT, values["F_ext"])[:size]
        except (TypeError, ValueError):  # a start value not yet valid: set and refused at initialisation
            return [1.0, 1.0][:size]

    def update_discrete_states(self):
        """The event: an impact where h - R has turned negative, a departure where it turned positive (switched_mode).

        Under the linear and no-pull laws the mode switches, and h and v do not jump: their values did not change (the
        standard forbids saying so), but every switch says the nominals changed (phase_nominals, also where
        the new ones happen to equal the old), because an importer that restarts its integrator only when
        told (fmusim's model exchange) must restart where the equations change. Under the rigid law an
        impact is a jump of the state (rigid_impact); a resting ball that F_ext lifts flies on.
        """
        if self._integrator is None:
            return DiscreteStatesUpdate()
        state = self._model_exchange()
        world, mode, impacts = state[:2], state[2], state[3]
        h, v, F_ext = self._in_frame(*world)
        ball, measured = self._integrator.ball, self._master_error
        x = h - ball.R
        if impact_is_instantaneous(ball.parameters):
            if mode == Mode.FLIGHT and (x < 0.0 or (x == 0.0 and v < 0.0)):
                # A master that noticed the impact -x below R resolves no bounce lower than that.
                apex_floor = max(UNRESOLVED_APEX_PER_RTOL * self._values["rtol"] * ball.R, -x)
                after = rigid_impact(ball, v, F_ext, impacts, apex_floor)
                state[:4] = [*in_world(self._integrator.ground, self.time, *after[:2]), *after[2:]]
                if measured is not None:  # the master's error is measured in the world's values
                    measured.rigid_impact(self.time, *world, [*state[:2], after[2]], self._values["F_ext"])
            elif mode == Mode.CONTACT and load_value(F_ext, ball.m, ball.g) < 0.0:
                after = [h, v, Mode.FLIGHT]
                state[2] = Mode.FLIGHT
                if measured is not None:
                    measured.switched(self.time, *world, [mode, Mode.FLIGHT], self._values["F_ext"])
            else:
                return DiscreteStatesUpdate()
            self._tell_master_error()
            state[4:6] = phase_nominals(ball, *after[:3], F_ext)
            return DiscreteStatesUpdate(nominalContinuousStatesChanged=True,
                                        valuesOfContinuousStatesChanged=state[:2] != world)
        switched = switched_mode(ball, h, v, mode, F_ext)
        if switched is None:
            return DiscreteStatesUpdate()
        modes = [mode]
        while switched is not None:  # a master that noticed an event late may be past the next one too
            state[2], state[3] = switched, state[3] + (mode == Mode.FLIGHT)
            mode, switched = switched, switched_mode(ball, h, v, switched, F_ext)
            modes.append(mode)
        if measured is not None:
            measured.switched(self.time, *world, modes, self._values["F_ext"])
        self._tell_master_error()
        state[4:6] = phase_nominals(ball, h, v, state[2], F_ext)
        # Said at every switch, even where the new phase's nominals equal the old ones to the bit (a weightless
        # ball whose impact speed is 2 R w): the equations changed, and the master must restart there.
        return DiscreteStatesUpdate(nominalContinuousStatesChanged=True)

    # --- outputs: the model exchange state once there is one, else the integrator's -------------------
    def _h(self):
        return self._exchange[0] if self._exchange else super()._h()

    def _v(self):
        return self._exchange[1] if self._exchange else super()._v()

    def _x(self):
        """h - R: model exchange's continuous state (get_continuous_states)."""
        return self._h() - (self._integrator.ball.R if self._integrator else self._values["R"])

    def _a(self):
        if not self._exchange:
            return super()._a()
        h, v, F_ext = self._in_frame(*self._exchange[:2])
        return self._integrator.ball.acceleration(h, v, self._exchange[2], F_ext) + \
            ground_motion(self._integrator.ground, self.time, 2)

    def _contact(self):
        return self._exchange[2] == Mode.CONTACT if self._exchange else super()._contact()

    def _contact_force(self):
        if not self._exchange:
            return super()._contact_force()
        h, v, F_ext = self._in_frame(*self._exchange[:2])
        return self._integrator.ball.contact_force(h, v, self._exchange[2], F_ext)

    def _impacts(self):
        return self._exchange[3] if self._exchange else super()._impacts()

    def _error_estimate(self):
        """Model exchange: the master's error measured so far, the current state included (master_error.py)."""
        if not self._exchange:
            return super()._error_estimate()
        if self._master_error is None:  # a state saved by an FMU that did not measure it
            return UNKNOWN
        # A read of the output is a state the master accepted: measured and kept, as at an fmi3CompletedIntegratorStep
        # (which the FMU does not need: fmusim and FMPy read the outputs at the same points).
        self._completed_step()
        return self._master_error.estimate()

    def _gap(self):
        """The event indicator of the current mode (event_indicator); h - R before initialisation."""
        if self._exchange:
            h, v, F_ext = self._in_frame(*self._exchange[:2])
            return event_indicator(self._integrator.ball, h, v, self._exchange[2], F_ext)
        integrator = self._integrator
        if integrator:
            return self._in_frame(integrator.h, integrator.v, integrator.t)[0] - integrator.ball.R
        return self._h() - self._values["R"]

    # --- FMU state: the model exchange state too -----------------------------------------------------
    def _get_fmu_state(self):
        state = super()._get_fmu_state()
        state["model_exchange"] = exchange_fields(self._exchange, self.time)
        state["master_error"] = None if self._master_error is None else self._master_error.saved()
        return state

    def _set_fmu_state(self, state):
        try:
            exchange = saved_exchange(state.get("model_exchange") if isinstance(state, dict) else None)
            measured = state.get("master_error") if isinstance(state, dict) and exchange is not None else None
            measured = None if measured is None else MasterError.checked(measured)
        except (TypeError, ValueError, IndexError) as error:
            self._error(f"{self.CALLS['set_state']} failed, nothing was changed: {error}")
            return
        before = len(self.log_queue)
        super()._set_fmu_state(state)
        if any(message.status >= Fmi3Status.error for message in self.log_queue[before:]):
            return
        if exchange is None:
            self._exchange, self._master_error = None, None
            return
        h, v, mode, impacts, time, *nominals = exchange
        self._exchange = [h, v, clipped_contact_mode(self._integrator.ball, mode), impacts, *nominals]
        self.time = time
        self._master_error = None  # a state saved before the master's error was measured: unknown from there
        if measured is not None:
            self._master_error = MasterError(self._integrator.ball, time, h, v, mode, self._values["F_ext"],
                                             self._integrator.ground)
            self._master_error.restore(measured)
