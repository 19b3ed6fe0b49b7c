"""One run under a wall-time cap, enforced in a child process on the machine that runs it.

Why a child process: a run cannot be interrupted from inside (the compiled CVODE loop and SciPy's
solve_ivp hold the thread; signals reach only a process's main thread, and Dask runs tasks in
worker threads). So each worker thread keeps one long-lived child (`python -m
bouncingball.sweep.child`), sends it one run at a time over a pipe and kills it when the cap
passes. It is started with subprocess, not multiprocessing: Dask's worker processes are daemonic,
and a daemonic process may not start multiprocessing children (that works on any user's cluster
with no `distributed.worker.daemon` setting). The child pays its start (Python, numpy, the
compiled engine: ~1 s) once and is reused until a run is killed; the cap counts only the run.
"""

from __future__ import annotations

import json
import math
import os
import select
import socket
import subprocess
import sys
import threading
import time

READY = "ready"
START_TIMEOUT = 300.0  # s: a first start may compile the numba engine (~3 s) on a loaded machine
DEFAULT_TIME_CAP = 2.0  # s per run


class _Child:
    """A child process that runs one run per line of JSON on stdin and answers with one line on stdout."""

    def __init__(self) -> None:
        self.process = subprocess.Popen([sys.executable, "-m", "bouncingball.sweep.child"], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, bufsize=0,
                                        env={**os.environ, "BOUNCINGBALL_SWEEP_PARENT": str(os.getpid())})
        self.buffer = b""
        line = self.read_line(START_TIMEOUT)
        if line != READY:
            self.close()
            raise RuntimeError(f"the sweep's child process did not start (it said {line!r})")

    def read_line(self, timeout: float) -> str | None:
        """The next line, or None if none came within timeout [s] or the child closed its stdout."""
        deadline = time.monotonic() + timeout
        fd = self.process.stdout.fileno()
        while b"\n" not in self.buffer:
            left = deadline - time.monotonic()
            if left <= 0.0 or not select.select([fd], [], [], left)[0]:
                return None
            chunk = os.read(fd, 1 << 16)
            if not chunk:
                return None
            self.buffer += chunk
        line, _, self.buffer = self.buffer.partition(b"\n")
        return line.decode()

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        for stream in (self.process.stdin, self.process.stdout):
            stream.close()


class CappedRunner:
    """Runs sweep runs (the dicts of Grid.runs()) in a child process, each under time_cap [s].

    Examples
    --------
    >>> from bouncingball.sweep.grid import Grid
    >>> runner = CappedRunner(time_cap=10.0)
    >>> row = runner.run(Grid(k=(1e4, 1e4, 1), zeta=(0.05, 0.05, 1), solvers=("cvode",)).runs()[0])
    >>> row["status"], row["events_found"] == row["events_exact"]
    ('finished', True)
    >>> runner.close()
    """

    def __init__(self, time_cap: float = DEFAULT_TIME_CAP) -> None:
        self.time_cap = time_cap
        self.child: _Child | None = None

    def run(self, spec: dict) -> dict:
        """One run's result row: spec's fields, status (finished, failed or timed out), reason and measures."""
        if self.child is None:
            self.child = _Child()
        process = self.child.process
        try:
            process.stdin.write((json.dumps(spec) + "\n").encode())
        except OSError:  # the child is gone: an earlier run killed it (out of memory...)
            return self._lost(spec, f"the child process died (exit code {self._restart()})")
        line = self.child.read_line(self.time_cap)
        if line is None:
            if process.poll() is None:
                self._restart()
                return _row(spec, "timed out", f"killed after {self.time_cap:g} s")
            return self._lost(spec, f"the child process died (exit code {self._restart()})")
        return {**spec, **json.loads(line), "worker": WORKER_NAME}

    def _lost(self, spec: dict, reason: str) -> dict:
        return _row(spec, "failed", reason)

    def _restart(self) -> int | None:
        self.child.close()
        code = self.child.process.returncode
        self.child = None
        return code

    def close(self) -> None:
        if self.child is not None:
            self.child.close()
            self.child = None


WORKER_NAME = f"{socket.gethostname()}:{os.getpid()}"
MEASURES = {"events_found": -1, "events_exact": -1, "event_mismatches": -1, "first_mismatch": "",
            "max_height_error": math.nan, "max_event_time_error": math.nan, "wall_time": math.nan, "rhs_calls": -1,
            "steps": -1}


def _row(spec: dict, status: str, reason: str = "", **measures) -> dict:
    return {**spec, "status": status, "reason": reason, **MEASURES, **measures, "worker": WORKER_NAME}


_local = threading.local()
_runners: list[CappedRunner] = []
_runners_lock = threading.Lock()


def run_batch(specs: list[dict], time_cap: float) -> list[dict]:
    """Run specs one after another in this thread's child process (a Dask task; never raises for a bad run)."""
    runner = getattr(_local, "runner", None)
    if runner is None:
        runner = _local.runner = CappedRunner(time_cap)
        with _runners_lock:
            _runners.append(runner)
    runner.time_cap = time_cap
    return [runner.run(spec) for spec in specs]


def close_all() -> None:
    """Stop this process's children (their worker threads start new ones if they run again)."""
    with _runners_lock:
        for runner in _runners:
            runner.close()


def noop(x):
    """A task that does nothing: its round trip is the overhead Dask adds to a task."""
    return x
