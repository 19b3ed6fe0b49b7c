import json
import math
import os
from pathlib import Path

import pytest
from hypothesis import settings

# Every run replays the same examples, so that a red run is reproducible anywhere (CI included).
# BOUNCINGBALL_HYPOTHESIS=explore draws new ones each run, to look for more.
settings.register_profile("replay", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("BOUNCINGBALL_HYPOTHESIS", "replay"))

TESTS = Path(__file__).resolve().parent
# Each module's measured time [s], longest first: the order the modules are handed out in. A run of the whole
# suite rewrites it (pytest_sessionfinish); commit it when it changed.
DURATIONS = TESTS / "durations.json"
# A stored time is replaced only when the new one differs by more than this fraction (or a second): a loaded
# machine's run-to-run noise alone does not rewrite the file.
NOISE = 0.25
# Under pytest-xdist: the modules shared among up to 4 workers, one per CPU; each module's tests in one worker
# (--dist loadscope: its module fixtures built once), handed out in the order pytest_collection_modifyitems
# gives them (--no-loadscope-reorder). Set here rather than in addopts so that pytest runs without the plugin
# too (-p no:xdist, or not installed); -n, --maxprocesses and --dist given on the command line win.
XDIST_DEFAULTS = {"numprocesses": "auto", "maxprocesses": 4}


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    if not config.pluginmanager.hasplugin("xdist") or hasattr(config, "workerinput"):
        return
    for name, value in XDIST_DEFAULTS.items():
        if getattr(config.option, name) is None:
            setattr(config.option, name, value)
    if config.option.dist == "no" and config.option.numprocesses != 0:
        config.option.dist = "loadscope"
    if "--loadscope-reorder" not in config.invocation_params.args:
        config.option.loadscopereorder = False


def stored_durations() -> dict[str, float]:
    """The module times of tests/durations.json (an empty record if it is missing or unreadable)."""
    try:
        return {str(name): float(seconds) for name, seconds in json.loads(DURATIONS.read_text()).items()}
    except (OSError, ValueError, AttributeError):
        return {}


def pytest_collection_modifyitems(config, items):
    """The modules longest first, so that no worker starts a long one while the others are done.

    A module with no stored time goes first: if it is long, starting it last would lengthen the run by all of
    it; if it is short, starting it first costs nothing.
    """
    durations = stored_durations()
    items.sort(key=lambda item: -durations.get(item.path.name, math.inf))  # stable: each module's order kept


_measured: dict[str, float] = {}  # module name: the sum of its tests' setup, call and teardown times [s]
_said: list[str] = []  # what the run did with tests/durations.json, for the terminal summary


def pytest_runtest_logreport(report):
    """Add up each module's time (under xdist in the controller, from its workers' reports)."""
    module = Path(report.nodeid.split("::")[0]).name
    _measured[module] = _measured.get(module, 0.0) + report.duration


DEFAULT_MARKS = "not study"  # pyproject.toml's addopts


def whole_suite_ran(session, exitstatus) -> bool:
    """Did every test module run whole: no selection (-k, -m, --lf, a node id, a file), no early stop?

    The default run leaves out the studies (addopts' -m 'not study'): that is the whole suite.
    """
    option = session.config.option
    selected = (option.keyword or option.markexpr not in ("", DEFAULT_MARKS) or getattr(option, "lf", False)
                or getattr(option, "deselect", None)
                or option.maxfail or getattr(option, "stepwise", False))
    here = session.config.invocation_params.dir
    everything = all("::" not in argument and (here / argument).resolve() in (TESTS, *TESTS.parents)
                     for argument in session.config.args)
    return not selected and everything and exitstatus in (pytest.ExitCode.OK, pytest.ExitCode.TESTS_FAILED)


def merged(stored: dict[str, float], measured: dict[str, float]) -> dict[str, float]:
    """The stored times with the measured ones where they moved beyond the noise, for the modules that exist."""
    kept = {}
    for name in sorted({*stored, *measured}):
        if not (TESTS / name).is_file():
            continue
        old, new = stored.get(name), measured.get(name)
        if new is None or (old is not None and abs(new - old) <= max(NOISE * old, 1.0)):
            kept[name] = old
        else:
            kept[name] = round(new, 1)
    return dict(sorted(kept.items(), key=lambda item: (-item[1], item[0])))


