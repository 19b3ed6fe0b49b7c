"""The reference article's settings: the "scipy" solver at its defaults, and how tables and pages name it."""

from __future__ import annotations

# The "scipy" solver (scipy_ref.py) at its defaults is the reference article's algorithm: solve_ivp's RK45 at SciPy's
# default tolerances, with max_step 0.01 s. Its name in every table, and its settings as pages state them:
ARTICLE_METHOD, ARTICLE_MAX_STEP, ARTICLE_RTOL, ARTICLE_ATOL = "RK45", 0.01, 1e-3, 1e-6
ARTICLE_LABEL = f"article ({ARTICLE_METHOD}, max_step {ARTICLE_MAX_STEP:g})"
ARTICLE_SETTINGS = f"{ARTICLE_METHOD}, max_step {ARTICLE_MAX_STEP:g}, rtol {ARTICLE_RTOL:g}, atol {ARTICLE_ATOL:g}"
