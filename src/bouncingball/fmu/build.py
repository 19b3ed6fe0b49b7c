"""Build the BouncingBall FMU with pythonfmu (FMI 2.0) or pythonfmu3 (FMI 3.0), and complete what it leaves out.

pythonfmu packs the slave script (bouncingball_fmu_slave.py, beside this module) and a copy of
this package into the FMU's resources. The copy gets a name of its own, bouncingball_fmu_<digest
of its sources>, so that the FMU neither replaces nor uses the bouncingball of a Python host, and
two different builds can run in one process. pythonfmu's modelDescription.xml has no units,
min/max, InitialUnknowns or DefaultExperiment; build_fmu() adds them from variables.VARIABLES. Its
Linux binary cannot run in a master without Python and cannot return fmi2Error; build_fmu()
compiles bouncingball_fmu_loader.c, which fixes both, and puts it in front of pythonfmu's binary
(docs/fmu.md explains why and what it costs). It compiles the compiled engine of the package's copy
once and ships numba's cache of it (engine_cache.py). Everything it needs ships in the wheel.

The FMI 3.0 FMU (fmi_version=3) is built the same way from the same script, package and variable
table, with pythonfmu3 and bouncingball_fmu3_loader.c; build3 holds what differs.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import platform
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
import zipfile
from pathlib import Path

from ..extras import install_command
from ..output import atomic_write, check_output_path
from . import build3
from .documentation import index_html
from .engine_cache import compile_cache, shipped_files
from .host_check import check_source
from .model_description import FmuBuildError, complete_model_description
from .reference import reference_path, write_reference_csv
from .variables import MODEL_NAME, VARIABLES

DEFAULT_OUTPUT = Path("dist") / f"{MODEL_NAME}.fmu"
DEFAULT_OUTPUTS = {2: DEFAULT_OUTPUT, 3: Path("dist") / f"{MODEL_NAME}3.fmu"}
HERE = Path(__file__).resolve().parent
SLAVE_SCRIPT = HERE / "bouncingball_fmu_slave.py"
LOADER_SOURCE = HERE / "bouncingball_fmu_loader.c"
LOADER3_SOURCE = HERE / "bouncingball_fmu3_loader.c"
LOADER_HEADER = HERE / "bouncingball_fmu_python.h"  # what the FMI 2.0 and 3.0 loaders share
PACKAGE_DIR = HERE.parent  # the bouncingball package, copied into the FMU
PACKAGE_FILES = ("*.py", "data/*.toml", "solvers/engines/*.c")
# What build_fmu says it is doing, in order (the compile of the engine's code is most of a build's time).
BUILD_STEPS = ("compiling the C loader and staging the package", "pythonfmu builds the FMU",
               "numba compiles the engine's code, linked into the FMU's native engine (most of the build; none where "
               "a build of the same sources is kept)", "packing the FMU",
               "writing the reference result (the exact solution)")
PLATFORM = "linux64"
PYTHONFMU_BINARY = f"{MODEL_NAME}_pythonfmu.so"  # pythonfmu's binary, loaded by ours


def build_fmu(output: str | Path | None = None, fmi_version: int = 2, step=None) -> Path:
    """Build the FMU of FMI version fmi_version (2 or 3) into output [.fmu] (default DEFAULT_OUTPUTS) and return it.

    The default's folder (dist/) is created; an output given in a folder that does not exist is refused, as
    every other output path is (a typo in a path must not become a new folder). step, if given, is called
    with the name of each build step as it starts (BUILD_STEPS, in order), for a progress display.
    """
    step = step or (lambda name: None)
    if fmi_version not in DEFAULT_OUTPUTS:
        raise ValueError(f"fmi_version = {fmi_version!r} is not allowed: it must be 2 or 3")
    make_folders = output is None
    output = Path(output if output is not None else DEFAULT_OUTPUTS[fmi_version])
    if output.suffix != ".fmu":
        raise ValueError(f"output = {str(output)!r} is not allowed: it must end in .fmu")
    check_output_path("output", output, make_folders=make_folders)
    _check_build_host()
    compiler = _compiler()
    library = "pythonfmu" if fmi_version == 2 else "pythonfmu3"
    try:
        import fmpy  # noqa: F401  (its FMI headers compile the loader)
        FmuBuilder = importlib.import_module(library).FmuBuilder
    except ImportError as error:
        raise ImportError(f"build-fmu needs {library} and FMPy ({error}): {install_command('fmu')}") from None

    with tempfile.TemporaryDirectory(prefix="bouncingball_fmu_") as temp:
        temp = Path(temp)
        step(BUILD_STEPS[0])
        loader = _compile_loader(compiler, temp / f"{MODEL_NAME}.so", fmi_version)
        script, package = _stage(temp / "stage", fmi_version)
        step(BUILD_STEPS[1])
        # pythonfmu imports the script, and with it the package's copy, into this process to read
        # its variables, and leaves its folder on sys.path: undo both once it is done.
        path, modules = list(sys.path), set(sys.modules)
        state = "FMUstate" if fmi_version == 2 else "FMUState"  # pythonfmu3 spells FMI 3.0's names
        try:
            # needsExecutionTool: the FMU runs on a Python installation with numpy and scikit-sundae.
            built = FmuBuilder.build_FMU(script, dest=temp / "pythonfmu", project_files=[package],
                                         needsExecutionTool=True, **{f"canGetAndSet{state}": True,
                                                                     f"canSerialize{state}": True})
        finally:
            sys.path[:] = path
            # The package's copy goes, unless this process had imported it (its name is its sources': an FMU of the
            # same sources run here, or read): removing the part the build added left that part to be imported
            # again beside the rest, with classes of its own (a restored FMU state was refused as not one).
            had_package = package.name in modules
            for name in set(sys.modules) - modules:
                if name == script.stem or (name.split(".")[0] == package.name and not had_package):
                    del sys.modules[name]
        step(BUILD_STEPS[2])
        cache = shipped_files(compile_cache(package, temp / "numba", compiler))
        step(BUILD_STEPS[3])
        if make_folders:
            output.parent.mkdir(parents=True, exist_ok=True)
        with atomic_write(output) as partial:
            _repack(Path(built), loader, partial, fmi_version, cache)
    step(BUILD_STEPS[4])
    write_reference_csv(reference_path(output))
    return output


def package_sources() -> list[Path]:
    """The files of this package that the FMU carries (paths relative to the package)."""
    return sorted({path.relative_to(PACKAGE_DIR) for pattern in PACKAGE_FILES for path in PACKAGE_DIR.rglob(pattern)
                   if "__pycache__" not in path.parts})


def _stage(folder: Path, fmi_version: int = 2) -> tuple[Path, Path]:
    """The slave script and the package's copy, both named after the digest of what they contain."""
    digest = hashlib.sha256()
    for relative in package_sources():
        digest.update(str(relative).encode() + b"\0" + (PACKAGE_DIR / relative).read_bytes() + b"\0")
    digest.update(SLAVE_SCRIPT.read_bytes())
    if fmi_version != 2:
        # Its own copy: FMPy deletes each unzipped FMU, and a copy shared with the FMI 2.0 FMU (imported first)
        # would look for the FMI 3.0 slave module in the deleted folder (and pythonfmu3 then crashes).
        digest.update(f"FMI {fmi_version}".encode())
    name = f"bouncingball_fmu_{digest.hexdigest()[:16]}"
    package = folder / name
    for relative in package_sources():
        (package / relative).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(PACKAGE_DIR / relative, package / relative)
    source = SLAVE_SCRIPT.read_text(encoding="utf-8")
    changes = {'PACKAGE = "bouncingball"\n': f'PACKAGE = "{name}"\n'}
    if fmi_version == 3:

        changes.update(build3.SCRIPT_CHANGES)
    for marker, replacement in changes.items():
        if source.count(marker) != 1:
            raise FmuBuildError(f"{SLAVE_SCRIPT.name} must contain {marker.strip()!r} exactly once")
        source = source.replace(marker, replacement)
    # pythonfmu names the slave's module after the script: two builds must not share it either.
    script = folder / f"{name}_slave.py"
    script.write_text(source, encoding="utf-8")
    return script, package


