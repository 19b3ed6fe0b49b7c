"""The BouncingBall FMU's slave: the bouncing ball as an FMI 2.0 co-simulation slave for pythonfmu.

The slave itself is slave_base.BallSlave; here it meets pythonfmu's Fmi2Slave. The FMU's slave script
(bouncingball_fmu_slave.py) only names this class: pythonfmu 0.7 executes the script anew for every
instance and keeps whatever class it defines alive, so the class lives here, in a module imported
once per process.
"""

from __future__ import annotations

from pythonfmu import Boolean, Fmi2Slave, Integer, Real, String
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Status, Fmi2Variability

from .slave_base import BallSlave

TYPES = {"Real": Real, "Integer": Integer, "Boolean": Boolean, "String": String}


class BouncingBall(BallSlave, Fmi2Slave):
    """A ball with compliant contact, integrated by CVODE with every contact found by root-finding."""

    STATUS = Fmi2Status

    def _register(self, variable, getter, setter) -> None:
        self.register_variable(TYPES[variable.type](
            variable.name, causality=Fmi2Causality[variable.causality],
            variability=Fmi2Variability[variable.variability], description=variable.description,
            initial=Fmi2Initial[variable.initial] if variable.initial else None, getter=getter, setter=setter))
