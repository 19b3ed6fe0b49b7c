"""The phase machine's state: one float array (machine.new_state), its slots named here, the one home of its layout.

BallIntegrator keeps the array; the phase machine (machine.py), compiled or not, reads and writes it
by these names; state.py saves and restores the restart point from it.

The state (T, X = h - R, V, MODE), the phase's constants (LOAD = m g - F_ext, HOP: the hop tolerance),
the counters (IMPACTS, DEPARTURES, LAST_IMPACT, STEPS, RHS_CALLS). REST_T, REST_X, REST_V: where the
rest began (REST_T NaN: not at rest). NEEDS_INIT: CVODE restarts at the state before its next
step. SEGMENT: the last step (SEG_*, from start to end, in mode SEG_MODE) is kept for the dense
output; PENDING: its end is an event (PEND_T, PEND_V) still to take. STEP_*: the last step's end.
ORIGIN, LENGTH, SPEED: the phase's frame. NFEV: CVODE's right-hand-side calls since its restart.
RS_*: the restart point (state.RestartPoint). FAIL_*: where a failure happened, and CVODE's flag.
T_LOW, ORIGIN_LOW, PEND_T_LOW, RS_T_LOW: the rounding error of an event time T, ORIGIN, PEND_T,
RS_T (the time is T + T_LOW; 0 at a time given, such as a grid point), so that event times do not
drift by an ulp of t per event (rounding.later). ERR_X, ERR_V: the run's error of (x, v) at the
restart point (error_estimate.phase_error); ERR_MAX: the bound on |h - h_true| over the phases
before it; ERR_FROM: the start of the first phase whose bound passed the promise (NaN: none);
SCALE: the largest height [m] of the phases so far (max(|h|, R)). PEND_X, PEND_KIND: the pending
event's gap (0 on R; below R for the no-pull law's release and engagement) and kind (codes.IMPACT ..
codes.ENGAGE). HC_REST_T: under the Hunt-Crossley law, when the pressed contact's rest criterion
(contact_laws.hunt_crossley_rest_margin) became true; CVODE integrates on through that rest (NaN: not at rest).
Under the Hunt-Crossley law the run's error of (x, v) is the sum of two ellipses (error_estimate.py): the one
of the phases before the last contact (ERR_X and ERR_V its half-widths [m, m/s], ERR_XV its correlation in [-1, 1])
and the last contact's own (ERR2_X, ERR2_V, ERR2_XV). In a contact CVODE integrates, HC_A00, HC_A01, HC_A11 and
HC_B00, HC_B01, HC_B11 are those at the last step end (STEP_T) in the phase's frame (x / LENGTH, v / SPEED), the
HC_QA* and HC_QB* at the kept step's start (SEG_T0), and HC_XMAX [m] the largest half-width of x's error at the
step ends so far.
"""

(T, X, V, MODE, LOAD, HOP, IMPACTS, DEPARTURES, LAST_IMPACT, STEPS, RHS_CALLS, REST_T, REST_X, REST_V,
 NEEDS_INIT, SEGMENT, SEG_MODE, SEG_T0, SEG_X0, SEG_V0, SEG_T1, SEG_X1, SEG_V1, PENDING, PEND_T, PEND_V,
 STEP_T, STEP_X, STEP_V, ORIGIN, LENGTH, SPEED, NFEV, RS_T, RS_X, RS_V, RS_MODE, RS_IMPACTS, RS_DEPARTURES,
 RS_LAST_IMPACT, RS_RHS_CALLS, RS_STEPS, FAIL_T, FAIL_X, FAIL_FLAG, T_LOW, ORIGIN_LOW, PEND_T_LOW, RS_T_LOW,
 ERR_X, ERR_V, ERR_MAX, ERR_FROM, SCALE, PEND_X, PEND_KIND, HC_REST_T, ERR_XV, ERR2_X, ERR2_V, ERR2_XV,
 HC_A00, HC_A01, HC_A11, HC_B00, HC_B01, HC_B11, HC_QA00, HC_QA01, HC_QA11, HC_QB00, HC_QB01, HC_QB11, HC_XMAX,
 STATE_SIZE) = range(75)