def is_stale(fmu: str | Path) -> bool:
    """True if fmu does not exist or is older than a source it is built from."""
    fmu = Path(fmu)
    if not fmu.is_file():
        return True
    sources = [SLAVE_SCRIPT, LOADER_SOURCE, LOADER3_SOURCE, LOADER_HEADER,
               *(PACKAGE_DIR / relative for relative in package_sources())]
    return max(path.stat().st_mtime for path in sources if path.exists()) > fmu.stat().st_mtime


def build_command(output: str | Path | None = None, fmi_version: int = 2) -> int:
    """`bouncingball build-fmu`: build and say where, each step as a line on stderr with the time so far (the
    numba compile takes most of it); a host that cannot build gets one line on stderr."""
    started = time.perf_counter()

    def step(name: str) -> None:
        number = BUILD_STEPS.index(name) + 1
        print(f"build-fmu: [{number}/{len(BUILD_STEPS)}] {name} ({time.perf_counter() - started:.0f} s so far)",
              file=sys.stderr, flush=True)

    try:
        path = build_fmu(output, fmi_version, step)
    except FmuBuildError as error:
        print(f"bouncingball: cannot build the FMU: {error}", file=sys.stderr)
        return 1
    print(f"wrote {path} and its reference result {reference_path(path)} in {time.perf_counter() - started:.0f} s")
    return 0


