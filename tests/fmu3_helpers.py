"""An FMI 3.0 FMU instance driven call by call through FMPy's FMU3Slave or FMU3Model (the FMU3 tests' helper)."""

from __future__ import annotations

from pathlib import Path

TYPES = {"Float64": "Float64", "Int32": "Int32", "Boolean": "Boolean", "String": "String"}


class Instance3:
    """One instance of the FMI 3.0 FMU, co-simulation or model exchange, keeping every logged (status, message)."""

    def __init__(self, unzipped: Path, interface: str = "CoSimulation", name: str = "ball",
                 early_return: bool = False, event_mode: bool = False):
        from fmpy import read_model_description
        from fmpy.fmi3 import FMU3Model, FMU3Slave

        description = read_model_description(str(unzipped))
        self.variables = {v.name: v for v in description.modelVariables}
        self.log: list[tuple[int, str]] = []
        kind = description.coSimulation if interface == "CoSimulation" else description.modelExchange
        cls = FMU3Slave if interface == "CoSimulation" else FMU3Model
        self.fmu = cls(guid=description.guid, unzipDirectory=str(unzipped), modelIdentifier=kind.modelIdentifier,
                       instanceName=name)
        if interface == "CoSimulation":
            self.fmu.instantiate(eventModeUsed=event_mode, earlyReturnAllowed=early_return, logMessage=self._logger)
        else:
            self.fmu.instantiate(logMessage=self._logger)

    def _logger(self, environment, status, category, message):
        self.log.append((status, message.decode("utf-8")))

    def errors(self) -> list[str]:
        return [message for status, message in self.log if status >= 3]

    def reference(self, name: str) -> int:
        return self.variables[name].valueReference

    def get(self, *names) -> list:
        values = []
        for name in names:
            variable = self.variables[name]
            value = getattr(self.fmu, f"get{variable.type}")([variable.valueReference])[0]
            values.append(value.decode("utf-8") if isinstance(value, bytes) else value)
        return values

    def set(self, **values) -> None:
        for name, value in values.items():
            variable = self.variables[name]
            getattr(self.fmu, f"set{variable.type}")([variable.valueReference], [value])
