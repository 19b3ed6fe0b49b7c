"""cosim_levitation.py's coupling with the ball as an FMI 3.0 FMU returning early at each impact and departure, where
the master sets F_ext (in event mode). Needs: pip install -e '.[fmu]' tqdm (and a C compiler).
Usage: python cosim_levitation3.py [OUTPUT_DIR]      (builds the FMUs there; default: the current directory)
Two cases against one fine-step reference (the FMI 2.0 coupling at 2^-12 s, most of the time this takes: a bar shows
it): levitation, cosim_levitation.py's (controller on from 2.25 s to 5 s, no impact then), and catch: a softer one from
0.5 s, holding the ball at 0.3 m as it bounces under its force. The force is held over each step: first order in it.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from pythonfmu import FmuBuilder
from tqdm import tqdm

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
out.mkdir(parents=True, exist_ok=True)
T_END, REFERENCE_STEP = 8.0, 2.0**-12
STEPS = [2.0**-k for k in range(3, 8)]  # 0.125 s ... 7.8 ms, as in cosim_levitation.py
CASES = {"levitation": {"t_on": 2.25, "t_off": 5.0, "h_set": 1.0},
         "catch": {"t_on": 0.5, "t_off": 8.0, "h_set": 0.3, "kp": 4.0, "kd": 0.5}}
for version, name in (("2", "BouncingBall.fmu"), ("3", "BouncingBall3.fmu")):
    subprocess.run([Path(sys.executable).parent / "bouncingball", "build-fmu", "--fmi-version", version, "-o",
                    out / name], check=True, stdout=subprocess.DEVNULL)
controller_fmu = FmuBuilder.build_FMU(Path(__file__).resolve().parent / "pd_controller.py", dest=out)


class Slave:
    """An FMU instance (FMI 2.0, or FMI 3.0 with early return and event mode), initialised with start values."""
    def __init__(self, fmu, name, **start):
        description = read_model_description(str(fmu))
        self.refs, self.event = {v.name: v.valueReference for v in description.modelVariables}, False
        self.fmi3 = description.fmiVersion.startswith("3")
        self.fmu = (FMU3Slave if self.fmi3 else FMU2Slave)(
            guid=description.guid, unzipDirectory=extract(str(fmu)), instanceName=name,
            modelIdentifier=description.coSimulation.modelIdentifier)
        self.fmu.instantiate(**({"eventModeUsed": True, "earlyReturnAllowed": True} if self.fmi3 else {}))
        self.set(**start)
        self.fmu.enterInitializationMode(), self.fmu.exitInitializationMode()
        self.event = self.fmi3  # with event mode, initialisation ends in event mode

    def get(self, *names):
        return (self.fmu.getFloat64 if self.fmi3 else self.fmu.getReal)([self.refs[name] for name in names])

    def set(self, **values):
        (self.fmu.setFloat64 if self.fmi3 else self.fmu.setReal)([self.refs[n] for n in values], list(values.values()))
        if self.event:  # inputs set at the event: leave event mode
            self.fmu.updateDiscreteStates(), self.fmu.enterStepMode()
            self.event = False

    def step(self, t, dt):
        """doStep from t by dt: the time reached (an event's, at an early return)."""
        if not self.fmi3:
            self.fmu.doStep(t, dt)
            return t + dt
        needed, _, early, reached = self.fmu.doStep(t, dt)
        self.event = early and needed
        if self.event:
            self.fmu.enterEventMode()
        return reached if early else t + dt


def cosimulate(ball_fmu, dt, case, bar):
    """The coupled run: rows of (t, h, v, F_ext, 1 at a communication point or 0 at an early return's event)."""
    ball, controller = Slave(ball_fmu, "ball"), Slave(controller_fmu, "controller", **case)
    rows, t, n = [], 0.0, 0
    while True:
        h, v = ball.get("h", "v")
        controller.set(h=h, v=v)  # the controller's output depends directly on its inputs: set them first
        force = controller.get("F")[0]
        rows.append((t, h, v, force, t == n * dt))
        ball.set(F_ext=force)  # held from t to the next communication point or event
        if n == round(T_END / dt):
            break
        reached = ball.step(t, (n + 1) * dt - t)
        controller.fmu.doStep(t, reached - t)
        bar.update(reached - t)
        n, t = (n, reached) if ball.event else (n + 1, (n + 1) * dt)
    for slave in (ball, controller):
        slave.fmu.terminate(), slave.fmu.freeInstance()
    return np.array(rows)


print(f"{'case':12s}{'step [s]':>10s}{'FMI 2.0: max |h - h_ref| [m]':>30s}{'FMI 3.0, early return':>24s}"
      f"{'early returns':>15s}")
for name, case in CASES.items():  # the bar counts the simulated time of the case's runs (disable=None: on a tty)
    with tqdm(total=(1 + 2 * len(STEPS)) * T_END, desc=name, unit="s", unit_scale=True, disable=None) as bar:
        reference = cosimulate(out / "BouncingBall.fmu", REFERENCE_STEP, case, bar)
        common = reference[:: round(STEPS[0] / REFERENCE_STEP), 1]
        for dt in STEPS:
            runs = [cosimulate(out / fmu, dt, case, bar) for fmu in ("BouncingBall.fmu", "BouncingBall3.fmu")]
            errors = [np.max(np.abs(rows[rows[:, 4] == 1, 1][:: round(STEPS[0] / dt)] - common)) for rows in runs]
            bar.write(f"{name:12s}{dt:10.7f}{errors[0]:30.3e}{errors[1]:24.3e}{np.sum(runs[1][:, 4] == 0):15d}")
    np.savetxt(path := out / f"cosim_{name}_reference.csv", reference[:, :4], delimiter=",", header="time,h,v,F_ext",
               comments="")
    print(f"wrote {path} (the reference run)")