# --- the build steps ------------------------------------------------------------------------------
def _check_build_host() -> None:
    if not (sys.platform.startswith("linux") and platform.machine() == "x86_64"):
        raise FmuBuildError(f"the FMU is built for Linux x86_64 only (pythonfmu's {PLATFORM} binary); "
                            f"this is {sys.platform} {platform.machine()}")
    for path in (SLAVE_SCRIPT, LOADER_SOURCE, LOADER3_SOURCE, LOADER_HEADER):
        if not path.is_file():
            raise FmuBuildError(f"{path} not found: this installation of bouncingball is incomplete; "
                                f"reinstall it: {install_command('fmu')}")


def _compiler() -> list[str]:
    """The C compiler's command ($CC, split as a shell would, else cc or gcc), checked to run."""
    told = os.environ.get("CC", "").strip()
    command = shlex.split(told) if told else [shutil.which("cc") or shutil.which("gcc") or ""]
    how = ("set CC to a C compiler that works (CC=gcc bouncingball build-fmu), or install one "
           "(Debian/Ubuntu: apt install gcc)")
    if not command[0]:
        raise FmuBuildError(f"no C compiler (cc or gcc on PATH) to compile the FMU's loader binary: {how}")
    tried = f"the C compiler {told!r} from $CC" if told else f"the C compiler {command[0]!r}"
    try:
        completed = subprocess.run([*command, "--version"], capture_output=True, text=True, check=False)
    except OSError as error:
        raise FmuBuildError(f"{tried} cannot be run ({error.strerror or error}): {how}") from None
    if completed.returncode != 0:
        raise FmuBuildError(f"{tried} failed on --version (exit code {completed.returncode}): {how}")
    return command


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _compile_loader(compiler: list[str], target: Path, fmi_version: int = 2) -> Path:
    """Compile the loader of FMI version fmi_version for the Python running this build."""
    source = LOADER_SOURCE if fmi_version == 2 else LOADER3_SOURCE
    command = [*compiler, "-shared", "-fPIC", "-O2", *loader_flags(fmi_version), "-o", str(target), str(source),
               "-ldl", "-lpthread", "-lm"]
    completed = subprocess.run(command, capture_output=True, text=True, check=False)
    if completed.returncode != 0:
        raise FmuBuildError(f"compiling {source.name} with {shlex.join(compiler)} failed:\n"
                            f"{completed.stderr.strip()}")
    return target


