"""The BouncingBall FMU through FMPy: model description, accuracy against the exact solution, state, errors."""

from __future__ import annotations

import math
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from bouncingball.fmu.variables import SMALLEST_POSITIVE, UNITS, VARIABLES
from bouncingball.physics import Ball
from bouncingball.scenes import load_scene
from bouncingball.solvers.cvode import DEFAULT_RTOL, CvodeSettings
from fmu_helpers import TIGHT, Instance, exact_at
from oracle_counts import oracle_counts

fmpy = pytest.importorskip("fmpy", reason="the FMU tests need the [fmu] extra")
pytest.importorskip("pythonfmu", reason="the FMU tests need the [fmu] extra")

BIN = Path(sys.executable).parent
ARTICLE = load_scene("article")


@pytest.fixture(scope="module")
def article_runs(fmu) -> dict[float, np.ndarray]:
    """The article through simulate_fmu at four communication steps, with rtol 1e-11 and atol 1e-14."""
    return {dt: fmpy.simulate_fmu(str(fmu), stop_time=ARTICLE.t_end, output_interval=dt, start_values=TIGHT,
                                  output=["h", "v", "impacts", "contact"])
            for dt in (0.5, 0.1, 0.01, 0.001)}


# --- the model description ------------------------------------------------------------------------
def test_model_description_has_units_ranges_and_start_values(fmu):
    md = fmpy.read_model_description(str(fmu))
    variables = {v.name: v for v in md.modelVariables}
    assert [v.name for v in md.modelVariables] == [v.name for v in VARIABLES]
    for spec in VARIABLES:
        variable = variables[spec.name]
        assert variable.description == spec.description and variable.description
        assert (variable.type, variable.causality, variable.variability) == (spec.type, spec.causality,
                                                                             spec.variability)
        assert (variable.unit or "") == spec.unit
        assert variable.min == (None if spec.min is None else str(spec.min) if spec.type == "Real" else "0")
    ball, settings = Ball(), CvodeSettings()
    for name in ("m", "k", "b", "R", "g"):
        assert float(variables[name].start) == getattr(ball, name)
    assert (float(variables["h"].start), float(variables["v"].start)) == (2.0, 0.0)
    assert (variables["h"].initial, variables["v"].initial) == ("exact", "exact")
    assert float(variables["F_ext"].start) == 0.0
    assert (float(variables["rtol"].start), float(variables["atol"].start), variables["method"].start) == (
        settings.rtol, 0.0, "auto")  # atol 0: no absolute bound (settings.atol None)
    assert variables["engine"].start == "auto"  # the compiled engine where numba is installed, its code shipped
    assert float(variables["m"].min) == SMALLEST_POSITIVE and float(variables["rtol"].max) == 1.0
    assert float(variables["b"].min) == 0.0 and float(variables["g"].min) == 0.0

    assert {u.name: {k: getattr(u.baseUnit, k) for k in ("kg", "m", "s", "rad") if getattr(u.baseUnit, k)}
            for u in md.unitDefinitions} == UNITS
    assert (md.defaultExperiment.startTime, md.defaultExperiment.stopTime) == ("0", "8.0")
    assert float(md.defaultExperiment.tolerance) == settings.rtol  # masters that take it pass the FMU's own back
    cs = md.coSimulation
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert cs.needsExecutionTool  # a Python installation with numpy and scikit-sundae runs it
    import pythonfmu

    import bouncingball

    assert md.version == bouncingball.__version__
    assert md.generationTool == f"bouncingball {bouncingball.__version__} (pythonfmu {pythonfmu.__version__})"
    assert [u.variable.name for u in md.outputs] == ["h", "v", "a", "contact", "contact_force", "impacts",
                                                     "error_estimate"]
    assert [u.variable.name for u in md.initialUnknowns] == ["a", "contact", "contact_force", "impacts",
                                                             "error_estimate"]


