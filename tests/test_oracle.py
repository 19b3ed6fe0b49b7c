"""Families of inputs where a solver returned wrong numbers with status OK (issue 20), judged by the oracle.

The referee is tests/mpmath_oracle.py, an independent 50-digit solution of the model. Each case runs
through the exact solver, simulate with the engines "sksundae" and "compiled", the stepping API
(BallIntegrator.advance over random step sizes, with get_state/set_state restarts and roll-backs),
and for some cases the FMU through FMPy.

The rule (judge), with q = 1e-9 for the exact solver and 1e-6 for the integrators:
- heights: max |h - h_oracle| <= q H on the output grid (all of it up to 3000 points, else 1000
  evenly spread points and the two points around every event), H = max(max |h_oracle|, R);
- events: in order, each oracle event matched by one of the same kind with |t - t_oracle| no more
  than the time the ball takes to move q H from the event (q H / |v|, or sqrt(2 q H / |a|) where it
  grazes; q (t_end - t_start) where it neither moves nor accelerates) and |v - v_oracle| <= q V (V:
  the largest oracle speed at an event or on the grid, or sqrt(2 |g - F_ext/m| H) if larger); an
  event may be missing only if it is one of the pair bounding a hop that the run may merge into the
  contact around it (the package's one rule, cvode.merged_hop_limit, for CVODE; none for the exact
  solver), or within its time tolerance of t_end; any other missing event fails, and so does an extra
  one unless the oracle's ball is within such a hop of R there at the speed of such a hop (an event
  decided by rounding), or within its time tolerance of t_end;
- rest: a rest declared at t_r needs the oracle's start in contact or one of its impacts within
  tolerance of t_r (the nearest), after which the oracle's ball never leaves for a resolvable hop (its first
  event after t_end included); the exact solver must also declare the oracle's rest.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from functools import cache, lru_cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st

import bouncingball as bb
from bouncingball.solvers.cvode import BallIntegrator, merged_hop_limit, resolvable_until
from mpmath_oracle import CONTACT, DEPARTURE, IMPACT, Oracle, TooManyEvents

SMALLEST_RESOLVABLE_HOP = 1e-12  # of R: the lowest undamped hops the micro-hop region draws
EXACT_TOLERANCE = 1e-9
INTEGRATOR_TOLERANCE = 1e-6
MAX_JUDGED_POINTS = 3000
G = 9.81


@dataclass(frozen=True)
class Case:
    """A ball, a start state, a run and an output interval (floats, hashable for the oracle cache)."""

    name: str
    m: float
    k: float
    b: float
    R: float
    g: float
    h0: float
    v0: float
    t_end: float
    dt: float
    F_ext: float = 0.0

    @property
    def ball(self) -> bb.Ball:
        return bb.Ball(m=self.m, k=self.k, b=self.b, R=self.R, g=self.g)


@lru_cache(maxsize=128)
def oracle_of(case: Case, max_events: int = 100_000) -> Oracle:
    return Oracle(case.m, case.k, case.b, case.R, case.g, case.h0, case.v0, case.t_end, F_ext=case.F_ext,
                  max_events=max_events)


_ORACLE_STATES: dict = {}


def oracle_states(case: Case, t: np.ndarray) -> np.ndarray:
    key = (case, t.tobytes())
    if key not in _ORACLE_STATES:
        if len(_ORACLE_STATES) > 64:
            _ORACLE_STATES.clear()
        _ORACLE_STATES[key] = oracle_of(case).state(t)
    return _ORACLE_STATES[key]


# --- the rule ------------------------------------------------------------------------------------
def judged_indices(t: np.ndarray, oracle: Oracle) -> np.ndarray:
    if len(t) <= MAX_JUDGED_POINTS:
        return np.arange(len(t))
    event_times = np.array([float(e.time) for e in oracle.events])
    after = np.searchsorted(t, event_times)
    near = np.concatenate([after - 1, after])
    spread = np.linspace(0, len(t) - 1, 1000).round().astype(int)
    return np.unique(np.clip(np.concatenate([spread, near]), 0, len(t) - 1))


def mergeable_hop(case: Case, api: str) -> float:
    """The highest hop [m] a run may merge into the contact around it: the package's one rule for CVODE
    (cvode.merged_hop_limit, 0 for an undamped or lifted ball), none for the exact solver; and for every
    solver a hop of a few ulps of R, which h = R + hop cannot show (a ball creeping to a rest height 1e-23 m
    below R, restarted from its h, may leave; a hop of height 0 after 675 s may be called a rest)."""
    solver_rule = 0.0 if api == "exact" else merged_hop_limit(case.ball, F_ext=case.F_ext)
    return max(solver_rule, 4 * math.ulp(case.R))


def unresolvable_hop(oracle: Oracle, departure, case: Case, reach: float) -> bool:
    """A departure into a hop lower than reach [m], or (lifted by F_ext >= m g) into a flight that stays that
    close to R for a whole run's length."""
    if departure.kind != DEPARTURE:
        return False
    if oracle.a > 0:
        return oracle.hop_height(departure) < reach
    return float(departure.velocity) * case.t_end - float(oracle.a) * case.t_end**2 / 2 < reach


