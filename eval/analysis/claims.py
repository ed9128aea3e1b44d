"""Claims about groups of runs, each decided by a stated test at a stated level.

The paper's findings (eval/analysis/findings.py) and the study's questions (eval/analysis/study.py) are made of the
claims built here: a comparison of two groups (`reach_comparison`, `robust_comparison`, settled by
`settle`) or a claim about one group alone (`one_group`). Each returns a `Part` whose verdict comes
from the rules below, none of which depends on the data.

**Outcomes per seed.** Per-seed outcomes are close to all-or-nothing (a seed solves the task or it
does not), so every claim is read as a claim about counts of seeds:

- *reaching 0.8*: success from p0 at or above `THRESHOLD` at some evaluation up to the step compared
  (eval/analysis/statistics.py's `seed_outcomes`), and the step it first did (never: tied last);
- *robust*: the seed's mean success from ood over the late window (the evaluations past two thirds of
  the step compared, eval/analysis/aggregate.py's `LATE_FRACTION`) is at least `ROBUST`.

**A comparison** ("A reaches 0.8 more often or sooner than B", "A is more robust than B") is made on
MATCHED seeds: only the seeds both groups have, each up to the last evaluation step both have
(`matched`). Two tests decide it, both two-sided, from eval/analysis/statistics.py:

- a claim about reaching 0.8: Fisher's exact test on the reach counts and the rank test (Mann-Whitney U
  by permutation) on the steps to 0.8, a seed that never got there tied last;
- a claim about robustness: Fisher's exact test on the counts of robust seeds and the permutation test
  of the difference in mean late-window success from ood.

**The verdicts** of the comparisons settled together (`settle`, one family: eval/analysis/findings.py settles all
the findings' comparisons at once, eval/analysis/study.py each question on each task), at a level `alpha` (`ALPHA`,
or the stricter level of a study read at two looks):

- **supported** (A ahead) when a test rejects, its p-value Holm-corrected across every test of the family
  (`stats.holm`), with A ahead, and none rejects with B ahead; **contradicted** (B ahead) the other way
  round;
- **no difference found** when no test rejects and both effects of the comparison lie within
  +-`stats.EQUIVALENCE_MARGIN` (0.3) by the two one-sided tests (TOST): the rate difference of the count
  test (Newcombe's interval), and for the second test Cliff's delta of the steps to 0.8 (Brunner and
  Munzel's interval) or the difference in mean late-window success from ood (Welch's interval). Each
  comparison's TOST p-value is the larger of its two effects' (both must hold), Holm-corrected across the
  family's comparisons; equivalently, each effect's interval at 1 - 2 x the level of the comparison's Holm
  step lies inside the margin, and that interval is shown beside the verdict (`Part.equivalence`);
- **undecided** otherwise, with the seeds per group that would decide it at the levels the family is read
  at (`seeds_to_decide`): enough for Fisher's test at the strictest Holm step (`alpha` over the family's
  tests) to detect a difference of `EFFECT` (0.3) around the pooled rate with 80% power, and for the
  equivalence test at its strictest step (`alpha` over the family's comparisons) to bound the rate
  difference within the margin with 80% power if the rates are equal.

All the tests are exact or analytic (eval/analysis/statistics.py): no verdict depends on a random number. A claim
that A *matches* B is supported when no test rejects and the equivalence test does, contradicted when a
test rejects either way, and undecided otherwise. A claim that the paper states as a ratio of steps
(finding 2's "a third of the steps") is tested as the comparison it implies, sooner or more often: a
ratio of medians has no test when seeds never reach 0.8. The tests of each aspect are declared once, in
`TESTS`.

**A claim about one group alone** ("SAC stays near 0") counts the seeds with the event the claim names
and takes the exact (Clopper-Pearson) 95% interval of its rate (`stats.reach_count`): a claim that few
seeds do it is supported when the interval lies below `MOST` (0.5), contradicted when it lies above,
and otherwise undecided, with the fewest seeds at which the observed rate's interval
would leave 0.5 out. (A claim that most seeds do it: the other way round.)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from lava_bridge_mj.eval.analysis import statistics as stats
from lava_bridge_mj.eval.analysis.aggregate import LATE_FRACTION, Group, groups_of
from lava_bridge_mj.eval.analysis.summary import THRESHOLD

ALPHA, POWER = stats.ALPHA, stats.POWER
EFFECT = 0.3
"""The difference in rate a comparison claim implies, for the power of a test that does not reject; the
equivalence margin (`stats.EQUIVALENCE_MARGIN`) is the same 0.3."""
MOST = 0.5
"""A claim about one group alone is about most seeds (rate above this) or few (below)."""
ROBUST = 0.5
"""Mean late-window success from ood at which a seed counts as robust."""
TOLERANCE = 1e-9
"""Success rates are multiples of 1/50 that may come out as 0.10000000000000002."""

SUPPORTED, CONTRADICTED = "supported", "contradicted"
UNDECIDED, NO_DIFFERENCE = "undecided", "no difference found"
NOT_RUN = "not run"
"""A group a claim would compare with is absent."""


@dataclasses.dataclass(frozen=True)
class Part:
    """One tested statement of a finding: what it claims, the numbers and tests, and its verdict."""

    claim: str
    measured: str
    verdict: str
    tests: str = ""
    """Each test's raw and Holm-adjusted p-value; empty for a claim about one group."""
    power: str = ""
    """The power to detect the claimed effect and the seeds needed, where no test rejected."""
    seeds_needed: int | None = None
    """Where a comparison is undecided: the fewest seeds per group that would decide it at the family's
    levels (`seeds_to_decide`); None where it is decided, for a claim about one group, and beyond
    `stats.MAX_SEEDS`."""
    equivalence: str = ""
    """Where no test rejected: each effect's interval at the level its equivalence test is read at, and
    the TOST p-value."""


