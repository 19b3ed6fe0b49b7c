"""The solvers: one call (simulate, simulation.py) and its three solvers, over the phase machine and its engines.

- simulation.py: ``simulate``, which checks a run's input and hands it to a solver;
- cvode.py, integrator.py (BallIntegrator, the stepping API), state.py and state_checks.py (its saved state),
  engine_selection.py (which engine runs), forcing.py (F_ext), result.py (what every solver returns);
- exact.py: the exact piecewise-analytic solution; scipy_ref.py and article.py: the article's SciPy algorithm;
- phase_machine/: the phase machine CVODE runs phase by phase, written once for both engines;
- engines/: the two CVODE engines it runs on (scikit-sundae's, interpreted; the compiled one).
"""

from __future__ import annotations

from .article import ARTICLE_ATOL, ARTICLE_LABEL, ARTICLE_MAX_STEP, ARTICLE_METHOD, ARTICLE_RTOL, ARTICLE_SETTINGS
from .forcing import ForceTable
from .result import Event, SimulationResult, SolverStats
from .simulation import SOLVERS, simulate

__all__ = ["ARTICLE_ATOL", "ARTICLE_LABEL", "ARTICLE_MAX_STEP", "ARTICLE_METHOD", "ARTICLE_RTOL", "ARTICLE_SETTINGS",
           "SOLVERS", "Event", "ForceTable", "SimulationResult", "SolverStats", "simulate"]