def test_fmu_carries_the_package_and_a_linux_binary_only(fmu):
    """The package travels under a name of its own: bouncingball_fmu_<16 hex digits of its sources>."""
    import re

    names = zipfile.ZipFile(fmu).namelist()
    [script] = [n for n in names if re.fullmatch(r"resources/bouncingball_fmu_[0-9a-f]{16}_slave\.py", n)]
    package = script.removesuffix("_slave.py")
    assert f"{package}/solvers/cvode.py" in names and f"{package}/data/scenes.toml" in names
    assert not any(n.startswith("resources/bouncingball/") for n in names)
    assert sorted(n for n in names if n.startswith("binaries/")) == [
        "binaries/linux64/BouncingBall.so", "binaries/linux64/BouncingBall_pythonfmu.so"]


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_the_loader_compiles_without_a_warning(tmp_path, fmi_version):
    import shutil

    from bouncingball.fmu.build import LOADER3_SOURCE, LOADER_SOURCE, loader_flags

    compiler = shutil.which("cc") or shutil.which("gcc")
    source = LOADER_SOURCE if fmi_version == 2 else LOADER3_SOURCE
    completed = subprocess.run([compiler, "-shared", "-fPIC", "-O2", *loader_flags(fmi_version), "-Werror", "-o",
                                tmp_path / "loader.so", source, "-ldl", "-lpthread", "-lm"], capture_output=True,
                               text=True, check=False)
    assert completed.returncode == 0 and completed.stderr == "", completed.stderr


def test_the_host_check_requires_what_pyproject_requires():
    import tomllib

    from bouncingball.fmu.host_check import REQUIREMENTS

    pyproject = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    dependencies = {}
    for requirement in pyproject["project"]["dependencies"]:
        name, _, specifiers = requirement.partition(">=")
        minimum, _, below = specifiers.partition(",<")
        dependencies[name] = (minimum, below or None)
    assert {distribution: (minimum, below) for _, distribution, minimum, below in REQUIREMENTS} == dependencies


def test_the_host_check_names_the_python_what_it_lacks_and_the_fix():
    from bouncingball.fmu.host_check import REQUIREMENTS, check_source, host_problem

    assert host_problem(REQUIREMENTS) == ""  # this Python runs the FMU
    line = host_problem((("no_such_module", "no-such-dist", "1.0", None), ("numpy", "numpy", "99", None),
                         ("numpy", "numpy", "1", np.__version__)))
    version = ".".join(map(str, sys.version_info[:3]))
    numpy = np.__version__
    assert line == (f"BouncingBall cannot run in the Python of this process, {sys.executable} (Python {version}): it "
                    "has no no-such-dist (ModuleNotFoundError: No module named 'no_such_module') and numpy "
                    f"{numpy} (it needs >=99) and numpy {numpy} (it needs >=1,<{numpy}); fix: "
                    f"{sys.executable} -m pip install 'no-such-dist>=1.0' 'numpy>=99' 'numpy>=1,<{numpy}'")
    namespace = {}  # as the loader runs it: a namespace of its own, only `problem` left in it
    exec(check_source(), namespace)
    assert {name: value for name, value in namespace.items() if name != "__builtins__"} == {"problem": ""}


def test_fmpy_validate_reports_no_problem(fmu):
    completed = subprocess.run([BIN / "fmpy", "validate", fmu], capture_output=True, text=True, check=False)
    assert completed.returncode == 0, completed.stdout + completed.stderr
    assert "No problems found" in completed.stdout


def test_fmutool_check_passes(fmu):
    pytest.importorskip("fmu_manipulation_toolbox", reason="fmutool comes with fmu-manipulation-toolbox")
    completed = subprocess.run([BIN / "fmutool", "-input", fmu, "-check"], capture_output=True, text=True,
                               check=False)
    output = completed.stdout + completed.stderr
    assert completed.returncode == 0, output
    assert "compliant with FMI-2.0" in output and "No semantic error" in output and "ERROR" not in output


def test_importing_the_fmu_modules_imports_no_fmu_tool():
    code = ("import sys, bouncingball, bouncingball.fmu.build, bouncingball.fmu.validate, bouncingball.cli; "
            "print(sorted(m for m in ('pythonfmu', 'fmpy', 'scipy', 'matplotlib') if m in sys.modules))")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert completed.stdout.strip() == "[]"


