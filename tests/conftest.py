import os
from pathlib import Path

import pytest
from hypothesis import settings

# Every run replays the same examples, so that a red run is reproducible anywhere (CI included).
# BOUNCINGBALL_HYPOTHESIS=explore draws new ones each run, to look for more.
settings.register_profile("replay", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("BOUNCINGBALL_HYPOTHESIS", "replay"))

# The modules that take a minute or more (builds, compiles, mpmath truths), run first: pytest-xdist hands each module
# to one worker in this order (--no-loadscope-reorder), so no worker starts one of them while the others are done.
LONG_MODULES = ("test_hunt_crossley.py", "test_bench.py", "test_wheel.py", "test_compiled.py", "test_fmu_masters.py",
                "test_fmu_engine.py", "test_examples.py", "test_sweep.py")


def pytest_collection_modifyitems(config, items):
    def rank(item):
        name = item.path.name
        return LONG_MODULES.index(name) if name in LONG_MODULES else len(LONG_MODULES)

    items.sort(key=rank)  # stable: each module's own order kept


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