def optional_events(oracle: Oracle, case: Case, time_tolerance, reach: float) -> set[int]:
    """Indices of the oracle's events a solver may miss: both ends of an unresolvable hop, and ends of the run."""
    optional = set()
    for i, event in enumerate(oracle.events):
        if unresolvable_hop(oracle, event, case, reach):
            optional.update({i, i + 1})
        if float(event.time) > case.t_end - time_tolerance(i):
            optional.add(i)
    return {i for i in optional if i < len(oracle.events)}


def grazing(oracle: Oracle, case: Case, time: float, reach: float) -> bool:
    """At this time the oracle's ball is within an unresolvable hop (reach [m]) of R, at the speed of such a hop
    (or a drift that stays within it until t_end): an event a solver reports there may be an artefact of
    rounding."""
    h, v = oracle.state_mp(time)
    speed = max(math.sqrt(2 * abs(float(oracle.a)) * reach), reach / case.t_end)
    return abs(float(h) - case.R) <= reach and abs(float(v)) <= speed


def judge(case: Case, q: float, t, h, events, rest_time, exact: bool = False, reach: float = 0.0) -> list[str]:
    """What is wrong with a run against the oracle under the rule of this module (empty if nothing).

    events None: the run gives no event list (the FMU), only its heights are judged here.
    """
    oracle = oracle_of(case)
    t, h = np.asarray(t, dtype=float), np.asarray(h, dtype=float)
    idx = judged_indices(t, oracle)
    h_or, v_or = oracle_states(case, t[idx])
    H = max(float(np.max(np.abs(h_or))), case.R)
    # the speed scale: the largest speed, or that of a fall through H (a height error q H is a speed error of
    # about q sqrt(2 |a| H) there)
    V = max([float(np.max(np.abs(v_or))), math.sqrt(2 * abs(float(oracle.a)) * H)]
            + [abs(float(e.velocity)) for e in oracle.events])
    T = case.t_end
    problems = []
    h_err = float(np.max(np.abs(h[idx] - h_or)))
    if not h_err <= q * H:
        worst = idx[int(np.argmax(np.abs(h[idx] - h_or)))]
        problems.append(f"h error {h_err:.3g} m > {q * H:.3g} m (x{h_err / (q * H):.3g}) at t = {t[worst]:.9g} s")
    if events is None:
        return problems

    def time_tolerance(event):
        # the time in which the ball moves q H from the event: q H / |v|, or sqrt(2 q H / |a|) where it grazes
        speed, a = abs(float(event.velocity)), abs(float(oracle.a))
        moving = 2 * q * H / (speed + math.sqrt(speed**2 + 2 * a * q * H))
        return moving if math.isfinite(moving) else q * T

    def matches(event, expected):
        return event.kind == expected.kind and abs(event.time - float(expected.time)) <= time_tolerance(expected)

    optional = optional_events(oracle, case, lambda i: time_tolerance(oracle.events[i]), reach)
    missing, wrong, extra = [], [], []
    j = 0
    for i, expected in enumerate(oracle.events):
        while j < len(events) and not matches(events[j], expected) and grazing(oracle, case, events[j].time, reach):
            j += 1  # an event where the ball only grazes R: neither required nor wrong
        if j < len(events) and matches(events[j], expected):
            if not abs(events[j].velocity - float(expected.velocity)) <= q * V:
                wrong.append(f"{expected.kind} at {float(expected.time):.9g} s with v = {events[j].velocity:.6g} "
                             f"m/s, not {float(expected.velocity):.6g}")
            j += 1
        elif i not in optional:
            missing.append(f"{expected.kind} at {float(expected.time):.9g} s (v {float(expected.velocity):.3g} m/s)")
    # an event within its time tolerance of t_end may be there or not (the oracle may place it just after)
    extra = [f"{e.kind} at {e.time:.9g} s" for e in events[j:]
             if not grazing(oracle, case, e.time, reach) and not e.time > case.t_end - time_tolerance(e)]
    if missing:
        pairs = list(zip(events, oracle.events, strict=False))  # by index: how far off, while the kinds agree
        aligned = [(abs(e.time - float(o.time)), o) for e, o in pairs if e.kind == o.kind]
        drift = max(aligned, default=None, key=lambda pair: pair[0])
        problems.append(f"{len(missing)} of {len(oracle.events)} events missing or off in time, first "
                        f"{missing[0]}" + ("" if drift is None else
                                           f"; by index, times off by up to {drift[0]:.3g} s "
                                           f"(x{drift[0] / time_tolerance(drift[1]):.3g} tolerance)"))
    if extra:
        problems.append(f"{len(extra)} events unmatched ({len(events)} reported), first {extra[0]}")
    if wrong:
        problems.append(f"{len(wrong)} event velocities off, first {wrong[0]}")
    problems += rest_problems(oracle, case, q, rest_time, exact, time_tolerance, reach)
    return problems


