"""The FMU's parameter engine: the compiled CVODE engine gives scikit-sundae's answer; where it cannot run, it says why.

Every run loads the FMU in its own Python process (a crash fails that test, and numba can be hidden
from it); the process saves its outputs, and the checks here compare them with the exact solution
and with the other engine.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from bouncingball.physics import Ball
from fmu_helpers import exact_at
from oracle_counts import oracle_counts

pytestmark = pytest.mark.slow  # each test runs the FMU's compiled engine in a fresh process: numba compiles it there

pytest.importorskip("fmpy", reason="the FMU tests need the [fmu] extra")
pytest.importorskip("pythonfmu", reason="the FMU tests need the [fmu] extra")

TESTS = Path(__file__).parent
SAME_ANSWER = 1e-12  # m: the two engines drive the same CVODE library through the same steps
EXACT = 1e-8  # m: the FMU against the exact solution at TIGHT tolerances (measured 4.9e-10 on the article)


def run_python(body: str, *arguments, env: dict | None = None) -> None:
    """Run body in a fresh Python (sys.argv[1:] = arguments; fmu_helpers importable); it must print ok last."""
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(TESTS)!r})
        import numpy as np
        import fmpy
        from fmpy import simulate_fmu
        from fmu_helpers import TIGHT, Instance

        def save_runs(runs, path):  # read back by load_runs
            np.savez(path, **{{f"{{engine}}_{{name}}": run[name] for engine, run in runs.items()
                               for name in ("time", "h", "impacts")}})
    """) + textwrap.dedent(body) + "\nprint('ok')\n"
    completed = subprocess.run([sys.executable, "-c", code, *map(str, arguments)], capture_output=True, text=True,
                               timeout=300, check=False, env={**os.environ, **(env or {})})
    assert (completed.returncode, completed.stdout.strip().splitlines()[-1:]) == (0, ["ok"]), (
        completed.stdout + completed.stderr)


@pytest.fixture()
def numba_hidden(tmp_path) -> dict:
    """An environment whose Python cannot import numba (a package of that name that raises ImportError)."""
    shadow = tmp_path / "shadow" / "numba"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text('raise ImportError("numba is hidden from this process")\n')
    return {"PYTHONPATH": os.pathsep.join(filter(None, [str(shadow.parent), os.environ.get("PYTHONPATH")]))}


def assert_engines_agree(runs) -> None:
    sksundae, compiled = runs["sksundae"], runs["compiled"]
    np.testing.assert_array_equal(compiled["time"], sksundae["time"])
    np.testing.assert_array_equal(compiled["impacts"], sksundae["impacts"])
    assert np.max(np.abs(compiled["h"] - sksundae["h"])) <= SAME_ANSWER


def load_runs(path):
    """The runs a child saved with save_runs: {engine: {"time", "h", "impacts"}}."""
    saved = np.load(path)
    return {engine: {name: saved[f"{engine}_{name}"] for name in ("time", "h", "impacts")}
            for engine in ("sksundae", "compiled")}


# --- the compiled engine gives the same answer -------------------------------------------------------
def test_compiled_engine_gives_the_sksundae_answer_on_the_article_at_1ms(fmu, tmp_path):
    """Both engines in one process, scikit-sundae's first: the compiled engine's modules are then imported
    from the second run's unzipped copy, after FMPy deleted the first's."""
    pytest.importorskip("numba", reason="the compiled engine needs numba")
    run_python("""
        runs = {engine: simulate_fmu(sys.argv[1], stop_time=8.0, output_interval=1e-3, output=["h", "impacts"],
                                     start_values={**TIGHT, "engine": engine}) for engine in ("sksundae", "compiled")}
        save_runs(runs, sys.argv[2])
    """, fmu, tmp_path / "runs.npz")
    runs = load_runs(tmp_path / "runs.npz")
    assert_engines_agree(runs)
    t = runs["compiled"]["time"]
    assert len(t) == 8001 and t[-1] == 8.0
    h, _, impacts = exact_at(t)
    assert np.max(np.abs(runs["compiled"]["h"] - h)) < EXACT
    np.testing.assert_array_equal(runs["compiled"]["impacts"], impacts)
    assert impacts[-1] == oracle_counts(Ball()).impacts


