"""bouncingball's build backend: setuptools', and a wheel that carries its compiled engine's code compiled ahead.

numba would compile the compiled engine at its first use after install (about a minute). A wheel's build
compiles it once for any CPU of the build host's architecture and puts numba's cache files in the
package (bouncingball/solvers/engines/ahead_of_time.py), so a first use reads them in well under a second.
That needs the engine's own requirements in the build environment, which get_requires_for_build_wheel
adds (the project's dependencies and its [fast] extra, read from pyproject.toml). An editable install
and an sdist compile nothing. BOUNCINGBALL_SHIP_NUMBA_CACHE=0 builds a wheel without it (its engine
then compiles at first use, and says so).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tomllib

from setuptools import build_meta
from setuptools.build_meta import *  # noqa: F403  (every hook as setuptools has it, but the two below)
from setuptools.command.build_py import build_py


def _ships_cache() -> bool:
    return os.environ.get("BOUNCINGBALL_SHIP_NUMBA_CACHE", "1") != "0"


def get_requires_for_build_wheel(config_settings=None):
    """setuptools' requirements, and where the wheel ships the compiled engine's code, those of the engine."""
    requires = build_meta.get_requires_for_build_wheel(config_settings)
    if _ships_cache():
        with open("pyproject.toml", "rb") as file:
            project = tomllib.load(file)["project"]
        requires += [*project["dependencies"], *project["optional-dependencies"]["fast"]]
    return requires


class BuildPy(build_py):
    """setuptools' build_py, then, for a wheel, the compiled engine of the package just built compiled into it."""

    def run(self):
        """Build the package, then compile its engine into it (not for an editable install).

        The package built is put first on the path the build environment already has (pip's isolated
        environment reaches its child processes through PYTHONPATH), and writes no bytecode into the
        wheel. A compile that fails leaves a wheel without the cache, said on stderr.
        """
        super().run()
        if self.editable_mode:
            return
        from_earlier_build = os.path.join(self.build_lib, "bouncingball", "numba-cache")  # engine_cache.SHIPPED
        shutil.rmtree(from_earlier_build, ignore_errors=True)  # a kept build folder's: not this build's code
        if not _ships_cache():
            return
        path = os.pathsep.join(filter(None, (os.path.abspath(self.build_lib), os.environ.get("PYTHONPATH"))))
        environment = {**os.environ, "PYTHONPATH": path, "PYTHONDONTWRITEBYTECODE": "1"}
        completed = subprocess.run([sys.executable, "-m", "bouncingball.solvers.engines.ahead_of_time"],
                                   env=environment, check=False)
        if completed.returncode != 0:
            print("bouncingball: the wheel ships no cache of its compiled engine (its compile exited with status "
                  f"{completed.returncode}): it compiles at its first use where it runs", file=sys.stderr)
