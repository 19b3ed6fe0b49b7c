"""What the Python that runs the FMU must have, checked by the FMU's loader before pythonfmu runs.

pythonfmu, given a Python without scikit-sundae, fails deep inside fmi2Instantiate with
``[FATAL] Fatal py exception encountered: [ctor] findClass ... ModuleNotFoundError`` (fmi2Fatal),
which some masters show only at debug level. The loader (bouncingball_fmu_loader.c) therefore
runs ``check_source()`` first, in the interpreter it is about to hand to pythonfmu (the host's
own in a Python master, the one it started in a C master): if that Python cannot import numpy,
or has no scikit-sundae, at the versions this package requires, fmi2Instantiate logs the one line
``host_problem`` returns, through the master's logger with status fmi2Error, and returns NULL
before pythonfmu sees the call.

The loader compiles the source in (the build passes it as BB_HOST_CHECK): ``host_problem`` must
be self-contained, its imports inside it.
"""

from __future__ import annotations

import inspect

# (module the FMU imports, distribution that provides it, minimum version, first version not allowed):
# pyproject.toml's [project] dependencies (tests/test_fmu.py keeps the two equal).
REQUIREMENTS = (
    ("numpy", "numpy", "1.24", None),
    ("sksundae", "scikit-sundae", "1.2", "2"),
)
# The Python hosts an FMU built with CPython 3.11.7 was run in (FMPy 0.3.32's simulate, then `bouncingball
# check` of its result: PASS in each): docs/fmu.md gives the commands. A master without Python was run
# with the build's own Python only.
TESTED_PYTHON_HOSTS = ("3.11.7", "3.12.1", "3.13.0")


def host_problem(requirements) -> str:
    """One line saying what this Python lacks to run the FMU and the pip install that fixes it; "" if nothing.

    requirements are (module, distribution, minimum, first version not allowed or None), as REQUIREMENTS.
    Each module is imported (numpy), or found where its import is left to its first use (scikit-sundae), and
    its distribution's version checked.
    """
    import importlib
    import importlib.util
    import os
    import sys
    from importlib import metadata

    # Found, not imported: scikit-sundae's import takes ~0.4 s (it loads SciPy), and the compiled engine needs only
    # its libraries; its engine imports it where it runs (solvers/engines/sundials.py: sksundae_cvode_class).
    located_only = {"sksundae"}

    def release(text):
        return tuple(int("".join(c for c in part if c.isdigit()) or 0) for part in text.split(".")[:3])

    def specifier(minimum, below):
        return f">={minimum}" + (f",<{below}" if below else "")

    missing, fixes = [], []
    for module, distribution, minimum, below in requirements:
        wanted = f"{distribution}{specifier(minimum, below)}"
        try:
            if module in located_only:
                if importlib.util.find_spec(module) is None:
                    raise ModuleNotFoundError(f"No module named {module!r}")
            else:
                importlib.import_module(module)
        except BaseException as error:  # noqa: B036  (anything the import raises means it cannot run)
            text = " ".join(f"{type(error).__name__}: {error}".split())
            missing.append(f"no {distribution} ({text})" if isinstance(error, ModuleNotFoundError)
                           else f"a {distribution} that cannot be imported ({text})")
            fixes.append(wanted)
            continue
        try:
            version = metadata.version(distribution)
        except Exception:  # no metadata (a vendored copy): the import is all that can be checked
            continue
        if release(version) < release(minimum) or (below and release(version) >= release(below)):
            missing.append(f"{distribution} {version} (it needs {specifier(minimum, below)})")
            fixes.append(wanted)
    if not missing:
        return ""
    executable = sys.executable or "(sys.executable is empty)"
    python = f"{executable} (Python {'.'.join(map(str, sys.version_info[:3]))})"
    packages = " ".join(f"'{wanted}'" for wanted in fixes)
    if os.path.basename(sys.executable).startswith("python"):
        fix = f"{sys.executable} -m pip install {packages}"
    else:
        fix = f"pip install {packages} into the Python environment at {sys.prefix}"
    return (f"BouncingBall cannot run in the Python of this process, {python}: it has {' and '.join(missing)}; "
            f"fix: {fix}")


def check_source(requirements=REQUIREMENTS) -> str:
    """The Python code the loader runs in a namespace of its own: it leaves host_problem's answer in ``problem``."""
    return (inspect.getsource(host_problem) + "\n"
            "try:\n"
            f"    problem = host_problem({requirements!r})\n"
            "except BaseException as error:\n"
            "    problem = 'BouncingBall could not check the Python of this process: ' + "
            "' '.join(repr(error).split())\n"
            "del host_problem\n")