# --- accuracy through FMPy --------------------------------------------------------------------------
def test_article_at_1ms_matches_the_exact_solution_at_every_point(article_runs):
    result = article_runs[0.001]
    assert len(result) == 8001 and result["time"][-1] == 8.0
    h, _, impacts = exact_at(result["time"])
    assert np.max(np.abs(result["h"] - h)) < 1e-8  # measured 4.9e-10
    np.testing.assert_array_equal(result["impacts"], impacts)
    assert impacts[-1] == oracle_counts(Ball()).impacts


README = Path(__file__).resolve().parents[1] / "README.md"


def test_the_readme_says_what_fmpy_records_at_the_fmus_defaults(fmu):
    """At 1 ms steps asked for: the README's height error and impact count; not asked (FMPy's command line): the
    interval FMPy picks from the default experiment, which the README names."""
    if not README.is_file():
        pytest.skip("runs in a source checkout")
    readme = " ".join(README.read_text(encoding="utf-8").split())
    run = fmpy.simulate_fmu(str(fmu), output_interval=1e-3, output=["h", "impacts"])
    h_exact, _, impacts = exact_at(run["time"])
    error = float(np.max(np.abs(run["h"] - h_exact)))
    quote = (f"the height is within {error:.3e} m of the exact solution, {int(run['impacts'][-1])} of "
             f"{int(impacts[-1])} impacts")
    assert quote in readme, quote
    default = fmpy.simulate_fmu(str(fmu), output=["h"])  # as `fmpy simulate` without --output-interval
    interval = float(np.diff(default["time"])[0])
    assert np.allclose(np.diff(default["time"]), interval, rtol=0, atol=1e-12) and default["time"][-1] == 8.0
    assert interval > 1e-3  # FMPy's 1000-point cap: not the 1 ms of the default experiment
    quote = f"FMPy's command line records every {interval * 1e3:g} ms at the FMU's default experiment"
    assert quote in readme, quote


def test_answer_does_not_depend_on_the_communication_step(article_runs):
    coarse = article_runs[0.5]
    np.testing.assert_allclose(coarse["time"], np.arange(17) * 0.5, rtol=0, atol=1e-12)
    h_exact, _, impacts = exact_at(coarse["time"])
    for dt in (0.1, 0.01, 0.001):
        fine = article_runs[dt]
        common = np.searchsorted(fine["time"], coarse["time"] - 1e-9)
        np.testing.assert_allclose(fine["time"][common], coarse["time"], rtol=0, atol=1e-12)
        assert np.max(np.abs(fine["h"][common] - coarse["h"])) < 1e-8  # measured 0: bit-identical
        np.testing.assert_array_equal(fine["impacts"][common], coarse["impacts"])
    # one doStep of 0.5 s crosses up to three impacts, and still lands on the exact solution
    assert np.max(np.abs(coarse["h"] - h_exact)) < 1e-8
    np.testing.assert_array_equal(coarse["impacts"], impacts)


# --- the master's tolerance: it may tighten rtol, never loosen it -----------------------------------------
LOOSER = f"(fmi2SetupExperiment) is looser than the FMU's rtol = {DEFAULT_RTOL!r}, so rtol = {DEFAULT_RTOL!r} is used"


def run_article_at_10ms(fmu, **options) -> tuple[float, np.ndarray, list[tuple[int, str]]]:
    """max |h - h_exact| [m], the impacts column and the FMU's log (status, message) of the 8 s article."""
    log = []
    result = fmpy.simulate_fmu(str(fmu), stop_time=8.0, output_interval=0.01, output=["h", "impacts"],
                               logger=lambda env, name, status, category, message: log.append(
                                   (status, message.decode("utf-8"))), **options)
    h, _, impacts = exact_at(result["time"])
    np.testing.assert_array_equal(result["impacts"], impacts)
    assert impacts[-1] == oracle_counts(Ball()).impacts
    return float(np.max(np.abs(result["h"] - h))), result["impacts"], log


@pytest.mark.parametrize("tolerance", [1e-4, 1e-3])  # OMSimulator always passes 1e-4
def test_a_looser_tolerance_from_the_master_is_not_used_and_the_fmu_says_so_once(fmu, tolerance):
    error, _, log = run_article_at_10ms(fmu, relative_tolerance=tolerance)
    assert error < 1e-6  # measured 1.04e-10 m (with the tolerance as rtol: 6.1e-4 m at 1e-4, 2.7e-2 m at 1e-3)
    said = [(status, message) for status, message in log if "fmi2SetupExperiment" in message]
    assert said == [(1, f"tolerance = {tolerance!r} {LOOSER}: a master's tolerance may tighten rtol but never "
                        "loosen it, because each bounce's error carries into every later bounce (at 1e-3 the "
                        "article's ball misses an impact); to loosen it, set the parameter rtol")]


