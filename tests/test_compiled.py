"""The compiled CVODE engine against scikit-sundae's: the same CVODE library, the same steps, the same numbers.

Both engines drive the same SUNDIALS CVODE with the same settings and share cvode.py's event
logic, so they must take the same internal steps; the heights are compared to 1e-12 m and the
event times to 1e-12 s. The scikit-sundae engine is itself checked against the exact solution in
test_cvode.py and test_hard_cases.py (which run whichever engine "auto" picks).
"""

import glob
import math
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.scenes import BUILTIN_SCENES, load_scene
from bouncingball.solvers.cvode import BallIntegrator, CvodeSettings, choose_engine
from bouncingball.solvers.engines import sundials

compiled = pytest.importorskip("bouncingball.solvers.engines.compiled",
                               reason="the compiled engine needs numba ([fast])")
if compiled.unavailable_reason() is not None:
    pytest.skip(f"compiled engine unavailable: {compiled.unavailable_reason()}", allow_module_level=True)

HEIGHT_AGREEMENT = 1e-12  # m
TIME_AGREEMENT = 1e-12  # s
ARTICLE = bb.Ball()


def assert_engines_agree(sksundae, fast):
    assert sksundae.stats.engine == "sksundae" and fast.stats.engine == "compiled"
    assert [e.kind for e in fast.events] == [e.kind for e in sksundae.events]
    for a, b in zip(sksundae.events, fast.events, strict=True):
        assert abs(a.time - b.time) <= TIME_AGREEMENT * max(1.0, abs(a.time))
        assert abs(a.velocity - b.velocity) <= 1e-9 * max(1.0, abs(a.velocity))
    assert (fast.stats.steps, fast.stats.rhs_calls) == (sksundae.stats.steps, sksundae.stats.rhs_calls)
    assert np.max(np.abs(fast.h - sksundae.h)) <= HEIGHT_AGREEMENT
    assert fast.rest_time == sksundae.rest_time


def run_both(*args, **options):
    return [bb.simulate(*args, engine=engine, **options) for engine in ("sksundae", "compiled")]


@pytest.mark.parametrize("name", BUILTIN_SCENES)
def test_every_builtin_scene_gives_the_same_steps_events_and_heights(name):
    scene = load_scene(name)
    assert_engines_agree(*(scene.simulate("cvode", engine=engine) for engine in ("sksundae", "compiled")))


@pytest.mark.parametrize("method", ["Adams", "BDF"])
def test_both_methods_and_a_max_step(method):
    assert_engines_agree(*run_both(ARTICLE, 2.0, 0.0, 3.0, 1e-3, method=method, max_step=0.05))


# The hard cases of test_hard_cases.py: grazing starts, the bounce threshold, tiny hops, long and
# stiff rests, the stiff failures found by the property test.
HARD_CASES = {
    "graze-1e-9": (ARTICLE, ARTICLE.R, 1e-9, 1.0, 1e-3, 0.0),
    "graze-1e-5": (ARTICLE, ARTICLE.R, 1e-5, 1.0, 1e-3, 0.0),
    "threshold": (bb.Ball(b=145.21960354346564 * (1 - 1e-8)), 2.0, 0.0, 2.0, 1e-3, 0.0),
    "rest-height-leave": (ARTICLE, ARTICLE.rest_height(), 0.1058604129 * (1 + 1e-6), 2.0, 1e-3, 0.0),
    "undamped-grazing": (bb.Ball(b=0.0), bb.Ball(b=0.0).rest_height(),
                         math.sqrt(1e4) * bb.Ball(b=0.0).static_deflection() * (1 + 1e-6), 2.0, 1e-3, 0.0),
    "hop-3e-5": (ARTICLE, ARTICLE.R, 3e-5, 0.5, 1e-4, 0.0),
    "long-rest": (ARTICLE, 2.0, 0.0, 1e6, 1.0, 0.0),
    "tiny-mass-rest": (bb.Ball(m=1e-6), 2.0, 0.0, 1e4, 1.0, 0.0),
    "stiff-short-contact": (bb.Ball(k=1e15, m=1e-9, b=1e-3), 0.1, 0.0, 0.01, 1e-5, 0.0),
    "stiff-tiny-ball": (bb.Ball(m=7.845629028153048e-06, k=1273664406.973477, b=131.07385603248107,
                                R=0.016349292318303628, g=5.745576497079252),
                        0.01761906428125259, 26.39033834877121, 25.48148283754829, 25.48148283754829 / 2000, 0.0),
    "lifted-by-F_ext": (bb.Ball(k=1e12, m=1.0, b=2e8), bb.Ball().R - 1e-3, 0.0, 0.01, 1e-4, 2.0 * 9.81),
    "hover-no-gravity": (bb.Ball(g=0.0), 1.0, 0.0, 1.0, 0.1, 0.0),
    "hover-lifted-at-R": (ARTICLE, ARTICLE.R, 0.0, 1.0, 0.1, ARTICLE.m * ARTICLE.g),
    "critical-creep-no-gravity": (bb.Ball(m=2.317700043930019e-4, k=57428147.75181946,
                                          b=2.0 * math.sqrt(57428147.75181946 * 2.317700043930019e-4), R=1.0, g=0.0),
                                  1.0, -12.5, 3.0, 3.0 / 2000, 0.0),
    "undamped-small-ball": (bb.Ball(m=1.0, k=1e8, b=0.0, R=1e-3, g=34.0), 1e-3 - 34.0 / 1e8, 1.0, 3.0, 3.0 / 2000,
                            0.0),
}