def rest_problems(oracle: Oracle, case: Case, q: float, rest_time, exact: bool, time_tolerance,
                  reach: float) -> list[str]:
    """A rest declared must start at the oracle's start in contact or at one of its impacts, after which the
    ball never makes a resolvable hop (the oracle's event after t_end counts too); the exact solver must
    also declare the oracle's rest."""
    if rest_time is None:
        if exact and oracle.rest_time is not None:
            return [f"no rest declared; the oracle rests from {float(oracle.rest_time):.9g} s"]
        return []
    # the impact nearest the declared rest (bounces before a rest can follow each other within the tolerance)
    starts = sorted((i for i, e in enumerate(oracle.events)
                     if e.kind == IMPACT and abs(float(e.time) - rest_time) <= time_tolerance(e)),
                    key=lambda i: abs(float(oracle.events[i].time) - rest_time))
    if oracle.phases[0].mode == CONTACT and abs(rest_time) <= q * case.t_end:
        starts.insert(0, -1)
    oracle_rest = None if oracle.rest_time is None else f"{float(oracle.rest_time):.9g} s"
    if not starts:
        return [f"rest declared at {rest_time:.9g} s, at no impact of the oracle (its rest: {oracle_rest})"]
    after = oracle.events[starts[0] + 1:] + ([oracle.next_event] if oracle.next_event is not None else [])
    hops = [e for e in after if e.kind == DEPARTURE and not unresolvable_hop(oracle, e, case, reach)]
    if hops:
        return [f"rest declared at {rest_time:.9g} s, but the oracle leaves at {float(hops[0].time):.9g} s "
                f"at {float(hops[0].velocity):.3g} m/s (its rest: {oracle_rest})"]
    return []


# --- the runs ------------------------------------------------------------------------------------
def run_simulate(case: Case, api: str):
    if api == "exact":
        result = bb.simulate(case.ball, case.h0, case.v0, case.t_end, case.dt, solver="exact", F_ext=case.F_ext)
    else:
        result = bb.simulate(case.ball, case.h0, case.v0, case.t_end, case.dt, F_ext=case.F_ext, engine=api)
    return result.t, result.h, list(result.events), result.rest_time


def run_stepping(case: Case, advances: int = 400, seed: int = 20):
    """advance() over random targets (mostly ~t_end/advances apart, some 1e-6 of that); at random
    points restart in place (set_state(get_state())) or roll back over one advance and redo it."""
    rng = np.random.default_rng(seed)
    integrator = BallIntegrator(case.ball, case.h0, case.v0, 0.0, case.F_ext)
    mean = case.t_end / advances
    times, heights, events = [0.0], [integrator.h], []
    t = 0.0
    while t < case.t_end:
        step = mean * (rng.uniform(0.2, 1.8) if rng.random() < 0.8 else 10 ** rng.uniform(-6, -1))
        t = min(t + step, case.t_end)
        action = rng.random()
        if action < 0.1:
            integrator.set_state(integrator.get_state())
        elif action < 0.2:
            snapshot = integrator.get_state()
            integrator.advance(t)
            integrator.set_state(snapshot)
        events += integrator.advance(t)
        times.append(integrator.t)
        heights.append(integrator.h)
    return np.array(times), np.array(heights), events, integrator.rest_time