def test_a_tighter_tolerance_from_the_master_is_used(fmu):
    default_error, _, default_log = run_article_at_10ms(fmu)  # FMPy passes the DefaultExperiment's rtol
    tight_error, _, tight_log = run_article_at_10ms(fmu, relative_tolerance=1e-13, debug_logging=True)
    assert not any("rtol" in message for _, message in default_log)  # the FMU's own tolerance: nothing to say
    assert (0, "rtol = 1e-13 is used: the tolerance of fmi2SetupExperiment, tighter than the parameter "
               f"rtol = {DEFAULT_RTOL!r}") in tight_log
    assert tight_error < default_error / 5  # measured 1.52e-11 m against 1.04e-10 m


def test_a_restored_state_keeps_the_tolerance_rule(unzipped):
    """A state taken under a looser master tolerance continues at rtol, in this instance or a fresh one."""
    first = Instance(unzipped, "first")
    fresh = None
    try:
        first.initialize(tolerance=1e-3)
        assert [status for status, message in first.log if LOOSER in message] == [1]
        first.step_to(2.0, 0.01)
        serialized = first.fmu.serializeFMUstate(first.fmu.getFMUstate())
        fresh = Instance(unzipped, "fresh")  # created now: FMPy's logger proxy sends every message to the last one
        state = fresh.fmu.deSerializeFMUstate(serialized)
        fresh.fmu.setFMUstate(state)
        fresh.fmu.freeFMUstate(state)
        fresh.t = 2.0
        continued, restored = first.step_to(8.0, 0.01), fresh.step_to(8.0, 0.01)
        h, _, impacts = exact_at(np.arange(201, 801) * 0.01)
        for run in (continued, restored):
            assert np.max(np.abs(np.array([row[0] for row in run]) - h)) < 1e-6  # measured 2.6e-10 and 2.3e-10 m
            assert [row[5] for row in run] == impacts.tolist() and impacts[-1] == oracle_counts(Ball()).impacts
        assert fresh.get("rtol") == [DEFAULT_RTOL] and fresh.errors() == []
    finally:
        first.free()
        if fresh is not None:
            fresh.free()


# --- inputs: F_ext ---------------------------------------------------------------------------------
def test_F_ext_equal_to_weight_gives_constant_velocity(fmu):
    m, g = 2.5, 9.81
    result = fmpy.simulate_fmu(str(fmu), stop_time=3.0, output_interval=0.1,
                               start_values={"m": m, "g": g, "h": 2.0, "v": 1.0, "F_ext": m * g},
                               output=["h", "v", "a", "impacts", "contact"])
    t = result["time"]
    np.testing.assert_allclose(result["h"], 2.0 + t, rtol=0, atol=1e-12)  # thrown up at 1 m/s, no net force
    np.testing.assert_allclose(result["v"], 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result["a"], 0.0, rtol=0, atol=1e-12)
    assert not result["impacts"].any() and not result["contact"].any()


def test_F_ext_step_change_mid_run(fmu):
    """F_ext = m g until t = 1 s (h = 2 + t), then 0: free flight from (3 m, 1 m/s), with bounces."""
    ball = Ball(m=2.0)
    weight = ball.m * ball.g
    signal = np.array([(0.0, weight), (1.0, weight), (1.0, 0.0), (4.0, 0.0)],
                      dtype=[("time", np.float64), ("F_ext", np.float64)])
    result = fmpy.simulate_fmu(str(fmu), stop_time=4.0, output_interval=0.01, input=signal,
                               start_values={"m": ball.m, "h": 2.0, "v": 1.0, **TIGHT},
                               output=["h", "v", "impacts"])
    t = result["time"]
    before = t <= 1.0
    np.testing.assert_allclose(result["h"][before], 2.0 + t[before], rtol=0, atol=1e-12)
    np.testing.assert_allclose(result["v"][before], 1.0, rtol=0, atol=1e-12)
    h, v, impacts = exact_at(t[~before], ball, h0=3.0, v0=1.0, t_start=1.0)
    assert np.max(np.abs(result["h"][~before] - h)) < 1e-8
    np.testing.assert_array_equal(result["impacts"][~before], impacts)
    truth = oracle_counts(ball, h0=3.0, v0=1.0, t_start=1.0, t_end=4.0)
    assert impacts[-1] == truth.impacts >= 2  # the flight from the switch state ends in real bounces