@pytest.mark.parametrize("case", HARD_CASES)
def test_the_hard_cases_give_the_same_steps_events_and_heights(case):
    ball, h0, v0, t_end, dt, F_ext = HARD_CASES[case]
    assert_engines_agree(*run_both(ball, h0, v0, t_end, dt, F_ext=F_ext))


def test_advance_with_states_and_a_changing_force_matches():
    """The FMU's path: advance() step by step, F_ext changed, a state taken and restored."""
    runs = []
    for engine in ("sksundae", "compiled"):
        integrator = BallIntegrator(ARTICLE, 2.0, 0.0, settings=CvodeSettings(engine=engine))
        trace = []
        for i in range(1, 3001):
            if i == 1000:
                integrator.F_ext = -3.0
            if i == 2000:
                saved = integrator.get_state()
            trace.append((integrator.advance(i * 1e-3), integrator.h, integrator.v))
        integrator.set_state(saved)
        integrator.advance(2.5)
        runs.append((trace, integrator.get_state()))
    (trace_a, state_a), (trace_b, state_b) = runs
    for (events_a, h_a, _), (events_b, h_b, _) in zip(trace_a, trace_b, strict=True):
        assert [e.kind for e in events_a] == [e.kind for e in events_b]
        assert abs(h_a - h_b) <= HEIGHT_AGREEMENT
    assert (state_a.steps, state_a.rhs_calls, state_a.impacts) == (state_b.steps, state_b.rhs_calls, state_b.impacts)
    assert abs(state_a.h - state_b.h) <= HEIGHT_AGREEMENT


def test_a_method_fighting_stiffness_fails_with_the_same_reason(monkeypatch):
    """As test_cvode's: the cap lowered to 50 steps, which Adams needs more of for one k = 1e12 contact."""
    import bouncingball.solvers.integrator as integrator

    monkeypatch.setattr(integrator, "MAX_STEPS_PER_PHASE", 50)
    with pytest.raises(integrator.SolverError, match="took more than 50 steps in one contact phase.*use method 'BDF'"):
        bb.simulate(bb.Ball(k=1e12), 2.0, 0.0, 1.0, 1e-3, method="Adams", engine="compiled")


def test_a_cvode_failure_is_a_clear_error():
    settings = CvodeSettings(engine="compiled")
    object.__setattr__(settings, "rtol", 1e-300)  # past its floor (settings.MIN_RTOL), to reach CVODE's own failure
    integrator = BallIntegrator(ARTICLE, 2.0, 0.0, settings=settings)
    with pytest.raises(RuntimeError, match=r"CVODE failed at t = 0.0 s \(flight, h = 2.0 m.*CV_TOO_MUCH_ACC.*accuracy"):
        integrator.advance(0.5)


# --- choosing the engine ---------------------------------------------------------------------------
def test_auto_takes_the_compiled_engine_and_says_why():
    result = bb.simulate(ARTICLE, 2.0, 0.0, 1.0)
    assert result.stats.engine == "compiled" and "SUNDIALS 7." in result.stats.engine_reason


def test_an_unknown_engine_is_refused_by_name():
    with pytest.raises(ValueError, match="engine = 'fast' is not allowed: it must be one of auto, compiled, sksundae"):
        bb.simulate(ARTICLE, 2.0, 0.0, 1.0, engine="fast")


def test_another_sundials_version_falls_back_with_the_reason(monkeypatch):
    monkeypatch.setattr(sundials, "SUPPORTED_MAJOR", 99)
    monkeypatch.setattr(sundials, "_LIBRARY", None)
    monkeypatch.setattr(sundials, "_UNAVAILABLE", None)
    engine, reason = choose_engine("auto")
    assert engine == "sksundae" and re.search(r"ships SUNDIALS 7\.\d+\.\d+.*supports SUNDIALS 99\.x", reason)
    with pytest.raises(ImportError, match="engine 'compiled' is not available: .*SUNDIALS 99"):
        bb.simulate(ARTICLE, 2.0, 0.0, 1.0, engine="compiled")
    result = bb.simulate(ARTICLE, 2.0, 0.0, 1.0)
    assert result.stats.engine == "sksundae" and "SUNDIALS 99" in result.stats.engine_reason


def _run_python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=300)


def test_without_numba_auto_falls_back_and_compiled_is_refused():
    completed = _run_python("""
        import sys
        sys.modules["numba"] = None  # as if not installed
        import bouncingball as bb
        r = bb.simulate(bb.Ball(), 2.0, 0.0, 1.0)
        print(r.stats.engine, "|", r.stats.engine_reason)
        try:
            bb.simulate(bb.Ball(), 2.0, 0.0, 1.0, engine="compiled")
        except ImportError as error:
            print(error)
    """)
    assert completed.returncode == 0, completed.stderr
    lines = completed.stdout.splitlines()
    assert lines[0].startswith("sksundae | compiled engine unavailable: numba is not installed")
    from bouncingball.extras import install_command

    assert lines[0].endswith(install_command("fast")), lines[0]
    assert lines[1].startswith("engine 'compiled' is not available: numba is not installed")


