"""Print issue 20's families against the mpmath oracle, and the rows of the README's accuracy table.

    python tests/oracle_table.py

Each family of tests/test_oracle.py through each API (the exact solver, simulate with each engine, the
stepping API): max |h - h_oracle| / max(|h_oracle|, R) on the judged points, events found / the oracle's,
the rest time, and the judge's verdict (tests/test_oracle.py asserts the same verdicts). Then the README's
accuracy table, its rows rebuilt from these runs: test_oracle.test_family checks each figure the README
prints against its own run, so paste these rows when it fails.
"""

import os
import sys
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import test_oracle as T  # noqa: E402

if __name__ == "__main__":
    warnings.simplefilter("ignore")
    rows = []
    for case in T.FAMILIES:
        outcomes = {api: T.run(case, api) for api in T.APIS}
        for api, (t, h, events, rest) in outcomes.items():
            problems = T.judge(case, T.tolerance_of(api), t, h, events, rest, exact=api == "exact",
                               reach=T.mergeable_hop(case, api))
            print(f"{case.name:30s} {api:9s} {T.relative_error(case, t, h):9.2e}  events {len(events):5d}/"
                  f"{len(T.oracle_of(case).events):5d}  rest {'-' if rest is None else f'{rest:.4g}'}  "
                  f"{'ok' if not problems else problems[0]}")
        row = T.readme_rows().get(case.name)
        if row is not None:
            rows.append(T.table_row(case, row["description"], outcomes))
    print("\nREADME.md's accuracy table (its rows, in the order of the cases):")
    print("\n".join(rows))