# --- FMU state -----------------------------------------------------------------------------------------
def test_a_build_in_a_process_that_imported_part_of_the_same_copy_leaves_its_states_restorable(fmu, unzipped,
                                                                                                 tmp_path):
    """A process that imported part of the FMU's copy of the package (numba's cache index names its types), then built
    an FMU of the same sources (the copy's name is its sources'), then runs the FMU: a state restores. The build once
    removed the part it had added, which was imported again beside the rest: the restored state was refused."""
    code = f"""
import importlib, sys
sys.path.insert(0, {str(Path(__file__).parent)!r})
from bouncingball.fmu.build import build_fmu
from fmu_helpers import TIGHT, Instance
resources = {str(unzipped / "resources")!r}
[package] = [name for name in {sorted(p.name for p in (unzipped / "resources").iterdir() if p.is_dir())!r}
             if name.startswith("bouncingball_fmu_")]
sys.path.insert(0, resources)
importlib.import_module(package + ".contact_laws.common")
sys.path.remove(resources)
build_fmu({str(tmp_path / "same.fmu")!r})
ball = Instance({str(unzipped)!r})
ball.initialize(**TIGHT)
ball.step_to(0.62, 0.01)
state = ball.fmu.getFMUstate()
ball.step_to(1.3, 0.01)
ball.fmu.setFMUstate(state)
print(ball.log)
"""
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, check=False)
    assert completed.returncode == 0, completed.stderr[-3000:]
    assert completed.stdout.strip().splitlines()[-1] == "[]"


def test_rollback_gives_the_same_outputs_bit_for_bit(unzipped):
    ball = Instance(unzipped)
    try:
        ball.initialize(**TIGHT)
        ball.step_to(0.62, 0.01)  # just before the first impact
        saved_outputs = ball.outputs()
        state = ball.fmu.getFMUstate()
        first = ball.step_to(1.3, 0.01)  # through the contact and the departure
        ball.fmu.setFMUstate(state)
        assert ball.outputs() == saved_outputs
        ball.t = 0.62
        again = ball.step_to(1.3, 0.01)
        ball.fmu.freeFMUstate(state)
        assert again == first  # integrated again from the restart point: the same numbers
        h, _, impacts = exact_at([0.62, 1.3])
        assert impacts[0] == 0 and first[-1][5] == impacts[1] > 0 and any(outputs[3] for outputs in first)
        assert abs(first[-1][0] - h[1]) < 1e-8
    finally:
        ball.free()


@pytest.mark.parametrize("take_state", [False, True], ids=["plain", "state-every-step"])
@pytest.mark.parametrize("m", [1e-6, 1e-9])
def test_tiny_mass_at_one_second_steps_stays_exact(unzipped, m, take_state):
    """Steps of many contact periods, with fmi2GetFMUstate before each (what a master that can reject
    steps does): at every communication point within 1e-6 m of the exact solution, at rest at the end."""
    ball = Instance(unzipped)
    try:
        ball.initialize(m=m)
        heights, states = [], []
        for t in range(60):
            if take_state:
                states.append(ball.fmu.getFMUstate())
            ball.fmu.doStep(float(t), 1.0)
            heights.append(ball.get("h")[0])
        for state in states:
            ball.fmu.freeFMUstate(state)
        h_exact, _, _ = exact_at(np.arange(1.0, 61.0), Ball(m=m))
        assert np.max(np.abs(np.array(heights) - h_exact)) <= 1e-6
        assert ball.errors() == []
    finally:
        ball.free()