@pytest.mark.slow
def test_a_numba_that_cannot_compile_falls_back_with_the_reason(tmp_path):
    (tmp_path / "numba").mkdir()
    (tmp_path / "numba" / "__init__.py").write_text("raise RuntimeError('LLVM is broken here')\n")
    completed = subprocess.run(
        [sys.executable, "-c", "import bouncingball as bb; r = bb.simulate(bb.Ball(b=0.0), 2.0, 0.0, 300.0); "
                               "print(r.stats.engine, '|', r.stats.engine_reason, '|', len(r.events))"],
        capture_output=True, text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(tmp_path)})
    assert completed.returncode == 0, completed.stderr
    engine, reason, events = completed.stdout.strip().split(" | ")
    assert engine == "sksundae" and "numba could not compile the engine (RuntimeError: LLVM is broken here)" in reason
    assert int(events) == len(bb.simulate(bb.Ball(b=0.0), 2.0, 0.0, 300.0, engine="sksundae").events)


def test_auto_weighs_the_compiled_engines_first_use_against_the_run():
    """In a fresh process a short run is cheaper on scikit-sundae than loading numba; a long one is not;
    once loaded, the compiled engine takes every run. The set-up time is reported apart."""
    completed = _run_python("""
        import sys
        import bouncingball as bb
        short = bb.simulate(bb.Ball(), 2.0, 0.0, 8.0)
        assert "numba" not in sys.modules
        long = bb.simulate(bb.Ball(b=0.0), 2.0, 0.0, 1000.0)  # after scikit-sundae is loaded: 37,000 steps to pay
        after = bb.simulate(bb.Ball(), 2.0, 0.0, 8.0)
        for r in (short, long, after):
            print(r.stats.engine, "|", r.stats.engine_reason, "|", r.stats.first_use_time, "|", r.stats.steps)
    """)
    assert completed.returncode == 0, completed.stderr
    (short, long, after) = [line.split(" | ") for line in completed.stdout.splitlines()]
    assert short[0] == "sksundae" and re.fullmatch(r"about \d+ CVODE steps expected, fewer than the \d+ over which "
                                                   r"loading the compiled engine in this process pays back", short[1])
    assert long[0] == "compiled" and after[0] == "compiled"
    assert float(short[2]) > 0.05 and float(long[2]) > 0.05 and float(after[2]) < 0.05  # loading, then pooled


@pytest.mark.parametrize("scene", ["article", "undamped", "stiff", "high-drop", "in-contact"])
def test_the_expected_steps_are_the_right_size(scene):
    """The estimate behind engine "auto" against the steps CVODE takes: within a factor 2."""
    from bouncingball.scenes import load_scene
    from bouncingball.solvers.cvode import expected_steps

    s = load_scene(scene)
    estimate = expected_steps(s.ball, s.h0, s.v0, 0.0, s.t_end)
    steps = s.simulate().stats.steps
    assert steps / 2 <= estimate <= 2 * steps, (estimate, steps)


def test_the_sksundae_engine_and_import_never_load_numba():
    completed = _run_python("""
        import sys
        import bouncingball as bb
        assert "numba" not in sys.modules
        bb.simulate(bb.Ball(), 2.0, 0.0, 1.0, engine="sksundae")
        assert "numba" not in sys.modules
    """)
    assert completed.returncode == 0, completed.stderr


@pytest.mark.slow
def test_many_solvers_created_run_and_freed_in_a_separate_process():
    """A wrong binding crashes the interpreter: so this one runs in its own process, scikit-sundae loaded first."""
    completed = _run_python("""
        import gc
        import sksundae.cvode  # the library scikit-sundae loaded is the one the engine binds
        import bouncingball as bb
        from bouncingball.solvers.cvode import BallIntegrator, CvodeSettings
        for i in range(100):
            integrator = BallIntegrator(bb.Ball(), 2.0, 0.0, settings=CvodeSettings(engine="compiled"))
            integrator.advance(0.7)
            if i % 2:
                for solver in integrator._solvers.values():
                    solver.close()  # freed now; the rest when collected
            del integrator
            gc.collect()
        r = bb.simulate(bb.Ball(), 2.0, 0.0, 8.0, engine="compiled")
        print(len(r.events), r.stats.steps)
    """)
    assert completed.returncode == 0, completed.stderr
    events, _ = completed.stdout.split()
    assert int(events) == len(bb.simulate(ARTICLE, 2.0, 0.0, 8.0, engine="sksundae").events)


