"""The FMU state's parts that are plain data: its format, the integrator's fields, a saved state's values and model
exchange's state.

slave_base.BallSlave gets, sets and serializes the FMU state (a dict, JSON when serialized); these make and read
its data, nothing else.
"""

from __future__ import annotations

import json
from dataclasses import fields

from .. import validation
from ..contact_laws import CONTACT_PARAMETERS
from ..physics import BALL_DEFAULTS, Mode
from ..solvers.cvode import IntegratorState, RestartPoint
from .variables import GROUND_FIELD_OF_START_VALUE, MODEL_NAME

# 7: the contact law's parameters; 6: the restart time's rounding error, model exchange's nominals; 5: the restart point
# (8 gained the ground's parameters without a new format: a state without them is on the still ground, as before)
STATE_FORMAT = "bouncingball-fmu-state-8"

# dataclasses.asdict's deep copy costs ~22 us per fmi2GetFMUstate, three quarters of it; every field is a number, a
# mode or None, so the fields themselves make the same dict.
_STATE_FIELDS = tuple(field.name for field in fields(IntegratorState))
_RESTART_FIELDS = tuple(field.name for field in fields(RestartPoint))


def saved_header(state, own: dict) -> tuple:
    """(values, start_time, stop_time, tolerance) of a saved FMU state, its values checked against own (the FMU's
    current ones, by name): ValueError (KeyError, TypeError) where it is not a state of this FMU."""
    if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
        reason = state.get("invalid", "") if isinstance(state, dict) else ""
        raise ValueError(f"it is not a {MODEL_NAME} state ({STATE_FORMAT}) {reason}")
    values = saved_values(state["values"], own)
    if set(values) != set(own):
        raise ValueError(f"its variables {sorted(values)} are not this FMU's")
    return values, validation.finite("start_time", state["start_time"], "s"), state["stop_time"], state["tolerance"]


def saved_values(saved: dict, own: dict) -> dict:
    """A saved state's values; a contact law's parameter this FMU gained since it was saved, which none of the laws
    then read, at its default; the ground's parameters likewise (an FMU without them ran on a still ground: 0)."""
    return {**{name: BALL_DEFAULTS[name] for name in CONTACT_PARAMETERS if name in own},
            **dict.fromkeys(GROUND_FIELD_OF_START_VALUE, 0.0), **saved}


def state_fields(state: IntegratorState) -> dict:
    """dataclasses.asdict(state), mode as an int: the FMU state's integrator part."""
    saved = {name: getattr(state, name) for name in _STATE_FIELDS}
    saved["mode"] = int(state.mode)
    if state.restart is not None:
        saved["restart"] = {name: getattr(state.restart, name) for name in _RESTART_FIELDS}
    return saved


def state_from_bytes(state: bytes):
    """A serialized FMU state read back (JSON); where it cannot be read, a dict saying why (the slave refuses it)."""
    try:
        return json.loads(state.decode("utf-8"))
    except ValueError as error:  # includes UnicodeDecodeError and JSONDecodeError
        return {"invalid": f"the serialized state cannot be read: {error}"}


def exchange_fields(exchange: list | None, time: float) -> list | None:
    """FMI 3.0 model exchange's state [h, v, mode, impacts, nominal of x = h - R, nominal of v] at time [s] as the FMU
    state saves it: [h, v, mode as an int, impacts, time, the two nominals]; None where model exchange has not begun."""
    return None if exchange is None else [*exchange[:2], int(exchange[2]), exchange[3], time, *exchange[4:6]]


def saved_exchange(saved: list | None) -> list | None:
    """exchange_fields' list read back, each field checked ([h, v, Mode, impacts, time, nominals]); ValueError,
    TypeError or IndexError names or shows a bad one."""
    if saved is None:
        return None
    return [validation.finite("state h", saved[0], "m"), validation.finite("state v", saved[1], "m/s"),
            Mode(saved[2]), int(saved[3]), validation.finite("state time", saved[4], "s"),
            validation.positive("state nominal of x", saved[5], "m"),
            validation.positive("state nominal of v", saved[6], "m/s")]
