"""Build the BouncingBall FMI 2.0 co-simulation FMU with pythonfmu, and complete what it leaves out.

pythonfmu packs the slave script (fmu/bouncingball_fmu_slave.py) and this package into the FMU's
resources. Its modelDescription.xml has no units, min/max, InitialUnknowns or DefaultExperiment;
build_fmu() adds them from VARIABLES. Its Linux binary cannot run in a master without Python and
cannot return fmi2Error; build_fmu() compiles fmu/bouncingball_fmu_loader.c, which fixes both, and
puts it in front of pythonfmu's binary (docs/fmu.md explains why and what it costs).
"""

from __future__ import annotations

import math
import os
import platform
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from pathlib import Path

MODEL_NAME = "BouncingBall"
DEFAULT_OUTPUT = Path("dist") / f"{MODEL_NAME}.fmu"
PROJECT_ROOT = Path(__file__).resolve().parents[2]
SLAVE_SCRIPT = PROJECT_ROOT / "fmu" / "bouncingball_fmu_slave.py"
LOADER_SOURCE = PROJECT_ROOT / "fmu" / "bouncingball_fmu_loader.c"
PACKAGE_DIR = Path(__file__).resolve().parent
PLATFORM = "linux64"
PYTHONFMU_BINARY = f"{MODEL_NAME}_pythonfmu.so"  # pythonfmu's binary, loaded by ours
SMALLEST_POSITIVE = math.ulp(0.0)  # FMI's min is inclusive: "> 0" is ">= 5e-324"