# --- the binding against scikit-sundae's own declarations ------------------------------------------
def _pxd_declarations() -> dict[str, tuple[str, tuple[str, ...]]]:
    """name -> (return type, argument types) from the .pxd files scikit-sundae ships, typedefs resolved."""
    import sksundae

    folder = os.path.dirname(sksundae.__file__)
    text = ""
    for path in sorted(glob.glob(os.path.join(folder, "*.pxd")) + glob.glob(os.path.join(folder, "*.pxi"))):
        with open(path) as source:
            text += source.read() + "\n"
    text = re.sub(r"#.*", "", text)
    text = re.sub(r"\s+", " ", text)
    typedefs = {name: base for base, name in re.findall(r"ctypedef ([\w ]+?) (\w+)(?=[ ;\n]|$)", text)
                if base not in ("struct",)}
    declarations = {}
    for restype, name, arguments in re.findall(r"ctypedef (\w+) \(\*(\w+)\)\(([^()]*)\)", text):
        declarations[name] = (restype, tuple(re.sub(r"\s*\w+$", "", a.strip()) for a in arguments.split(",")))
    pattern = re.compile(r"(?:^|[ :])((?:const )?(?:long )?\w+\**) (\w+)\(([^()]*)\)")
    for restype, name, arguments in pattern.findall(text):
        if restype in ("ctypedef", "return", "cdef"):
            continue
        types = []
        for argument in arguments.split(","):
            argument = argument.strip().replace("const ", "")
            if not argument:
                continue
            match = re.fullmatch(r"([\w ]+?)\s*(\**)\s*(\w+)", argument)
            types.append(match.group(1) + match.group(2) if match else argument)
        declarations[name] = (restype.replace("const ", ""), tuple(types))
    return declarations, typedefs


def _c_type(name: str, typedefs: dict) -> str:
    """A C type reduced to what the ABI sees: a pointer, or a basic type with its typedefs resolved."""
    stars = len(name) - len(name.rstrip("*"))
    base = name.rstrip("*").strip()
    if stars or base in ("N_Vector", "SUNContext", "SUNMatrix", "SUNLinearSolver", "CVRhsFn", "CVRootFn",
                         "CVLsJacFn") or base.endswith("*"):
        return "pointer"
    while base in typedefs and typedefs[base] != base:
        base = typedefs[base]
    return base


def test_every_bound_function_matches_the_declaration_scikit_sundae_ships():
    declarations, typedefs = _pxd_declarations()
    assert typedefs.get("sunrealtype") == "double"
    unchecked = []
    for functions in sundials.FUNCTIONS.values():
        for name, (restype, argtypes) in functions.items():
            if name not in declarations:
                unchecked.append(name)
                continue
            declared_restype, declared_args = declarations[name]
            ours = [_c_type(t, typedefs) for t in (restype, *argtypes)]
            theirs = [_c_type(t, typedefs) for t in (declared_restype, *declared_args)]
            assert ours == theirs, name
    # not used by scikit-sundae, so not declared there: the version query SUNDIALS documents in sundials_version.h
    assert unchecked == ["SUNDIALSGetVersion"]


@pytest.mark.parametrize(("callback", "typedef"), [("_rhs", "CVRhsFn"), ("_roots", "CVRootFn"),
                                                 ("_jacobian", "CVLsJacFn")])
def test_the_compiled_callbacks_match_the_declared_callback_types(callback, typedef):
    declarations, typedefs = _pxd_declarations()
    restype, argtypes = declarations[typedef]
    signature = getattr(compiled, callback)._sig
    ours = [str(t) for t in (signature.return_type, *signature.args)]
    theirs = [_c_type(t, typedefs) for t in (restype, *argtypes)]
    assert ["double" if t == "float64" else "int" if t == "int32" else "pointer" for t in ours] == theirs


def test_the_index_type_scikit_sundae_was_built_with_is_the_one_we_pass():
    """sunindextype is set when SUNDIALS is built: 32 bits in this wheel; the engine passes a C int."""
    _, typedefs = _pxd_declarations()
    assert typedefs["sunindextype"] == "int"
    assert sundials._CTYPES["sunindextype"] is __import__("ctypes").c_int


def test_phases_longer_than_the_step_buffer_are_complete(monkeypatch):
    from bouncingball.solvers import integrator

    monkeypatch.setattr(integrator, "_SCRATCH_ROWS", 7)  # the article's phases take up to ~100 steps
    assert_engines_agree(*run_both(ARTICLE, 2.0, 0.0, 8.0, 1e-3))


@pytest.mark.parametrize("engine", ["compiled", "sksundae"])
def test_the_cli_runs_either_engine_and_says_which(engine, capsys):
    from bouncingball.cli import main

    assert main(["run", "article", "--t-end", "2", "--engine", engine]) == 0
    text = capsys.readouterr().out
    assert f"  engine      {engine} (requested)" in text and "engine " + engine in text


def test_a_host_exporting_its_own_sundials_symbols_does_not_capture_the_engine(tmp_path):
    """A host whose global scope has a SUNContext_Create of its own (another SUNDIALS): ours is still called."""
    import shutil

    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler")
    source = tmp_path / "host.c"
    source.write_text("int SUNContext_Create(int comm, void **ctx) { *ctx = 0; return -99; }\n")
    host = tmp_path / "libhost.so"
    subprocess.run([compiler, "-shared", "-fPIC", "-o", str(host), str(source)], check=True)
    completed = _run_python(f"""
        import ctypes
        ctypes.CDLL({str(host)!r}, mode=ctypes.RTLD_GLOBAL)  # the host's symbols come first in the global scope
        import bouncingball as bb
        r = bb.simulate(bb.Ball(), 2.0, 0.0, 8.0, engine="compiled")
        print(len(r.events), r.stats.steps)
    """)
    assert completed.returncode == 0, completed.stderr
    reference = bb.simulate(ARTICLE, 2.0, 0.0, 8.0, engine="sksundae")
    assert completed.stdout.split() == [str(len(reference.events)), str(reference.stats.steps)]


