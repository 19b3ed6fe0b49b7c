"""One mode's CVODE for the compiled engine (and the FMU's native one): its settings, its memory, its callbacks' data.

The compiled engine (solvers/engines/compiled.py, numba) and the native engine (solvers/engines/native.py, the same
code compiled ahead into a library) drive the SUNDIALS CVODE library scikit-sundae installs with C callbacks for the
right-hand side, the root functions and the Jacobian. ``PhaseSolver`` is one mode's CVODE, made with the callbacks'
addresses its subclass gives (``callbacks``), with the same settings and step sequence as the scikit-sundae engine's;
its ``handle`` is the row of addresses the compiled phase machine reads. The constants below are the layout of the
memory they share: the compiled code reads them as it is compiled (so this file is one of jit.ENGINE_SOURCES).

Imports neither numba nor scikit-sundae.
"""

from __future__ import annotations

import ctypes
import weakref

import numpy as np

from ...contact_laws import BallParameters
from .sundials import free as _free
from .sundials import library
from .sundials import message as _message
from .sundials_log import SundialsLog

CV_ADAMS, CV_BDF = 1, 2
CV_ONE_STEP = 2
# cvode.py's defaults for scikit-sundae's options that CVODE would otherwise take from itself.
MAX_NONLIN_ITERS = 3
MAX_CONV_FAILS = 10
MAX_ORDER = {CV_ADAMS: 12, CV_BDF: 5}
NUM_ROOTS = 3

# The block user_data points to (int64): what the callbacks need besides the state.
U_PARAMETERS, U_GET_ARRAY, U_COLUMNS, U_EVALUATIONS, U_MAX_EVALUATIONS, U_SIZE = range(6)
# The callbacks' float64 parameters: CVODE integrates x / length, v / speed (x = h - R) from P_ORIGIN [s] (time 0;
# a vibrating ground's load is equations.load_at's there + CVODE's time); the ball from P_BALL (BallParameters).
(P_MODE, P_OWN_SIDE, P_HOP, P_J00, P_J01, P_J10, P_J11, P_LENGTH, P_SPEED, P_LOAD, P_ORIGIN,
 P_BALL) = range(12)
P_SIZE = P_BALL + len(BallParameters._fields)

# The C functions the compiled loop calls, by their place in the address array it receives.
LOOP_FUNCTIONS = ("CVode", "CVodeGetRootInfo", "CVodeReInit", "CVodeSetStopTime", "CVodeClearStopTime",
                  "CVodeGetNumRhsEvals")
CVODE, ROOT_INFO, REINIT, SET_STOP, CLEAR_STOP, NUM_RHS = range(len(LOOP_FUNCTIONS))
# engine: one row per mode (PhaseSolver.handle()): the addresses of its call table and arrays, its CVODE
# memory and vector. Integers only, so that a call into the compiled machine unpacks no Python objects.
H_CALLS, H_MEMORY, H_VECTOR, H_STATE, H_PARAMETERS, H_USER_DATA, H_WORK, H_COUNTER, H_SIZE = range(9)


