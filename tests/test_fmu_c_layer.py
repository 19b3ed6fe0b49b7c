"""The FMU's C layer serves values and takes steps without entering Python (fmu/c_layer.py), and changes no number.

Each case runs in its own Python process through FMPy (fmu_helpers.Instance, fmu3_helpers.Instance3). The slave is
found in that process and its Python step counted: a run whose values are served and whose in-step steps the loader
takes is compared, value for value and bit for bit, with the same run in an instance whose slave hands the loader
nothing (every call in Python, as before the C layer). What a set, a restored state or a reset changes is read back
at once, never a value served from before it.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

TESTS = Path(__file__).parent

_PRELUDE = """
import gc, sys
sys.path.insert(0, {tests!r})


_seen = []  # the slaves found already (kept, so that no new one can take an id of theirs)


def slave_of(instance):
    '''The FMU's Python slave made for instance (the one not seen before), its Python steps counted in
    slave.python_steps.'''
    slaves = [o for o in gc.get_objects() if type(o).__name__ == "BouncingBall" and hasattr(o, "_served")
              and not any(o is seen for seen in _seen)]
    assert len(slaves) == 1, len(slaves)
    slave = slaves[0]
    _seen.append(slave)
    step, slave.python_steps = slave._step, 0

    def counted(*arguments):
        slave.python_steps += 1
        return step(*arguments)

    slave._step = counted
    return slave
