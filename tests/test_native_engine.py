"""The FMU's native engine (solvers/engines/native.py): the compiled engine's code run without numba.

It must give numba's compiled engine's numbers to the bit (the same code, compiled once), load only what it needs
(no numba, no scikit-sundae, no SciPy in an FMU's process), refuse a library it cannot trust, and turn code that
raised into an error, never a number. Each run is a fresh Python process (a crash fails that test only; numba is
either never imported or the one engine there).
"""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba", reason="the native engine is built from numba's compile")
pytest.importorskip("fmpy", reason="the FMU tests need the [fmu] extra")
pytest.importorskip("pythonfmu", reason="the FMU tests need the [fmu] extra")

TESTS = Path(__file__).parent
SOURCES = TESTS.parent / "src" / "bouncingball"
LIBRARY = "bouncingball_engine.so"

# Every law, a still ground and a vibrating table (its steps run in Python, the machine's calls native), the FMU's
# two ways of advancing (stopping at each event or not): 2000 steps of 1 ms from 2 m (the table: from 10 cm).
_RUNS = """
import importlib, sys
import numpy as np
package, out = sys.argv[1], sys.argv[2]
if len(sys.argv) > 3:
    sys.path.insert(0, sys.argv[3])
    native = importlib.import_module(package + ".solvers.engines.native")
    assert native.activate(sys.argv[3] + "/" + sys.argv[4]) is None
bouncingball = importlib.import_module(package)
cvode = importlib.import_module(package + ".solvers.cvode")
Ground = importlib.import_module(package + ".ground").Ground
scenes = [({}, 2.0, None), ({"contact": "rigid", "e": 0.5}, 2.0, None),
          ({"contact": "linear-no-pull", "b": 200.0}, 2.0, None),
          ({"contact": "hunt-crossley", "k": 3e6, "n": 1.5, "alpha": 0.3}, 2.0, None),
          ({"contact": "rigid", "e": 0.5}, 0.1, Ground.sine(1e-3, 10.0, 0.0)),
          ({"k": 1e5, "b": 20.0}, 0.1, Ground.sine(1e-3, 10.0, 0.0))]
rows = []
for parameters, h0, ground in scenes:
    for stop_at_event in (False, True):
        integrator = cvode.BallIntegrator(bouncingball.Ball(**parameters), h0, 0.0, 0.0, 0.0,
                                          cvode.CvodeSettings(engine="compiled"), ground=ground)
        assert integrator.engine == "compiled"
        for i in range(1, 2001):
            t = i * 1e-3
            events = [] if integrator.advance_within_step(t) else integrator.advance(t, stop_at_event=stop_at_event)
            rows.append((integrator.t, integrator.h, integrator.v, integrator.error_estimate_at_t,
                         integrator.impacts, len(events)))
np.save(out, np.array(rows))
print(sorted(name for name in sys.modules if name.split(".")[0] in ("numba", "sksundae", "scipy")))
"""


def _python(code: str, *arguments) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *map(str, arguments)], capture_output=True, text=True,
                          timeout=600, check=False)


def _fmu_package(unzipped: Path) -> str:
    """The name of the FMU's copy of the package."""
    return next(path.name for path in (unzipped / "resources").iterdir()
                if path.is_dir() and path.name.startswith("bouncingball_fmu_"))


def test_the_fmu_ships_the_native_engine_and_not_numba_s_cache(fmu):
    import zipfile

    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
    assert f"resources/{LIBRARY}" in names
    assert not [name for name in names if "numba-cache" in name]


def test_every_law_and_a_vibrating_table_step_as_numba_s_compiled_engine_to_the_bit(unzipped, tmp_path):
    resources = unzipped / "resources"
    native = _python(_RUNS, _fmu_package(unzipped), tmp_path / "native.npy", resources, LIBRARY)
    assert native.returncode == 0, native.stderr
    assert native.stdout.strip().splitlines()[-1] == "[]"  # no numba, no scikit-sundae, no SciPy
    numba = _python(_RUNS, "bouncingball", tmp_path / "numba.npy")
    assert numba.returncode == 0, numba.stderr
    ran, expected = np.load(tmp_path / "native.npy"), np.load(tmp_path / "numba.npy")
    assert ran.shape == expected.shape == (6 * 2 * 2000, 6)
    assert expected[:, 4].max() > 10 and expected[:, 5].sum() > 50  # bounces, and events told
    assert np.array_equal(ran, expected, equal_nan=True)