def test_serialized_state_restores_in_a_fresh_instance(unzipped):
    values = {"g": 3.71, "b": 5.0, "h": 1.5, "v": 0.5, "F_ext": 0.4, "method": "BDF", **TIGHT}
    first = Instance(unzipped, "first")
    fresh = Instance(unzipped, "fresh")
    try:
        first.initialize(**values)
        first.step_to(1.3, 0.1)
        state = first.fmu.getFMUstate()
        serialized = first.fmu.serializeFMUstate(state)
        first.fmu.freeFMUstate(state)
        expected = first.step_to(3.0, 0.1)

        state = fresh.fmu.deSerializeFMUstate(serialized)
        fresh.fmu.setFMUstate(state)
        fresh.fmu.freeFMUstate(state)
        assert fresh.get("g", "b", "F_ext", "rtol", "atol", "method") == [3.71, 5.0, 0.4, 1e-11, 1e-14, "BDF"]
        fresh.t = 1.3
        assert fresh.step_to(3.0, 0.1) == expected  # bit for bit
        h, _, impacts = exact_at([3.0], Ball(g=3.71, b=5.0), h0=1.5, v0=0.5, F_ext=0.4)
        assert abs(expected[-1][0] - h[0]) < 1e-8 and expected[-1][5] == impacts[0] > 0
    finally:
        first.free()
        fresh.free()


# --- instances ----------------------------------------------------------------------------------------
def test_two_instances_with_different_g_stay_independent(unzipped):
    earth, moon = Instance(unzipped, "earth"), Instance(unzipped, "moon")
    try:
        earth.initialize(**TIGHT)
        moon.initialize(g=1.62, **TIGHT)
        t = np.arange(1, 301) * 0.01
        earth_h, moon_h, moon_impacts = [], [], []
        for _ in t:  # interleaved steps
            earth_h.append(earth.step_to(earth.t + 0.01, 0.01)[0][0])
            out = moon.step_to(moon.t + 0.01, 0.01)[0]
            moon_h.append(out[0])
            moon_impacts.append(out[5])
        h, _, _ = exact_at(t)
        assert np.max(np.abs(np.array(earth_h) - h)) < 1e-8
        h, _, impacts = exact_at(t, Ball(g=1.62))
        assert np.max(np.abs(np.array(moon_h) - h)) < 1e-8
        np.testing.assert_array_equal(moon_impacts, impacts)
        assert earth.get("g") == [9.81] and moon.get("g") == [1.62]
    finally:
        earth.free()
        moon.free()


# --- failures never kill the host ---------------------------------------------------------------------
@pytest.mark.parametrize(("name", "value", "expected"), [
    ("m", -1.0, "m = -1.0 kg is not allowed: it must be finite and > 0"),
    ("k", 0.0, "k = 0.0 N/m is not allowed: it must be finite and > 0"),
    ("b", -5.0, "b = -5.0 N s/m is not allowed: it must be finite and >= 0"),
    ("R", math.nan, "R = nan m is not allowed: it must be finite and > 0"),
    ("g", -9.81, "g = -9.81 m/s2 is not allowed: it must be finite and >= 0"),
    ("h", math.inf, "h = inf m is not allowed: it must be a finite number"),
    ("F_ext", math.nan, "F_ext = nan N is not allowed: it must be a finite number"),
    ("rtol", 2.0, "rtol = 2.0 is not allowed: it must be in [1e-15, 1] (CVODE cannot honour a relative tolerance "
                  "within a few ulps of double precision's 2.2e-16)"),
    ("atol", -1.0, "atol = -1.0 m is not allowed: it must be finite and >= 0"),
    ("method", "RK4", "method = 'RK4' is not allowed: it must be one of auto, Adams, BDF"),
    ("engine", "fast", "engine = 'fast' is not allowed: it must be one of auto, compiled, sksundae"),
])
def test_invalid_parameter_gives_fmi2Error_with_a_message(unzipped, name, value, expected):
    ball = Instance(unzipped, f"bad_{name}")
    try:
        ball.set(**{name: value})
        ball.fmu.setupExperiment(startTime=0.0)
        ball.fmu.enterInitializationMode()
        with pytest.raises(fmpy.fmi1.FMICallException) as raised:
            ball.fmu.exitInitializationMode()
        assert raised.value.status == 3  # fmi2Error, not fmi2Fatal
        assert ball.errors() == [expected]
    finally:
        ball.free()
    healthy = Instance(unzipped, "healthy")  # the host carries on
    healthy.initialize()
    assert healthy.step_to(0.1, 0.1)[0][5] == 0
    healthy.free()