@pytest.mark.skipif(not os.path.exists("/proc/self/statm"), reason="reads the resident size from /proc")
@pytest.mark.slow
def test_solvers_free_their_sundials_memory():
    """3000 solvers created, run and dropped (half closed explicitly): ~50 MB would stay resident if none were freed."""
    completed = _run_python("""
        import gc, os
        import numpy as np
        import bouncingball as bb
        from bouncingball.physics import Mode
        from bouncingball.solvers.engines import compiled
        from bouncingball.solvers.engines.compiled import PhaseSolver

        def resident():
            with open("/proc/self/statm") as statm:
                return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

        def cycle(i):
            solver = PhaseSolver(bb.Ball(), Mode.FLIGHT, "Adams", 1e-11, 0.0, 1000, 1e-300, [-1, 0, 1], 10**6)
            engine, scratch = np.stack([solver.handle()] * 2), np.zeros((1, 3))
            assert compiled._engine_start(engine, 0, np.inf, 2.0 - 0.06, 0.0, 1.0, 1.0, 0.0, 9.81, 0.0) == 0  # the gap
            while (flag := compiled._engine_steps(engine, 0, scratch, 1.0, True)[0]) == 0:
                pass
            assert flag == 2 and abs(scratch[0, 0] - (2.0 - 0.06) ** 0.5 * (2 / 9.81) ** 0.5) < 1e-9
            if i % 2:
                solver.close()

        for i in range(200):
            cycle(i)
        gc.collect()
        before = resident()
        for i in range(3000):
            cycle(i)
        gc.collect()
        print(resident() - before)
    """)
    assert completed.returncode == 0, completed.stderr
    assert int(completed.stdout) < 5e6


# A run of the copied package's compiled engine that says which of its compiled code numba read from its disk cache:
# run_phases (the phase machine, which inlines phases.py's, physics.py's and the others' functions) and the
# right-hand side callback (compiled.py's, which inlines physics.py's equations).
_CACHE_REPORT = textwrap.dedent("""
    import json
    import bouncingball as bb
    from bouncingball.solvers.engines import compiled
    result = bb.simulate(bb.Ball(), 2.0, 0.0, 1.0, 1e-3, engine="compiled")
    machine = compiled.run_phases.stats
    print(json.dumps({"machine_hits": sum(machine.cache_hits.values()), "rhs_hits": compiled._rhs.cache_hits,
                      "machine_misses": sum(machine.cache_misses.values()), "impact": result.events[0].time}))
""")


def _compiled_run_of_a_copy(package: Path) -> dict:
    import json

    completed = subprocess.run([sys.executable, "-c", _CACHE_REPORT], cwd=package.parent, capture_output=True,
                               text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(package.parent),
                                                                    "NUMBA_CACHE_DIR": str(package.parent / "cache")})
    assert completed.returncode == 0, completed.stderr
    report = {**json.loads(completed.stdout), "stderr": completed.stderr}
    # whatever numba compiled or read, the engine answers: the first impact of a drop from 2 m at rest
    assert report["impact"] == pytest.approx(math.sqrt(2.0 * (2.0 - ARTICLE.R) / ARTICLE.g), abs=1e-10)
    return report


@pytest.fixture(scope="module")
def compiled_copy(tmp_path_factory) -> Path:
    """A copy of the package beside its own numba cache (folder cache), compiled and cached once by a first run, then
    read from the cache by a second: the first two stages of the test below, which each of its cases starts from."""
    import shutil

    package = tmp_path_factory.mktemp("compiled-copy") / "bouncingball"
    shutil.copytree(Path(bb.__file__).parent, package, ignore=shutil.ignore_patterns("__pycache__"))
    first = _compiled_run_of_a_copy(package)  # compiles and caches
    assert first["machine_misses"] > 0 and first["machine_hits"] == 0 and first["rhs_hits"] == 0
    # said on stderr before it compiled (the Python API's say), not again once cached
    assert first["stderr"].startswith("bouncingball: numba compiles the compiled engine for this host, once (about "
                                      "a minute; no code compiled from these sources yet), into "), first["stderr"]
    again = _compiled_run_of_a_copy(package)
    assert again["machine_hits"] > 0 and again["machine_misses"] == 0 and again["rhs_hits"] == 1  # the cache works
    assert again["stderr"] == ""
    return package


# Each case compiles the whole engine (100 to 140 s loaded): the case of the bug (a source the callbacks inline) in
# the default run, the machine's own source a study.
@pytest.mark.slow
@pytest.mark.parametrize(("source", "callbacks_too"),
                         [("physics.py", True),
                          pytest.param("solvers/phase_machine/machine.py", False, marks=pytest.mark.study)])