def run(case: Case, api: str):
    return run_stepping(case) if api == "stepping" else run_simulate(case, api)


def tolerance_of(api: str) -> float:
    return EXACT_TOLERANCE if api == "exact" else INTEGRATOR_TOLERANCE


def assert_judged(case: Case, api: str, outcome) -> None:
    t, h, events, rest_time = outcome
    problems = judge(case, tolerance_of(api), t, h, events, rest_time, exact=api == "exact",
                     reach=mergeable_hop(case, api))
    assert problems == [], f"{case.name} [{api}]: " + "; ".join(problems)


# --- the families --------------------------------------------------------------------------------
def article_lifted(zeta: float, name: str) -> Case:
    m, k = 1.0, 1e4
    return Case(f"1-article-lifted-zeta-{name}", m, k, 2 * zeta * math.sqrt(k * m), 0.06, G,
                0.06 - m * G / k, 0.0, 1.0, 1e-3, F_ext=20.0)


FAMILIES = [
    # 0. the article's scene, for the README's table
    Case("0-article", 1.0, 1e4, 10.0, 0.06, G, 2.0, 0.0, 8.0, 1e-3),
    # 1. a lifted contact near critical damping
    Case("1-issue-lifted-0.1kg", 0.1, 1e4, 2 * math.sqrt(1e4 * 0.1), 0.06, G, 0.05, 0.0, 1.0, 1e-3,
         F_ext=2 * 0.1 * G),
    *(article_lifted(z, n) for z, n in [(0.998, "0.998"), (0.999, "0.999"), (0.9999, "0.9999"),
                                         (1 - 1e-12, "1-1e-12"), (1.0, "1"), (1 + 1e-12, "1+1e-12"),
                                         (1.001, "1.001")]),
    # found by exploring the near-critical region: F_ext one ulp above m g, which m g rounded onto (a rest was
    # declared; the ball rises 3.6e-16 m above R and leaves at 42 s), and a start at R at rest with v0 = 0.0
    # (atan2 of -0.0: a negative extremum time, then OverflowError)
    Case("1-lifted-by-an-ulp", 10.0, 9.81, 19.809088823063014, 100.0, G, 90.0, 0.0, 17.163838429769175,
         0.042909596074422934, F_ext=98.10000000000001),
    Case("1-at-rest-on-r", 1.0, 98.1, 19.80906901397419, 1.0, G, 1.0, 0.0, 0.5048187773461522,
         0.0012620469433653806),
    # ... and at R at rest with F_ext 2e-16 N below m g: g - F_ext/m rounded to 0 and the ball started in flight
    # (the load's sign, from the exact product, now decides every mode and force)
    Case("1-at-r-weighing-2e-16-n", 10.0**0.125, 130.8184524952221, 26.15168605220967, 1.0, G, 1.0, 0.0,
         0.5048187773461522, 0.0012620469433653806, F_ext=13.081845249522209),
    # 2. a stiff contact after a long fall
    Case("2-stiff-100m", 1e-6, 4.6e13, 0.0, 1e-3, G, 100.0, 0.0, 100.0, 0.02),
    Case("2-stiff-1000m", 1e-6, 5.5e13, 0.0, 1e-3, G, 1000.0, 0.0, 100.0, 0.02),
    Case("2-stiff-1000m-180s", 1e-6, 5.5e13, 0.0, 1e-3, G, 1000.0, 0.0, 180.0, 0.02),  # resolvable to 190 s
    Case("2-stiff-1e12-R2mm", 1e-6, 1e12, 0.0, 2e-3, G, 100.0, 0.0, 100.0, 0.02),
    # 3. undamped micro-hops (2538 events)
    Case("3-micro-hops", 1.0, 1e12, 0.0, 0.06, G, 0.06, 1.7717787672280082e-4, 0.05, 1e-5),
    # 4. the article scene shrunk: h0 = 10 R, static deflection ~1e-2 R (1e-1 R for the R = 1e-6)
    Case("4-scale-R1e-6", 1.0, 1e8, 10.0, 1e-6, G, 1e-5, 0.0, 1.0, 2e-4),
    Case("4-scale-R1e-7", 1.0, 1e10, 10.0, 1e-7, G, 1e-6, 0.0, 0.2, 1e-4),
    Case("4-scale-R1e-8", 1.0, 1e11, 10.0, 1e-8, G, 1e-7, 0.0, 0.05, 2e-5),
    # 5. a contact so soft that its static deflection (6e120 m) dwarfs the ball's motion (1e102 m): the flow
    # written about the rest height, x = y - d, cancelled every digit of x (the exact solution 0.083 off,
    # CVODE's dense output 0.14; found by fuzzing the range the package accepts)
    Case("5-soft-contact", 748984168.4626325, 0.005280603483927696, 0.0, 2.805999634182557e+97,
         4.238516545823933e+106, 5.466539572921386e+97, 0.0, 0.01746748238597513, 1.746748238597513e-05),
]
FMU_CASES = ["1-issue-lifted-0.1kg", "1-article-lifted-zeta-1", "2-stiff-100m", "3-micro-hops", "4-scale-R1e-6"]
APIS = ["exact", "sksundae", "compiled", "stepping"]
BY_NAME = {case.name: case for case in FAMILIES}