# SI units as exponents of the base units
UNITS = {
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "kg": {"kg": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
}


@dataclass(frozen=True)
class FmuVariable:
    """One variable of the FMU's interface; the slave registers these, the build adds unit/min/max."""

    name: str
    type: str  # Real, Integer, Boolean or String
    causality: str  # parameter, input or output
    variability: str  # fixed, continuous or discrete
    description: str
    unit: str = ""
    min: float | None = None
    max: float | None = None
    initial: str = ""  # "exact" for outputs whose start value is the initial state


VARIABLES = (
    FmuVariable("m", "Real", "parameter", "fixed", "mass of the ball (> 0)", "kg", SMALLEST_POSITIVE),
    FmuVariable("k", "Real", "parameter", "fixed", "contact spring stiffness (> 0)", "N/m", SMALLEST_POSITIVE),
    FmuVariable("b", "Real", "parameter", "fixed", "contact damping coefficient (>= 0)", "N.s/m", 0.0),
    FmuVariable("R", "Real", "parameter", "fixed", "radius of the ball: contact while h < R (> 0)", "m",
                SMALLEST_POSITIVE),
    FmuVariable("g", "Real", "parameter", "fixed", "gravitational acceleration (>= 0)", "m/s2", 0.0),
    FmuVariable("h", "Real", "output", "continuous", "height of the ball's centre; its start value is the "
                "initial height", "m", initial="exact"),
    FmuVariable("v", "Real", "output", "continuous", "vertical velocity dh/dt, upwards positive; its start "
                "value is the initial velocity", "m/s", initial="exact"),
    FmuVariable("a", "Real", "output", "continuous", "vertical acceleration dv/dt", "m/s2"),
    FmuVariable("contact", "Boolean", "output", "discrete", "true while the ball touches the ground"),
    FmuVariable("contact_force", "Real", "output", "continuous", "force of the ground on the ball, upwards "
                "positive (the damper can pull just before departure)", "N"),
    FmuVariable("impacts", "Integer", "output", "discrete", "number of impacts since the start", min=0),
    FmuVariable("F_ext", "Real", "input", "continuous", "external vertical force on the ball, upwards "
                "positive, held constant over each communication step", "N"),
    FmuVariable("rtol", "Real", "parameter", "fixed", "CVODE relative tolerance, in (0, 1]; a tolerance "
                "given in fmi2SetupExperiment replaces it", min=SMALLEST_POSITIVE, max=1.0),
    FmuVariable("atol", "Real", "parameter", "fixed", "CVODE absolute tolerance on h [m] and v [m/s] (> 0)",
                min=SMALLEST_POSITIVE),
    FmuVariable("method", "String", "parameter", "fixed", "CVODE method: auto (Adams in flight, BDF for a "
                "stiff contact), Adams or BDF"),
)


class FmuBuildError(RuntimeError):
    """The FMU cannot be built here; the message says what is missing."""


def build_fmu(output: str | Path = DEFAULT_OUTPUT) -> Path:
    """Build the FMU into output [.fmu] and return its path."""
    output = Path(output)
    if output.suffix != ".fmu":
        raise ValueError(f"output = {str(output)!r} is not allowed: it must end in .fmu")
    _check_build_host()
    try:
        import fmpy  # noqa: F401  (its FMI 2.0 headers compile the loader)
        from pythonfmu import FmuBuilder
    except ImportError as error:
        raise ImportError(f"build-fmu needs pythonfmu and FMPy ({error}): pip install 'bouncingball[fmu]'") from None

    with tempfile.TemporaryDirectory(prefix="bouncingball_fmu_") as temp:
        temp = Path(temp)
        loader = _compile_loader(temp / f"{MODEL_NAME}.so")
        built = FmuBuilder.build_FMU(SLAVE_SCRIPT, dest=temp / "pythonfmu", project_files=[PACKAGE_DIR],
                                     needsExecutionTool=False, canGetAndSetFMUstate=True,
                                     canSerializeFMUstate=True)
        output.parent.mkdir(parents=True, exist_ok=True)
        partial = output.with_name(output.name + ".partial")
        _repack(Path(built), loader, partial)
        os.replace(partial, output)
    return output


def is_stale(fmu: str | Path) -> bool:
    """True if fmu does not exist or is older than a source it is built from."""
    fmu = Path(fmu)
    if not fmu.is_file():
        return True
    sources = [SLAVE_SCRIPT, LOADER_SOURCE, *PACKAGE_DIR.rglob("*.py"), *PACKAGE_DIR.rglob("*.toml")]
    return max(path.stat().st_mtime for path in sources if path.exists()) > fmu.stat().st_mtime


def build_command(output: str | Path = DEFAULT_OUTPUT) -> int:
    """`bouncingball build-fmu`: build and say where; a host that cannot build gets one line on stderr."""
    try:
        path = build_fmu(output)
    except FmuBuildError as error:
        print(f"bouncingball: cannot build the FMU: {error}", file=sys.stderr)
        return 1
    print(f"wrote {path}")
    return 0


# --- the build steps ------------------------------------------------------------------------------
def _check_build_host() -> None:
    if not (sys.platform.startswith("linux") and platform.machine() == "x86_64"):
        raise FmuBuildError(f"the FMU is built for Linux x86_64 only (pythonfmu's {PLATFORM} binary); "
                            f"this is {sys.platform} {platform.machine()}")
    for path in (SLAVE_SCRIPT, LOADER_SOURCE):
        if not path.is_file():
            raise FmuBuildError(f"{path} not found: build-fmu runs from a source checkout of bouncingball")


def _compiler() -> str:
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not compiler:
        raise FmuBuildError("no C compiler (cc or gcc, or $CC) to compile the FMU's loader binary")
    return compiler


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _compile_loader(target: Path) -> Path:
    """Compile fmu/bouncingball_fmu_loader.c for the Python running this build."""
    from importlib.resources import files

    headers = Path(str(files("fmpy") / "c-code"))  # FMPy ships the FMI 2.0 headers
    libpython = shared_libpython()
    if not sys.executable:
        raise FmuBuildError("sys.executable is empty: run the build from a python executable")
    command = [_compiler(), "-shared", "-fPIC", "-O2", "-Wall", "-fvisibility=hidden", f"-I{headers}",
               f"-DBB_LIBPYTHON={_c_string(str(libpython or ''))}", f"-DBB_PYTHON={_c_string(sys.executable)}",
               f"-DBB_INNER={_c_string(PYTHONFMU_BINARY)}", "-o", str(target), str(LOADER_SOURCE),
               "-ldl", "-lpthread"]
    completed = subprocess.run(command, capture_output=True, text=True, check=False)
    if completed.returncode != 0:
        raise FmuBuildError(f"compiling {LOADER_SOURCE.name} failed:\n{completed.stderr.strip()}")
    return target


def shared_libpython() -> Path | None:
    """The shared libpython of the running Python, which a master without Python loads; None if there is none."""
    libdir, soname = sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("INSTSONAME")
    if not (libdir and soname and ".so" in soname):  # a static build names libpython3.X.a here
        return None
    path = Path(libdir) / soname
    return path if path.is_file() else None


def _repack(built: Path, loader: Path, target: Path) -> None:
    """Copy pythonfmu's FMU with the completed XML, our binary in front of pythonfmu's, Linux only."""
    binaries = f"binaries/{PLATFORM}/"
    with zipfile.ZipFile(built) as source, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as fmu:
        for info in source.infolist():
            if info.filename == "modelDescription.xml":
                fmu.writestr(info.filename, complete_model_description(source.read(info)))
            elif info.filename == f"{binaries}{MODEL_NAME}.so":
                fmu.writestr(binaries + PYTHONFMU_BINARY, source.read(info))
            elif not info.filename.startswith("binaries/"):  # other platforms' binaries lack the fix
                fmu.writestr(info, source.read(info))
        fmu.write(loader, f"{binaries}{MODEL_NAME}.so")


def complete_model_description(xml: bytes) -> bytes:
    """Add units, min/max, DefaultExperiment and InitialUnknowns to pythonfmu's modelDescription.xml."""
    from bouncingball.scenes import load_scene

    root = ET.fromstring(xml)
    children = list(root)
    co_simulation = root.find("CoSimulation")
    units = ET.Element("UnitDefinitions")
    for name, exponents in UNITS.items():
        unit = ET.SubElement(units, "Unit", name=name)
        ET.SubElement(unit, "BaseUnit", {base: str(power) for base, power in exponents.items()})
    root.insert(children.index(co_simulation) + 1, units)

    article = load_scene("article")
    experiment = ET.Element("DefaultExperiment", startTime="0", stopTime=repr(article.t_end),
                            stepSize=repr(article.output_interval))
    root.insert(list(root).index(root.find("ModelVariables")), experiment)

    scalars = root.find("ModelVariables").findall("ScalarVariable")
    index = {scalar.get("name"): i + 1 for i, scalar in enumerate(scalars)}
    for variable in VARIABLES:
        typed = scalars[index[variable.name] - 1].find(variable.type)
        if variable.unit:
            typed.set("unit", variable.unit)
        if variable.min is not None:
            typed.set("min", repr(variable.min) if variable.type == "Real" else str(int(variable.min)))
        if variable.max is not None:
            typed.set("max", repr(variable.max))

    structure = root.find("ModelStructure")
    initial_unknowns = ET.SubElement(structure, "InitialUnknowns")
    for variable in VARIABLES:  # outputs computed at initialisation: every output without initial="exact"
        if variable.causality == "output" and variable.initial != "exact":
            ET.SubElement(initial_unknowns, "Unknown", index=str(index[variable.name]))
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
