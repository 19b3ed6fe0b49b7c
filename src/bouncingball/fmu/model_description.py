"""The FMU's modelDescription.xml as pythonfmu writes it, completed: units, ranges, experiment and stamp.

complete_model_description completes FMI 2.0's; the rest is what both FMI versions' get (build3.py completes
FMI 3.0's with them).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from .variables import UNITS, VARIABLES


class FmuBuildError(RuntimeError):
    """The FMU cannot be built here; the message says what is missing."""


def complete_model_description(xml: bytes) -> bytes:
    """Add units, min/max, DefaultExperiment and InitialUnknowns to pythonfmu's modelDescription.xml."""
    root = ET.fromstring(xml)
    stamp(root, "pythonfmu")
    children = list(root)
    root.insert(children.index(root.find("CoSimulation")) + 1, unit_definitions())
    root.insert(list(root).index(root.find("ModelVariables")), default_experiment())

    scalars = root.find("ModelVariables").findall("ScalarVariable")
    index = {scalar.get("name"): i + 1 for i, scalar in enumerate(scalars)}
    # The loader checks value references against VARIABLES' order (BB_VARIABLE_TYPES): pythonfmu must agree.
    if [(s.get("name"), s.get("valueReference")) for s in scalars] != [(v.name, str(i)) for i, v in
                                                                           enumerate(VARIABLES)]:
        raise FmuBuildError("pythonfmu numbered the variables other than in VARIABLES' order")
    for variable in VARIABLES:
        add_unit_and_range(scalars[index[variable.name] - 1].find(variable.type), variable)

    structure = root.find("ModelStructure")
    initial_unknowns = ET.SubElement(structure, "InitialUnknowns")
    for variable in VARIABLES:  # outputs computed at initialisation: every output without initial="exact"
        if variable.causality == "output" and variable.initial != "exact":
            ET.SubElement(initial_unknowns, "Unknown", index=str(index[variable.name]))
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


# --- what both FMI versions' model descriptions get ------------------------------------------------
def stamp(root: ET.Element, library: str) -> None:
    """The model's version and the generation tool (bouncingball, and the pythonfmu library it used)."""
    from importlib.metadata import version as installed_version

    from .. import __version__

    root.set("version", __version__)
    root.set("generationTool", f"bouncingball {__version__} ({library} {installed_version(library)})")


def unit_definitions() -> ET.Element:
    """UnitDefinitions: every unit of the variable table, in SI base units."""
    units = ET.Element("UnitDefinitions")
    for name, exponents in UNITS.items():
        unit = ET.SubElement(units, "Unit", name=name)
        ET.SubElement(unit, "BaseUnit", {base: str(power) for base, power in exponents.items()})
    return units


def default_experiment() -> ET.Element:
    """The article scene, 0 to 8 s every 1 ms, at the FMU's own rtol."""
    from ..scenes import load_scene
    from ..solvers.cvode import CvodeSettings

    article = load_scene("article")
    # The FMU's own rtol as the tolerance: a master that takes it from here passes it back (see slave_base's rule).
    return ET.Element("DefaultExperiment", startTime="0", stopTime=repr(article.t_end),
                      stepSize=repr(article.output_interval), tolerance=repr(CvodeSettings().rtol))


def add_unit_and_range(typed: ET.Element, variable) -> None:
    """The unit, min and max of variable (a variables.FmuVariable) on its typed XML element."""
    if variable.unit:
        typed.set("unit", variable.unit)
    if variable.min is not None:
        typed.set("min", repr(variable.min) if variable.type == "Real" else str(int(variable.min)))
    if variable.max is not None:
        typed.set("max", repr(variable.max))
