"""The judge of events (accuracy.event_mismatches) on event lists built by hand from the exact solution."""

import dataclasses

import numpy as np
import pytest

import bouncingball as bb
from bouncingball.accuracy import event_mismatches, impact_counts
from bouncingball.solvers.exact import ExactSolution
from bouncingball.solvers.result import DEPARTURE, IMPACT, Event
from oracle_counts import oracle_counts

ARTICLE = bb.Ball()
TOLERANCE = 1e-6  # m
MIN_HOP = 1e-9  # m


@pytest.fixture(scope="module")
def article():
    return ExactSolution(ARTICLE, 2.0, 0.0, 0.0, 8.0)


def shifted(event: Event, dt: float) -> Event:
    return dataclasses.replace(event, time=event.time + dt)


def test_the_exact_events_agree_with_themselves(article):
    assert len(article.events) == oracle_counts(ARTICLE).events
    assert event_mismatches(list(article.events), article, TOLERANCE, MIN_HOP) == []


def test_an_event_is_late_only_beyond_the_time_the_ball_needs_to_move_by_the_tolerance(article):
    first = article.events[0]
    allowed = TOLERANCE / abs(first.velocity)
    late = [shifted(first, 0.9 * allowed), *article.events[1:]]
    assert event_mismatches(late, article, TOLERANCE, MIN_HOP) == []
    too_late = [shifted(first, 1.1 * allowed), *article.events[1:]]
    problems = event_mismatches(too_late, article, TOLERANCE, MIN_HOP)
    assert problems and problems[0].startswith(f"exact impact at t = {first.time!r} s")


def test_a_missing_bounce_or_a_wrong_kind_is_reported(article):
    missing = [*article.events[:4], *article.events[6:]]  # the third bounce's departure and impact
    assert len(event_mismatches(missing, article, TOLERANCE, MIN_HOP)) == 2
    wrong_kind = [dataclasses.replace(article.events[0], kind=DEPARTURE), *article.events[1:]]
    assert event_mismatches(wrong_kind, article, TOLERANCE, MIN_HOP) != []


def test_a_hop_below_min_hop_may_be_missing_or_extra():
    """Undamped from the rest height, leaving R at 1e-5 m/s: hops of v^2 / 2 g = 5.1e-12 m."""
    ball = bb.Ball(b=0.0)
    v_departure = 1e-5
    v0 = ((ball.k / ball.m) * ball.static_deflection() ** 2 + v_departure**2) ** 0.5
    exact = ExactSolution(ball, ball.rest_height(), v0, 0.0, 0.1)
    assert [e.kind for e in exact.events][:2] == [DEPARTURE, IMPACT]
    tolerance = 1e-12  # m: the ball moves by it in 1e-7 s at 1e-5 m/s, so no event is "at the end"
    assert event_mismatches([], exact, tolerance, min_hop=1e-9) == []  # merged into the contact
    assert event_mismatches([], exact, tolerance, min_hop=1e-13) != []  # a hop above min_hop must be found
    at_rest = ExactSolution(bb.Ball(), bb.Ball().rest_height(), 0.0, 0.0, 1.0)
    assert at_rest.events == []
    extra = [Event(0.5, DEPARTURE, v_departure), Event(0.5 + 2 * v_departure / ball.g, IMPACT, -v_departure)]
    assert event_mismatches(extra, at_rest, TOLERANCE, min_hop=1e-9) == []
    assert event_mismatches(extra, at_rest, TOLERANCE, min_hop=1e-13) != []


def test_an_event_within_its_tolerance_of_the_end_may_fall_on_either_side(article):
    last = article.events[-1]
    t_end = last.time + 0.5 * TOLERANCE / abs(last.velocity)
    exact = ExactSolution(ARTICLE, 2.0, 0.0, 0.0, t_end)
    assert event_mismatches(list(exact.events[:-1]), exact, TOLERANCE, MIN_HOP) == []  # found past the end
    early = Event(t_end - 0.5 * TOLERANCE / abs(last.velocity), IMPACT, last.velocity)
    before = ExactSolution(ARTICLE, 2.0, 0.0, 0.0, early.time - 1e-12)
    assert event_mismatches([*before.events, early], before, TOLERANCE, MIN_HOP) == []  # found before it
    far = Event(early.time - 10 * TOLERANCE / abs(last.velocity), IMPACT, last.velocity)
    assert event_mismatches([*before.events, far], before, TOLERANCE, MIN_HOP) != []


def test_impact_counts_without_mergeable_impacts_is_the_per_point_rule():
    """Against the rule stated directly: before(t - tie) <= count <= up_to(t + tie), for non-decreasing counts."""
    rng = np.random.default_rng(7)
    for _ in range(500):
        times = np.sort(rng.uniform(0.0, 10.0, rng.integers(0, 8)))
        t = np.sort(rng.choice(np.linspace(0.0, 10.0, 41), rng.integers(1, 30)))
        tie = float(rng.choice([0.0, 0.1, 0.3]))
        exact = np.searchsorted(times, t, side="right")
        counts = np.maximum.accumulate(np.maximum(exact + rng.choice([0, 0, 0, 1, -1], len(t)), 0))
        wrong = (counts < np.searchsorted(times, t - tie, side="left")) | \
            (counts > np.searchsorted(times, t + tie, side="right"))
        assert np.array_equal(impact_counts(times, t, counts, tie).mismatches, np.flatnonzero(wrong))


def test_impact_counts_lets_mergeable_impacts_go_missing_and_nothing_else():
    times = np.array([1.0, 2.0, 3.0, 4.0])
    t = np.array([0.5, 1.5, 2.5, 3.5, 4.5])
    mergeable = np.array([False, True, True, False])
    counts = impact_counts(times, t, np.array([0, 1, 1, 1, 2]), mergeable=mergeable)  # 2 and 3 merged
    assert counts.mismatches.tolist() == [] and counts.merged.tolist() == [1, 2]
    missing_4 = impact_counts(times, t, np.array([0, 1, 1, 1, 1]), mergeable=mergeable)
    assert missing_4.mismatches.tolist() == [4]
    assert impact_counts(times, t, np.array([0, 1, 1, 2, 3]), mergeable=mergeable).merged.tolist() == [1]
    made_up = impact_counts(times, t, np.array([0, 1, 1, 1, 3]), mergeable=mergeable)  # 2 and 3 merged, one extra
    assert made_up.mismatches.tolist() == [4]
    went_back = impact_counts(times, t, np.array([0, 1, 2, 1, 2]), mergeable=mergeable)  # 2 counted, then uncounted
    assert went_back.mismatches.tolist() == [3, 4]  # and at 4.5 s, 2 is one short of 1, 2 and 4
