"""The phase machine's state: its named fields, grouped by concern, and the two containers made from them.

The machine (machine.py, drivers.py, error_estimate.py), compiled or not, reads and writes the state
by attribute (``state.t``, ``state.rs_t``); BallIntegrator keeps it, state.py saves and restores the
restart point from it. Each group below is declared once, one line per field: its name, its value
in a new state, what it holds. Every field is a float64 (a mode, kind, count or flag too: exact as a
double). From the one list come:

- ``STATE_DTYPE``, a numpy structured dtype: the compiled engine's machine reads and writes a record
  of it (over ``compiled_state``'s memory), as fast as an array's slot;
- ``MachineState``, a ``dataclass(slots=True)`` with the same fields: the scikit-sundae engine's,
  whose interpreted machine reads an attribute faster than an array's slot;
- ``StateView``, a ctypes structure over the compiled record's memory: what Python reads and
  writes of the compiled engine's state by the same names (an attribute, where a record's item
  costs seven times as much).

A field added to a group reaches all three; nothing counts the fields by hand.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
from typing import NamedTuple

import numpy as np


class Field(NamedTuple):
    """One field of the state: its name, its value in a new state, what it holds."""

    name: str
    initial: float
    meaning: str


_NAN = math.nan

STATE_AND_MODE = (
    Field("t", 0.0, "the time [s]"),
    Field("t_low", 0.0, "t's rounding error [s] (rounding.later): an event time is t + t_low; 0 at a time given"),
    Field("x", 0.0, "the gap h - R [m], which keeps the digits of a deflection that h rounds away"),
    Field("v", 0.0, "the velocity [m/s], positive upwards"),
    Field("mode", 0.0, "the mode held: codes.FLIGHT, CONTACT or FREE"),
    Field("load", 0.0, "m g - F_ext [N], constant over a phase"),
    Field("hop", 0.0, "the hop tolerance [m] at this load (settings.hop_tolerance)"),
    Field("rest_t", _NAN, "when the rest began [s] (NaN: not at rest); it is taken on the contact's exact flow"),
    Field("rest_x", 0.0, "the gap [m] where the rest began"),
    Field("rest_v", 0.0, "the velocity [m/s] where the rest began"),
)
COUNTERS = (
    Field("impacts", 0.0, "impacts so far"),
    Field("departures", 0.0, "departures so far"),
    Field("last_impact", _NAN, "the last impact's time [s] (NaN: none yet)"),
    Field("steps", 0.0, "CVODE's steps so far"),
    Field("rhs_calls", 0.0, "right-hand-side calls before CVODE's last restart"),
    Field("nfev", 0.0, "right-hand-side calls since CVODE's last restart"),
)
CVODE_PHASE = (
    Field("needs_init", 0.0, "1.0: CVODE restarts at the state before its next step"),
    Field("origin", 0.0, "the phase's start [s], CVODE's time 0"),
    Field("origin_low", 0.0, "origin's rounding error [s]"),
    Field("length", 0.0, "the phase's length scale [m] (phases.frame): CVODE integrates x / length"),
    Field("speed", 0.0, "the phase's speed scale [m/s]: CVODE integrates v / speed"),
    Field("step_t", 0.0, "the last step end's time [s]"),
    Field("step_x", 0.0, "the last step end's gap [m]"),
    Field("step_v", 0.0, "the last step end's velocity [m/s]"),
)
KEPT_STEP_AND_PENDING_EVENT = (
    Field("segment", 0.0, "1.0: the last step (seg_*) is kept, for the dense output of a time inside it"),
    Field("seg_mode", 0.0, "the kept step's mode"),
    Field("seg_t0", 0.0, "the kept step's start [s]"),
    Field("seg_x0", 0.0, "the gap [m] at its start"),
    Field("seg_v0", 0.0, "the velocity [m/s] at its start"),
    Field("seg_t1", 0.0, "the kept step's end [s]"),
    Field("seg_x1", 0.0, "the gap [m] at its end"),
    Field("seg_v1", 0.0, "the velocity [m/s] at its end"),
    Field("pending", 0.0, "1.0: the kept step ends at an event still to take (pend_*)"),
    Field("pend_t", 0.0, "the pending event's time [s]"),
    Field("pend_t_low", 0.0, "pend_t's rounding error [s]"),
    Field("pend_x", 0.0, "the pending event's gap [m]: 0 on R, below it for a law's release or engagement"),
    Field("pend_v", 0.0, "the pending event's velocity [m/s]"),
    Field("pend_kind", 0.0, "the pending event's kind: codes.IMPACT, DEPARTURE, RELEASE, ENGAGE or RESTART"),
)
RESTART_POINT = (  # state.RestartPoint: where CVODE last restarted, the state and counters there
    Field("rs_t", 0.0, "the restart's time [s]"),
    Field("rs_t_low", 0.0, "rs_t's rounding error [s]"),
    Field("rs_x", 0.0, "the gap [m] there"),
    Field("rs_v", 0.0, "the velocity [m/s] there"),
    Field("rs_mode", 0.0, "the mode there"),
    Field("rs_impacts", 0.0, "impacts before it"),
    Field("rs_departures", 0.0, "departures before it"),
    Field("rs_last_impact", 0.0, "the last impact's time [s] before it (NaN: none)"),
    Field("rs_rhs_calls", 0.0, "right-hand-side calls before it"),
    Field("rs_steps", 0.0, "CVODE's steps before it"),
)
FAILURE = (
    Field("fail_t", 0.0, "where the machine failed [s]"),
    Field("fail_x", 0.0, "the gap [m] there (a step end beyond R's margin: how far)"),
    Field("fail_flag", 0.0, "CVODE's flag (0: an event stepped over)"),
)
ERROR_ESTIMATE = (  # error_estimate.py, at the restart point
    Field("err_x", 0.0, "the run's error of x [m] (Hunt-Crossley: the first ellipse's half-width)"),
    Field("err_v", 0.0, "the run's error of v [m/s] (Hunt-Crossley: the first ellipse's half-width)"),
    Field("err_xv", 0.0, "the first ellipse's correlation in [-1, 1] (Hunt-Crossley; 0 otherwise)"),
    Field("err2_x", 0.0, "the second ellipse's half-width in x [m]: the last contact's own error (Hunt-Crossley)"),
    Field("err2_v", 0.0, "the second ellipse's half-width in v [m/s] (Hunt-Crossley)"),
    Field("err2_xv", 0.0, "the second ellipse's correlation in [-1, 1] (Hunt-Crossley)"),
    Field("err_max", 0.0, "the bound on |h - h_true| [m] over the phases before the restart"),
    Field("err_from", _NAN, "the start [s] of the first phase whose bound passed the promise (NaN: none)"),
    Field("scale", 0.0, "the largest height [m] of the phases so far, max(|h|, R)"),
    Field("est_t", _NAN, "the time [s] the run's estimate est was taken at (drivers.keep_estimate; NaN: none)"),
    Field("est", 0.0, "the run's estimate [m] at est_t, the current phase so far included (run_estimate's)"),
)
HUNT_CROSSLEY_OWN = (  # the law's contact, which CVODE integrates: its ellipses in the phase's frame
    Field("hc_rest_t", _NAN, "when the pressed contact's rest criterion became true [s] (NaN: not at rest)"),
    Field("hc_a00", 0.0, "the first ellipse (errors before the contact) at the last step end, (0, 0)"),
    Field("hc_a01", 0.0, "... its (0, 1)"),
    Field("hc_a11", 0.0, "... its (1, 1)"),
    Field("hc_b00", 0.0, "the second ellipse (the contact's own error) at the last step end, (0, 0)"),
    Field("hc_b01", 0.0, "... its (0, 1)"),
    Field("hc_b11", 0.0, "... its (1, 1)"),
    Field("hc_qa00", 0.0, "the first ellipse at the kept step's start, (0, 0)"),
    Field("hc_qa01", 0.0, "... its (0, 1)"),
    Field("hc_qa11", 0.0, "... its (1, 1)"),
    Field("hc_qb00", 0.0, "the second ellipse at the kept step's start, (0, 0)"),
    Field("hc_qb01", 0.0, "... its (0, 1)"),
    Field("hc_qb11", 0.0, "... its (1, 1)"),
    Field("hc_xmax", 0.0, "the largest half-width of x's error [m] at the contact's step ends so far"),
)

GROUPS = {"state and mode": STATE_AND_MODE, "counters": COUNTERS, "CVODE's phase": CVODE_PHASE,
          "the kept step and the pending event": KEPT_STEP_AND_PENDING_EVENT, "the restart point": RESTART_POINT,
          "the failure": FAILURE, "the error estimate": ERROR_ESTIMATE,
          "the Hunt-Crossley law's own": HUNT_CROSSLEY_OWN}
FIELDS = tuple(field for group in GROUPS.values() for field in group)
NAMES = tuple(field.name for field in FIELDS)

STATE_DTYPE = np.dtype([(name, np.float64) for name in NAMES])
MachineState = dataclasses.make_dataclass(
    "MachineState", [(field.name, float, dataclasses.field(default=field.initial)) for field in FIELDS],
    slots=True)
MachineState.__module__ = __name__
MachineState.__doc__ = "The scikit-sundae engine's state: layout.FIELDS as attributes (see the module's doc)."
StateView = type("StateView", (ctypes.Structure,), {
    "_fields_": [(name, ctypes.c_double) for name in NAMES],
    "__doc__": "The compiled engine's state record as Python reads and writes it, by the same names.",
    "__module__": __name__})


# Each field at its initial value: copied into every new compiled state (filling a StateView field by field costs
# ~10 us of each simulate's ~1.4 ms).
_INITIAL_VIEW = StateView(*(field.initial for field in FIELDS))


def interpreted_state() -> tuple[MachineState, MachineState]:
    """A new state for the scikit-sundae engine: (what Python reads, what the machine takes), one object."""
    state = MachineState()
    return state, state


def compiled_state() -> tuple[StateView, np.ndarray]:
    """A new state for the compiled engine: (a StateView, a float64 array over its memory).

    The compiled engine's entry points (compiled.py) take the array, which numba types fast, and hand
    the machine the STATE_DTYPE record over that memory.
    """
    view = StateView.from_buffer_copy(_INITIAL_VIEW)
    return view, np.frombuffer(view, np.float64)


def copied(state):
    """A copy of a state (either container), for a test or a look that must not change it."""
    if isinstance(state, MachineState):
        return dataclasses.replace(state)
    return type(state).from_buffer_copy(state)
