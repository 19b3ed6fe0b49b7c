"""bouncingball: a ball with compliant contact, integrated by SUNDIALS CVODE with exact events."""

from .ground import Ground
from .physics import Ball, Mode
from .solvers import SOLVERS, simulate
from .solvers.result import AccuracyWarning, Event, EventKind, SimulationResult, SolverStats

__version__ = "0.1.0"

__all__ = ["SOLVERS", "AccuracyWarning", "Ball", "Event", "EventKind", "Ground", "Mode", "SimulationResult",
           "SolverStats", "simulate", "__version__"]
