"""Run a function in a child process that is killed past a time cap: a run that hangs or crashes becomes a result.

The bench's stability matrix, `bouncingball validate` and the sweep's Dask workers run solvers that
may take minutes (the article's explicit method on a stiff scene) or bring the process down (a host
that aborts): each such run goes through `run_capped`, so the caller always gets an answer within
the cap.

Why a child process: a run cannot be interrupted from inside (the compiled CVODE loop and SciPy's
solve_ivp hold the thread; signals reach only a process's main thread, and Dask runs tasks in worker
threads). Why one long-lived child per thread, started with subprocess: Dask's worker processes are
daemonic, and a daemonic process may not start multiprocessing children; a fork of a process that
runs threads (Dask's, FMPy's) is not safe. The child pays its start (Python, numpy: about 0.5 s)
once and runs call after call until one is killed or crashes it; the next call starts a new one.
The cap counts only the call.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

FINISHED, FAILED, TIMED_OUT = "finished", "failed", "timed out"
START_TIMEOUT = 300.0  # s: a child's start and warm-up (a first warm-up may compile the numba engine)
_HEADER = struct.Struct("!Q")  # each message: its length, then the pickle


@dataclass(frozen=True)
class Capped:
    """What a capped run gave: status FINISHED with its value, or FAILED / TIMED_OUT with a note why not."""

    status: str
    value: Any = None
    note: str = ""


def run_capped(function: Callable[..., Any], args: tuple, cap: float, warm_up: Callable[[], Any] | None = None,
               quiet: bool = False) -> Capped:
    """function(*args) in this thread's child process, killed if it has not returned within cap [s].

    Parameters
    ----------
    function : callable
        Called in the child: it and args are pickled there (a module-level function or a bound
        method of a picklable object), and so is its return value back.
    args : tuple
        Its arguments.
    cap : float
        Wall-time limit [s] of the call (the child's start and warm-up are not counted).
    warm_up : callable, optional
        Called once in each new child, untimed, before its first call (loading the engines, so that
        the first call times its run, not their loading). A warm-up that fails raises RuntimeError.
    quiet : bool
        Discard what the call writes to stdout and stderr (a C library's warnings).

    Returns
    -------
    Capped
        FINISHED with the return value; FAILED with the exception's first line (or the child's
        exit code if it died); TIMED_OUT if the cap passed first (the child is killed).

    Examples
    --------
    >>> import math
    >>> run_capped(math.sqrt, (2.0,), 10.0).value
    1.4142135623730951
    >>> run_capped(math.sqrt, (-1.0,), 10.0).note
    'ValueError: math domain error'
    >>> import time
    >>> run_capped(time.sleep, (5.0,), 0.2)
    Capped(status='timed out', value=None, note='killed after 0.2 s')
    """
    runner = getattr(_local, "runner", None)
    if runner is None:
        runner = _local.runner = CappedRunner()
        with _runners_lock:
            _runners.append(runner)
    return runner.call(function, args, cap, warm_up, quiet)


def close_all() -> None:
    """Stop this process's children (their threads start new ones if they run again)."""
    with _runners_lock:
        for runner in _runners:
            runner.close()


class CappedRunner:
    """One child process, started at the first call and again after a call that killed it."""

    def __init__(self) -> None:
        self.process: subprocess.Popen | None = None
        self.buffer = bytearray()
        self.warmed: set = set()

    def call(self, function: Callable[..., Any], args: tuple, cap: float, warm_up: Callable[[], Any] | None = None,
             quiet: bool = False) -> Capped:
        """function(*args) in the child, under cap [s]: see run_capped."""
        request = pickle.dumps((function, args, quiet))
        if self.process is None:
            self._start()
        if warm_up is not None and warm_up not in self.warmed:
            warmed = self._ask(pickle.dumps((warm_up, (), quiet)), START_TIMEOUT)
            if warmed.status != FINISHED:
                raise RuntimeError(f"the capped child's warm-up {getattr(warm_up, '__name__', warm_up)} "
                                   f"{warmed.status}: {warmed.note}")
            self.warmed.add(warm_up)
        return self._ask(request, cap)

    def close(self) -> int | None:
        """Kill the child (if any) and wait for it; its exit code."""
        if self.process is None:
            return None
        process, self.process = self.process, None
        if process.poll() is None:
            process.kill()
        process.wait()
        for stream in (process.stdin, process.stdout):
            stream.close()
        self.buffer.clear()
        self.warmed.clear()
        return process.returncode

    def _start(self) -> None:
        self.process = subprocess.Popen([sys.executable, "-c", "from bouncingball.capped import serve; serve()",
                                         str(os.getpid())], stdin=subprocess.PIPE, stdout=subprocess.PIPE, bufsize=0)
        started = self._ask(pickle.dumps(sys.path), START_TIMEOUT)  # it imports what this process imports
        if started.status != FINISHED:
            raise RuntimeError(f"the capped child process did not start ({started.status}: {started.note})")

    def _ask(self, request: bytes, cap: float) -> Capped:
        try:
            self.process.stdin.write(_HEADER.pack(len(request)) + request)
        except OSError:  # the child is gone
            return Capped(FAILED, note=f"the child process died (exit code {self.close()})")
        try:
            answer = self._receive(cap)
        except EOFError:  # it closed its end: it died
            self.process.wait()
            return Capped(FAILED, note=f"the child process died (exit code {self.close()})")
        if answer is None:
            self.close()
            return Capped(TIMED_OUT, note=f"killed after {cap:g} s")
        status, payload = pickle.loads(answer)
        return Capped(FINISHED, payload) if status == FINISHED else Capped(FAILED, note=payload)

    def _receive(self, cap: float) -> bytes | None:
        """The next answer; None if none began within cap [s]; EOFError if the child closed its end."""
        deadline = time.monotonic() + cap
        fd = self.process.stdout.fileno()
        while True:
            if len(self.buffer) >= _HEADER.size:
                end = _HEADER.size + _HEADER.unpack_from(self.buffer)[0]
                if len(self.buffer) >= end:
                    answer = bytes(self.buffer[_HEADER.size:end])
                    del self.buffer[:end]
                    return answer
            elif not select.select([fd], [], [], max(deadline - time.monotonic(), 0.0))[0]:
                return None  # the cap is on the answer's start: a large value may take longer to arrive
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                raise EOFError
            self.buffer += chunk


_local = threading.local()
_runners: list[CappedRunner] = []
_runners_lock = threading.Lock()
atexit.register(close_all)


def _forget() -> None:
    """In a forked process: the parent's children are not ours to use or kill."""
    global _local, _runners
    _local, _runners = threading.local(), []


os.register_at_fork(after_in_child=_forget)


# --- the child ----------------------------------------------------------------------------------------------
def serve() -> None:
    """The child's loop: one pickled (function, args, quiet) in on stdin, one (status, value or note) out.

    Started by CappedRunner with this process's parent's pid as its argument; it exits when its
    stdin closes. Ctrl-C is the parent's to handle: the parent kills it.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(int(sys.argv[1]))
    # The answers go to the original stdout; anything else printed to fd 1 (a C library's warning)
    # goes to stderr instead, so that it cannot corrupt the protocol.
    answers = os.fdopen(os.dup(1), "wb", buffering=0)
    os.dup2(2, 1)
    requests = sys.stdin.buffer
    path = _read(requests)
    sys.path[:0] = [entry for entry in pickle.loads(path) if entry not in sys.path]
    _send(answers, (FINISHED, None))
    while (request := _read(requests)) is not None:
        try:
            function, args, quiet = pickle.loads(request)
            with _silenced(quiet):
                answer = (FINISHED, function(*args))
        except Exception as error:  # the parent reports it as the call's result
            answer = (FAILED, f"{type(error).__name__}: {error}".splitlines()[0][:300])
        try:
            _send(answers, answer)
        except Exception as error:  # a value that cannot be pickled
            _send(answers, (FAILED, f"its value cannot be sent back: {type(error).__name__}: {error}"[:300]))


def _read(stream) -> bytes | None:
    header = stream.read(_HEADER.size)
    if len(header) < _HEADER.size:
        return None
    return stream.read(_HEADER.unpack(header)[0])


def _send(stream, answer: tuple) -> None:
    payload = pickle.dumps(answer)
    stream.write(_HEADER.pack(len(payload)) + payload)


@contextlib.contextmanager
def _silenced(quiet: bool):
    if not quiet:
        yield
        return
    sys.stdout.flush()
    sys.stderr.flush()
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.dup2(null, 2)
    try:
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved, 1)
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


def _die_with_parent(parent: int) -> None:
    """On Linux, be killed when the process that started us dies (else a long run would outlive it)."""
    if sys.platform.startswith("linux"):
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before prctl
        sys.exit(0)
