"""What the FMI 3.0 FMU's build does otherwise than the FMI 2.0 one (build.build_fmu(fmi_version=3)).

The same slave script, package copy and variable table, built with pythonfmu3: the script's import
and class line name pythonfmu3's Fmi3Slave and its slave module is slave3 (SCRIPT_CHANGES); the
model description gets what pythonfmu3 leaves out or gets wrong (complete_model_description).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from .model_description import FmuBuildError, add_unit_and_range, default_experiment, stamp, unit_definitions
from .variables import FMI3_VARIABLES, VARIABLES

SCRIPT_CHANGES = {
    "from pythonfmu import Fmi2Slave\n": "from pythonfmu3 import Fmi3Slave\n",
    "class BouncingBall(Fmi2Slave):": "class BouncingBall(Fmi3Slave):",
    'SLAVE_MODULE = "slave"\n': 'SLAVE_MODULE = "slave3"\n',
}
TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String"}
# What the FMU's binary (bouncingball_fmu3_loader.c) does. pythonfmu3 0.3.4 writes every one of these
# false, and canHandleVariableCommunicationStepSize as the last common option's value (a loop variable
# it reuses): set them all.
CO_SIMULATION = {
    "canHandleVariableCommunicationStepSize": "true",
    "hasEventMode": "true",
    "mightReturnEarlyFromDoStep": "true",
    "canReturnEarlyAfterIntermediateUpdate": "false",
    "providesIntermediateUpdate": "false",
    "providesEvaluateDiscreteStates": "false",
    "providesDirectionalDerivatives": "false",
    "providesAdjointDerivatives": "false",
}
MODEL_EXCHANGE = {"needsCompletedIntegratorStep": "false", "providesEvaluateDiscreteStates": "false",
                  "providesDirectionalDerivatives": "false", "providesAdjointDerivatives": "false"}


def _list_calculated_states(root: ET.Element, elements: list) -> None:
    """A continuous state calculated at initialisation (x = h - R) as an InitialUnknown, which pythonfmu3 leaves out."""
    structure = root.find("ModelStructure")
    states = {e.get("derivative") for e in elements if e.get("derivative") is not None}
    listed = {e.get("valueReference") for e in structure.findall("InitialUnknown")}
    for element in elements:
        reference = element.get("valueReference")
        if reference in states and reference not in listed and element.get("initial") in (None, "approx", "calculated"):
            events = structure.find("EventIndicator")  # InitialUnknowns come before the EventIndicators
            unknown = ET.Element("InitialUnknown", valueReference=reference)
            if events is None:
                structure.append(unknown)
            else:
                structure.insert(list(structure).index(events), unknown)


def complete_model_description(xml: bytes) -> bytes:
    """Add units, min/max, DefaultExperiment and the interface's capabilities to pythonfmu3's modelDescription.xml."""
    root = ET.fromstring(xml)
    stamp(root, "pythonfmu3")
    interfaces = {"CoSimulation": CO_SIMULATION, "ModelExchange": MODEL_EXCHANGE}
    for name, attributes in interfaces.items():
        element = root.find(name)
        if element is None:
            raise FmuBuildError(f"pythonfmu3's model description has no {name}")
        for key, value in attributes.items():
            element.set(key, value)
    last = max(list(root).index(root.find(name)) for name in interfaces)
    if root.find("UnitDefinitions") is not None:
        raise FmuBuildError("pythonfmu3 wrote UnitDefinitions: the build writes them from the variable table")
    root.insert(last + 1, unit_definitions())
    if root.find("DefaultExperiment") is not None:
        root.remove(root.find("DefaultExperiment"))
    root.insert(list(root).index(root.find("ModelVariables")), default_experiment())

    elements = list(root.find("ModelVariables"))
    variables = VARIABLES + FMI3_VARIABLES
    # The loader checks value references against this order (BB_VARIABLE_TYPES): pythonfmu3 must agree.
    if [(e.tag, e.get("name"), e.get("valueReference")) for e in elements] != [
            (TYPES[v.type], v.name, str(i)) for i, v in enumerate(variables)]:
        raise FmuBuildError("pythonfmu3 numbered or typed the variables other than VARIABLES + FMI3_VARIABLES")
    for element, variable in zip(elements, variables, strict=True):
        add_unit_and_range(element, variable)
        if variable.type == "Integer" and element.get("min") is not None:
            element.set("min", str(int(variable.min)))
    _list_calculated_states(root, elements)
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
