"""Print issue 20's families against the mpmath oracle: the README's accuracy table comes from this.

    python tests/oracle_table.py

Each family of tests/test_oracle.py through each API (the exact solver, simulate with each engine, the
stepping API): max |h - h_oracle| / max(|h_oracle|, R) on the judged points, events found / the oracle's,
the rest time, and the judge's verdict (tests/test_oracle.py asserts the same verdicts).
"""

import os
import sys
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import test_oracle as T  # noqa: E402

if __name__ == "__main__":
    warnings.simplefilter("ignore")
    for case in T.FAMILIES:
        oracle = T.oracle_of(case)
        for api in T.APIS:
            t, h, events, rest = T.run(case, api)
            idx = T.judged_indices(np.asarray(t), oracle)
            h_oracle, _ = T.oracle_states(case, np.asarray(t)[idx])
            scale = max(float(np.max(np.abs(h_oracle))), case.R)
            error = float(np.max(np.abs(np.asarray(h)[idx] - h_oracle))) / scale
            problems = T.judge(case, T.tolerance_of(api), t, h, events, rest, exact=api == "exact",
                               reach=T.mergeable_hop(case, api))
            print(f"{case.name:30s} {api:9s} {error:9.2e}  events {len(events):5d}/{len(oracle.events):5d}  "
                  f"rest {'-' if rest is None else f'{rest:.4g}'}  {'ok' if not problems else problems[0]}")