def loader_flags(fmi_version: int = 2) -> list[str]:
    """Compiler flags for the loader: warnings on, FMPy's FMI headers, the Python the FMU is built for."""
    from importlib.resources import files

    headers = Path(str(files("fmpy") / "c-code"))  # FMPy ships the FMI 2.0 and 3.0 headers
    libpython = shared_libpython()
    if not sys.executable:
        raise FmuBuildError("sys.executable is empty: run the build from a python executable")
    return ["-Wall", "-Wextra", f"-I{headers}", f"-DBB_LIBPYTHON={_c_string(str(libpython or ''))}",
            f"-DBB_PYTHON={_c_string(sys.executable)}", f"-DBB_INNER={_c_string(PYTHONFMU_BINARY)}",
            f"-DBB_PYTHON_VERSION={_c_string(f'{sys.version_info.major}.{sys.version_info.minor}')}",
            f"-DBB_HOST_CHECK={_c_string(check_source())}",
            *(_variable_flags() if fmi_version == 2 else _fmi3_flags())]


def _variable_flags(variables=VARIABLES) -> list[str]:
    return [f"-DBB_VARIABLE_TYPES={_c_string(''.join(variable.type[0] for variable in variables))}"]


def _fmi3_flags() -> list[str]:
    from .variables import EVENT_INDICATOR, FMI3_VARIABLES

    variables = VARIABLES + FMI3_VARIABLES
    names = [variable.name for variable in variables]
    return [*_variable_flags(variables), f"-DBB_TIME_REFERENCE={names.index('time')}",
            f"-DBB_CONTACT_REFERENCE={names.index('contact')}",
            f"-DBB_STATES={sum(bool(variable.derivative) for variable in variables)}",
            f"-DBB_EVENT_INDICATORS={names.count(EVENT_INDICATOR)}"]


def shared_libpython() -> Path | None:
    """The shared libpython of the running Python, which a master without Python loads; None if there is none."""
    libdir, soname = sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("INSTSONAME")
    if not (libdir and soname and ".so" in soname):  # a static build names libpython3.X.a here
        return None
    path = Path(libdir) / soname
    return path if path.is_file() else None


def _repack(built: Path, loader: Path, target: Path, fmi_version: int = 2, extra=()) -> None:
    """Copy pythonfmu's FMU with the completed XML, our binary in front of pythonfmu's, Linux only, and the files
    extra names ((file, its name in the FMU): the compiled engine's cache)."""
    binaries = f"binaries/{PLATFORM if fmi_version == 2 else 'x86_64-linux'}/"
    if fmi_version == 3:
        complete = build3.complete_model_description
    else:
        complete = complete_model_description
    with zipfile.ZipFile(built) as source, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as fmu:
        for info in source.infolist():
            if info.filename == "modelDescription.xml":
                description = complete(source.read(info))
                fmu.writestr(info.filename, description)
                fmu.writestr("documentation/index.html", index_html(description))
            elif info.filename == f"{binaries}{MODEL_NAME}.so":
                fmu.writestr(binaries + PYTHONFMU_BINARY, source.read(info))
            elif info.filename.startswith("sources/"):  # pythonfmu3's sources build its binary alone, not ours
                continue
            elif not info.filename.startswith("binaries/"):  # other platforms' binaries lack the fix
                fmu.writestr(info, source.read(info))
        fmu.write(loader, f"{binaries}{MODEL_NAME}.so")
        for path, name in extra:
            fmu.write(path, name)
