"""BouncingBall: the slave script pythonfmu packs into the FMU; the slave itself is bouncingball.fmu.slave.

pythonfmu 0.7 executes this script anew for every fmi2Instantiate and keeps alive whatever class
it defines there (~45 kB per instance for the whole slave class). So the script stays small: it
names the slave class of a module imported once per process. tests/test_fmu_state_machine.py measures what an
instance still costs. Where the FMU ships its native engine (solvers/engines/native.py), scikit-sundae is imported
only where its own engine runs (solvers/engines/sundials.py, sksundae_cvode_class): its import takes ~0.4 s. Where
it does not, numba's compiled engine runs, and scikit-sundae is imported here, as it was before the native engine.

The FMU carries its own copy of bouncingball under a name of its own (PACKAGE, set by the build to
bouncingball_fmu_<digest of its sources>), so that it neither replaces nor uses a bouncingball the
host process imports, and two different builds in one process do not meet.

The FMI 3.0 FMU is built from this script too: its build makes the import below pythonfmu3's
Fmi3Slave, the class line's base Fmi3Slave, and SLAVE_MODULE slave3 (bouncingball.fmu.build).
"""

import importlib
import os

from pythonfmu import Fmi2Slave

PACKAGE = "bouncingball"
SLAVE_MODULE = "slave"


class BouncingBall(Fmi2Slave):  # pythonfmu finds the slave's name on this line; the class is the one below
    pass


if importlib.import_module(f"{PACKAGE}.fmu.engine_cache").native_library(os.path.dirname(__file__)) is None:
    importlib.import_module(f"{PACKAGE}.solvers.engines.sundials").sksundae_cvode_class()
_slave = importlib.import_module(f"{PACKAGE}.fmu.{SLAVE_MODULE}")
BouncingBall = _slave.BouncingBall  # noqa: F811
# pythonfmu 0.7 releases a reference to this script's namespace it never took, at each fmi2Instantiate: give it back.
importlib.import_module(f"{PACKAGE}.fmu.pythonfmu_workarounds").keep_script_namespace(globals(), locals())