class PhaseSolver:
    """CVODE for one mode of the ball, with scikit-sundae's CVODE calls that BallIntegrator uses.

    A subclass names the C callbacks (``callbacks``: the addresses of the right-hand side, the root functions and
    the Jacobian, each as compiled.py's ``_rhs``, ``_roots`` and ``_jacobian`` declare it).

    Parameters
    ----------
    ball : Ball
        The ball.
    mode : Mode
        The mode whose equations this solver integrates.
    method : str
        "Adams" or "BDF".
    rtol : float
        CVODE's relative tolerance; its absolute one is the same, on the state scaled to the phase.
    max_step : float
        The largest step [s]; 0 for none.
    max_num_steps : int
        CVODE's limit of steps per call.
    own_side : float
        The value of h - R the root function reports at h == R (the mode's own side).
    directions : sequence of int
        The crossing direction CVODE reports for each root function (h - R, v, rest margin).
    max_evaluations : int
        Root-function evaluations allowed per phase; beyond, CVode fails with CV_RTFUNC_FAIL
        (see ``exceeded``).
    """

    def __init__(self, ball, mode, method: str, rtol: float, max_step: float, max_num_steps: int,
                 own_side: float, directions, max_evaluations: int) -> None:
        self._lib = library()
        self.log = SundialsLog()
        self._method = CV_ADAMS if method == "Adams" else CV_BDF
        self._settings = (rtol, rtol, max_step, max_num_steps)
        self._mode = mode
        self.parameters = np.zeros(P_SIZE)
        self.parameters[[P_MODE, P_OWN_SIDE]] = int(mode), own_side
        self.bind(ball)
        self._directions = (ctypes.c_int * NUM_ROOTS)(*directions)
        addresses = self._lib.addresses
        self._user_data = np.zeros(U_SIZE, dtype=np.intp)
        self._user_data[[U_PARAMETERS, U_GET_ARRAY, U_COLUMNS]] = (
            self.parameters.ctypes.data, addresses["N_VGetArrayPointer"], addresses["SUNDenseMatrix_Cols"])
        self._user_data[U_MAX_EVALUATIONS] = max_evaluations
        self._calls = np.array([addresses[name] for name in LOOP_FUNCTIONS], dtype=np.intp)
        self._work = np.zeros(1 + NUM_ROOTS)
        self._counter = np.zeros(1, dtype=np.int64)  # a C long
        self._handles = {}
        self._state = None

    # --- set-up and clean-up ----------------------------------------------------------------------
    def _check(self, name: str, flag: int) -> None:
        if flag < 0:
            raise RuntimeError(f"{name} failed: {_message(flag)}")

    def _create(self, name, *args):
        handle = self._lib.functions[name](*args)
        if not handle:
            raise MemoryError(f"{name} returned NULL")
        return handle

    def _setup(self, t0: float, y0) -> None:
        f = self._lib.functions
        context = ctypes.c_void_p()
        self._check("SUNContext_Create", f["SUNContext_Create"](0, ctypes.byref(context)))
        handles = self._handles
        handles["context"] = context
        # Freed in reverse order of creation, even if a step below fails.
        self._finalizer = weakref.finalize(self, _free, f, handles)
        self._check("SUNContext_ClearErrHandlers", f["SUNContext_ClearErrHandlers"](context))
        handles["vector"] = vector = self._create("N_VNew_Serial", 2, context)
        data = f["N_VGetArrayPointer"](vector)
        self._state = np.ctypeslib.as_array(ctypes.cast(data, ctypes.POINTER(ctypes.c_double)), shape=(2,))
        self._state[:] = y0
        handles["matrix"] = matrix = self._create("SUNDenseMatrix", 2, 2, context)
        handles["linear_solver"] = linear_solver = self._create("SUNLinSol_Dense", vector, matrix, context)
        handles["memory"] = memory = self._create("CVodeCreate", self._method, context)
        self._memory = memory
        rtol, atol, max_step, max_num_steps = self._settings
        rhs, roots, jacobian = self.callbacks
        for name, *args in (
            ("CVodeSetUserData", self._user_data.ctypes.data),
            ("CVodeInit", rhs, t0, vector),
            ("CVodeSStolerances", rtol, atol),
            ("CVodeSetLinearSolver", linear_solver, matrix),
            ("CVodeSetJacFn", jacobian),
            ("CVodeSetMaxNonlinIters", MAX_NONLIN_ITERS),
            ("CVodeSetMaxConvFails", MAX_CONV_FAILS),
            ("CVodeRootInit", NUM_ROOTS, roots),
            ("CVodeSetRootDirection", self._directions),
            ("CVodeSetInitStep", 0.0),
            ("CVodeSetMinStep", 0.0),
            ("CVodeSetMaxStep", max_step),
            ("CVodeSetMaxOrd", MAX_ORDER[self._method]),
            ("CVodeSetMaxNumSteps", max_num_steps),
        ):
            self._check(name, f[name](memory, *args))

    def close(self) -> None:
        """Free every SUNDIALS object now (also done when the solver is garbage-collected)."""
        if self._handles:
            self._finalizer()

    # --- the calls BallIntegrator makes (solvers/engines/stepper.py) ---------------------------------------
    def bind(self, ball, parameters=None) -> None:
        """Integrate ball's equations (or parameters, the machine's: a vibrating ground's) from now on."""
        self.parameters[P_BALL:] = ball.parameters if parameters is None else parameters

    def handle(self) -> np.ndarray:
        """This solver's row of the compiled machine's engine (see _H_*; its CVODE made on first use)."""
        if not self._handles:
            with self.log.capturing():
                self._setup(0.0, (0.0, 0.0))
            self._row = row = np.zeros(H_SIZE, dtype=np.intp)  # the addresses hold until close
            row[[H_CALLS, H_MEMORY, H_VECTOR, H_STATE, H_PARAMETERS, H_USER_DATA, H_WORK, H_COUNTER]] = (
                self._calls.ctypes.data, self._memory, self._handles["vector"], self._state.ctypes.data,
                self.parameters.ctypes.data, self._user_data.ctypes.data, self._work.ctypes.data,
                self._counter.ctypes.data)
        return self._row

    def message(self, flag: int) -> str:
        """CVODE's flag in words."""
        return _message(flag)
