"""Each use pays only for what it needs: plotting, FMU, FMPy and the SciPy peer are imported only where used.

scikit-sundae itself imports scipy.sparse and scipy.optimize when its CVODE module loads (scipy is
one of its own requirements), so a CVODE run may load exactly those modules and no other.
"""

import subprocess
import sys

HEAVY = ("scipy", "matplotlib", "fmpy", "pythonfmu")


def _modules_after(code: str) -> list[str]:
    script = (
        "import sys\n"
        f"{code}\n"
        f"print(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r} + ('sksundae',)))\n"
    )
    completed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    return eval(completed.stdout.strip().splitlines()[-1])


def test_import_is_lean():
    assert _modules_after("import bouncingball; import bouncingball.scenes") == []


def test_cvode_run_loads_nothing_beyond_scikit_sundae():
    baseline = set(_modules_after("import sksundae.cvode"))
    run = _modules_after(
        "import bouncingball\n"
        "r = bouncingball.simulate(bouncingball.Ball(), 2.0, 0.0, 1.0)\n"
        "assert len(r.events) == 2"
    )
    assert set(run) - baseline == set()
    assert not [m for m in run if m.split(".")[0] in ("matplotlib", "fmpy", "pythonfmu")]


def test_exact_run_and_cli_without_plot_load_no_extra():
    baseline = set(_modules_after("import sksundae.cvode"))
    modules = _modules_after(
        "from bouncingball.cli import main\n"
        "assert main(['run', 'article', '--t-end', '1', '--solver', 'exact']) == 0"
    )
    assert modules == []
    modules = _modules_after("from bouncingball.cli import main\nassert main(['run', 'article', '--t-end', '1']) == 0")
    assert set(modules) - baseline == set()


def test_an_fmu_on_the_compiled_engine_loads_no_scikit_sundae_nor_what_it_loads():
    """The FMU's start-up pays for the SUNDIALS libraries only: scikit-sundae's import (~0.4 s, SciPy's optimize and
    sparse with it) is left to its own engine's first use."""
    import importlib.util

    import pytest

    if importlib.util.find_spec("numba") is None:
        pytest.skip("the compiled engine needs numba")
    modules = _modules_after(  # what the loader runs first (the host check), then pythonfmu (the slave script)
        "from bouncingball.fmu.host_check import check_source\n"
        "namespace = {}\nexec(check_source(), namespace)\nassert namespace['problem'] == ''\n"
        "import bouncingball.fmu.bouncingball_fmu_slave as script\n"
        "slave = script.BouncingBall(instance_name='ball', resources=None)\n"
        "slave.setup_experiment(0.0); slave.enter_initialization_mode(); slave.exit_initialization_mode()\n"
        "assert slave._integrator.engine == 'compiled' and slave.do_step(0.0, 1e-3)"
    )
    assert modules and [m for m in modules if m.split(".")[0] == "sksundae" or
                        m.startswith(("scipy.optimize", "scipy.sparse"))] == []
