"""The ball and the PD controller as an OSP system (OspSystemStructure.xml), run by libcosim through libcosimpy.

Needs: pip install -e '.[fmu]' libcosimpy (pythonfmu builds the controller; the ball FMU needs a C compiler).
Usage: python run.py [OUTPUT_DIR]      (builds both FMUs there, runs 8 s, writes libcosim_levitation.csv)

libcosim's fixed-step algorithm steps both FMUs, then passes h and v to the controller and its F to the
ball: the force a step uses was computed from the state one step earlier. Before t_on the ball is free,
so its result there must be the exact solution, impacts included.
"""

import csv
import shutil
import subprocess
import sys
from pathlib import Path

from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver
from pythonfmu import FmuBuilder

from bouncingball.check.judge import check_result

HERE = Path(__file__).resolve().parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
out.mkdir(parents=True, exist_ok=True)
T_END, T_ON, T_OFF = 8.0, 2.25, 5.0

subprocess.run([Path(sys.executable).parent / "bouncingball", "build-fmu", "-o", out / "BouncingBall.fmu"],
               check=True, stdout=subprocess.DEVNULL)
FmuBuilder.build_FMU(HERE.parent / "pd_controller.py", dest=out)
shutil.copy(HERE / "OspSystemStructure.xml", out)  # its FMU paths are relative to it

log_output_level(CosimLogLevel.WARNING)
execution = CosimExecution.from_osp_config_file(str(out / "OspSystemStructure.xml"))
observer = CosimObserver.create_last_value()
execution.add_observer(observer)
ball, controller = (execution.slave_index_from_instance_name(name) for name in ("ball", "controller"))
refs = {(slave, v.name.decode()): v.reference for slave in (ball, controller) for v in execution.slave_variables(slave)}

rows = []
while execution.status().current_time < round(T_END * 1e9):  # libcosim's time: integer nanoseconds
    assert execution.step()
    h, v = observer.last_real_values(ball, [refs[ball, "h"], refs[ball, "v"]])
    (force,) = observer.last_real_values(controller, [refs[controller, "F"]])
    (impacts,) = observer.last_integer_values(ball, [refs[ball, "impacts"]])
    rows.append((execution.status().current_time / 1e9, h, v, force, impacts))
with (out / "libcosim_levitation.csv").open("w", newline="") as file:
    writer = csv.writer(file)
    writer.writerow(["time", "h", "v", "F_ext", "impacts"])
    writer.writerows([repr(x) for x in row] for row in rows)

free = [row for row in rows if row[0] <= T_ON]  # the ball alone: the exact solution applies
outcome = check_result({name: [row[i] for row in free] for i, name in ((0, "time"), (1, "h"), (4, "impacts"))})
print(f"libcosim: {len(rows)} steps of {rows[0][0]:g} s to {rows[-1][0]:g} s, {rows[-1][4]} impacts in all")
print(f"free ball up to t_on = {T_ON} s: max |h - h_exact| = {outcome.max_height_error:.3e} m, "
      f"impacts {outcome.impacts_found} (exact {outcome.impacts_exact}): {outcome.verdict.split(':')[0]}")
hold = next(i for i, row in enumerate(rows) if row[0] == T_OFF)
print(f"held by the controller: h(t_off) = {rows[hold][1]:.12f} m, v(t_off) = {rows[hold][2]:.3e} m/s, "
      f"F just before = {rows[hold - 1][3]:.6f} N")
print(f"wrote {out / 'libcosim_levitation.csv'}")
sys.exit(0 if outcome.passed else 1)