def test_compiled_engine_with_F_ext_as_input(fmu, tmp_path):
    """F_ext = m g until t = 1 s (h = 2 + t), then 0: free flight from (3 m, 1 m/s), with bounces."""
    pytest.importorskip("numba", reason="the compiled engine needs numba")
    ball = Ball(m=2.0)
    run_python("""
        weight = float(sys.argv[3])
        signal = np.array([(0.0, weight), (1.0, weight), (1.0, 0.0), (4.0, 0.0)],
                          dtype=[("time", np.float64), ("F_ext", np.float64)])
        runs = {engine: simulate_fmu(sys.argv[1], stop_time=4.0, output_interval=1e-3, input=signal,
                                     output=["h", "impacts"],
                                     start_values={**TIGHT, "m": 2.0, "h": 2.0, "v": 1.0, "engine": engine})
                for engine in ("compiled", "sksundae")}
        save_runs(runs, sys.argv[2])
    """, fmu, tmp_path / "runs.npz", ball.m * ball.g)
    runs = load_runs(tmp_path / "runs.npz")
    assert_engines_agree(runs)
    t, h = runs["compiled"]["time"], runs["compiled"]["h"]
    before = t <= 1.0
    np.testing.assert_allclose(h[before], 2.0 + t[before], rtol=0, atol=1e-12)
    h_exact, _, impacts = exact_at(t[~before], ball, h0=3.0, v0=1.0, t_start=1.0)
    assert np.max(np.abs(h[~before] - h_exact)) < EXACT
    np.testing.assert_array_equal(runs["compiled"]["impacts"][~before], impacts)
    assert impacts[-1] == oracle_counts(ball, h0=3.0, v0=1.0, t_start=1.0, t_end=4.0).impacts >= 2


def test_compiled_engine_resumes_from_an_fmu_state(unzipped, tmp_path):
    """A state taken at 1.3 s, then a detour (F_ext = 50 N to 2 s), then the state restored, in the same
    instance and (serialized) in a fresh one: both continue as the uninterrupted run does."""
    pytest.importorskip("numba", reason="the compiled engine needs numba")
    run_python("""
        def outputs(rows):
            return np.array([(row[0], row[1], row[3], row[5]) for row in rows])  # h, v, contact, impacts

        straight = Instance(sys.argv[1], "straight")
        straight.initialize(engine="compiled", **TIGHT)
        # the same communication points as the resumed runs (from 1.3 s on, 1.3 + i dt)
        uninterrupted = np.concatenate((outputs(straight.step_to(1.3, 1e-3)), outputs(straight.step_to(3.0, 1e-3))))

        ball = Instance(sys.argv[1], "ball")
        ball.initialize(engine="compiled", **TIGHT)
        ball.step_to(1.3, 1e-3)
        state = ball.fmu.getFMUstate()
        serialized = ball.fmu.serializeFMUstate(state)
        ball.set(F_ext=50.0)
        ball.step_to(2.0, 1e-3)
        ball.fmu.setFMUstate(state)
        ball.fmu.freeFMUstate(state)
        ball.t = 1.3
        resumed = outputs(ball.step_to(3.0, 1e-3))

        fresh = Instance(sys.argv[1], "fresh")  # never initialised: its engine comes with the state
        state = fresh.fmu.deSerializeFMUstate(serialized)
        fresh.fmu.setFMUstate(state)
        fresh.fmu.freeFMUstate(state)
        assert fresh.get("engine", "F_ext") == ["compiled", 0.0]
        fresh.t = 1.3
        deserialized = outputs(fresh.step_to(3.0, 1e-3))
        for instance in (straight, ball, fresh):
            assert instance.errors() == [], instance.errors()
            instance.free()
        np.savez(sys.argv[2], uninterrupted=uninterrupted, resumed=resumed, deserialized=deserialized)
    """, unzipped, tmp_path / "runs.npz")
    saved = np.load(tmp_path / "runs.npz")
    uninterrupted = saved["uninterrupted"]
    t = np.arange(1, 3001) * 1e-3
    h, _, impacts = exact_at(t)
    assert np.max(np.abs(uninterrupted[:, 0] - h)) < EXACT
    np.testing.assert_array_equal(uninterrupted[:, 3], impacts)
    tail = uninterrupted[1300:]
    assert tail[-1, 3] == impacts[-1] > impacts[1299]  # the resumed part holds impacts
    for name in ("resumed", "deserialized"):
        run = saved[name]
        # the restored state integrates again from its restart point: the same run bit for bit
        np.testing.assert_array_equal(run, tail)


