"""The machine a benchmark ran on: CPU, load, versions, date and commit, written at the top of each report."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

PACKAGES = ("numpy", "scikit-sundae", "scipy", "FMPy", "pythonfmu", "matplotlib", "tqdm")


def environment() -> dict[str, str]:
    """CPU, cores, load, Python and package versions, date and git commit."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as info:
            cpu = next((line.split(":", 1)[1].strip() for line in info if line.startswith("model name")), cpu)
    except OSError:
        pass
    load = ", ".join(f"{value:.2f}" for value in os.getloadavg())
    commit = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True, text=True,
                            cwd=Path(__file__).parent, check=False).stdout.strip()
    return {"machine": f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}",
            "load": f"{load} (1, 5, 15 min) at the start",
            "software": f"Python {platform.python_version()}, " + versions(PACKAGES),
            "date": datetime.datetime.now().astimezone().isoformat(timespec="minutes"),
            "commit": commit or "unknown"}


def versions(packages: tuple[str, ...]) -> str:
    """'name version' of each installed package, '(not installed)' for the others, comma-separated."""
    found = []
    for package in packages:
        try:
            found.append(f"{package} {metadata.version(package)}")
        except metadata.PackageNotFoundError:
            found.append(f"{package} (not installed)")
    return ", ".join(found)


def environment_lines(environment: dict[str, str]) -> list[str]:
    return [f"- {key}: {value}" for key, value in environment.items()]
