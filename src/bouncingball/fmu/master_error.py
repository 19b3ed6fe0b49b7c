"""Model exchange's error_estimate: the master's own error, measured against each phase's exact flow.

In model exchange the master integrates h and v, and the FMU's CVODE does not run. Under the linear,
no-pull and rigid laws every phase (a flight, a contact, the no-pull law's free spell, a rigid ball's
rest on R) has a closed-form flow, affine in its start state (contact_laws.law_flow_value). So each
state the master accepts (a completed integrator step, an event, a read of the output) is compared
with the exact flow from its phase's start: their difference is the master's own error over the
phase. The error the phase started with is carried to it by the flow's transition matrix (the flow
of the unit vectors under no load), and across each event by the event's saltation matrix, as the
CVODE engines carry their own (solvers/phase_machine/error_estimate.carry_error): a compliant impact
or departure keeps the state and jumps the field (dv += -+ (b/m) dx), a rigid impact reflects it
(v+ = -e v-). A master that switched a few ulps past the surface (h - R = x_e at its event) made an
error of its own there: the state is off the surface by x_e, so the saltation applies to the error
less that offset (MasterError.switched, MasterError.rigid_impact).

That carry is first order in the error: it holds while the master's events lag the truth's by a small part
of a contact. A master that drifts further (the article at rtol 1e-4: its impacts 43 ms late after seven
bounces, a contact lasting 32 ms) is judged by the exact solution itself (solvers.exact.ExactSolution, from the
start and from each change of F_ext): each accepted state's error is the smaller of the two, the carry's and
|h - h_exact|, which agree where both hold (the carry where the exact solution's own rounding grows, in an
ill-conditioned run; the exact solution where the carry's linearisation fails).

On a vibrating ground each phase is measured in the ground's frame (x = h - R - s, v - s'), against the phase
machine's own flows there (contact_laws.law_flow_at: a flight's parabola less the ground's motion, the linear
contact's forced oscillation, the rigid ride); the ground's forcing is additive, so the transition matrices are the
still ground's, and the saltation takes the load in that frame at the event (equations.load_at). The states the
slave gives are the world's.

What is measured is the master's error itself, not a bound: error_estimate is ESTIMATE_SAFETY times the largest
error so far. Hunt and Crossley's contact has no closed form: there the error is unknown (UNKNOWN).
"""

from __future__ import annotations

import math

from ..codes import DEPARTURE, IMPACT
from ..contact_laws import LAWS, law_flow_at, law_flow_value
from ..equations import load_at, load_value
from ..ground import Ground
from ..physics import Ball, Mode
from ..solvers.exact import ExactSolution
from ..solvers.phase_machine.error_estimate import event_saltation
from ..solvers.phase_machine.settings import ESTIMATE_SAFETY, PROMISE
from ..solvers.vibrating_ground import machine_ground, relative_to

UNKNOWN = -1.0  # error_estimate where the law has no closed form to measure against
EXACT_HORIZON = 1.0  # s: the exact solution is built this far ahead at first, twice as far each time it is passed