def test_a_change_to_a_compiled_source_recompiles_the_code_numbas_disk_cache_held(compiled_copy, tmp_path, source,
                                                                                  callbacks_too):
    """numba keys each cached function by its own file, but the compiled code inlines functions of other files: after
    a change to physics.py alone it loaded compiled.py's old callbacks (the engines then disagreed). A change made by
    appending a function no one calls (so that it does not depend on the source's text) must be compiled anew, in
    the callbacks and the phase machine alike, where an unchanged source is read from the cache (compiled_copy)."""
    import shutil

    shutil.copytree(compiled_copy.parent, tmp_path, dirs_exist_ok=True)  # the copy and its cache, moved elsewhere
    package = tmp_path / "bouncingball"
    unchanged = _compiled_run_of_a_copy(package)  # the cache is named after the sources, wherever they are
    assert unchanged["machine_misses"] == 0 and unchanged["stderr"] == ""
    changed = package / source
    with changed.open("a") as file:
        file.write("\n\ndef _appended_by_a_test(x):\n    return 2.0 * x\n")
    after = _compiled_run_of_a_copy(package)
    assert after["machine_misses"] > 0 and after["machine_hits"] == 0 and "numba compiles" in after["stderr"]
    if callbacks_too:  # the right-hand side inlines physics.py's equations, not the machine
        assert after["rhs_hits"] == 0
    assert after["impact"] == unchanged["impact"]  # the change is harmless: the code compiled anew is the same


@pytest.mark.slow
def test_many_short_runs_load_the_compiled_engine_once_they_would_have_paid_for_it():
    completed = _run_python("""
        import bouncingball as bb
        from bouncingball.solvers import engine_selection as rule
        runs = [bb.simulate(bb.Ball(), 2.0, 0.0, 8.0)]
        break_even = rule.compiled_break_even()  # scikit-sundae loaded by the first run, the compiled engine not
        runs += [bb.simulate(bb.Ball(), 2.0, 0.0, 8.0) for _ in range(29)]
        engines = [run.stats.engine for run in runs]
        first = engines.index("compiled")
        print(first, engines[first:].count("sksundae"), rule._sksundae_steps, int(break_even), runs[0].stats.steps,
              int(rule.expected_steps(bb.Ball(), 2.0, 0.0, 0.0, 8.0)))
    """)
    assert completed.returncode == 0, completed.stderr
    first, later_sksundae, sksundae_steps, break_even, steps, expected = map(int, completed.stdout.split())
    assert later_sksundae == 0  # once loaded, always
    assert sksundae_steps == first * steps  # each run on scikit-sundae counted its steps
    # the switch comes on the first run whose expected steps reach the break-even with those already run
    assert sksundae_steps + expected >= break_even > sksundae_steps - steps + expected


def test_the_compiled_decisions_and_flows_are_the_interpreted_ones_to_the_bit():
    """One source, two runs: numba rounded `rise ** 2` otherwise than Python at times (a contact's scale an ulp
    off, and CVODE took another step), so the compiled copies must give the interpreted numbers exactly."""
    import random

    from bouncingball import contact_laws, equations
    from bouncingball.solvers.phase_machine import phases

    generator = random.Random(3)
    scales, flow = compiled._compiled[phases.phase_scales], compiled._compiled[equations.gap_flow_value]
    for _ in range(3000):
        m, k = 10.0 ** generator.uniform(-3, 3), 10.0 ** generator.uniform(0, 8)
        ball = contact_laws.BallParameters(
            m, k, 2.0 * math.sqrt(k * m) * generator.uniform(0.0, 3.0), 10.0 ** generator.uniform(-3, 0), 9.81,
            float(generator.choice((contact_laws.LINEAR, contact_laws.RIGID))), 0.7, 0.0, 1.5, 0.0)
        load = m * 9.81 * generator.uniform(-0.5, 1.5)
        x, v, tau = generator.uniform(-1e-2, 2.0), generator.uniform(-10.0, 10.0), 10.0 ** generator.uniform(-6, 0)
        for mode in (0, 1):
            assert scales(ball, mode, x, v, load) == phases.phase_scales(ball, mode, x, v, load)
            assert flow(mode, x, v, tau, load, m, k, ball.b) == equations.gap_flow_value(mode, x, v, tau, load, m, k,
                                                                                        ball.b)


def test_both_engines_report_a_failed_phase_alike(monkeypatch):
    """A phase past its step cap keeps none of its steps and is reported at its start, whichever engine ran it
    (the compiled engine had counted the failed flight's steps and named the time it stopped at)."""
    from bouncingball.solvers import integrator

    monkeypatch.setattr(integrator, "MAX_STEPS_PER_PHASE", 150)  # root evaluations, a few per step
    outcomes = []
    for engine in ("sksundae", "compiled"):
        # a contact from R at -1 m/s (about 30 steps of 1 ms), then a flight of 0.18 s that needs 180
        ball_integrator = BallIntegrator(ARTICLE, 0.06, -1.0, settings=CvodeSettings(max_step=1e-3, engine=engine))
        with pytest.raises(integrator.SolverError, match="took more than 150 steps in one flight phase") as failure:
            ball_integrator.integrate_grid(np.linspace(0.0, 1.0, 101))
        outcomes.append((str(failure.value), ball_integrator.steps, ball_integrator.t))
    assert outcomes[0] == outcomes[1] and 0 < outcomes[0][1] < 150 and outcomes[0][2] > 0.0


