"""Co-simulation: the ball FMU and a PD controller FMU (pd_controller.py) coupled by a master loop on FMPy's FMU2Slave.

Needs: pip install -e '.[fmu]' in the checkout (pythonfmu, FMPy; building the ball FMU needs a C compiler).
Usage: python cosim_levitation.py [OUTPUT_DIR]      (builds both FMUs there; default: the current directory)

The ball is dropped from 2 m and bounces; from t_on = 2.25 s the controller holds it at 1 m, and at
t_off = 5 s it lets go. F_ext is held over each communication step, so the coupled result converges
at first order as the step shrinks; the impacts, though, are found inside the ball's steps.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from pythonfmu import FmuBuilder

import bouncingball as bb

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
out.mkdir(parents=True, exist_ok=True)
T_END, T_ON, T_OFF = 8.0, 2.25, 5.0
STEPS = [2.0**-k for k in range(3, 8)]  # 0.125 s ... 7.8 ms: powers of two hit t_on and t_off exactly
REFERENCE_STEP = 2.0**-12

subprocess.run([Path(sys.executable).parent / "bouncingball", "build-fmu", "-o", out / "BouncingBall.fmu"],
               check=True, stdout=subprocess.DEVNULL)
controller_fmu = FmuBuilder.build_FMU(Path(__file__).resolve().parent / "pd_controller.py", dest=out)


class Slave:  # an FMU instance, its variables by name
    def __init__(self, fmu, name):
        self.description = read_model_description(str(fmu))
        self.refs = {v.name: v.valueReference for v in self.description.modelVariables}
        self.fmu = FMU2Slave(guid=self.description.guid, unzipDirectory=extract(str(fmu)), instanceName=name,
                             modelIdentifier=self.description.coSimulation.modelIdentifier)
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0, stopTime=T_END)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def get(self, *names):
        return self.fmu.getReal([self.refs[name] for name in names])

    def set(self, **values):
        self.fmu.setReal([self.refs[name] for name in values], list(values.values()))


def cosimulate(dt):
    """The coupled run at communication step dt: rows of (t, h, v, F_ext, impacts) at every communication point."""
    ball, controller = Slave(out / "BouncingBall.fmu", "ball"), Slave(controller_fmu, "controller")
    rows, n = [], round(T_END / dt)
    for i in range(n + 1):
        t = i * dt
        h, v = ball.get("h", "v")
        controller.set(h=h, v=v)  # the controller's output depends directly on its inputs: set them first
        force = controller.get("F")[0]
        rows.append((t, h, v, force, ball.fmu.getInteger([ball.refs["impacts"]])[0]))
        if i < n:
            ball.set(F_ext=force)  # held over [t, t + dt]
            ball.fmu.doStep(t, dt)
            controller.fmu.doStep(t, dt)
    for slave in (ball, controller):
        slave.fmu.terminate(), slave.fmu.freeInstance()
    return np.array(rows)


def exact_from(rows):
    """max |h - h_exact| over rows, and the impacts, of the free ball (F_ext = 0) from the state of the first row."""
    t0, h0, v0 = rows[0, :3]
    exact = bb.simulate(bb.Ball(), h0, v0, rows[-1, 0] - t0, rows[1, 0] - t0, solver="exact")
    return np.max(np.abs(rows[:, 1] - exact.h)), exact.impacts


reference = cosimulate(REFERENCE_STEP)
gains = {v.name: v.start for v in read_model_description(controller_fmu).modelVariables}  # pd_controller.py's
print(f"ball dropped from 2 m; PD controller (kp = {gains['kp']} N/m, kd = {gains['kd']} N s/m, h_set = "
      f"{gains['h_set']} m) on from {gains['t_on']} s to {gains['t_off']} s; reference: communication step "
      f"{REFERENCE_STEP:g} s, {reference[-1, 4]:.0f} impacts")
print(f"{'step [s]':>10s}{'max |h - h_ref| [m]':>21s}{'ratio':>7s}{'h(t_off) [m]':>20s}{'v(t_off) [m/s]':>22s}"
      f"{'impacts':>8s}{'free: |h - h_exact|':>21s}{'impacts':>8s}{'after t_off':>13s}{'impacts':>8s}")
errors = []
for dt in STEPS:
    rows = cosimulate(dt)  # compared at the common times, the multiples of the largest step
    error = np.max(np.abs(rows[:: round(STEPS[0] / dt), 1] - reference[:: round(STEPS[0] / REFERENCE_STEP), 1]))
    i_on, i_off = round(T_ON / dt), round(T_OFF / dt)
    free_error, free_impacts = exact_from(rows[: i_on + 1])  # F_ext = 0 before t_on and after t_off
    late_error, late_impacts = exact_from(rows[i_off:])
    ratio = f"{errors[-1] / error:7.2f}" if errors else " " * 7
    print(f"{dt:10.7f}{error:21.3e}{ratio}{rows[i_off, 1]:20.15f}{rows[i_off, 2]:22.15f}{rows[-1, 4]:8.0f}"
          f"{free_error:21.3e}{free_impacts:8d}{late_error:13.3e}{late_impacts:8d}")
    errors.append(error)
np.savetxt(out / "cosim_levitation.csv", reference[:, :4], delimiter=",", header="time,h,v,F_ext", comments="")
impact, departure = bb.simulate(bb.Ball(), 2.0, 0.0, T_ON, 1e-3, solver="exact").events[:2]
longer = ", ".join(f"{dt:g} s" for dt in STEPS if dt > departure.time - impact.time)
print(f"impacts resolved inside steps: each run counts the exact impacts before t_on and after t_off; a contact "
      f"lasts {departure.time - impact.time:.4f} s, so at steps of {longer} whole contacts fall inside one step")
print(f"wrote {out / 'cosim_levitation.csv'} (the reference run)")