class MasterError:
    """The error of a model-exchange master's states: measured per phase, carried across events.

    Parameters
    ----------
    ball : Ball
        The ball.
    t, h, v : float
        The start: time [s], height [m], velocity [m/s], where the master's error is 0.
    mode : Mode
        The mode at the start.
    F_ext : float
        The external force [N] at the start.
    ground : Ground, optional
        The ground (still at 0 by default, or a sine): the states given are the world's, measured in its frame.
    """

    def __init__(self, ball: Ball, t: float, h: float, v: float, mode: Mode, F_ext: float,
                 ground: Ground | None = None) -> None:
        self.ground = Ground() if ground is None else ground
        self.ball, self.parameters = ball, machine_ground(ball, self.ground)
        self.known = LAWS[ball.contact].closed_form
        self.err_x = self.err_v = 0.0  # the error of (x, v) [m, m/s] at the phase's start
        self.largest = 0.0  # the largest |x error| [m] measured so far
        self.scale = max(abs(h), ball.R)  # the height scale [m] the run reached: max(|h|, R)
        self.passed_at = math.nan  # the time [s] the measured error first passed the promise (NaN: never)
        self.lost = False  # the master stepped over an event unseen: the error is unbounded
        self.told = False  # the warning that the estimate passed the promise was logged
        self.t0 = self.x0 = self.v0 = self.load = 0.0
        self.mode = Mode.FLIGHT
        self._start(t, h, v, mode, F_ext)
        self.piece = (t, h, v, F_ext)  # where the exact solution starts: the start, or the last change of F_ext
        self._exact: ExactSolution | None = None
        self._judge_error = math.inf  # the exact solution's own error estimate [m]

    def _exact_state(self, t: float) -> tuple[float, float]:
        """(h [m], v [m/s]) of the exact solution at t, from the current piece's start (built EXACT_HORIZON ahead,
        twice as far each time it is passed); NaN where it cannot be had (contacts too short for double precision)."""
        exact = self._exact
        if exact is None or t > exact.t_end:
            start, h, v, F_ext = self.piece
            horizon = EXACT_HORIZON if exact is None else 2.0 * (exact.t_end - start)
            try:
                exact = self._exact = ExactSolution(self.ball, h, v, start, max(start + horizon, t), F_ext,
                                                    ground=self.ground)
            except ValueError:
                return math.nan, math.nan
            self._judge_error = exact.error_estimate
        h, v = exact.state(t)
        return float(h[0]), float(v[0])

    def _error_of_x(self, t: float, h: float, ex: float) -> float:
        """|h - h_true| [m] at t: the smaller of the carried error's ex and the exact solution's difference, but never
        below that difference less the exact solution's own error (a bound on it): where the master's impacts part
        from the truth's (a table's bounces amplify its error a thousandfold), the carry's linearisation fails low."""
        direct = abs(h - self._exact_state(t)[0])
        return abs(ex) if math.isnan(direct) else max(min(abs(ex), direct), direct - self._judge_error)

    def _start(self, t: float, h: float, v: float, mode: Mode, F_ext: float) -> None:
        """A phase starts at the state (the world's h, v at t): the reference is the exact flow from there."""
        self.t0, (self.x0, self.v0), self.mode = t, self._in_frame(t, h, v), Mode(mode)
        self.load = load_value(F_ext, self.ball.m, self.ball.g)  # the ground's acceleration: load_at's, at each t

    def _in_frame(self, t: float, h: float, v: float) -> tuple[float, float]:
        """(x = h - R - s [m], v - s' [m/s]) at t [s]: the gap and velocity in the ground's frame."""
        h, v = relative_to(self.ground, t, h, v)
        return h - self.ball.R, v

    # --- what the slave calls ---------------------------------------------------------------------
    def error_at(self, t: float, h: float, v: float) -> tuple[float, float]:
        """The error (of x [m], of v [m/s]) of the master's state (h, v) at t: carried plus the phase's own."""
        parameters, mode, tau = self.parameters, int(self.mode), t - self.t0
        x_flow, v_flow = law_flow_at(parameters, mode, self.x0, self.v0, self.t0, tau, self.load)
        p00, p10 = law_flow_value(parameters, mode, 1.0, 0.0, tau, 0.0)  # the ground's forcing is additive
        p01, p11 = law_flow_value(parameters, mode, 0.0, 1.0, tau, 0.0)
        ex0, ev0 = self.err_x, self.err_v
        x, v = self._in_frame(t, h, v)
        return p00 * ex0 + p01 * ev0 + (x - x_flow), p10 * ex0 + p11 * ev0 + (v - v_flow)

    def accept(self, t: float, h: float, v: float) -> tuple[float, float]:
        """A state the master accepted (h, v at t): its error measured and taken into the largest; the error."""
        if not self.known:
            return 0.0, 0.0
        ex, ev = self.error_at(t, h, v)
        self.largest = max(self.largest, self._error_of_x(t, h, ex)) if not math.isnan(ex) else math.inf
        self.scale = max(self.scale, abs(h))
        if math.isnan(self.passed_at) and not self.largest <= PROMISE * self.scale:
            self.passed_at = t
        return ex, ev

    def estimate(self, t: float | None = None, h: float = 0.0, v: float = 0.0) -> float:
        """error_estimate [m]: ESTIMATE_SAFETY times the largest error so far (with the state (h, v) at t, if given)."""
        if not self.known:
            return UNKNOWN
        if self.lost:
            return math.inf
        largest = self.largest
        if t is not None:
            largest = max(largest, self._error_of_x(t, h, self.error_at(t, h, v)[0]))
        return ESTIMATE_SAFETY * largest

    def forced(self, t: float, h: float, v: float, F_ext: float) -> None:
        """F_ext changes at the state: the phase ends there, the next one starts under the new force."""
        if self.known:
            self.err_x, self.err_v = self.accept(t, h, v)
            h_exact, v_exact = self._exact_state(t)
            if math.isnan(h_exact):  # none to be had: the carry's truth
                h_exact, v_exact = h - self.err_x, v - self.err_v
            self.piece, self._exact = (t, h_exact, v_exact, F_ext), None
        self._start(t, h, v, self.mode, F_ext)

    def switched(self, t: float, h: float, v: float, modes: list, F_ext: float) -> None:
        """The linear or no-pull ball's switches at the state (h, v at t) through modes (the old one first).

        The state is kept; at an impact or a departure from the pressed contact (a crossing of h = R) the field
        jumps by -+ b/m times the error of x, as carry_error says, and the master, which switched at
        x_e = h - R rather than on R, adds (b/m) x_e to v (to first order; none where the field is continuous,
        at the no-pull law's switches below R and its departures from the free sub-mode).
        """
        if self.known:
            ex, ev = self.accept(t, h, v)
            parameters, (x, u) = self.parameters, self._in_frame(t, h, v)
            load = load_at(parameters, self.load, t)
            for old, new in zip(modes, modes[1:], strict=False):
                kind = IMPACT if new == Mode.CONTACT and old == Mode.FLIGHT else DEPARTURE
                if {old, new} == {Mode.FLIGHT, Mode.CONTACT}:
                    jump, _ = event_saltation(parameters, kind, int(old), u, u, load)
                    ev = ev + jump * (ex - x)
            self.err_x, self.err_v = ex, ev
        self._start(t, h, v, modes[-1], F_ext)

    def rigid_impact(self, t: float, h: float, v: float, after: list, F_ext: float) -> None:
        """The rigid ball's impact at the state (h, v at t), after it [h, v, mode, ...] (rigid_impact's, the world's).

        A rebound reflects the error (saltation [[-e, 0], [-(1 + e) g_eff / v, -e]]) of the state less its
        offset x_e = h - R from R, where the truth's impact is. A ball put to rest on R (its bounces summed)
        keeps no error of x or v, but the truth still bounces, up to the first bounce's apex: that much is
        taken into the largest, unless the law itself ends the bounces there (v_min).
        """
        if self.known:
            ex, ev = self.accept(t, h, v)
            parameters, (x, v), (x_after, v_after) = self.parameters, self._in_frame(t, h, v), self._in_frame(t,
                                                                                                            *after[:2])
            load = load_at(parameters, self.load, t)
            g_eff, mode_after = load / parameters.m, after[2]
            if v >= 0.0:  # found below R moving up: put on R, v kept
                ex, ev = ex + (x_after - x), ev
            elif mode_after == Mode.FLIGHT:
                jump, reflection = event_saltation(parameters, IMPACT, int(Mode.FLIGHT), v, v_after, load)
                dx = ex - x
                ex, ev = reflection * dx, jump * dx + reflection * ev
            else:
                v_true = -parameters.e * v
                if v_true >= parameters.v_min and g_eff > 0.0:  # the truth bounces on
                    self.largest = max(self.largest, abs(ex) + v_true * v_true / (2.0 * g_eff))
                ex, ev = 0.0, 0.0
            self.err_x, self.err_v = ex, ev
        self._start(t, after[0], after[1], after[2], F_ext)

    def warning(self) -> str:
        """The log's line where the measured error passed the promise (passed_at not NaN).

        Judged by the error measured, not by the estimate (twice it): the master's error is measured, not bounded.
        """
        error = self.largest
        return (f"by t = {self.passed_at:.6g} s the model-exchange master's error, measured against the exact flow, "
                f"is {error:.2g} m, {error / self.scale:.2g} of the height scale {self.scale:.3g} m: past the promise "
                f"of {PROMISE:g} from t = {self.passed_at:.6g} s on; tighten the master's tolerance, or run the FMU in "
                "co-simulation, where its own CVODE keeps the promise")

    # --- an FMU state -----------------------------------------------------------------------------
    def saved(self) -> list:
        """What an FMU state keeps of it (JSON: NaN as None)."""
        passed_at = None if math.isnan(self.passed_at) else self.passed_at
        return [self.err_x, self.err_v, self.largest, self.scale, passed_at, self.lost, self.told, self.t0, self.x0,
                self.v0, int(self.mode), self.load, *self.piece]

    @staticmethod
    def checked(saved) -> list:
        """saved() of an FMU state, each field converted (TypeError, ValueError where one is not what it must be)."""
        if len(saved) != 16:
            raise ValueError(f"its master_error has {len(saved)} fields, not 16")
        err_x, err_v, largest, scale, passed_at, lost, told, t0, x0, v0, mode, load, *piece = saved
        numbers = [float(value) for value in (err_x, err_v, largest, scale, t0, x0, v0, load, *piece)]
        return [*numbers[:4], math.nan if passed_at is None else float(passed_at), bool(lost), bool(told),
                *numbers[4:7], Mode(int(mode)), numbers[7], tuple(numbers[8:])]

    def restore(self, checked: list) -> None:
        """The fields of a saved() that checked() converted."""
        (self.err_x, self.err_v, self.largest, self.scale, self.passed_at, self.lost, self.told, self.t0, self.x0,
         self.v0, self.mode, self.load, self.piece) = checked
        self._exact = None


