"""capped.run_capped: a call that finishes, fails, hangs or crashes its process is a result, and the next call works."""

import math
import os
import threading
import time

import pytest

from bouncingball import capped
from bouncingball.capped import FAILED, FINISHED, TIMED_OUT, run_capped

WARM_UPS = "BOUNCINGBALL_TEST_WARM_UPS"


def warm_up():
    """Counts the warm-ups this child ran, in its environment."""
    os.environ[WARM_UPS] = str(int(os.environ.get(WARM_UPS, "0")) + 1)


def warm_ups_and_pid():
    return int(os.environ.get(WARM_UPS, "0")), os.getpid()


def failing_warm_up():
    raise RuntimeError("no engine here")


def unpicklable():
    return threading.Lock()


def test_value_error_timeout_and_crash_each_give_a_result_and_the_child_comes_back():
    assert run_capped(math.hypot, (3.0, 4.0), 10.0) == capped.Capped(FINISHED, 5.0)
    first_child = run_capped(os.getpid, (), 10.0).value
    assert first_child != os.getpid() and run_capped(os.getpid, (), 10.0).value == first_child  # reused
    assert run_capped(math.sqrt, (-1.0,), 10.0) == capped.Capped(FAILED, note="ValueError: math domain error")
    started = time.monotonic()
    assert run_capped(time.sleep, (30.0,), 0.3) == capped.Capped(TIMED_OUT, note="killed after 0.3 s")
    assert time.monotonic() - started < 10.0
    # A call that brings its process down (a host that aborts): this process goes on.
    assert run_capped(os.abort, (), 10.0) == capped.Capped(FAILED, note="the child process died (exit code -6)")
    assert run_capped(os._exit, (3,), 10.0).note == "the child process died (exit code 3)"
    second_child = run_capped(os.getpid, (), 10.0).value
    assert second_child not in (first_child, os.getpid())
    assert run_capped(unpicklable, (), 10.0).note.startswith("its value cannot be sent back: TypeError")


def test_warm_up_runs_once_per_child_and_a_failing_one_says_so():
    capped.close_all()
    assert run_capped(warm_ups_and_pid, (), 10.0, warm_up=warm_up).value[0] == 1
    assert run_capped(warm_ups_and_pid, (), 10.0, warm_up=warm_up).value[0] == 1
    run_capped(time.sleep, (30.0,), 0.2)  # kills the child: the next one warms up again
    assert run_capped(warm_ups_and_pid, (), 10.0, warm_up=warm_up).value[0] == 1
    with pytest.raises(RuntimeError, match="warm-up failing_warm_up failed: RuntimeError: no engine here"):
        run_capped(os.getpid, (), 10.0, warm_up=failing_warm_up)


def test_each_thread_has_its_own_child():
    here = run_capped(os.getpid, (), 10.0).value
    there = []
    thread = threading.Thread(target=lambda: there.append(run_capped(os.getpid, (), 10.0).value))
    thread.start()
    thread.join()
    assert there[0] not in (here, os.getpid())


def test_quiet_call_discards_what_it_prints(capfd):
    capped.close_all()
    run_capped(os.getpid, (), 10.0)  # the child's start, outside what is captured below
    capfd.readouterr()
    assert run_capped(print, ("shown",), 10.0).status == FINISHED
    assert run_capped(print, ("hidden",), 10.0, quiet=True).status == FINISHED
    assert run_capped(os.write, (2, b"hidden too\n"), 10.0, quiet=True).value == 11
    assert run_capped(print, ("shown again",), 10.0).status == FINISHED
    out, err = capfd.readouterr()
    assert (out, err) == ("", "shown\nshown again\n")
