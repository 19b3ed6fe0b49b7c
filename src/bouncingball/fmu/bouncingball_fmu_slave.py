"""BouncingBall: the slave script pythonfmu packs into the FMU; the slave itself is bouncingball.fmu.slave.

pythonfmu 0.7 executes this script anew for every fmi2Instantiate and keeps alive whatever class
it defines there (~45 kB per instance for the whole slave class). So the script stays small: it
binds scikit-sundae to its own SUNDIALS, then names the slave class of a module imported once per
process. tests/test_fmu_state_machine.py measures what an instance still costs.

The FMU carries its own copy of bouncingball under a name of its own (PACKAGE, set by the build to
bouncingball_fmu_<digest of its sources>), so that it neither replaces nor uses a bouncingball the
host process imports, and two different builds in one process do not meet.

The FMI 3.0 FMU is built from this script too: its build makes the import below pythonfmu3's
Fmi3Slave, the class line's base Fmi3Slave, and SLAVE_MODULE slave3 (bouncingball.fmu.build).
"""

import importlib
import os
import sys

from pythonfmu import Fmi2Slave

PACKAGE = "bouncingball"
SLAVE_MODULE = "slave"


def _import_sundials_for_this_fmu():
    """Import scikit-sundae so that its SUNDIALS calls bind to its own SUNDIALS libraries.

    A host that carries another SUNDIALS (a C master linked to a system SUNDIALS 6) would
    otherwise capture scikit-sundae's calls into its own, different library and crash. Where
    scikit-sundae is already loaded (a Python host imported it), it is used as it is.
    """
    deep_bind = getattr(os, "RTLD_DEEPBIND", 0)
    flags = sys.getdlopenflags()
    if deep_bind and "sksundae" not in sys.modules:
        import numpy  # noqa: F401  (numpy resolves as usual; only SUNDIALS is bound deep)

        sys.setdlopenflags(flags | deep_bind)
    try:
        importlib.import_module("sksundae.cvode")
    finally:
        sys.setdlopenflags(flags)


_import_sundials_for_this_fmu()


class BouncingBall(Fmi2Slave):  # pythonfmu finds the slave's name on this line; the class is the one below
    pass


_slave = importlib.import_module(f"{PACKAGE}.fmu.{SLAVE_MODULE}")
BouncingBall = _slave.BouncingBall  # noqa: F811
# pythonfmu 0.7 uses this script's namespace after the script has run but keeps no reference to it:
# once Python collects it, the next fmi2Instantiate crashes (the 3rd or 4th in a row). Keep it.
_slave.SCRIPT_NAMESPACES.append(globals())
