"""Claims about groups of runs, each decided by a stated test at a stated level.

The paper's findings (eval/findings.py) and the study's questions (eval/study.py) are made of the
claims built here: a comparison of two groups (`reach_comparison`, `robust_comparison`, settled by
`settle`) or a claim about one group alone (`one_group`). Each returns a `Part` whose verdict comes
from the rules below, none of which depends on the data.

**Outcomes per seed.** Per-seed outcomes are close to all-or-nothing (a seed solves the task or it
does not), so every claim is read as a claim about counts of seeds:

- *reaching 0.8*: success from p0 at or above `THRESHOLD` at some evaluation up to the step compared
  (eval/statistics.py's `seed_outcomes`), and the step it first did (never: tied last);
- *robust*: the seed's mean success from ood over the late window (the evaluations past two thirds of
  the step compared, eval/aggregate.py's `LATE_FRACTION`) is at least `ROBUST`.

**A comparison** ("A reaches 0.8 more often or sooner than B", "A is more robust than B") is made on
MATCHED seeds: only the seeds both groups have, each up to the last evaluation step both have
(`matched`). Two tests decide it, both two-sided, from eval/statistics.py:

- a claim about reaching 0.8: Fisher's exact test on the reach counts and the rank test (Mann-Whitney U
  by permutation) on the steps to 0.8, a seed that never got there tied last;
- a claim about robustness: Fisher's exact test on the counts of robust seeds and the permutation test
  of the difference in mean late-window success from ood.

The p-values of the comparisons settled together (`settle`) form one family, Holm-corrected
(`stats.holm`): eval/findings.py settles all the findings' comparisons at once, eval/study.py each
question's on each task. A test rejects when its adjusted p-value is at most `ALPHA`. A claim that A
is better than B is **supported** when a test rejects with A ahead and none rejects with B ahead;
**contradicted** when a test rejects with B ahead and none with A ahead. When none rejects, the power
decides what that means: the exact power of Fisher's test at `ALPHA` with these seeds (eval/statistics.py's `power`) to
detect the effect the claim implies, a difference of `EFFECT` (0.3) in the rate, placed around the
observed pooled rate (pooled - 0.15 against pooled + 0.15, shifted to stay within [0, 1]). Below
`POWER` (80%) the verdict is **not enough seeds to decide**, with the seeds per group that would give
80% (`seeds_needed`); at or above it, **no difference found**. The power is that of one test at
`ALPHA`; the correction across the family only lowers it, so an adequate power here is an upper bound.
A claim that A *matches* B is supported when no test rejects and the power is adequate, contradicted
when a test rejects either way, and not enough seeds to decide otherwise. A claim that the paper
states as a ratio of steps (finding 2's "a third of the steps") is tested as the comparison it implies,
sooner or more often: a ratio of medians has no test when seeds never reach 0.8.

**A claim about one group alone** ("SAC stays near 0") counts the seeds with the event the claim names
and takes the exact (Clopper-Pearson) 95% interval of its rate (`stats.reach_count`): a claim that few
seeds do it is supported when the interval lies below `MOST` (0.5), contradicted when it lies above,
and otherwise not enough seeds to decide, with the fewest seeds at which the observed rate's interval
would leave 0.5 out. (A claim that most seeds do it: the other way round.)
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from lava_bridge_mj.eval import statistics as stats
from lava_bridge_mj.eval.aggregate import LATE_FRACTION, Group, groups_of
from lava_bridge_mj.eval.summary import THRESHOLD

ALPHA, POWER = stats.ALPHA, stats.POWER
EFFECT = 0.3
"""The difference in rate a comparison claim implies, for the power of a test that does not reject."""
MOST = 0.5
"""A claim about one group alone is about most seeds (rate above this) or few (below)."""
ROBUST = 0.5
"""Mean late-window success from ood at which a seed counts as robust."""
TOLERANCE = 1e-9
"""Success rates are multiples of 1/50 that may come out as 0.10000000000000002."""

SUPPORTED, CONTRADICTED = "supported", "contradicted"
UNDECIDED, NO_DIFFERENCE = "not enough seeds to decide", "no difference found"
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
    """Where no test of a comparison rejected: the fewest seeds per group that give Fisher's test `POWER`
    to detect `EFFECT` around the observed rates (`power_text`); None where a test rejected, for a claim
    about one group, and beyond `stats.MAX_SEEDS`."""


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


# --- comparisons, before and after the correction ----------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Pending:
    """A comparison claim with its raw p-values, waiting for the family's correction."""

    claim: str
    measured: str
    p: dict[str, float]
    """Test name -> raw two-sided p-value."""
    a_ahead: dict[str, bool | None]
    """Test name -> True when A's side is ahead, False when B's, None when they are level."""
    counts: tuple[int, int, int, int]
    """A's events and seeds, B's events and seeds: the binary outcome behind the power."""
    matches: bool = False
    """The claim is that A matches B (no difference), not that A is better."""