# --- where the compiled engine cannot run ----------------------------------------------------------------
def test_compiled_engine_without_numba_gives_fmi2Error_with_the_reason(unzipped_numba_cache, numba_hidden):
    """An FMU without the native engine (numba's cache instead): the instance stays usable: with engine sksundae the
    same instance then initialises and runs."""
    run_python("""
        ball = Instance(sys.argv[1])
        ball.set(engine="compiled")
        ball.fmu.setupExperiment(startTime=0.0)
        ball.fmu.enterInitializationMode()
        try:
            ball.fmu.exitInitializationMode()
        except fmpy.fmi1.FMICallException as error:
            assert error.status == 3, error.status  # fmi2Error, not fmi2Fatal
        else:
            raise AssertionError("engine compiled was accepted without numba")
        [message] = ball.errors()
        assert message.startswith("engine 'compiled' is not available: numba is not installed"), message
        assert "numba is hidden from this process" in message, message
        assert message.endswith(": pip install numba, into the Python that runs the FMU"), message  # not [fast]
        ball.set(engine="sksundae")
        ball.fmu.exitInitializationMode()
        print(*ball.step_to(1.0, 0.5)[-1])
        assert ball.errors() == [message]
        ball.free()
    """, unzipped_numba_cache, env=numba_hidden)


def test_auto_engine_without_numba_runs_on_sksundae(unzipped_numba_cache, numba_hidden, tmp_path):
    """An FMU without the native engine (numba's cache instead): auto runs scikit-sundae's, and says why."""
    run_python("""
        ball = Instance(sys.argv[1])
        ball.fmu.setDebugLogging(True, [])  # messages of status OK are logged only then
        ball.initialize(engine="auto", **TIGHT)
        rows = ball.step_to(2.0, 1e-3)
        [(status, message)] = ball.log  # said once, with status OK: not a warning that stops a strict master
        assert status == 0 and message.startswith("engine auto runs scikit-sundae's: compiled engine unavailable: "
                                                   "numba is not installed"), ball.log
        assert not [name for name in sys.modules if name.endswith(".solvers.engines.compiled")]
        ball.free()
        np.save(sys.argv[2], np.array([(row[0], row[5]) for row in rows]))
    """, unzipped_numba_cache, tmp_path / "run.npy", env=numba_hidden)
    run = np.load(tmp_path / "run.npy")
    h, _, impacts = exact_at(np.arange(1, 2001) * 1e-3)
    assert np.max(np.abs(run[:, 0] - h)) < EXACT
    np.testing.assert_array_equal(run[:, 1], impacts)


# --- the first use of the compiled engine: numba's cache shipped in an FMU without the native engine --------------
# A first 1 s run of the FMU just unzipped, in a fresh process and a user-wide cache of its own: what numba read from
# its cache and compiled (every compiled function of the FMU's copy of the package), and the FMU's log in order.
_FIRST_RUN = """
    import json, sys
    from fmpy import extract, simulate_fmu
    log = []
    def logger(*arguments):
        log.append(arguments[-1].decode("utf-8"))
    result = simulate_fmu(extract(sys.argv[1], sys.argv[2]), stop_time=1.0, output_interval=1e-3, logger=logger,
                          debug_logging=True)  # messages of status OK are logged only then
    [compiled] = [module for name, module in sys.modules.items() if name.endswith(".solvers.engines.compiled")]
    dispatchers = [value for value in vars(compiled).values() if hasattr(value, "stats")]
    dispatchers += list(compiled._compiled.values())
    print(json.dumps({"log": log, "h": float(result["h"][-1]),
                      "hits": sum(sum(d.stats.cache_hits.values()) for d in dispatchers) + compiled._rhs.cache_hits,
                      "misses": sum(sum(d.stats.cache_misses.values()) for d in dispatchers)}))
"""


def _first_run(fmu: Path, folder: Path, cache: Path) -> dict:
    import json

    completed = subprocess.run([sys.executable, "-c", textwrap.dedent(_FIRST_RUN), str(fmu), str(folder)],
                               capture_output=True, text=True, timeout=300, check=False,
                               env={**os.environ, "NUMBA_CACHE_DIR": str(cache)})
    assert completed.returncode == 0, completed.stderr
    report = json.loads(completed.stdout.splitlines()[-1])
    h, _, _ = exact_at(np.array([1.0]))
    assert abs(report["h"] - h[0]) < 1e-6  # whichever way the engine came, it answers (the FMU's rtol)
    return report


def test_the_fmus_first_use_of_the_compiled_engine_reads_the_cache_it_ships(fmu_numba_cache, tmp_path):
    """A fresh unzip in a fresh process on a host with no cache: engine auto runs the compiled engine, every function
    read from the FMU's own cache, none compiled, nothing said."""
    report = _first_run(fmu_numba_cache, tmp_path / "unzipped", tmp_path / "cache")
    assert report["misses"] == 0 and report["hits"] > 0, report
    assert report["log"] == [], report["log"]


