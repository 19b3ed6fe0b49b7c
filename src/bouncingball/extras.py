"""The command that installs an optional extra, as this bouncingball was installed: every message's install hint.

bouncingball is not on a package index: `pip install 'bouncingball[plot]'` works only where it was
installed from one. The command is made from how pip installed it (its direct_url.json, PEP 610):
from a checkout, editable or not, the checkout's folder with the extra; from a wheel, the wheel;
from an index, the name. Where that source is gone, the extra's own requirements. Standard library
only: the FMU's copy of the package imports it too.
"""

from __future__ import annotations

import json
import re
import shlex
import sys
from importlib import metadata
from pathlib import Path
from urllib.parse import unquote, urlparse

DISTRIBUTION = "bouncingball"
# The extras of pyproject.toml's [project.optional-dependencies] that a user installs (tests/test_extras.py
# holds this to pyproject.toml).
EXTRAS = ("plot", "reference", "fmu", "fast", "bench", "sweep", "all")
_CHECKOUT = Path(__file__).resolve().parents[2]  # src/bouncingball/extras.py -> the checkout, if it is one
_EXTRA_MARKER = re.compile(r"""^(?P<requirement>[^;]+?)\s*;\s*extra\s*==\s*["'](?P<extra>[^"']+)["']\s*$""")


def install_command(*extras: str) -> str:
    """The command that installs extras (names of EXTRAS) into the Python running this, as printed in messages.

    Parameters
    ----------
    *extras : str
        The extras, for example "plot".

    Returns
    -------
    str
        `<python> -m pip install ...`: with -e and the checkout's folder for an editable install (or a
        source tree not installed), the folder or wheel it was installed from, the name where it came
        from an index, or else the extras' requirements themselves.

    Raises
    ------
    ValueError
        An extra that is not one of EXTRAS.
    """
    unknown = [extra for extra in extras if extra not in EXTRAS]
    if unknown or not extras:
        raise ValueError(f"extra = {unknown[0] if unknown else ''!r} is not allowed: it must be one of "
                         f"{', '.join(EXTRAS)}")
    pip = f"{shlex.quote(sys.executable)} -m pip install"
    source, editable = _installed_from()
    if source is not None:
        target = f"{source}[{','.join(extras)}]"
        return f"{pip}{' -e' if editable else ''} {shlex.quote(target)}"
    requirements = _requirements(extras)
    return f"{pip} {' '.join(shlex.quote(requirement) for requirement in requirements)}"


def _installed_from() -> tuple[str | None, bool]:
    """(What to pip install, with the extras appended, editable or not); (None, False) if nothing is left of it."""
    try:
        distribution = metadata.distribution(DISTRIBUTION)
    except metadata.PackageNotFoundError:  # run from a source tree on sys.path, not installed
        return (str(_CHECKOUT), True) if _is_checkout(_CHECKOUT) else (None, False)
    text = distribution.read_text("direct_url.json")
    if text is None:  # from an index
        return DISTRIBUTION, False
    try:
        direct = json.loads(text)
        url = urlparse(direct["url"])
    except (ValueError, KeyError, TypeError):
        return None, False
    if url.scheme != "file":
        return None, False
    path = Path(unquote(url.path))
    if not path.exists():
        return None, False
    return str(path), bool(direct.get("dir_info", {}).get("editable", False))


def _is_checkout(folder: Path) -> bool:
    pyproject = folder / "pyproject.toml"
    return pyproject.is_file() and re.search(r'(?m)^name = "bouncingball"$', pyproject.read_text("utf-8")) is not None


def _requirements(extras, seen: set | None = None) -> list[str]:
    """The requirements the extras add, from the installed metadata (the extras it names, resolved)."""
    seen = set() if seen is None else seen
    try:
        declared = metadata.requires(DISTRIBUTION) or []
    except metadata.PackageNotFoundError:
        return [f"{DISTRIBUTION}[{','.join(extras)}]"]
    found: list[str] = []
    for extra in extras:
        if extra in seen:
            continue
        seen.add(extra)
        for line in declared:
            match = _EXTRA_MARKER.match(line)
            if match is None or match["extra"] != extra:
                continue
            requirement = match["requirement"].strip()
            nested = re.fullmatch(rf"{DISTRIBUTION}\s*\[(?P<names>[^\]]+)\]", requirement)
            for item in (_requirements(nested["names"].split(","), seen) if nested else [requirement]):
                if item not in found:
                    found.append(item)
    return found
