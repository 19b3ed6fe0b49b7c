"""Co-simulation with FMI 3.0 early return: cosim_levitation.py's coupling, the ball as an FMI 3.0 FMU that returns at
each impact and departure, so that the master updates F_ext there (in event mode) instead of at the next
communication point.

Needs: pip install 'bouncingball[fmu]' (pythonfmu, pythonfmu3, FMPy; building the ball FMUs needs a C compiler).
Usage: python cosim_levitation3.py [OUTPUT_DIR]      (builds the FMUs there; default: the current directory)

Two cases, each against the same fine-step reference (the FMI 2.0 coupling at a step of 2^-12 s):
- levitation: cosim_levitation.py's, the controller on from 2.25 s to 5 s, when no impact happens;
- catch: a softer controller (kp = 4 N/m, kd = 0.5 N s/m) on from 0.5 s, the ball still falling, to
  8 s, holding it at 0.3 m: the ball hits the ground and bounces under the controller's force.
Early return updates F_ext at each event instead of at the next communication point; the force is
still held over the rest of each step, so both couplings converge at first order in the step.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from pythonfmu import FmuBuilder

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
out.mkdir(parents=True, exist_ok=True)
T_END = 8.0
STEPS = [2.0**-k for k in range(3, 8)]  # 0.125 s ... 7.8 ms, as in cosim_levitation.py
REFERENCE_STEP = 2.0**-12
CASES = {"levitation": {"t_on": 2.25, "t_off": 5.0, "h_set": 1.0},
         "catch": {"t_on": 0.5, "t_off": 8.0, "h_set": 0.3, "kp": 4.0, "kd": 0.5}}

bouncingball = Path(sys.executable).parent / "bouncingball"
for version in ("2", "3"):
    subprocess.run([bouncingball, "build-fmu", "--fmi-version", version, "-o",
                    out / f"BouncingBall{'' if version == '2' else 3}.fmu"], check=True, stdout=subprocess.DEVNULL)
controller_fmu = FmuBuilder.build_FMU(Path(__file__).resolve().parent / "pd_controller.py", dest=out)


class Slave:
    """An FMU instance (FMI 2.0, or FMI 3.0 with early return and event mode), initialised with start values."""

    def __init__(self, fmu, name, **start):
        description = read_model_description(str(fmu))
        self.refs = {v.name: v.valueReference for v in description.modelVariables}
        self.fmi3 = description.fmiVersion.startswith("3")
        kind = FMU3Slave if self.fmi3 else FMU2Slave
        self.fmu = kind(guid=description.guid, unzipDirectory=extract(str(fmu)), instanceName=name,
                        modelIdentifier=description.coSimulation.modelIdentifier)
        if self.fmi3:
            self.fmu.instantiate(eventModeUsed=True, earlyReturnAllowed=True)
        else:
            self.fmu.instantiate()
            self.fmu.setupExperiment(startTime=0.0, stopTime=T_END)
        self.set(**start)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        if self.fmi3:
            self.fmu.updateDiscreteStates()
            self.fmu.enterStepMode()

    def get(self, *names):
        refs = [self.refs[name] for name in names]
        return self.fmu.getFloat64(refs) if self.fmi3 else self.fmu.getReal(refs)

    def set(self, **values):
        refs, values = [self.refs[name] for name in values], list(values.values())
        self.fmu.setFloat64(refs, values) if self.fmi3 else self.fmu.setReal(refs, values)

    def step(self, t, dt):
        """doStep from t by dt: the time reached, and whether it is an event's (an early return)."""
        if not self.fmi3:
            self.fmu.doStep(t, dt)
            return t + dt, False
        needed, _, early, reached = self.fmu.doStep(t, dt)
        if early and needed:
            self.fmu.enterEventMode()  # left in cosimulate once F_ext is set at the event
        return (reached, True) if early else (t + dt, False)

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def cosimulate(ball_fmu, dt, case):
    """The coupled run: rows of (t, h, v, F_ext) at every communication point and every early return."""
    ball, controller = Slave(ball_fmu, "ball"), Slave(controller_fmu, "controller", **case)
    rows, t, n, early_returns, event = [], 0.0, 0, 0, False
    while True:
        h, v = ball.get("h", "v")
        controller.set(h=h, v=v)  # the controller's output depends directly on its inputs: set them first
        force = controller.get("F")[0]
        rows.append((t, h, v, force))
        ball.set(F_ext=force)  # held from t to the next communication point or event
        if event:
            ball.fmu.updateDiscreteStates()
            ball.fmu.enterStepMode()
        if n == round(T_END / dt):
            break
        reached, event = ball.step(t, (n + 1) * dt - t)
        controller.fmu.doStep(t, reached - t)
        early_returns += event
        n, t = (n, reached) if event else (n + 1, (n + 1) * dt)
    ball.free(), controller.free()
    return np.array(rows), early_returns


print(f"{'case':12s}{'step [s]':>10s}{'FMI 2.0: max |h - h_ref| [m]':>30s}{'FMI 3.0, early return':>24s}"
      f"{'early returns':>15s}")
for name, case in CASES.items():
    reference, _ = cosimulate(out / "BouncingBall.fmu", REFERENCE_STEP, case)
    common = reference[:: round(STEPS[0] / REFERENCE_STEP), 1]
    for dt in STEPS:
        errors, counts = [], []
        for fmu in ("BouncingBall.fmu", "BouncingBall3.fmu"):
            rows, early_returns = cosimulate(out / fmu, dt, case)
            on_grid = rows[np.isclose(rows[:, 0] / STEPS[0], np.round(rows[:, 0] / STEPS[0]), rtol=0, atol=1e-12)]
            errors.append(np.max(np.abs(on_grid[:, 1] - common)))
            counts.append(early_returns)
        print(f"{name:12s}{dt:10.7f}{errors[0]:30.3e}{errors[1]:24.3e}{counts[1]:15d}")
    np.savetxt(out / f"cosim_{name}_reference.csv", reference, delimiter=",", header="time,h,v,F_ext", comments="")
print(f"wrote {', '.join(str(out / f'cosim_{name}_reference.csv') for name in CASES)} (the reference runs)")