def pytest_sessionfinish(session, exitstatus):
    if hasattr(session.config, "workerinput") or not whole_suite_ran(session, exitstatus):
        return
    stored = stored_durations()
    durations = merged(stored, _measured)
    if durations == stored:
        return
    changed = sum(durations.get(name) != stored.get(name) for name in {*durations, *stored})
    try:
        DURATIONS.write_text(json.dumps(durations, indent=1) + "\n")
        _said.append(f"{DURATIONS}: {changed} module times updated from this run; commit it")
    except OSError as error:
        _said.append(f"{DURATIONS} not updated ({error}): the modules keep their stored order")


def pytest_terminal_summary(terminalreporter):
    for line in _said:
        terminalreporter.write_line(line)


@pytest.fixture(scope="session")
def fmu(tmp_path_factory) -> Path:
    """The FMU, built once per session through `bouncingball build-fmu -o`; what it printed beside it (build.txt)."""
    import contextlib
    import io

    from bouncingball.cli import main

    path = tmp_path_factory.mktemp("fmu") / "BouncingBall.fmu"
    said = io.StringIO()
    with contextlib.redirect_stderr(said), contextlib.redirect_stdout(said):
        assert main(["build-fmu", "-o", str(path)]) == 0
    path.with_name("build.txt").write_text(said.getvalue(), encoding="utf-8")
    return path


@pytest.fixture(scope="session")
def fmu_numba_cache(fmu, tmp_path_factory) -> Path:
    """The FMU as build-fmu makes it where the native engine's library cannot be built: numba's cache files of its
    compile in resources/numba-cache instead of the library (fmu/engine_cache.py's shipped_files)."""
    import zipfile

    from bouncingball.fmu import build, engine_cache
    from bouncingball.solvers.engines.ahead_of_time import NATIVE_LIBRARY

    folder = tmp_path_factory.mktemp("fmu_numba_cache")
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder / "unzipped")
    [package] = [path for path in (folder / "unzipped" / "resources").glob("bouncingball_fmu_*") if path.is_dir()]
    # The build's compile, kept in the user-wide cache under the key of the same package and compiler: found there.
    cache = engine_cache.compile_cache(package, folder / "numba", build._compiler())
    assert cache is not None and (cache / NATIVE_LIBRARY).is_file()
    (cache / NATIVE_LIBRARY).rename(folder / NATIVE_LIBRARY)  # shipped_files then ships numba's files
    try:
        shipped = engine_cache.shipped_files(cache)
    finally:
        (folder / NATIVE_LIBRARY).rename(cache / NATIVE_LIBRARY)
    path = folder / "BouncingBall.fmu"
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as target:
        for info in source.infolist():
            if info.filename != f"resources/{NATIVE_LIBRARY}":
                target.writestr(info, source.read(info))
        for file, name in shipped:
            target.write(file, name)
    return path


@pytest.fixture(scope="session")
def unzipped_numba_cache(fmu_numba_cache, tmp_path_factory) -> Path:
    """fmu_numba_cache extracted once per session."""
    from fmpy import extract

    return Path(extract(str(fmu_numba_cache), str(tmp_path_factory.mktemp("unzipped_numba_cache"))))


@pytest.fixture(scope="session")
def unzipped(fmu, tmp_path_factory) -> Path:
    """The FMU extracted once per session, for FMU2Slave and the C master."""
    from fmpy import extract

    return Path(extract(str(fmu), str(tmp_path_factory.mktemp("unzipped"))))


@pytest.fixture(scope="session")
def validated_article(fmu) -> tuple[str, str]:
    """`bouncingball validate article --fmu FMU`, run once per session: what it prints (stdout, stderr)."""
    import contextlib
    import io

    from bouncingball.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        assert main(["validate", "article", "--fmu", str(fmu)]) == 0
    return out.getvalue(), err.getvalue()


@pytest.fixture(scope="session")
def fmu3(tmp_path_factory) -> Path:
    """The FMI 3.0 FMU, built once per session through `bouncingball build-fmu --fmi-version 3 -o`."""
    from bouncingball.cli import main

    path = tmp_path_factory.mktemp("fmu3") / "BouncingBall3.fmu"
    assert main(["build-fmu", "--fmi-version", "3", "-o", str(path)]) == 0
    return path


@pytest.fixture(scope="session")
def unzipped3(fmu3, tmp_path_factory) -> Path:
    """The FMI 3.0 FMU extracted once per session, for FMU3Slave, FMU3Model and the C master."""
    from fmpy import extract

    return Path(extract(str(fmu3), str(tmp_path_factory.mktemp("unzipped3"))))
