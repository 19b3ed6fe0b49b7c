"""The engine protocol: the three calls the phase machine makes on a CVODE engine, for one mode at a time.

Both engines implement them; the phase machine (machine.py) is written against them alone.

``engine_start(engine, mode, t_stop, y0, y1, length, speed, hop, load, origin) -> flag``
    Restart the mode's CVODE at time 0 (the phase's start, origin [s]) from the scaled state (y0, y1) =
    (x / length, v / speed), in the phase's frame (length [m], speed [m/s]), with the hop
    tolerance [m] of the rest root and the load m g - F_ext [N] of the right-hand side (on a vibrating
    ground, equations.load_at's at origin + CVODE's time). t_stop:
    CVODE's stop time from the phase's start [s], or inf for none. flag: CVODE's (< 0 failed).
``engine_steps(engine, mode, scratch, t_toward, one_step) -> (flag, count, rows, gap_root, rest_root, rhs_calls)``
    CVODE's steps toward t_toward (in the phase's time): with one_step, one CVode call (which may
    end at a root of any of the three root functions); else steps to the stop time or the first
    terminal root, stepping through the roots of v, until the buffer scratch (n, 3) is full. rows:
    scratch or an array of the engine's own, rows[:count] the step ends (tau, y0, y1) as CVODE
    gives them; on a failure, the failure's time in rows[count - 1, 0] where count > 0. flag:
    CVODE's (0 a step, 1 the stop time, 2 a root, < 0 a failure) or BUFFER_FULL (call again for
    the phase's further steps). gap_root, rest_root: CVodeGetRootInfo's entries for the gap and the
    rest margin at a root (0 where none). rhs_calls: CVODE's right-hand-side evaluations since
    its restart.
``engine_exceeded(engine, mode) -> bool``
    Whether the last failure was the phase taking more root evaluations than allowed (too many steps).

``engine`` is what the engine's PhaseMachine.engine makes of the two modes' solvers
(stepper.phase_machine). As written here the calls go to the scikit-sundae engine's solvers
(stepper.SksundaePhaseSolver: ``start``, ``steps``, ``exceeded``), and the machine runs
interpreted; the compiled engine compiles the machine with these names bound to its own
functions over SUNDIALS (compiled.py: ``_engine_start``, ``_engine_steps``, ``_engine_exceeded``).
"""

from __future__ import annotations

CV_SUCCESS, CV_TSTOP_RETURN, CV_ROOT_RETURN = 0, 1, 2  # CVode's return flags (cvode.h)
BUFFER_FULL = 99  # engine_steps' flag: the buffer is full, call again for the phase's further steps


def engine_start(engine, mode, t_stop, y0, y1, length, speed, hop, load, origin):
    """See the module's doc."""
    return engine[mode].start(t_stop, y0, y1, length, speed, hop, load, origin)


def engine_steps(engine, mode, scratch, t_toward, one_step):
    """See the module's doc."""
    return engine[mode].steps(scratch, t_toward, one_step)


def engine_exceeded(engine, mode):
    """See the module's doc."""
    return engine[mode].exceeded
