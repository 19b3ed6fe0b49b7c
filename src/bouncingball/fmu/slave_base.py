"""The BouncingBall FMU's slave, for either FMI version: everything but pythonfmu's own classes.

Every number comes from bouncingball's CVODE integrator (BallIntegrator), made at initialisation;
before it, the outputs are the Ball's closed forms at the start values (no integrator is made for
them). The interface is variables.VARIABLES, each output read by the getter _output_getters pairs
with it. Nothing here raises: pythonfmu (and pythonfmu3) would turn an exception into a fatal
status and release the instance. Errors are logged with status error instead, and the FMU's binary
(bouncingball_fmu_loader.c, bouncingball_fmu3_loader.c) returns an error for a call that logged
one. The integrator's warnings are held for the slave (BallIntegrator.held_warnings), which logs
them with status warning after the call that made them: no warnings filter is touched.

BallSlave imports neither pythonfmu nor pythonfmu3: slave.BouncingBall (FMI 2.0) and
slave3.BouncingBall (FMI 3.0) put it in front of their library's slave class, and give it the
library's status enumeration (STATUS), the names of the FMI calls its messages cite (CALLS) and
the registration of one variable (_register).
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from typing import NamedTuple

from .. import limits, validation
from ..ground import Ground
from ..physics import Ball, Mode, unread_message, without_unread
from ..scenes import SCENE_DEFAULTS
from ..solvers.cvode import BallIntegrator, CvodeSettings, IntegratorState, SolverError, check_resolvable
from ..solvers.integrator import checked_start
from ..solvers.phase_machine.drivers import is_rounding_of
from ..solvers.phase_machine.settings import MIN_RTOL, RTOL_RANGE_WHY
from ..solvers.vibrating_ground import ground_motion, relative_start, relative_to
from .c_layer import ServedValues
from .engine_cache import activate_native, first_use
from .saved_state import STATE_FORMAT, saved_header, state_fields, state_from_bytes
from .variables import (
    FMI3_VARIABLES,
    FMU_CONTACT_LAWS,
    GROUND_FIELD_OF_START_VALUE,
    SCENE_FIELD_OF_START_VALUE,
    SCENE_OWN_FIELDS,
    VARIABLES,
    ball_fields_of,
    ground_of,
)

DEFAULT_ENGINE = "auto"  # the compiled engine where numba is installed, loaded from the cache the FMU ships
SETTABLE_AFTER_INITIALISATION = ("F_ext",)
# Outputs the slave computes: a master may set the start values of h and v (initial="exact"), not these.
COMPUTED_OUTPUTS = tuple(v.name for v in VARIABLES if v.causality == "output" and v.initial != "exact")


class StartOutputs(NamedTuple):
    """The outputs a, contact and contact_force before initialisation (start_outputs)."""

    a: float  # m/s2
    contact: bool
    contact_force: float  # N


NO_START_OUTPUTS = StartOutputs(math.nan, False, math.nan)  # of start values initialisation would refuse


class BallSlave:
    """A ball with compliant contact, integrated by CVODE with every contact found by root-finding."""

    STATUS = None  # the library's status enumeration (ok, warning, error members)
    CALLS = {"setup": "fmi2SetupExperiment", "step": "fmi2DoStep", "set_state": "fmi2SetFMUstate"}
    STOP_AT_EVENT = False  # True: do_step returns at the first impact or departure inside the step
    STEPPED, REFUSED = True, False  # what do_step returns: the step taken, or refused (an error logged)
    VERSION_GETTERS: dict = {}  # FMI 3.0's own variables (FMI3_VARIABLES), after VARIABLES: their getters' names

    author = "bouncingball"
    description = ("A ball with compliant contact (spring k, damper b) over rigid ground, integrated by "
                   "SUNDIALS CVODE; every impact and departure inside a step is found by root-finding")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # pythonfmu 0.7 appends the FMU's resources folder to sys.path for each instance: keep one.
        resources = kwargs.get("resources")
        while resources is not None and sys.path.count(resources) > 1:
            sys.path.remove(resources)
        if resources is not None:
            _search_package_in(resources)
        self._resources = resources
        activate_native(resources)  # the compiled engine from the FMU's library, where it runs here
        # The values set by the master: parameters, start values of h and v, the input F_ext. The defaults are the
        # article's, not read from the package's data files: a master (FMPy) may delete the FMU's unzipped folder.
        ball, settings = Ball(), CvodeSettings()
        self._values = {**{name: SCENE_DEFAULTS[field] if field in SCENE_OWN_FIELDS else getattr(ball, field)
                           for name, field in SCENE_FIELD_OF_START_VALUE.items()},
                        **dict.fromkeys(GROUND_FIELD_OF_START_VALUE, 0.0),
                        "rtol": settings.rtol, "atol": settings.atol or 0.0, "method": settings.method,
                        "engine": DEFAULT_ENGINE}
        self._start_time = 0.0
        self._stop_time: float | None = None
        self._tolerance: float | None = None
        self._tolerance_told = False  # the master's tolerance and the rtol used are logged once per instance
        self._unread_told = set()  # the warnings of parameters the contact law does not read, logged once each
        self._integrator: BallIntegrator | None = None
        self._warnings: list[Warning] = []  # its integrators' held_warnings: logged after the call that made them
        getters = self._output_getters()
        for variable in VARIABLES:
            if variable.causality == "output":
                getter = getters[variable.name]
            else:  # a parameter or input reads the value set
                getter = lambda name=variable.name: self._values[name]  # noqa: E731
            self._register(variable, getter, lambda value, name=variable.name: self._set(name, value))
        for variable in FMI3_VARIABLES if self.VERSION_GETTERS else ():
            self._register(variable, getattr(self, self.VERSION_GETTERS[variable.name]),
                           lambda value, name=variable.name: self._error(f"{name} cannot be set"))
        self._served = ServedValues(resources, getattr(self, "vars", {}), self.STOP_AT_EVENT)  # while being made

    def _output_getters(self) -> dict:
        """Each output's getter by the output's name (variables.VARIABLES'), the one table that pairs them."""
        return {"h": self._h, "v": self._v, "a": self._a, "contact": self._contact,
                "contact_force": self._contact_force, "impacts": self._impacts, "error_estimate": self._error_estimate}

    def _register(self, variable, getter, setter) -> None:
        """Register variable (a variables.FmuVariable) with the library, read by getter, written by setter."""
        raise NotImplementedError

    # --- FMI calls ------------------------------------------------------------------------------
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._start_time, self._stop_time, self._tolerance = start_time, stop_time, tolerance

    def exit_initialization_mode(self):
        try:
            integrator = self._make_integrator()
            if self._stop_time is not None:  # refuse now what could not be integrated up to the stop time
                stop_time = validation.finite("stopTime", self._stop_time, "s")
                check_resolvable(integrator.ball, stop_time)
                limits.check_scene(integrator.ball, *relative_to(integrator.ground, integrator.t, integrator.h,
                                                                 integrator.v), integrator.F_ext, integrator.t,
                                   max(stop_time, integrator.t))
            integrator.held_warnings = self._warnings
            self._integrator = integrator
            self._tell_tolerance(integrator.settings.rtol)
            if self._values["engine"] == "auto" and integrator.engine != "compiled":
                self.log(f"engine auto runs scikit-sundae's: {integrator.engine_reason}", self.STATUS.ok)
        except (ValueError, ImportError) as error:  # ImportError: the compiled engine cannot run here, and why
            self._error(error)

    def do_step(self, current_time, step_size):
        """Advance by step_size [s], every contact resolved (STOP_AT_EVENT); the values left to the loader (c_layer)."""
        if (stepped := self._step(current_time, step_size)) is self.STEPPED:
            self._served.publish(self._integrator, self._values)
        return stepped

    def _step(self, current_time, step_size):
        if (integrator := self._integrator) is None:
            self._error(f"{self.CALLS['step']} before initialisation (or after a failed one)")
            return self.REFUSED
        try:
            if not self._served.finish_begun(integrator):  # else the loader's compiled step began it: ended here
                self._advance(integrator, current_time, current_time + step_size, step_size)
        except (ValueError, SolverError) as error:
            self._log_warnings()  # those before the failure first
            self._error(error)
            return self.REFUSED
        self._log_warnings()
        return self.STEPPED

    def _advance(self, integrator, current_time, target, step_size) -> None:
        # Most short steps, at the FMU's own time exactly: arithmetic that cannot warn.
        if integrator.advance_within_step(target, current_time):
            return
        rounded = current_time != (t := integrator.t)
        # A master's own rounding of the communication points is tolerated, a jump is not.
        if rounded and not is_rounding_of(current_time, t):
            raise ValueError(f"currentCommunicationPoint = {current_time!r} s is not allowed: the FMU is at "
                             f"t = {t!r} s")
        if not (step_size >= 0.0 and math.isfinite(target)):
            raise ValueError(f"communicationStepSize = {step_size!r} s is not allowed: it must be >= 0 and "
                             "end the step at a finite time")
        if rounded:  # the same arithmetic from the FMU's own time
            target = max(target, t)  # a current time rounded below t, and a step shorter than that rounding
            if integrator.advance_within_step(target, t):
                return
        integrator.advance(target, self.STOP_AT_EVENT)

    # --- FMU state: everything needed to continue exactly, in this or a fresh instance ------------
    def _get_fmu_state(self):
        integrator = None
        if self._integrator is not None:
            integrator = state_fields(self._integrator.get_state())
        return {"format": STATE_FORMAT, "values": dict(self._values), "start_time": self._start_time,
                "stop_time": self._stop_time, "tolerance": self._tolerance, "integrator": integrator}

    def _set_fmu_state(self, state):
        """All or nothing: the whole state is checked (parameters, start values, integrator) first."""
        try:
            values, start_time, stop_time, tolerance = saved_header(state, self._values)
            ball, settings, ground = self._ball_and_settings(values, tolerance)
            for name in ("h", "v", "F_ext"):
                validation.finite(name, values[name])
            saved, integrator = state["integrator"], None
            if saved is not None:
                integrator = self._integrator
                if integrator is None or (integrator.ball, integrator.settings, integrator.ground) != (ball, settings,
                                                                                                      ground):
                    with self._engine_first_use(settings.engine):
                        integrator = BallIntegrator(ball, values["h"], values["v"], start_time, values["F_ext"],
                                                    settings, ground=ground)
                    integrator.held_warnings = self._warnings
                t, h, v, F_ext = (validation.finite(f"state {name}", saved[name], unit)
                                  for name, unit in (("t", "s"), ("h", "m"), ("v", "m/s"), ("F_ext", "N")))
                limits.check_scene(ball, *relative_to(ground, t, h, v), F_ext, t)
                integrator.set_state(IntegratorState(**saved))  # checks every field before it changes any
        except (KeyError, TypeError, ValueError, ImportError) as error:
            self._log_warnings()
            self._error(f"{self.CALLS['set_state']} failed, nothing was changed: {error}")
            return
        self._log_warnings()  # set_state integrates again from the restart point: SUNDIALS may have warned
        self._values, self._start_time, self._stop_time, self._tolerance = values, start_time, stop_time, tolerance
        self._integrator = integrator

    _fmu_state_from_bytes = staticmethod(state_from_bytes)

    # --- variables ------------------------------------------------------------------------------
    def _set(self, name, value):
        if name in COMPUTED_OUTPUTS:
            self._error(f"{name} is an output: it cannot be set")
        elif self._integrator is not None and name not in SETTABLE_AFTER_INITIALISATION:
            self._error(f"{name} = {value!r} is not allowed: {name} cannot change after initialisation")
        elif name == "F_ext" and self._integrator is not None:
            integrator = self._integrator
            try:
                integrator.F_ext = value  # checked first (its range from the current state): refused, nothing changes
            except ValueError as error:
                self._error(error)
                return
            self._values[name] = value
        else:
            self._values[name] = value  # a parameter or start value: checked, as a whole, at initialisation

    def _h(self):
        return self._values["h"] if self._integrator is None else self._integrator.h

    def _v(self):
        return self._values["v"] if self._integrator is None else self._integrator.v

    def _a(self):
        return self._start_outputs().a if self._integrator is None else self._integrator.acceleration

    def _contact(self):
        return self._start_outputs().contact if self._integrator is None else self._integrator.mode == Mode.CONTACT

    def _contact_force(self):
        return self._start_outputs().contact_force if self._integrator is None else self._integrator.contact_force

    def _impacts(self):
        return 0 if self._integrator is None else self._integrator.impacts

    def _error_estimate(self):
        return 0.0 if self._integrator is None else self._integrator.error_estimate_at_t

    # --- helpers ----------------------------------------------------------------------------------
    def _ball_and_settings(self, values=None, tolerance=None) -> tuple[Ball, CvodeSettings, Ground]:
        """The ball, CVODE settings and ground from values (default: the current ones); ValueError names a bad value."""
        if values is None:
            values, tolerance = self._values, self._tolerance
        contact = validation.choice("contact_law", values["contact_law"], FMU_CONTACT_LAWS)
        ball = Ball(**_read_fields(contact, ball_fields_of(values), self._unread_told, self.log, self.STATUS.warning))
        rtol = values["rtol"]
        if tolerance is not None:  # the master's tolerance may tighten rtol, never loosen it
            rtol = min(CvodeSettings(rtol=rtol).rtol, validation.in_closed_range(
                f"tolerance ({self.CALLS['setup']})", tolerance, MIN_RTOL, 1.0, why=RTOL_RANGE_WHY))
        settings = CvodeSettings(rtol=rtol, atol=values["atol"], method=values["method"], engine=values["engine"])
        return ball, settings, _read_ground(values, self._unread_told, self.log, self.STATUS.warning)

    def _tell_tolerance(self, used: float) -> None:
        """Once per instance: a warning if the master asked for a looser tolerance than rtol, a note if tighter."""
        asked, rtol = self._tolerance, self._values["rtol"]
        if not (self._tolerance_told or asked is None or asked == rtol):
            self._tolerance_told = True
            self.log(tolerance_note(asked, rtol, used, self.CALLS["setup"]),
                     self.STATUS.warning if asked > rtol else self.STATUS.ok)

    def _make_integrator(self) -> BallIntegrator:
        """An integrator at the start state; ValueError names a bad value.

        ImportError: the engine asked for is "compiled" and cannot run here (the message says why).
        """
        ball, settings, ground = self._ball_and_settings()
        values = self._values
        h, v = validation.finite("h", values["h"], "m"), validation.finite("v", values["v"], "m/s")
        with self._engine_first_use(settings.engine):
            return BallIntegrator(ball, h, v, self._start_time, values["F_ext"], settings, ground=ground)

    def _engine_first_use(self, engine: str):
        """Around an integrator's making on engine: the compiled engine's code from the FMU's cache, or numba's
        compile said in the log before it starts (nothing to do for scikit-sundae's engine)."""
        if engine == "sksundae":
            return contextlib.nullcontext()
        return first_use(self._resources, lambda message: self.log(message, self.STATUS.ok))

    def _start_outputs(self) -> StartOutputs:
        """Before initialisation: the outputs of the start values (start_outputs), no integrator made for them."""
        try:
            ball, settings, ground = self._ball_and_settings()
        except ValueError:
            return NO_START_OUTPUTS
        return start_outputs(ball, settings, self._values, self._start_time, ground)

    def _log_warnings(self) -> None:
        """The integrators' warnings held since the last call (BallIntegrator.held_warnings), to the master's log."""
        for warning in self._warnings:  # SundialsLog keeps one per cause, BallIntegrator one AccuracyWarning
            self.log(str(warning), self.STATUS.warning)
        self._warnings.clear()

    def _error(self, error) -> None:
        self.log(str(error), self.STATUS.error)


def _read_ground(values: dict, told: set, log, warning) -> Ground:
    """The ground of the FMU's values (variables.ground_of); where ground_amplitude is 0, a ground_frequency or
    ground_phase set is logged once as not read (log's status warning; told: the messages said), as _read_fields
    does a contact law's parameters."""
    ground = ground_of(values)
    unread = [name for name in ("ground_frequency", "ground_phase") if not ground.moves and values[name] != 0.0]
    message = (f"{' and '.join(f'{name} = {values[name]!r}' for name in unread)} "
               f"{'are' if len(unread) > 1 else 'is'} ignored: ground_amplitude = 0 is a still ground")
    if unread and message not in told:
        told.add(message)
        log(message, warning)
    return ground


def _read_fields(contact: str, ball_fields: dict, told: set, log, warning) -> dict:
    """ball_fields with the parameters the contact law does not read at their defaults, each logged once (log's
    status warning; told: the messages said), not refused: a master may set every parameter to its start value."""
    ball_fields, unread = without_unread(ball_fields)
    if unread:
        message = unread_message(contact, unread, law="contact_law", verdict="is ignored (taken at its default)")
        if message not in told:
            told.add(message)
            log(message, warning)
    return ball_fields


def start_outputs(ball: Ball, settings: CvodeSettings, values: dict, start_time: float,
                  ground: Ground) -> StartOutputs:
    """The outputs of the start values (values: the slave's) on ground, in the mode the ball starts in: the Ball's
    closed forms (on a vibrating ground, relative to it, its acceleration added to a).

    NO_START_OUTPUTS where initialisation would refuse a value: the checks are BallIntegrator's of its start
    (relative_start's, checked_start's), without making one (its CVODE objects, and numba's engine, are not needed).
    """
    try:
        h, v = validation.finite("h", values["h"], "m"), validation.finite("v", values["v"], "m/s")
        h, v, _, F_ext = relative_start(ball, ground, h, v, start_time, values["F_ext"], settings, checked_start)
        F_relative = F_ext - ball.m * ground_motion(ground, start_time, 2)  # the table's acceleration as a load
        mode = ball.initial_mode(h, v, F_relative)
    except ValueError:
        return NO_START_OUTPUTS
    return StartOutputs(ball.acceleration(h, v, mode, F_relative) + ground_motion(ground, start_time, 2),
                        mode == Mode.CONTACT, ball.contact_force(h, v, mode, F_relative))


def tolerance_note(asked: float, rtol: float, used: float, setup_call: str) -> str:
    """What the log says of a master's tolerance asked (setup_call's) against the parameter rtol, rtol used."""
    if asked > rtol:
        return (f"tolerance = {asked!r} ({setup_call}) is looser than the FMU's rtol = {rtol!r}, so rtol = {used!r} "
                "is used: a master's tolerance may tighten rtol but never loosen it, because each bounce's error "
                "carries into every later bounce (at 1e-3 the article's ball misses an impact); to loosen it, set "
                "the parameter rtol")
    return f"rtol = {used!r} is used: the tolerance of {setup_call}, tighter than the parameter rtol = {rtol!r}"


def _search_package_in(resources: str) -> None:
    """Import the package's modules not imported yet (the compiled engine) from this instance's copy too.

    The process keeps the package's modules of the first instance, whose unzipped folder a master
    (FMPy) may since have deleted; this instance's copy has the same sources (the package's name is
    their digest). Folders that are gone are dropped, so the search path stays short.
    """
    root = __name__.split(".")[0]
    for name, module in list(sys.modules.items()):
        path = getattr(module, "__path__", None)
        if path is None or not (name == root or name.startswith(root + ".")):
            continue
        folder = os.path.join(resources, *name.split("."))
        if os.path.isdir(folder):
            path[:] = [entry for entry in path if entry != folder and os.path.isdir(entry)] + [folder]