def test_numbas_private_api_that_jit_uses_is_still_there(tmp_path):
    """jit's one block of numba's private API (its cache's locator classes, _CacheLocator, the index files' format, the
    host's key): this fails on an upgrade that changes it, instead of the compiled engine silently compiling afresh in
    every process."""
    import numba
    from numba.core.caching import CacheImpl

    from bouncingball.solvers.engines import jit

    # compiled.py's import put it before numba's own (each copy of the package in the process, an FMU's, puts its own)
    assert CacheImpl._locator_classes.index(jit._digest_locator()) < CacheImpl._locator_classes.index(
        numba.core.caching.InTreeCacheLocator)
    folder = jit.cache_folder(jit.sources_digest(jit.engine_sources()))
    assert compiled.run_phases.stats.cache_path == folder
    triple, cpu, features = jit._host_key()
    assert triple.startswith("x86_64") and cpu and features.startswith(("+", "-"))
    bb.simulate(bb.Ball(), 2.0, 0.0, 0.1, 1e-3, engine="compiled")  # run_phases compiled or read, so indexed
    [index] = Path(folder).glob("drivers.run_phases-*.nbi")
    version, stamp, keys = jit._index(str(index))
    assert (version, stamp) == (numba.__version__, jit.sources_digest(jit.engine_sources()))
    assert (triple, cpu, features) in [key[1] for key in keys]
    assert jit.cache_misfit(folder, stamp) is None
    assert str(index) in jit._indexes(folder)  # numba's name for this Python's index
    # an index _copy_cache writes is one numba reads
    from numba.core.caching import IndexDataCacheFile

    copied = tmp_path / "copied"
    copied.mkdir()
    jit._copy_cache(folder, str(copied))
    reader = IndexDataCacheFile(str(copied), index.name.removesuffix(".nbi"), stamp)
    assert keys and all(reader.load(key) is not None for key in keys)


def test_a_cache_compiled_elsewhere_is_named_for_what_does_not_fit(tmp_path):
    """The code in a cache folder runs here only if numba, the sources and the CPU are this host's: a cache that
    differs in one says which (what the FMU logs before numba compiles)."""
    from bouncingball.solvers.engines import jit

    digest = jit.sources_digest(jit.engine_sources())
    host = jit._host_key()
    assert jit.cache_misfit(str(tmp_path), digest) == "no code compiled from these sources yet"
    index = tmp_path / f"drivers.run_phases-1{_python_tag()}.nbi"
    for version, stamp, key, why in [
            ("0.1.0", digest, host, "its code was compiled by numba 0.1.0, this is numba "),
            (jit.numba.__version__, "other", host, "its code was compiled from other sources"),
            (jit.numba.__version__, digest, (host[0], "a486", host[2]), "its code was compiled for the CPU a486 ("),
            (jit.numba.__version__, digest, ("aarch64-unknown-linux-gnu", "generic", ""),
             "its code was compiled for the CPU generic (aarch64-unknown-linux-gnu), this is ")]:
        _write_index(index, version, stamp, {((), key, ("", "")): "x.1.nbc"})
        assert jit.cache_misfit(str(tmp_path), digest).startswith(why)
        assert jit.cache_misfit(str(tmp_path), digest, portable=True).startswith(why)
    index.rename(tmp_path / "drivers.run_phases-1.py29.nbi")  # another Python's: numba would not read it here
    python = _python_tag()[1:]
    assert jit.cache_misfit(str(tmp_path), digest) == f"its code was compiled for Python py29, this is {python}"


def _python_tag() -> str:
    return f".py{sys.version_info[0]}{sys.version_info[1]}{sys.abiflags}"


def _write_index(path, version, stamp, overloads) -> None:
    """An index file as numba writes one: its version pickled, then the stamp and the overloads."""
    import pickle

    with open(path, "wb") as file:
        pickle.dump(version, file)
        file.write(pickle.dumps((stamp, overloads)))