def test_invalid_tolerance_in_setup_experiment_gives_fmi2Error(unzipped):
    ball = Instance(unzipped)
    try:
        with pytest.raises(fmpy.fmi1.FMICallException) as raised:
            ball.initialize(tolerance=5.0)
        assert raised.value.status == 3
        [error] = ball.errors()
        assert error.startswith("tolerance (fmi2SetupExperiment) = 5.0 is not allowed: it must be in [1e-15, 1]")
    finally:
        ball.free()


@pytest.mark.parametrize("values, tolerance, expected", [
    (dict(rtol=1e-20), None, "rtol = 1e-20 is not allowed: it must be in [1e-15, 1] (CVODE cannot honour"),
    # an ulp of max(|h|, R) = 2 m: 2**-51 m
    (dict(atol=1e-30), None, "atol = 1e-30 m is not allowed: it must be 0 (none) or finite and >= "
                             "4.440892098500626e-16 m"),
    ({}, 1e-17, "tolerance (fmi2SetupExperiment) = 1e-17 is not allowed: it must be in [1e-15, 1]"),
])
def test_a_tolerance_beyond_double_precision_gives_fmi2Error_at_initialisation(unzipped, values, tolerance, expected):
    """More accuracy than double precision allows: it failed at the first doStep with CVODE's text naming neither."""
    ball = Instance(unzipped)
    try:
        with pytest.raises(fmpy.fmi1.FMICallException) as raised:
            ball.initialize(tolerance=tolerance, **values)
        assert raised.value.status == 3
        [message] = ball.errors()
        assert message.startswith(expected)
    finally:
        ball.free()


def test_atol_zero_is_none(unzipped):
    ball = Instance(unzipped)
    try:
        ball.initialize(atol=0.0)
        ball.fmu.doStep(0.0, 1.0)
        assert ball.errors() == []
        assert abs(ball.outputs()[0] - exact_at([1.0])[0][0]) < 1e-8
    finally:
        ball.free()


def test_a_contact_too_short_for_double_precision_gives_fmi2Error_and_changes_nothing(unzipped):
    """k = 1e15 N/m, m = 1e-9 kg: a contact lasts 3 ps, below what double precision resolves at 1e5 s."""
    from bouncingball.solvers.cvode import resolvable_until

    ball_model = Ball(k=1e15, m=1e-9)
    limit = resolvable_until(ball_model)
    ball = Instance(unzipped)
    try:
        ball.initialize(k=1e15, m=1e-9)
        assert 1.0 < limit < 2.0
        ball.fmu.doStep(0.0, 0.5)
        before = ball.outputs()
        with pytest.raises(fmpy.fmi1.FMICallException) as raised:
            ball.fmu.doStep(0.5, 1e5)
        assert raised.value.status == 3
        [message] = ball.errors()
        assert "k = 1000000000000000.0 N/m with m = 1e-09 kg is not allowed up to t = 100000.5 s" in message
        assert f"t <= {limit!r} s" in message  # exactly: a rounded bound misleads
        assert ball.outputs() == before  # refused before any work: the instance carries on from t = 0.5 s
        ball.fmu.doStep(0.5, 0.5)
        assert abs(ball.get("h")[0] - exact_at([1.0], ball_model)[0][0]) <= 1e-6
    finally:
        ball.free()


def test_changing_a_parameter_after_initialisation_is_an_error(unzipped):
    ball = Instance(unzipped)
    try:
        ball.initialize()
        with pytest.raises(fmpy.fmi1.FMICallException) as raised:
            ball.set(g=1.0)
        assert raised.value.status == 3
        assert ball.errors() == ["g = 1.0 is not allowed: g cannot change after initialisation"]
    finally:
        ball.free()