def is_default(group: Group) -> bool:
    """True when every setting that sets the group apart is RunConfig's default."""
    return not group.changed_settings


def pick(groups: list[Group], method: str, demos: int = 500) -> Group | None:
    """The method's group on that demo set in its default configuration; None if there is none."""
    return next((g for g in groups_of(groups, method, demos) if is_default(g)), None)


def until(group: Group, step: float) -> Group:
    return dataclasses.replace(group, runs=[
        dataclasses.replace(run, rows=[row for row in run.rows if row["step"] <= step]) for run in group.runs])


def matched(a: Group, b: Group) -> tuple[Group, Group] | None:
    """Both groups cut to the seeds they share, each up to the last evaluation step both have; None
    when they share no seed or no step."""
    seeds = set(a.seeds) & set(b.seeds)
    if not seeds:
        return None
    a, b = (dataclasses.replace(g, runs=[run for run in g.runs if run.seed in seeds]) for g in (a, b))
    if not (len(a.steps) and len(b.steps)):
        return None
    step = min(a.steps[-1], b.steps[-1])
    return until(a, step), until(b, step)


def _seeds_text(seeds: list[int]) -> str:
    """[0, 1, 2, 3, 5] -> '0-3, 5'."""
    spans, start = [], None
    for i, seed in enumerate(seeds):
        start = seed if start is None else start
        if i + 1 == len(seeds) or seeds[i + 1] != seed + 1:
            spans.append(f"{start}" if start == seed else f"{start}-{seed}")
            start = None
    return ", ".join(spans)


def _count(reach: stats.ReachCount) -> str:
    return f"{reach.reached}/{reach.seeds} [{reach.low:.2f}, {reach.high:.2f}]"


# --- the tests, declared once ----------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Test:
    """One test of a comparison, on the per-seed outcomes of A and B: its two-sided p-value and the effect
    its equivalence is bounded on; the effect's sign says which side is ahead."""

    name: str
    words: str
    """What A ahead means, as a verdict says it."""
    p: Callable[[np.ndarray, np.ndarray], float]
    effect: Callable[[np.ndarray, np.ndarray], stats.Effect]
    event: Callable[[np.ndarray], np.ndarray] | None = None
    """For a test on counts of seeds: which seeds count."""


def _counts(event: Callable[[np.ndarray], np.ndarray], a: np.ndarray, b: np.ndarray) -> tuple[int, int, int, int]:
    return int(event(a).sum()), len(a), int(event(b).sum()), len(b)


def _count_test(name: str, words: str, event: Callable[[np.ndarray], np.ndarray]) -> Test:
    """Fisher's exact test on the counts of seeds whose outcome shows `event`, bounded on the rate difference."""
    return Test(name, words, lambda a, b: stats.fisher_p(*_counts(event, a, b)),
                lambda a, b: stats.rate_effect(*_counts(event, a, b)), event)


def reached(first_reach: np.ndarray) -> np.ndarray:
    return np.isfinite(first_reach)


def robust(late: np.ndarray) -> np.ndarray:
    return late >= ROBUST - TOLERANCE


TESTS = {
    "learns faster": (
        _count_test("Fisher's test on reach counts", "reaches 0.8 more often", reached),
        Test("rank test on steps to 0.8", "reaches 0.8 sooner", stats.rank_p, stats.sooner_effect)),
    "more robust": (
        _count_test("Fisher's test on robust-seed counts", "has more robust seeds", robust),
        Test("permutation test on late ood success", "has higher late success from ood", stats.permutation_p,
             stats.mean_effect)),
}
"""Each aspect a comparison is made on, and its two tests: a count test and a rank or permutation test.
The per-seed outcome of *learns faster* is the first step at 0.8 (inf: never), of *more robust* the mean
late-window success from ood."""
TESTS_PER_COMPARISON = 2


