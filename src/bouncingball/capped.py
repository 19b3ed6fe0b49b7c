"""Run a function in a child process that is killed past a time cap: a run that hangs or crashes becomes a result.

The bench, the stability matrix and `bouncingball validate` run solvers that may take minutes (the
article's explicit method on a stiff scene) or bring the process down (a host that aborts): each
such run goes through `run_capped`, so the caller always gets an answer within the cap.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

FINISHED, FAILED, TIMED_OUT = "finished", "failed", "timed out"


@dataclass(frozen=True)
class Capped:
    """What a capped run gave: status FINISHED with its value, or FAILED / TIMED_OUT with a note why not."""

    status: str
    value: Any = None
    note: str = ""


def run_capped(function: Callable[..., Any], args: tuple, cap: float) -> Capped:
    """function(*args) in a forked child process, killed if it has not returned within cap [s].

    Parameters
    ----------
    function : callable
        Called in the child; its return value must be picklable.
    args : tuple
        Its arguments (inherited by the fork, not pickled).
    cap : float
        Wall-time limit [s].

    Returns
    -------
    Capped
        FINISHED with the return value; FAILED with the exception's first line (or the child's
        exit code if it died); TIMED_OUT if the cap passed first.
    """
    # fork: the child inherits the arguments as they are (no pickling of scenes or FMU paths) and
    # starts in milliseconds; callers start no threads before it (FMPy's FMUs run after).
    context = multiprocessing.get_context("fork")
    receiver, sender = context.Pipe(duplex=False)
    process = context.Process(target=_call_into, args=(function, args, sender), daemon=True)
    process.start()
    sender.close()
    try:
        if not receiver.poll(cap):
            return Capped(TIMED_OUT, note=f"killed after {cap:g} s")
        status, payload = receiver.recv()
        return Capped(FINISHED, payload) if status == FINISHED else Capped(FAILED, note=payload)
    except EOFError:
        process.join()
        return Capped(FAILED, note=f"the child process died (exit code {process.exitcode})")
    finally:
        if process.is_alive():
            process.kill()
        process.join()
        receiver.close()


def _call_into(function: Callable[..., Any], args: tuple, sender) -> None:
    try:
        sender.send((FINISHED, function(*args)))
    except Exception as error:  # the parent reports it as the run's result
        sender.send((FAILED, f"{type(error).__name__}: {error}".splitlines()[0][:200]))
    finally:
        sender.close()