def test_an_unknown_or_mistyped_value_reference_is_an_error_and_the_instance_carries_on(unzipped):
    ball = Instance(unzipped)
    try:
        ball.initialize()
        method, impacts = ball.variables["method"].valueReference, ball.variables["impacts"].valueReference
        for call, arguments, message in [
            (ball.fmu.setReal, ([method], [1.0]), f"fmi2SetReal: value reference {method} is not a variable of type R"),
            (ball.fmu.getReal, ([99],), "fmi2GetReal: value reference 99 is not a variable of type Real"),
            (ball.fmu.setReal, ([impacts], [1.0]), f"fmi2SetReal: value reference {impacts} is not a variable of type"),
            (ball.fmu.getInteger, ([0],), "fmi2GetInteger: value reference 0 is not a variable of type Integer"),
        ]:
            with pytest.raises(fmpy.fmi1.FMICallException) as raised:
                call(*arguments)
            assert raised.value.status == 3  # fmi2Error, not fmi2Fatal
            assert ball.errors()[-1].startswith(message)
        assert ball.get("method") == ["auto"]
        ball.fmu.doStep(0.0, 0.7)  # the instance carries on
        assert abs(ball.get("h")[0] - exact_at([0.7])[0][0]) < 1e-8
    finally:
        ball.free()  # does not touch pythonfmu's released instance
    healthy = Instance(unzipped, "healthy")
    healthy.initialize()
    assert healthy.step_to(1.0, 0.5)[-1][5] == 1
    healthy.free()


def test_the_scene_to_start_value_mapping_covers_the_fmus_start_values():
    """fmu/variables.py's one mapping: every name a variable of the table, the ball's parameters all there,
    and a scene's start values give back that scene (testing.scene_with_start_values, what check uses)."""
    from bouncingball.check.judge import scene_with_start_values
    from bouncingball.fmu.variables import SCENE_FIELD_OF_START_VALUE, VARIABLES, start_values_of
    from bouncingball.scenes import BALL_KEYS, load_scene

    names = {variable.name for variable in VARIABLES}
    assert set(SCENE_FIELD_OF_START_VALUE) <= names
    assert set(BALL_KEYS) <= set(SCENE_FIELD_OF_START_VALUE.values())
    scene = load_scene("zero-gravity")
    values = start_values_of(scene)
    assert values["h"] == scene.h0 == 2.0 and values["v"] == scene.v0 == -1.0 and values["g"] == 0.0
    moved = scene_with_start_values("article", values)
    assert (moved.ball, moved.h0, moved.v0, moved.F_ext) == (scene.ball, scene.h0, scene.v0, scene.F_ext)


def test_a_build_host_that_cannot_compile_the_engine_ships_no_cache_and_says_why(tmp_path, capsys):
    """The FMU is still built, with no cache of its compiled engine; stderr says why (the compiling process's last
    line) and what follows: the engine compiles at its first use where the FMU runs."""
    pytest.importorskip("numba", reason="without numba the build compiles nothing, and says nothing")
    from bouncingball.fmu import engine_cache

    package = tmp_path / "bouncingball_fmu_broken"
    package.mkdir()
    (package / "__init__.py").write_text('raise ImportError("no engine on this host")\n')
    assert engine_cache.compile_cache(package, tmp_path / "cache", ["cc"]) is None
    assert engine_cache.shipped_files(None) == []
    assert capsys.readouterr().err == ("bouncingball: the FMU ships no cache of its compiled engine, which could not "
                                       "be compiled here (ImportError: no engine on this host): it compiles at its "
                                       "first use where it runs\n")


def test_build_fmu_says_each_step_as_it_starts_and_the_time_so_far(fmu):
    """A build takes seconds to minutes (numba's compile): never silent, each step a line on stderr."""
    import re

    from bouncingball.fmu.build import BUILD_STEPS

    lines = fmu.with_name("build.txt").read_text(encoding="utf-8").splitlines()
    steps = [re.fullmatch(r"build-fmu: \[(\d)/(\d)\] (.*) \((\d+) s so far\)", line) for line in lines[:-1]]
    assert [(int(m[1]), int(m[2]), m[3]) for m in steps] == [(i + 1, 5, name) for i, name in enumerate(BUILD_STEPS)]
    seconds = [int(m[4]) for m in steps]
    assert seconds == sorted(seconds)
    assert re.fullmatch(rf"wrote {re.escape(str(fmu))} and its reference result .*_ref.csv in \d+ s", lines[-1])