# --- comparisons, before and after the correction ----------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Pending:
    """A comparison claim with its raw p-values and effects, waiting for the family's correction."""

    claim: str
    measured: str
    p: dict[str, float]
    """Test name -> raw two-sided p-value."""
    effects: dict[str, stats.Effect]
    """Test name -> A's difference from B that the test is about, with its interval."""
    counts: tuple[int, int, int, int]
    """A's events and seeds, B's events and seeds: the binary outcome behind the count test."""
    matches: bool = False
    """The claim is that A matches B (no difference), not that A is better."""

    def a_ahead(self, name: str) -> bool | None:
        """True when A's side is ahead on that test's effect, False when B's, None when they are level."""
        estimate = self.effects[name].estimate
        return None if abs(estimate) <= TOLERANCE else estimate > 0


def _pending(aspect: str, a: np.ndarray, b: np.ndarray, claim: str, measured: str, matches: bool) -> Pending:
    """The aspect's tests made on the per-seed outcomes `a` and `b`."""
    tests = TESTS[aspect]
    event = next(t.event for t in tests if t.event is not None)
    return Pending(claim, measured, {t.name: t.p(a, b) for t in tests}, {t.name: t.effect(a, b) for t in tests},
                   _counts(event, a, b), matches)


def reach_comparison(a: Group, b: Group, claim: str, matches: bool = False) -> Pending | None:
    """A against B on reaching `THRESHOLD` from p0: Fisher's test on the reach counts, the rank test
    on the steps to it; None when the groups share no seed or step."""
    pair = matched(a, b)
    if pair is None:
        return None
    a, b = pair
    outcomes = [stats.seed_outcomes(g, THRESHOLD) for g in (a, b)]
    steps = [o.first_reach for o in outcomes]
    sooner = (stats.sooner_effect(*steps).estimate + 1) / 2
    measured = (f"seeds {_seeds_text(sorted(a.seeds))} to step {outcomes[0].step:,.0f}: reached 0.8 "
                f"{_count(outcomes[0].reach)} against {_count(outcomes[1].reach)}, P(A sooner) = {sooner:.2f}")
    return _pending("learns faster", *steps, claim, measured, matches)


def late_ood(group: Group) -> np.ndarray:
    """Per seed, the mean success from ood over the evaluations past two thirds of the group's last
    common step."""
    steps = group.steps
    window = steps > (1 - LATE_FRACTION) * steps[-1]
    return group.scores("success_ood")[:, window].mean(axis=1)


def robust_comparison(a: Group, b: Group, claim: str) -> Pending | None:
    """A against B on robustness: Fisher's test on the counts of robust seeds, the permutation test on
    the mean late-window success from ood; None when the groups share no seed or step."""
    pair = matched(a, b)
    if pair is None:
        return None
    a, b = pair
    late = [late_ood(g) for g in (a, b)]
    counts = [stats.reach_count(int(robust(x).sum()), len(x)) for x in late]
    measured = (f"seeds {_seeds_text(sorted(a.seeds))} to step {a.steps[-1]:,.0f}: mean late-window success from ood "
                f"{late[0].mean():.2f} against {late[1].mean():.2f}, robust seeds (>= {ROBUST:g}) {_count(counts[0])} "
                f"against {_count(counts[1])}")
    return _pending("more robust", *late, claim, measured, False)


def claimed_rates(events_a: int, seeds_a: int, events_b: int, seeds_b: int) -> tuple[float, float]:
    """The rates a difference of `EFFECT` implies around the pooled observed rate, within [0, 1]."""
    pooled = (events_a + events_b) / (seeds_a + seeds_b)
    low = min(max(pooled - EFFECT / 2, 0.0), 1.0 - EFFECT)
    return low + EFFECT, low


def seeds_to_decide(pending: Pending, difference_level: float, equivalence_level: float) -> tuple[int | None, str]:
    """The seeds per group that would decide a comparison no test decides, at the levels the family is read
    at: enough for Fisher's test at `difference_level` to detect `EFFECT` around the pooled rate with
    `POWER`, and for the equivalence test at `equivalence_level` to bound each of the comparison's effects
    within the margin with `POWER` if it is 0 (the rate difference's power exactly, at the pooled rate; the
    other effect's from its error per seed); the largest of these (None beyond `stats.MAX_SEEDS`), and the
    figures in words."""
    counts = pending.counts
    high, low = claimed_rates(*counts)
    power = stats.power(high, low, counts[1], counts[3], alpha=difference_level)
    to_detect = stats.seeds_needed(high, low, alpha=difference_level)
    pooled = (counts[0] + counts[2]) / (counts[1] + counts[3])
    to_bound = [stats.seeds_for_equivalence(pooled, equivalence_level)] + [
        stats.seeds_for_equivalence_of(e, equivalence_level) for e in pending.effects.values() if e.unit_error is not None]
    needed = None if None in [to_detect, *to_bound] else max(to_detect, *to_bound)

    def seeds(n: int | None) -> str:
        return f"{n}" if n else f"more than {stats.MAX_SEEDS}"

    text = (f"power {power:.2f} to detect {high:.2f} against {low:.2f} at {difference_level:.3g}; {POWER:.0%} power "
            f"needs {seeds(to_detect)} seeds per group for that and {' and '.join(seeds(n) for n in to_bound)} to "
            f"bound the effects within +-{stats.EQUIVALENCE_MARGIN:g} at {equivalence_level:.3g} (a rate difference "
            f"at {pooled:.2f}, then the other effect)")
    return needed, text


