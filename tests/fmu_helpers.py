"""Shared by the FMU tests: one FMU build per test session, and an FMU instance driven call by call."""

from __future__ import annotations

import csv
import shutil
import stat
import subprocess
from ctypes import byref
from pathlib import Path

from bouncingball.accuracy import exact_on_grid
from bouncingball.physics import Ball

TIGHT = {"rtol": 1e-11, "atol": 1e-14}  # the tolerances the accuracy numbers are measured at


FMU_PAGE = Path(__file__).resolve().parents[1] / "docs" / "fmu.md"


def page_figure(value: float, digits: int = 2) -> str:
    """value as docs/fmu.md prints it: digits significant, an exponent without padding (1.1e-10, 6.2e-2)."""
    mantissa, exponent = f"{value:.{digits - 1}e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def assert_fmu_page_quotes(*quotes: str) -> None:
    """docs/fmu.md (its whitespace as one space) holds each quote: a figure computed by the test that calls this."""
    import pytest

    if not FMU_PAGE.is_file():
        pytest.skip("docs/fmu.md is in a source checkout")
    text = " ".join(FMU_PAGE.read_text(encoding="utf-8").split())
    missing = [quote for quote in quotes if quote not in text]
    assert missing == [], "docs/fmu.md quotes other figures than the code computes now:\n" + "\n".join(missing)


C_MASTER = Path(__file__).parent / "c_master" / "fmi2_master.c"
C_MASTER3 = Path(__file__).parent / "c_master" / "fmi3_master.c"


def compile_c_master(target: Path, *flags: str, source: Path = C_MASTER) -> Path | None:
    """A plain C master of tests/c_master (FMI 2.0, or source), compiled to target; None without a C compiler."""
    import fmpy

    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        return None
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run([compiler, "-O1", "-Wall", "-Werror", *flags, f"-I{headers}", "-o", str(target), str(source),
                    *(["-Wl,--no-as-needed", "-lsundials_cvode", "-lsundials_nvecserial"]
                      if "-DHOST_SUNDIALS" in flags else []), "-ldl"], check=True)
    return target


def python_without_sksundae(tmp_path: Path, *packages: str) -> Path:
    """The python of a fresh venv with packages (and not scikit-sundae); the test is skipped if pip cannot."""
    import sys

    import pytest

    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", venv], check=True, timeout=300)
    python = venv / "bin" / "python"
    installed = subprocess.run([python, "-m", "pip", "install", "--quiet", *packages], capture_output=True, text=True,
                               check=False, timeout=600)
    if installed.returncode != 0:
        pytest.skip(f"cannot install {', '.join(packages)} into a fresh venv: {installed.stderr[-500:]}")
    return python


def host_report(python: Path, script: str, fmu: Path) -> dict:
    """What script, run by python on fmu, prints as JSON on its last line (it must exit 0)."""
    import json

    completed = subprocess.run([python, "-c", script, str(fmu)], capture_output=True, text=True, check=False,
                               timeout=300)
    assert completed.returncode == 0, completed.stdout + completed.stderr
    return json.loads(completed.stdout.splitlines()[-1])


def ecos_executables() -> dict[str, Path]:
    """ecospy's `ecos` (its command line) and `proxyfmu` (an FMU in a process of its own), made executable.

    The ecospy wheel (0.7.2) ships both without the execute bit: the command line cannot start, and a
    proxyfmu:// model fails with "Unable to create/bind proxyfmu process!". Set it once here.
    """
    import ecospy

    binaries = Path(ecospy.__file__).parent / "binaries"
    executables = {name: binaries / name for name in ("ecos", "proxyfmu")}
    for path in executables.values():
        mode = path.stat().st_mode
        if mode & stat.S_IXUSR == 0:
            path.chmod(mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    return executables


def ecos_csv_to_check(path: Path, instance: str, target: Path) -> Path:
    """One instance's time, h and impacts of ecos' CSV (`iterations, time, instance::h[REAL], ...`), as a plain
    CSV for numpy."""
    with path.open(newline="") as file:
        rows = list(csv.reader(file, skipinitialspace=True))
    header = [name.strip() for name in rows[0]]
    columns = [header.index(name) for name in ("time", f"{instance}::h[REAL]", f"{instance}::impacts[INT]")]
    with target.open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["time", "h", "impacts"])
        writer.writerows([row[i] for i in columns] for row in rows[1:])
    return target


def exact_at(t, ball: Ball | None = None, h0: float = 2.0, v0: float = 0.0, t_start: float = 0.0,
             F_ext: float = 0.0):
    """Exact (h, v, impacts so far) at the times t, for the article's ball unless given another."""
    exact = exact_on_grid(t, ball or Ball(), h0, v0, F_ext, t_start)
    return exact.h, exact.v, exact.impacts


_PROXIED_CALLBACKS: list = []  # the logger FMPy's process-wide proxy calls, kept until another replaces it


class Instance:
    """One FMU instance driven through FMPy's FMU2Slave, keeping every logged (status, message)."""

    OUTPUTS = ("h", "v", "a", "contact", "contact_force", "impacts")

    def __init__(self, unzipped: Path, name: str = "ball"):
        from fmpy import calloc, free, read_model_description
        from fmpy.fmi2 import (
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )
        from fmpy.logging import addLoggerProxy

        description = read_model_description(str(unzipped))
        self.variables = {v.name: v for v in description.modelVariables}
        self.log: list[tuple[int, str]] = []
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(self._logger)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        # formats the FMU's printf-style messages; FMPy's proxy keeps one logger per process, so the messages
        # of every instance reach the log of the instance created last, and of any FMU FMPy runs later with its
        # default callbacks (simulate_fmu): the callbacks must outlive the instance, or a later FMU's log line
        # calls freed memory (a bench FMU's warning crashed the test process so)
        addLoggerProxy(byref(callbacks))
        _PROXIED_CALLBACKS[:] = [callbacks]  # the proxy calls only the last: the earlier ones may go
        self._callbacks = callbacks
        self.fmu = FMU2Slave(guid=description.guid, unzipDirectory=str(unzipped),
                             modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(callbacks=callbacks)
        self.t = 0.0

    def _logger(self, environment, instance_name, status, category, message):
        self.log.append((status, message.decode("utf-8")))

    def set(self, **values) -> None:
        for name, value in values.items():
            variable = self.variables[name]
            setter = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger, "Boolean": self.fmu.setBoolean,
                      "String": self.fmu.setString}[variable.type]
            setter([variable.valueReference], [value])

    def get(self, *names) -> list:
        values = []
        for name in names:
            variable = self.variables[name]
            getter = {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger, "Boolean": self.fmu.getBoolean,
                      "String": self.fmu.getString}[variable.type]
            value = getter([variable.valueReference])[0]
            values.append(value.decode("utf-8") if isinstance(value, bytes) else value)
        return values

    def outputs(self) -> tuple:
        return tuple(self.get(*self.OUTPUTS))

    def initialize(self, tolerance: float | None = None, **values) -> None:
        self.set(**values)
        self.fmu.setupExperiment(tolerance=tolerance, startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def step_to(self, t_end: float, dt: float) -> list[tuple]:
        """doStep from the current time to t_end in steps of dt; the outputs after each step."""
        outputs = []
        n = round((t_end - self.t) / dt)
        t0 = self.t
        for i in range(1, n + 1):
            t_next = t0 + i * dt
            self.fmu.doStep(self.t, t_next - self.t)
            self.t = t_next
            outputs.append(self.outputs())
        return outputs

    def errors(self) -> list[str]:
        return [message for status, message in self.log if status >= 3]

    def free(self) -> None:
        self.fmu.freeInstance()