@pytest.mark.parametrize("api", APIS)
@pytest.mark.parametrize("case", FAMILIES, ids=lambda case: case.name)
def test_family(case, api):
    outcome = run(case, api)
    assert_judged(case, api, outcome)
    assert_readme_figures(case, api, outcome)


# --- the README's accuracy table: its figures are the runs above, measured here, as printed there -----------------
README = Path(__file__).resolve().parents[1] / "README.md"
# | description (`case`) | simulate's error; stepping the stepping API's | events found of the oracle's |
README_ROW = re.compile(r"^\| (?P<description>.+) \(`(?P<name>[^`]+)`\) \| (?P<simulate>[^;|]+); stepping "
                        r"(?P<stepping>[^|]+) \| (?P<found>\d+) of (?P<expected>\d+) \|$", re.M)


@cache
def readme_rows() -> dict[str, dict[str, str]]:
    """The README's accuracy table by case name (empty outside a source checkout)."""
    if not README.is_file():
        return {}
    return {match["name"]: match.groupdict() for match in README_ROW.finditer(README.read_text(encoding="utf-8"))}


def relative_error(case: Case, t, h) -> float:
    """max |h - h_oracle| / max(|h_oracle|, R) on the judged points: the README table's measure."""
    t, h = np.asarray(t, dtype=float), np.asarray(h, dtype=float)
    idx = judged_indices(t, oracle_of(case))
    h_oracle, _ = oracle_states(case, t[idx])
    return float(np.max(np.abs(h[idx] - h_oracle))) / max(float(np.max(np.abs(h_oracle))), case.R)


def printed_error(error: float) -> str:
    """An error as the table prints it: two significant digits, and errors of a few ulps as "< 1e-14"."""
    return "< 1e-14" if error < 1e-14 else f"{error:.1e}".replace("e-0", "e-")


def table_row(case: Case, description: str, outcomes: dict) -> str:
    """The README row of a case from its runs (outcomes by api: t, h, events, rest time)."""
    errors = {api: printed_error(relative_error(case, *outcomes[api][:2])) for api in outcomes}
    assert errors["sksundae"] == errors["compiled"], errors  # one figure for simulate: both engines
    return (f"| {description} (`{case.name}`) | {errors['sksundae']}; stepping {errors['stepping']} | "
            f"{len(outcomes['sksundae'][2])} of {len(oracle_of(case).events)} |")


def assert_readme_figures(case: Case, api: str, outcome) -> None:
    row = readme_rows().get(case.name)
    if row is None or api == "exact":
        return
    printed = printed_error(relative_error(case, *outcome[:2]))
    cell = (row["stepping"] if api == "stepping" else row["simulate"]).strip()
    events = f"{len(outcome[2])} of {len(oracle_of(case).events)}"
    where = f"README.md's accuracy table, {case.name} [{api}] (python tests/oracle_table.py prints the rows)"
    assert cell == printed, f"{where}: prints {cell}, the run gives {printed}"
    if api != "stepping":
        assert f"{row['found']} of {row['expected']}" == events, f"{where}: prints {row['found']} of " \
                                                                 f"{row['expected']} events, the run gives {events}"