def _interval_text(effect: stats.Effect, confidence: float) -> str:
    low, high = effect.interval(confidence)
    return f"{effect.measure} {effect.estimate:+.2f} [{low:+.2f}, {high:+.2f}]"


def settle(pending: list[Pending], untested: int = 0, alpha: float = ALPHA) -> list[Part]:
    """The verdicts of the comparisons, read at `alpha` as one family. Differences: every test's p-value
    Holm-corrected across the family. Equivalence: per comparison the larger of its two tests' TOST
    p-values (both effects within the margin), Holm-corrected across the family's comparisons. `untested`
    comparisons of the family are not made yet (their runs are still to come): each counts its p-values as
    1, so the correction is over the whole family, and as Holm's adjusted p-values never rise when another
    p-value falls, a verdict given now stands once they are made."""
    raw = [p for c in pending for p in c.p.values()]
    adjusted = iter(stats.holm(raw + [1.0] * (TESTS_PER_COMPARISON * untested)))
    equivalence = [max(stats.equivalence_p(e) for e in c.effects.values()) for c in pending]
    comparisons = len(pending) + untested
    equivalence_adjusted = stats.holm(equivalence + [1.0] * untested)
    # the level of each comparison's own Holm step: its interval at 1 - 2 x that level is what TOST reads
    order = np.argsort(equivalence, kind="stable")
    step_level = np.empty(len(pending))
    step_level[order] = alpha / (comparisons - np.arange(len(pending)))
    parts = []
    for i, c in enumerate(pending):
        tests, rejected = [], set()
        for name, p in c.p.items():
            adj = next(adjusted)
            tests.append(f"{name} p = {p:.3g} (Holm {adj:.3g})" if math.isfinite(p) else f"{name}: no test")
            if math.isfinite(adj) and adj <= alpha and c.a_ahead(name) is not None:
                rejected.add(c.a_ahead(name))
        equivalent = equivalence_adjusted[i] <= alpha
        confidence = 1 - 2 * step_level[i]
        bounds = (f"TOST against +-{stats.EQUIVALENCE_MARGIN:g} at {confidence:.2%}: "
                  + ", ".join(_interval_text(e, confidence) for e in c.effects.values())
                  + f"; TOST p = {equivalence[i]:.3g} (Holm {equivalence_adjusted[i]:.3g})")
        if c.matches:
            verdict = CONTRADICTED if rejected else SUPPORTED if equivalent else UNDECIDED
        elif rejected == {True}:
            verdict = SUPPORTED
        elif rejected == {False}:
            verdict = CONTRADICTED
        else:
            verdict = NO_DIFFERENCE if equivalent and not rejected else UNDECIDED
        needed, power = (None, "") if rejected or equivalent else seeds_to_decide(
            c, alpha / (TESTS_PER_COMPARISON * comparisons), alpha / comparisons)
        parts.append(Part(c.claim, c.measured, verdict, "; ".join(tests), power, needed,
                          "" if rejected else bounds))
    return parts


# --- claims about one group -----------------------------------------------------------------------
def one_group(claim: str, events: int, seeds: int, few: bool) -> Part:
    """A claim that few (or most) seeds of a group show an event, decided by the Clopper-Pearson interval
    of the rate against `MOST`."""
    reach = stats.reach_count(events, seeds)
    below, above = reach.high < MOST, reach.low > MOST
    if below or above:
        verdict = SUPPORTED if below == few else CONTRADICTED
        return Part(claim, f"{_count(reach)} of the seeds", verdict)
    rate = reach.rate
    needed = next((n for n in range(seeds + 1, stats.MAX_SEEDS + 1)
                   if not stats.reach_count(round(rate * n), n).low <= MOST <= stats.reach_count(round(rate * n),
                                                                                               n).high), None)
    power = (f"at the observed rate {needed} seeds would place the interval on one side of {MOST:g}" if needed
             else f"at the observed rate no number of seeds up to {stats.MAX_SEEDS} decides")
    return Part(claim, f"{_count(reach)} of the seeds", UNDECIDED, power=power)