def test_code_compiled_for_the_generic_cpu_is_shipped_code_that_fits_and_is_filed_under_this_cpu(tmp_path):
    """A shipped cache compiled for numba's generic CPU of this architecture fits any CPU of it: as shipped it fits
    (not in the user-wide cache, where numba would not find it), and the copy into the user-wide cache files each
    overload under this host's CPU, data files copied byte for byte."""
    from bouncingball.solvers.engines import jit

    digest = jit.sources_digest(jit.engine_sources())
    host = jit._host_key()
    generic = (host[0], "generic", "")
    shipped, folder = tmp_path / "shipped", tmp_path / "user"
    shipped.mkdir()
    folder.mkdir()
    overloads = {(("float64",), generic, ("a", "b")): "m.f-1.py.1.nbc",
                 (("int64",), host, ("a", "b")): "m.f-1.py.2.nbc"}
    _write_index(shipped / f"m.f-1{_python_tag()}.nbi", jit.numba.__version__, digest, overloads)
    for data in overloads.values():
        (shipped / data).write_bytes(data.encode() * 3)
    assert jit.cache_misfit(str(shipped), digest, portable=True) is None
    assert jit.cache_misfit(str(shipped), digest) is None  # one overload is this host's own
    _write_index(shipped / f"m.f-1{_python_tag()}.nbi", jit.numba.__version__, digest,
                 {key: data for key, data in overloads.items() if key[1] == generic})
    assert jit.cache_misfit(str(shipped), digest).startswith("its code was compiled for the CPU generic (")
    assert jit.cache_misfit(str(shipped), digest, portable=True) is None
    _write_index(shipped / f"m.f-1{_python_tag()}.nbi", jit.numba.__version__, digest, overloads)

    jit._copy_cache(str(shipped), str(folder))
    version, stamp, copied = jit._index(str(folder / f"m.f-1{_python_tag()}.nbi"))
    assert (version, stamp) == (jit.numba.__version__, digest)
    assert copied == {(("float64",), host, ("a", "b")): "m.f-1.py.1.nbc",
                      (("int64",), host, ("a", "b")): "m.f-1.py.2.nbc"}
    for data in overloads.values():
        assert (folder / data).read_bytes() == data.encode() * 3
    assert sorted(path.name for path in folder.iterdir()) == sorted([*overloads.values(), f"m.f-1{_python_tag()}.nbi"])
    assert jit.cache_misfit(str(folder), digest) is None


def test_the_cache_is_taken_whole_under_a_lock_by_processes_importing_at_once(tmp_path):
    """Four processes find the cache folder empty at once (Dask's workers importing) and a shipped cache that fits:
    each takes the lock in turn, one copies the shipped code in, and none compiles, announces a compile, leaks a file
    handle (-X dev makes that a ResourceWarning, here an error) or leaves a temporary file."""
    from bouncingball.solvers.engines import jit

    bb.simulate(bb.Ball(), 2.0, 0.0, 0.1, 1e-3, engine="compiled")  # the user-wide cache holds this run's code
    shipped = Path(jit.cache_folder(jit.sources_digest(jit.engine_sources())))
    code = textwrap.dedent(f"""
        import bouncingball as bb
        from bouncingball.solvers.engines import jit
        with jit.first_use({str(shipped)!r}, lambda message: print("said", message)):
            result = bb.simulate(bb.Ball(), 2.0, 0.0, 0.1, 1e-3, engine="compiled")
        from bouncingball.solvers.engines import compiled
        print(sum(compiled.run_phases.stats.cache_misses.values()), compiled._rhs.cache_hits)
    """)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    processes = [subprocess.Popen([sys.executable, "-X", "dev", "-W", "error::ResourceWarning", "-c", code], env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(4)]
    outputs = [process.communicate(timeout=300) for process in processes]
    assert [out.strip() for out, _ in outputs] == ["0 1"] * 4, [err for _, err in outputs]
    [folder] = (tmp_path / "bouncingball").iterdir()
    assert folder.name == shipped.name
    assert sorted(path.name for path in folder.iterdir()) == sorted(["lock", *(path.name for path in
                                                                               shipped.glob("*.nb[ci]"))])


@pytest.mark.slow  # numba compiles the engine in the child (about a minute)
def test_a_cache_folder_that_cannot_be_used_is_said_before_numba_compiles_in_the_process(tmp_path):
    """A user-wide cache that cannot be written (here under a file): the engine still runs, compiled in the process,
    and stderr says so once, naming the folder, before numba starts."""
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    code = ("import bouncingball as bb\n"
            "r = bb.simulate(bb.Ball(), 2.0, 0.0, 1.0, 1e-3, engine='compiled')\n"
            "print(r.stats.engine, r.h[-1])\n")
    completed = subprocess.run([sys.executable, "-c", code], env={**os.environ, "NUMBA_CACHE_DIR": str(blocker)},
                               capture_output=True, text=True, timeout=300, check=False)
    assert completed.returncode == 0, completed.stderr
    engine, h = completed.stdout.split()
    exact = bb.simulate(bb.Ball(), 2.0, 0.0, 1.0, 1e-3, solver="exact")
    assert engine == "compiled" and abs(float(h) - exact.h[-1]) < 1e-8
    [line] = completed.stderr.splitlines()
    assert line.startswith("bouncingball: numba compiles the compiled engine in this process (about a minute), and "
                           f"cannot keep it: its cache folder {blocker}/bouncingball/numba-")


def test_an_index_that_cannot_be_read_is_a_misfit_the_shipped_cache_replaces(tmp_path):
    """A truncated index in the user-wide cache (a full disk, a killed copy) is named as a misfit, not an error that
    leaves numba compiling in every process: a shipped cache that fits is copied over it."""
    from bouncingball.solvers.engines import jit

    digest = jit.sources_digest(jit.engine_sources())
    index = tmp_path / f"m.f-1{_python_tag()}.nbi"
    index.write_bytes(b"\x80\x04\x95")
    assert jit.cache_misfit(str(tmp_path), digest) == f"its index {index.name} cannot be read (UnpicklingError)"