class MeasuredMaster:
    """The FMI 3.0 slave's side of the measure (slave3.BouncingBall's first base): each accepted state measured.

    The slave's _exchange is model exchange's state [h, v, mode, ...] and _master_error its MasterError, made with it.
    The binary calls _completed_step after each fmi3CompletedIntegratorStep; a change of F_ext ends a phase.
    """

    _exchange: list | None
    _master_error: MasterError | None

    def _completed_step(self) -> None:
        """The master completed an integrator step at the state it set: its error measured (MasterError.accept)."""
        if self._exchange is not None and self._master_error is not None:
            self._master_error.accept(self.time, *self._exchange[:2])
            self._tell_master_error()

    def _tell_master_error(self) -> None:
        """Once per instance: the warning that the master's error passed the promise (status OK, as co-simulation's)."""
        measured = self._master_error
        if measured is not None and not measured.told and not math.isnan(measured.passed_at):
            measured.told = True
            self.log(measured.warning(), self.STATUS.warning)

    def _set(self, name, value):
        before = self._values.get("F_ext")
        super()._set(name, value)
        measured = self._master_error
        if name == "F_ext" and self._exchange is not None and measured is not None and self._values["F_ext"] != before:
            measured.forced(self.time, *self._exchange[:2], self._values["F_ext"])
            self._tell_master_error()