def reach_comparison(a: Group, b: Group, claim: str, matches: bool = False) -> Pending | None:
    """A against B on reaching `THRESHOLD` from p0: Fisher's test on the reach counts, the rank test
    on the steps to it; None when the groups share no seed or step."""
    pair = matched(a, b)
    if pair is None:
        return None
    a, b = pair
    outcomes = [stats.seed_outcomes(g, THRESHOLD) for g in (a, b)]
    c = stats.compare(*outcomes)
    ra, rb = c.a.reach, c.b.reach
    p = {"Fisher's test on reach counts": c.p["reach"], "rank test on steps to 0.8": c.p["steps"]}
    ahead = {"Fisher's test on reach counts": None if ra.rate == rb.rate else ra.rate > rb.rate,
             "rank test on steps to 0.8": None if c.sooner == 0.5 else c.sooner > 0.5}
    measured = (f"seeds {_seeds_text(sorted(a.seeds))} to step {c.a.step:,.0f}: reached 0.8 {_count(ra)} against "
                f"{_count(rb)}, P(A sooner) = {c.sooner:.2f}")
    return Pending(claim, measured, p, ahead, (ra.reached, ra.seeds, rb.reached, rb.seeds), matches)


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
    robust = [stats.reach_count(int((x >= ROBUST - TOLERANCE).sum()), len(x)) for x in late]
    means = [float(x.mean()) for x in late]
    p = {"Fisher's test on robust-seed counts": stats.fisher_p(robust[0].reached, robust[0].seeds,
                                                              robust[1].reached, robust[1].seeds),
         "permutation test on late ood success": stats.permutation_p(*late)}
    ahead = {"Fisher's test on robust-seed counts": None if robust[0].rate == robust[1].rate
             else robust[0].rate > robust[1].rate,
             "permutation test on late ood success": None if means[0] == means[1] else means[0] > means[1]}
    measured = (f"seeds {_seeds_text(sorted(a.seeds))} to step {a.steps[-1]:,.0f}: mean late-window success from ood "
                f"{means[0]:.2f} against {means[1]:.2f}, robust seeds (>= {ROBUST:g}) {_count(robust[0])} against "
                f"{_count(robust[1])}")
    return Pending(claim, measured, p, ahead, (robust[0].reached, robust[0].seeds, robust[1].reached, robust[1].seeds))


def claimed_rates(events_a: int, seeds_a: int, events_b: int, seeds_b: int) -> tuple[float, float]:
    """The rates a difference of `EFFECT` implies around the pooled observed rate, within [0, 1]."""
    pooled = (events_a + events_b) / (seeds_a + seeds_b)
    low = min(max(pooled - EFFECT / 2, 0.0), 1.0 - EFFECT)
    return low + EFFECT, low


def power_text(counts: tuple[int, int, int, int]) -> tuple[float, int | None, str]:
    """The power of Fisher's test to detect `EFFECT` around the pooled rate with these seeds, the seeds
    per group that give `POWER` (None beyond `stats.MAX_SEEDS`), and the two in words."""
    high, low = claimed_rates(*counts)
    power = stats.power(high, low, counts[1], counts[3])
    needed = stats.seeds_needed(high, low)
    text = (f"power {power:.2f} to detect {high:.2f} against {low:.2f}; "
            + (f"{needed} seeds per group give {POWER:.0%}" if needed else f"more than {stats.MAX_SEEDS} seeds "
               f"per group needed for {POWER:.0%}"))
    return power, needed, text


def settle(pending: list[Pending], untested: int = 0, alpha: float = ALPHA) -> list[Part]:
    """The verdicts of the comparisons, their p-values Holm-corrected as one family and rejected at
    `alpha` (the power beside a verdict stays at `ALPHA`). `untested` p-values of the family are not
    computed yet (comparisons whose runs are still to come): each counts as 1, so the correction is over
    the whole family, and as Holm's adjusted p-values never rise when another p-value falls, a rejection
    made now stands once they are computed."""
    raw = [p for c in pending for p in c.p.values()]
    adjusted = iter(stats.holm(raw + [1.0] * untested))
    parts = []
    for c in pending:
        tests, rejected = [], set()
        for name, p in c.p.items():
            adj = next(adjusted)
            tests.append(f"{name} p = {p:.3g} (Holm {adj:.3g})" if math.isfinite(p) else f"{name}: no test")
            if math.isfinite(adj) and adj <= alpha and c.a_ahead[name] is not None:
                rejected.add(c.a_ahead[name])
        power, needed, text = power_text(c.counts)
        if c.matches:
            verdict = CONTRADICTED if rejected else SUPPORTED if power >= POWER else UNDECIDED
        elif rejected == {True}:
            verdict = SUPPORTED
        elif rejected == {False}:
            verdict = CONTRADICTED
        else:
            verdict = NO_DIFFERENCE if power >= POWER and not rejected else UNDECIDED
        parts.append(Part(c.claim, c.measured, verdict, "; ".join(tests), "" if rejected else text,
                          None if rejected else needed))
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
