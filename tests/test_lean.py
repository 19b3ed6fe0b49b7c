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