def test_the_readme_accuracy_table_names_cases_run_here():
    """Every row of the table is a case above (so test_family checks its figures), and the table is there."""
    if not README.is_file():
        pytest.skip("runs in a source checkout")
    rows = readme_rows()
    assert len(rows) >= 5 and set(rows) <= set(BY_NAME), sorted(rows)
    text = README.read_text(encoding="utf-8")
    table = text[text.index("| case | max"):].split("\n\n")[0].splitlines()[2:]
    assert len(table) == len(rows), "a row of the accuracy table is not in the form the test reads"


@pytest.mark.parametrize("name", FMU_CASES)
@pytest.mark.slow
def test_family_through_fmpy(fmu, name):
    fmpy = pytest.importorskip("fmpy")
    case = BY_NAME[name]
    start = {"m": case.m, "k": case.k, "b": case.b, "R": case.R, "g": case.g, "h": case.h0, "v": case.v0,
             "F_ext": case.F_ext}
    out = fmpy.simulate_fmu(str(fmu), start_values=start, stop_time=case.t_end, output_interval=case.dt,
                            output=["h", "v", "impacts"])
    t, h, impacts = out["time"], out["h"], out["impacts"]
    problems = judge(case, INTEGRATOR_TOLERANCE, t, h, None, None)  # the FMU gives no event list
    problems += impact_count_problems(case, t, impacts)
    assert problems == [], f"{case.name} [fmu]: " + "; ".join(problems)


def impact_count_problems(case: Case, t, impacts) -> list[str]:
    """The FMU's impact counter against the oracle's impacts: each required one counted once its time
    (plus tolerance) has passed, none counted before its time (minus tolerance)."""
    oracle = oracle_of(case)
    H = max(float(np.max(np.abs(oracle_states(case, t)[0]))), case.R)
    listed = [(i, e) for i, e in enumerate(oracle.events) if e.kind == IMPACT]
    if not listed:
        low = high = np.zeros(len(t), dtype=int)
    else:
        times = np.array([float(e.time) for _, e in listed])
        slack = INTEGRATOR_TOLERANCE * np.minimum(H / np.array([abs(float(e.velocity)) for _, e in listed]),
                                                  case.t_end)
        optional = optional_events(oracle, case, lambda i: 0.0, mergeable_hop(case, "fmu"))
        required = np.array([i not in optional for i, _ in listed])
        low = ((times[None, :] + slack[None, :] < t[:, None]) & required[None, :]).sum(axis=1)
        high = (times[None, :] - slack[None, :] <= t[:, None]).sum(axis=1)
    bad = np.flatnonzero((impacts < low) | (impacts > high))
    if not len(bad):
        return []
    i = bad[0]
    return [f"impacts {int(impacts[i])} at t = {t[i]:.9g} s, oracle {int(low[i])}..{int(high[i])} "
            f"({len(bad)} output points off; at t_end {int(impacts[-1])}, oracle {int(low[-1])}..{int(high[-1])})"]