def test_an_fmu_run_imports_neither_numba_nor_scikit_sundae_and_is_right(fmu):
    """FMPy runs the FMU in its own process: the compiled engine runs (native), and that process never imports
    numba, scikit-sundae, or SciPy's optimize and sparse (scikit-sundae's import: ~0.4 s)."""
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(TESTS)!r})
        from fmpy import simulate_fmu
        from fmu_helpers import exact_at
        logs = []
        result = simulate_fmu({str(fmu)!r}, stop_time=2.0, output_interval=1e-3, output=["h"],
                              logger=lambda *a: logs.append(a[-1].decode()), debug_logging=True)
        error = max(abs(result["h"] - exact_at(result["time"])[0]))
        print(error)
        print(sorted(name for name in sys.modules if name.split(".")[0] in ("numba", "sksundae")
                     or name.startswith(("scipy.optimize", "scipy.sparse"))))
    """)
    completed = _python(code)
    assert completed.returncode == 0, completed.stderr
    error, modules = completed.stdout.strip().splitlines()[-2:]
    assert modules == "[]"
    assert float(error) < 1e-8


def test_a_library_of_other_sources_or_none_is_refused_and_said(unzipped, tmp_path):
    """A library whose sources' digest is not the package's (an edited copy), and a file that is no library: each
    refused with the reason (the slave then logs it and runs numba's compiled engine)."""
    library = (unzipped / "resources" / LIBRARY).read_bytes()
    digest = re.search(rb"[0-9a-f]{64}", library).group()
    (tmp_path / "other.so").write_bytes(library.replace(digest, digest[::-1]))
    (tmp_path / "none.so").write_bytes(b"not a library")
    code = textwrap.dedent("""
        import importlib, sys
        sys.path.insert(0, sys.argv[2])
        native = importlib.import_module(sys.argv[1] + ".solvers.engines.native")
        print(native.activate(sys.argv[3]))
        print(native.activate(sys.argv[4]))
        print(native.active())
    """)
    completed = _python(code, _fmu_package(unzipped), unzipped / "resources", tmp_path / "other.so",
                        tmp_path / "none.so")
    assert completed.returncode == 0, completed.stderr
    other, none, active = completed.stdout.strip().splitlines()
    assert other == f"the native engine {tmp_path / 'other.so'} was compiled from other sources than this package's"
    assert none.startswith(f"the native engine {tmp_path / 'none.so'} does not load here: ")
    assert active == "None"


def test_an_fmu_whose_library_is_refused_says_why_once_and_runs_another_engine(fmu, tmp_path):
    """The FMU's library replaced by one of other sources, numba hidden: the FMU's log says why the native engine is
    not used, and auto runs scikit-sundae's engine (saying why), right."""
    import os
    import zipfile

    changed = tmp_path / "other_library.fmu"
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(changed, "w") as target:
        for info in source.infolist():
            data = source.read(info)
            if info.filename == f"resources/{LIBRARY}":
                digest = re.search(rb"[0-9a-f]{64}", data).group()
                data = data.replace(digest, digest[::-1])
            target.writestr(info, data)
    shadow = tmp_path / "shadow" / "numba"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text('raise ImportError("numba is hidden from this process")\n')
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(TESTS)!r})
        from fmpy import simulate_fmu
        from fmu_helpers import exact_at
        logs = []
        result = simulate_fmu({str(changed)!r}, stop_time=1.0, output_interval=1e-3, output=["h"], debug_logging=True,
                              logger=lambda *a: logs.append(a[-1].decode()))
        print(max(abs(result["h"] - exact_at(result["time"])[0])))
        print(repr(logs))
    """)
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                               check=False, env={**os.environ, "PYTHONPATH": os.pathsep.join(
                                   filter(None, [str(shadow.parent), os.environ.get("PYTHONPATH")]))})
    assert completed.returncode == 0, completed.stderr
    error, logs = completed.stdout.strip().splitlines()[-2:]
    logs = eval(logs)
    refusals = [line for line in logs if line.startswith("the FMU's native engine is not used: ")]
    assert len(refusals) == 1 and refusals[0].endswith("was compiled from other sources than this package's"), logs
    assert any(line.startswith("engine auto runs scikit-sundae's: compiled engine unavailable: numba is not "
                               "installed") for line in logs), logs
    assert float(error) < 1e-8


def test_code_that_raised_in_the_library_is_an_error_not_a_number(unzipped):
    """A zero mass in the parameters (refused long before, in the package): numba's code raises ZeroDivisionError;
    in the library the entry point returns 0 and the engine raises NativeEngineError, the process alive."""
    code = textwrap.dedent("""
        import importlib, sys
        import numpy as np
        sys.path.insert(0, sys.argv[2])
        native = importlib.import_module(sys.argv[1] + ".solvers.engines.native")
        assert native.activate(sys.argv[2] + "/" + sys.argv[3]) is None
        cvode = importlib.import_module(sys.argv[1] + ".solvers.cvode")
        bouncingball = importlib.import_module(sys.argv[1])
        settings = cvode.CvodeSettings(engine="compiled")
        integrator = cvode.BallIntegrator(bouncingball.Ball(), 2.0, 0.0, 0.0, 0.0, settings)
        integrator.advance(0.01)
        engine = native.active()
        values = engine.parameters(integrator.ball.parameters)
        values[0] = 0.0  # m
        try:
            engine.phase_ends(values, 1e-6, 1e-6, integrator._machine_state, 0.0, 1.0)
        except native.NativeEngineError as error:
            print("raised:", error)
        else:
            print("returned")
    """)
    completed = _python(code, _fmu_package(unzipped), unzipped / "resources", LIBRARY)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.strip().startswith("raised: the native engine's phase_ends raised in its compiled code")


def test_the_runtime_lays_out_numba_s_meminfo_as_this_numba_does():
    """native_runtime.c stands in for numba's runtime: numba's compiled code reads an array's MemInfo header by its
    fields' places (refct, dtor, dtor_info, data, size), as numba's own runtime lays it out."""
    from numba.core.runtime import nrtdynmod

    assert str(nrtdynmod._meminfo_struct_type) == "{i64, i8*, i8*, i8*, i64}"
    runtime = (SOURCES / "solvers" / "engines" / "native_runtime.c").read_text()
    header = re.search(r"typedef struct \{(.*?)\} MemInfo;", runtime, re.S).group(1)
    assert [line.split()[-1].strip("*;") for line in header.strip().splitlines()][:5] == [
        "refct", "dtor", "dtor_info", "data", "size"]


def test_side_extreme_is_numpy_s_least_or_largest_nan_included():
    """contact_laws.dispatch.side_extreme is written as a loop (numba's min and max need a helper the library lacks):
    it must give what numpy's give, a NaN step end included."""
    from bouncingball import Ball
    from bouncingball.codes import CONTACT, FLIGHT
    from bouncingball.contact_laws import dispatch

    rng = np.random.default_rng(7)
    x, v = rng.normal(size=9) * 1e-3, rng.normal(size=9)
    no_pull = Ball(contact="linear-no-pull", b=200.0).parameters
    linear = Ball().parameters
    assert dispatch.side_extreme(linear, FLIGHT, x, v) == np.min(x)
    assert dispatch.side_extreme(linear, CONTACT, x, v) == np.max(x)
    assert dispatch.side_extreme(no_pull, CONTACT, x, v) == np.max(x + (no_pull.b / no_pull.k) * v)
    x[4] = np.nan
    for parameters, mode in ((linear, FLIGHT), (linear, CONTACT), (no_pull, CONTACT)):
        assert np.isnan(dispatch.side_extreme(parameters, mode, x, v))


@pytest.mark.slow  # a whole compile of the engine (about 50 s)
def test_a_library_that_cannot_be_linked_leaves_numba_s_cache_and_the_build_says_why(tmp_path, capsys):
    """A C compiler that fails: the compile's folder holds numba's cache files and no library (so the FMU ships the
    cache, shipped_files), and stderr says why and what the FMU then runs."""
    from bouncingball.fmu import engine_cache
    from bouncingball.solvers.engines import ahead_of_time

    cache = ahead_of_time.compile_portable(SOURCES, tmp_path, "the FMU", ["false"])
    assert cache is not None and not (cache / LIBRARY).exists()
    shipped = engine_cache.shipped_files(cache)
    assert len(shipped) > 20 and all(name.startswith("resources/numba-cache/") for _, name in shipped)
    assert capsys.readouterr().err == (
        "bouncingball: the FMU ships no native engine, which could not be built here (RuntimeError: linking the native "
        "engine with false failed: exit status 1): it runs numba's compiled engine, which adds about 0.7 s to its "
        "start\n")
