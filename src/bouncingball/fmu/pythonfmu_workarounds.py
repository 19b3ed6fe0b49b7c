"""Two bugs of pythonfmu 0.7 (and pythonfmu3 0.3, the second) that corrupt the heap, and their workarounds.

1. At every fmi2Instantiate, pythonfmu 0.7's findClass imports the slave script's module, runs the script again
   with the module's namespace as globals and a fresh dict as locals, then calls Py_DECREF on the namespace, which
   it had only borrowed (PyModule_GetDict). Each instance takes one reference that the namespace's holders still
   count on; uncompensated, the namespace is freed while the module uses it (the 3rd or 4th fmi2Instantiate in a
   row crashed). ``keep_script_namespace``, run by the script, gives that reference back, once per such run. A run
   as a module (the import, and pythonfmu3, which only imports the script) has its globals as its locals: nothing
   is taken from it, and nothing is given. The reference is taken, not held in a list: a list gives back all it
   holds when it is freed, as the module holding it is at the interpreter's exit. An earlier workaround kept the
   namespaces in a list: at exit the namespace was freed after the list's second release while the list and the
   module still pointed at it, and now and then a process that had made two instances or more crashed at its exit
   ("corrupted double-linked list").
2. pythonfmu's binary releases its Python state twice when the process exits with the binary loaded (its static
   shared_ptr's destructor, then its own destructor function calls finalizePythonInterpreter), which corrupts the
   heap about one exit in four. Released once before, the second release does nothing. Our FMU's C loader does it
   for every host (fmu/bouncingball_fmu_python.h: Python's exit handlers do not run in a C master, which never
   finalizes the Python it starts); ``release_python_state_first`` does it in a Python host for an FMU that is
   pythonfmu's binary alone (the bench's empty slaves).

This module imports only the standard library: the bench's empty slaves carry its source (bench/runners.py).
tests/test_pythonfmu_workarounds.py counts the namespace's references against its holders after several instances:
the bug in a plain pythonfmu slave, none of it in ours or in the bench's empty slave.
"""

import atexit
import ctypes
import glob
import os


def keep_script_namespace(namespace: dict, local_namespace: dict) -> None:
    """Give back the reference pythonfmu takes from namespace (the script's globals()) when it runs the script with
    local_namespace (its locals()) a dict of its own; nothing where the script runs as a module."""
    if local_namespace is not namespace:
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(namespace))


_RELEASED: set[str] = set()


def release_python_state_first(resources: str) -> None:
    """Have Python's exit call finalizePythonInterpreter of each pythonfmu binary of the FMU whose resources folder
    is resources (once per binary), before the C library's exit releases the state twice."""
    for path in glob.glob(os.path.join(os.path.dirname(os.path.abspath(resources)), "binaries", "*", "*.so")):
        try:
            release = getattr(ctypes.CDLL(path), "finalizePythonInterpreter", None)
        except OSError:  # another platform's binary
            continue
        if release is not None and path not in _RELEASED:
            _RELEASED.add(path)
            atexit.register(release)