def test_the_fmu_ships_code_compiled_for_any_cpu_of_its_architecture(fmu_numba_cache, tmp_path, monkeypatch):
    """Every overload in the FMU's cache was compiled for numba's generic CPU (no instruction this host has and
    another CPU of its architecture may lack), for this numba and from the FMU's own sources."""
    import zipfile

    pytest.importorskip("numba")
    from bouncingball.solvers.engines import jit

    with zipfile.ZipFile(fmu_numba_cache) as archive:
        archive.extractall(tmp_path, [name for name in archive.namelist() if name.startswith("resources/")])
        names = [name for name in archive.namelist() if name.startswith("resources/numba-cache/")]
    # the overloads' signatures name the FMU's copy of the package (its BallParameters): importable, as in the FMU
    monkeypatch.syspath_prepend(str(tmp_path / "resources"))
    indexes = sorted((tmp_path / "resources" / "numba-cache").glob("*.nbi"))
    assert len(indexes) > 10 and len(names) > 2 * len(indexes) - 1
    host = jit._host_key()
    for index in indexes:
        version, _, overloads = jit._index(str(index))
        assert version == jit.numba.__version__
        assert {key[1] for key in overloads} == {(host[0], "generic", "")}, index.name


def test_a_shipped_cache_that_does_not_fit_is_compiled_once_and_said_first(fmu_numba_cache, tmp_path):
    """The FMU's cache compiled by another numba (its index files' version changed): numba compiles, said in the
    FMU's log as its first message; the code is then kept in the user-wide cache, which the next process reads."""
    import pickle
    import zipfile

    changed = tmp_path / "other_numba.fmu"
    with zipfile.ZipFile(fmu_numba_cache) as source, zipfile.ZipFile(changed, "w") as target:
        indexes = 0
        for info in source.infolist():
            data = source.read(info)
            if info.filename.endswith(".nbi"):
                version = pickle.loads(data)
                data = pickle.dumps("0.1.0") + data[len(pickle.dumps(version)):]
                indexes += 1
            target.writestr(info, data)
    assert indexes > 10
    first = _first_run(changed, tmp_path / "first", tmp_path / "cache")
    assert first["misses"] > 0, first
    assert len(first["log"]) == 1 and first["log"][0].startswith(
        "numba compiles the compiled engine for this host, once (about a minute; the cache shipped with it does not "
        "fit (its code was compiled by numba 0.1.0, this is numba "), first["log"]
    again = _first_run(changed, tmp_path / "again", tmp_path / "cache")
    assert again["misses"] == 0 and again["hits"] > 0 and again["log"] == [], again


_SECOND_INSTANCE = """
    import json, sys
    from fmpy import simulate_fmu
    logs = []
    def logger(*arguments):
        logs[-1].append(arguments[-1].decode("utf-8"))
    for engine in ("sksundae", "compiled"):  # simulate_fmu unzips the FMU afresh each time, and deletes it after
        logs.append([])
        result = simulate_fmu(sys.argv[1], stop_time=1.0, output_interval=1e-3, logger=logger, debug_logging=True,
                              start_values={"engine": engine})
    [compiled] = [module for name, module in sys.modules.items() if name.endswith(".solvers.engines.compiled")]
    dispatchers = [value for value in vars(compiled).values() if hasattr(value, "stats")]
    dispatchers += list(compiled._compiled.values())
    print(json.dumps({"logs": logs, "h": float(result["h"][-1]),
                      "misses": sum(sum(d.stats.cache_misses.values()) for d in dispatchers)}))
"""


def test_a_second_instance_whose_first_unzip_is_deleted_reads_the_shipped_cache(fmu_numba_cache, tmp_path):
    """A first instance on the scikit-sundae engine imports the package's copy from its unzipped folder, which FMPy
    deletes after the run; the second, on the compiled engine, imports the engine from its own unzip: it reads the
    engine's sources there, so numba's cache is used (it compiled for 16 s, in every such process, keeping nothing)."""
    import json

    completed = subprocess.run([sys.executable, "-c", textwrap.dedent(_SECOND_INSTANCE), str(fmu_numba_cache)],
                               capture_output=True, text=True, timeout=300, check=False,
                               env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")})
    assert completed.returncode == 0, completed.stderr
    report = json.loads(completed.stdout.splitlines()[-1])
    h, _, _ = exact_at(np.array([1.0]))
    assert abs(report["h"] - h[0]) < 1e-6
    assert report["misses"] == 0 and report["logs"] == [[], []], report
