import os
from pathlib import Path

import pytest
from hypothesis import settings

# CI replays the same examples every run, so that a red run is reproducible; locally hypothesis explores.
settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(scope="session")
def fmu(tmp_path_factory) -> Path:
    """The FMU, built once per session through `bouncingball build-fmu -o`."""
    from bouncingball.cli import main

    path = tmp_path_factory.mktemp("fmu") / "BouncingBall.fmu"
    assert main(["build-fmu", "-o", str(path)]) == 0
    return path


@pytest.fixture(scope="session")
def unzipped(fmu, tmp_path_factory) -> Path:
    """The FMU extracted once per session, for FMU2Slave and the C master."""
    from fmpy import extract

    return Path(extract(str(fmu), str(tmp_path_factory.mktemp("unzipped"))))