"""


def run_case(body: str, *arguments: str) -> str:
    code = _PRELUDE.format(tests=str(TESTS)) + textwrap.dedent(body)
    completed = subprocess.run([sys.executable, "-c", code, *arguments], capture_output=True, text=True, timeout=300,
                               check=False)
    assert completed.returncode == 0, completed.stdout + completed.stderr
    return completed.stdout


SCENES = {
    "article": {},
    "rigid, summed to rest": {"contact_law": "rigid", "e": 0.5},
    "linear-no-pull": {"contact_law": "linear-no-pull", "k": 1e5, "b": 200.0},
    "hunt-crossley": {"contact_law": "hunt-crossley", "k": 1e6, "n": 1.5, "alpha": 0.2},
    "vibrating table": {"ground_amplitude": 0.003, "ground_frequency": 10.0},
    "past the promise": {"rtol": 1e-4},  # the accuracy warning, checked by the slave at each step from then on
}


@pytest.mark.parametrize("scene", list(SCENES))
def test_fmi2_served_run_equals_the_python_run_to_the_bit(unzipped, scene):
    out = run_case("""
        from fmu_helpers import Instance
        start = eval(sys.argv[2])
        runs = {}
        for served in (True, False):
            ball = Instance(sys.argv[1])
            slave = slave_of(ball)
            slave._served.linked &= served  # unlinked: the loader is handed nothing, every call runs in Python
            ball.initialize(**start)
            rows = ball.step_to(3.0, 1e-3)
            runs[served] = (rows, ball.get("error_estimate", "F_ext", "m", "rtol"), ball.log, slave.python_steps)
            ball.free()
        (served, served_last, served_log, python_steps), (plain, plain_last, plain_log, all_steps) = runs.values()
        assert all_steps == 3000, all_steps
        assert served == plain and served_last == plain_last  # every output at every step, to the bit
        assert served_log == plain_log  # the same messages
        print(any("past the promise" in message for _, message in served_log), python_steps)
    """, str(unzipped), repr(SCENES[scene]))
    warned, python_steps = out.split()[-2] == "True", int(out.split()[-1])
    assert warned == (scene == "past the promise")
    if scene == "vibrating table":  # the ground's motion is the Python ground's: every step in Python
        assert python_steps == 3000
    elif scene == "past the promise":  # the warning checked after each step that ran CVODE, once its error is carried
        assert 10 < python_steps < 1000
    else:  # only the first: every other step taken by the FMU's binary, CVODE's included
        assert python_steps == 1


def test_fmi3_served_run_equals_the_python_run_to_the_bit(unzipped3):
    out = run_case("""
        from fmu3_helpers import Instance3
        names = ("time", "h", "v", "a", "contact", "contact_force", "impacts", "error_estimate", "der(x)", "der(v)",
                 "gap", "x")
        runs = {}
        for early_return in (False, True):
            for served in (True, False):
                ball = Instance3(sys.argv[1], early_return=early_return)
                slave = slave_of(ball)
                slave._served.linked &= served
                ball.fmu.enterInitializationMode(startTime=0.0)
                ball.fmu.exitInitializationMode()
                rows, t = [], 0.0
                while t < 2.0:
                    t_next = min(round(t * 1000 + 1) / 1000, 2.0)
                    *_, t = ball.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=t_next - t)
                    rows.append(tuple(ball.get(*names)))
                runs[early_return, served] = rows, slave.python_steps
                ball.fmu.terminate()
                ball.fmu.freeInstance()
        for early_return in (False, True):
            (served, python_steps), (plain, all_steps) = runs[early_return, True], runs[early_return, False]
            assert served == plain, early_return  # every value at every step, to the bit
            assert python_steps == 1, (early_return, python_steps, all_steps)
        print("ok")
    """, str(unzipped3))
    assert out.split()[-1] == "ok"


def test_what_a_set_a_restored_state_or_a_reset_changes_is_read_back_at_once(unzipped):
    out = run_case("""
        from fmu_helpers import Instance
        ball = Instance(sys.argv[1])
        slave = slave_of(ball)
        assert slave._served.linked
        ball.initialize()
        ball.step_to(0.5, 1e-3)  # in flight: a = -g + F_ext / m
        assert ball.get("a") == [-9.81]
        ball.set(F_ext=3.0)
        a, F_ext = ball.get("a", "F_ext")
        assert abs(a - (-9.81 + 3.0)) < 1e-12 and F_ext == 3.0, (a, F_ext)
        saved, h_saved = ball.fmu.getFMUstate(), ball.get("h")
        ball.step_to(0.6, 1e-3)
        assert ball.get("h") != h_saved
        ball.fmu.setFMUstate(saved)
        ball.t = 0.5
        assert ball.get("h") == h_saved
        ball.fmu.reset()
        ball.t = 0.0
        ball.initialize(h=1.0)
        assert ball.get("h", "F_ext") == [1.0, 0.0]
        ball.step_to(0.1, 1e-3)
        # 0.1 s of free fall from 1 m, at rest at first: h = 1 - g t^2 / 2
        assert abs(ball.get("h")[0] - (1.0 - 9.81 * 0.1**2 / 2)) < 1e-12, ball.get("h")
        print("ok")
    """, str(unzipped))
    assert out.split()[-1] == "ok"


def test_a_step_whose_compiled_code_raises_ends_the_instance_with_an_error(unzipped):
    """Its state may have changed before the raise: the step is not run again in Python (a result from an unknown
    state), the call returns fmi2Error with a line that says so, and the instance takes no further call, as where the
    slave's own step raises out of the FMU."""
    out = run_case("""
        import fmpy
        from fmu_helpers import Instance
        ball = Instance(sys.argv[1])
        slave = slave_of(ball)
        ball.initialize()
        ball.step_to(0.1, 1e-3)
        slave._served._kept.parameters[0] = 0.0  # the compiled step's m: a ZeroDivisionError at the acceleration
        python_steps = slave.python_steps
        try:
            ball.fmu.doStep(0.1, 1e-3)
        except fmpy.fmi1.FMICallException as error:
            assert error.status == 3, error.status  # fmi2Error
        else:
            raise AssertionError("the step was taken")
        assert slave.python_steps == python_steps  # not run again in Python
        assert "the compiled engine raised" in ball.errors()[-1], ball.errors()
        try:
            ball.fmu.doStep(0.1, 1e-3)
        except fmpy.fmi1.FMICallException:
            pass
        else:
            raise AssertionError("a further call was taken")
        assert "an earlier error ended this instance" in ball.errors()[-1], ball.errors()
        ball.free()
        print("ok")
    """, str(unzipped))
    assert out.split()[-1] == "ok"