# --- the property test: where integrators lie ----------------------------------------------------
EXAMPLES = int(os.environ.get("BOUNCINGBALL_EXAMPLES", "25"))
EXPLORING = os.environ.get("BOUNCINGBALL_HYPOTHESIS") == "explore"
PROPERTY = settings(max_examples=EXAMPLES, deadline=None,
                    phases=[Phase.explicit, Phase.reuse, Phase.generate] + ([Phase.shrink] if EXPLORING else []),
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
MAX_ORACLE_EVENTS = 200


def log_uniform(low: float, high: float):
    # a box drawn at its edge (low == high up to the rounding of log10) is one point, not an empty range
    exponents = math.log10(low), math.log10(high)
    return st.floats(min(exponents), max(exponents)).map(lambda x: 10.0**x)


@st.composite
def near_critical(draw) -> Case:
    """Damping ratio 1 +- 10^-(2..15) (or exactly 2 sqrt(k m)), lifted by 0..3 m g, starting near R."""
    R = draw(log_uniform(1e-8, 1e3))
    m = draw(log_uniform(1e-3, 1e2))
    deflection = R * draw(log_uniform(1e-4, 1e-1))  # m g / k
    k = m * G / deflection
    zeta = 1.0 + draw(st.sampled_from([-1.0, 0.0, 1.0])) * 10.0 ** -draw(st.floats(2, 15))
    lift = draw(st.sampled_from([0.0, 1.0, 2.0]) | st.floats(0, 3))
    w = math.sqrt(k / m)
    h0 = R - deflection * draw(st.floats(-2, 3))
    v0 = w * deflection * draw(st.floats(-3, 3))
    t_end = draw(st.floats(5, 60)) / w
    return Case("near-critical", m, k, 2 * zeta * math.sqrt(k * m), R, G, h0, v0, t_end, t_end / 400,
                F_ext=lift * m * G)


# 1e4 ulps of t (resolvable_until), with a margin: the stiffest contact a run to t can have
def fastest_contact_rate(t_end: float) -> float:
    return math.pi / (2e4 * 2.3e-16 * t_end)


@st.composite
def long_fall(draw) -> Case:
    """A fall of 1..1000 m onto a contact whose deflection v_impact / sqrt(k/m) is 1e-9..1e-3 of R.

    R and the deflection are drawn only where the contact is resolvable up to t_end (R >= ~1e-5 m):
    the rest of the box is refused by the package before any work.
    """
    drop = draw(log_uniform(1.0, 1e3))
    v_impact = math.sqrt(2 * G * drop)
    t_fall = math.sqrt(2 * drop / G)
    t_end = t_fall * draw(st.floats(1.001, 4.0))
    w_max = fastest_contact_rate(t_end)
    R = draw(log_uniform(max(1e-8, v_impact / (w_max * 1e-3)), 1e3))
    rho = draw(log_uniform(max(1e-9, v_impact / (w_max * R)), 1e-3))
    m = draw(log_uniform(1e-6, 10.0))
    w = v_impact / (rho * R)
    zeta = draw(st.sampled_from([0.0]) | st.floats(0, 1.5))
    k = m * w * w
    return Case("long-fall", m, k, 2 * zeta * math.sqrt(k * m), R, G, R + drop, 0.0, t_end, t_end / 500)


@st.composite
def micro_hops(draw) -> Case:
    """Undamped hops 1..1000 times the smallest resolvable one, from R, for up to ~90 hops."""
    R = draw(log_uniform(1e-8, 1e3))
    hop = SMALLEST_RESOLVABLE_HOP * R * draw(log_uniform(1.0, 1e3))
    v0 = math.sqrt(2 * G * hop)
    flight = 2 * v0 / G
    contact = flight * draw(log_uniform(1e-3, 10.0))
    w = math.pi / contact
    m = draw(log_uniform(1e-3, 1e2))
    t_end = (flight + contact) * draw(st.floats(1.0, 90.0))
    return Case("micro-hops", m, m * w * w, 0.0, R, G, R, v0, t_end, t_end / 400)


@pytest.mark.parametrize("api", APIS)
def test_a_restart_keeps_a_gap_below_an_ulp_of_r(api):
    """F_ext = m g to the last bit (rest height exactly R), damping ratio 1 - 1.5e-10: the ball creeps up to R.

    A state that carried h alone rounded the gap below ulp(R) to 0, and the stepping API's restarts then
    had the ball leave the ground (found by the near-critical property).
    """
    case = Case("near-critical", 0.02398975025259775, 682263.6222338036, 255.86976295570093, 0.0011303196992556316,
                9.81, 0.0011298348752669717, 1.8395252899208632e-203, 0.008054337604100086, 2.0135844010250215e-05,
                0.23533944997798392)
    assert_judged(case, api, run(case, api))


def property_check(case: Case, api: str) -> None:
    assume(math.isfinite(case.k) and case.k > 0 and resolvable_until(case.ball) >= case.t_end)
    try:
        oracle_of(case, MAX_ORACLE_EVENTS)
    except TooManyEvents:
        assume(False)
    outcome = run_stepping(case, advances=100) if api == "stepping" else run_simulate(case, api)
    assert_judged(case, api, outcome)


@PROPERTY
@pytest.mark.parametrize("api", APIS)
@given(case=near_critical())
def test_near_critical_damping(api, case):
    property_check(case, api)


@PROPERTY
@pytest.mark.parametrize("api", APIS)
@given(case=long_fall())
def test_stiff_contact_after_a_long_fall(api, case):
    property_check(case, api)


@PROPERTY
@pytest.mark.parametrize("api", APIS)
@given(case=micro_hops())
@pytest.mark.slow
def test_undamped_micro_hops(api, case):
    property_check(case, api)
