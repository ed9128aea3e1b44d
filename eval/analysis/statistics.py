"""Statistics for nearly all-or-nothing outcomes: reach counts, exact and rank tests, power.

Per seed, success from p0 tends to be 0 or about 1 for most of training: a seed solves the task or
it does not. An IQM across 10-15 such seeds reads 1.0 whenever three or fewer fail, so the report
also states, per group and per pair of groups:

- **Reach count**: the seeds whose success from p0 reached the threshold at some evaluation up to the
  step compared, with the exact (Clopper-Pearson) 95% interval of the reach rate.
- **Fisher's exact test** (two-sided) on the two groups' reach counts. Fisher's rather than Barnard's:
  conditioning on the total makes it slightly conservative, but its p-value for every table of a
  given size comes from one hypergeometric distribution, which is what lets `power` enumerate all
  outcomes exactly.
- **Rank test on steps to threshold**: Mann-Whitney U (two-sided) with every seed that never got
  there tied in last place, its p-value from the exact permutation distribution of U, so the many
  ties are handled without a normal approximation.
- **Permutation tests** on the final success from p0 and on each seed's mean over the late window
  (eval/analysis/aggregate.py's last third): the difference of the group means, two-sided.
- Both permutation p-values are **exact**: every split of the seeds into the two groups is counted, by
  dynamic programming over the distinct values (`permutation_sum_p`; 49 against 49 seeds have 2.5e28
  splits), so no verdict depends on a random number. Values off any grid (never the case for success
  rates of finitely many episodes, or for midranks) fall back to random splits, drawn until the p-value's
  99.9% interval leaves the level it is compared with on one side.
- **Holm's correction** across the pairs a report tests, one family per test.
- **Difference in rate** between two groups (the effect size behind Fisher's test) with Newcombe's
  hybrid score interval (his method 10: each rate's Wilson interval, combined), which keeps its
  coverage near 95% at a handful of seeds and at rates of 0 or 1, where the Wald interval collapses.
- **Probability of improvement** (rliable's definition: P(X > Y) + P(X = Y) / 2 for a random seed of
  each group) of the late-window success from p0, and the **area under the success curve** per seed,
  normalised by the steps it spans (1 = success 1.0 at every evaluation).
- **Power**: the probability that Fisher's test at level `ALPHA` rejects, for given reach rates and
  seeds per group, computed exactly by summing the binomial probabilities of every outcome table that
  the test rejects (no normal approximation); `seeds_needed` is the smallest number of seeds per group
  that gives `POWER` (80%), up to `MAX_SEEDS`. An exact test's power is not monotone in the number of
  seeds (it saws up and down with the discreteness of the p-values); `seeds_needed` is the first
  number of seeds that reaches the target.

Everything here takes arrays of per-seed values (numpy and scipy; rliable for the probability of
improvement) except `seed_outcomes`, which reads them from a group of runs.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from fractions import Fraction

import numpy as np
import scipy.integrate
import scipy.optimize
import scipy.stats

from lava_bridge_mj.eval.analysis.aggregate import LATE_FRACTION

ALPHA = 0.05
"""Level of every test and of the power calculation."""
POWER = 0.8
"""The power `seeds_needed` asks for."""
MAX_SEEDS = 100
"""`seeds_needed` looks no further than this many seeds per group."""
CONFIDENCE = 0.95
PERMUTATIONS = 10_000
"""Random splits per batch of a Monte Carlo p-value, the fallback for values off every grid (never the
case for success rates or midranks, whose p-values are exact)."""
PERMUTATION_SEED = 2024
"""Seed of the Monte Carlo fallback's draws."""
_RELATIVE_TOLERANCE = 1 + 1e-7
"""Tables whose probability equals the observed one up to rounding count as at least as extreme."""


# --- per group -----------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class ReachCount:
    """`reached` of `seeds` seeds got to the threshold; [low, high] is the exact interval of the rate."""

    reached: int
    seeds: int
    low: float
    high: float

    @property
    def rate(self) -> float:
        return self.reached / self.seeds if self.seeds else math.nan


@functools.cache  # asked for again by each table and pair the group is in
def reach_count(reached: int, seeds: int, confidence: float = CONFIDENCE) -> ReachCount:
    """The reach count with its Clopper-Pearson interval (scipy's exact binomial interval)."""
    if not 0 <= reached <= seeds or seeds < 1:
        raise ValueError(f"a reach count needs 0 <= reached <= seeds and seeds >= 1, got {reached} of {seeds}")
    interval = scipy.stats.binomtest(reached, seeds).proportion_ci(confidence, method="exact")
    return ReachCount(reached, seeds, float(interval.low), float(interval.high))


@dataclasses.dataclass(frozen=True)
class RateDifference:
    """Rate A minus rate B with the [low, high] confidence interval of the difference."""

    difference: float
    low: float
    high: float


def rate_difference(events_a: int, seeds_a: int, events_b: int, seeds_b: int,
                    confidence: float = CONFIDENCE) -> RateDifference:
    """The difference of two binomial rates and its Newcombe hybrid score interval (Newcombe 1998,
    method 10), from scipy's Wilson score interval of each rate."""
    for events, seeds in ((events_a, seeds_a), (events_b, seeds_b)):
        if not 0 <= events <= seeds or seeds < 1:
            raise ValueError(f"a rate needs 0 <= events <= seeds and seeds >= 1, got {events} of {seeds}")
    rate_a, rate_b = events_a / seeds_a, events_b / seeds_b
    (low_a, high_a), (low_b, high_b) = (
        scipy.stats.binomtest(k, n).proportion_ci(confidence, method="wilson") for k, n in
        ((events_a, seeds_a), (events_b, seeds_b)))
    difference = rate_a - rate_b
    return RateDifference(difference, difference - math.hypot(rate_a - low_a, high_b - rate_b),
                          difference + math.hypot(high_a - rate_a, rate_b - low_b))


def normalised_auc(steps: np.ndarray, success: np.ndarray) -> np.ndarray:
    """Area under each row of `success` (seeds, steps) over `steps` by the trapezoid rule, divided by
    the steps spanned: the mean success over training, 1 for success 1.0 throughout. With a single
    evaluation, that evaluation's value."""
    steps, success = np.asarray(steps, float), np.atleast_2d(np.asarray(success, float))
    if len(steps) == 1:
        return success[:, 0].copy()
    return np.trapezoid(success, steps, axis=1) / (steps[-1] - steps[0])


@dataclasses.dataclass(frozen=True)
class SeedOutcomes:
    """A group's per-seed outcomes up to `step`, the last evaluation step compared."""

    step: float
    first_reach: np.ndarray
    """Per seed, the first evaluation step with success from p0 at or above the threshold; inf if none."""
    final: np.ndarray
    """Per seed, success from p0 at `step`."""
    late: np.ndarray
    """Per seed, the mean success from p0 over the evaluations past two thirds of `step`."""
    auc: np.ndarray
    """Per seed, `normalised_auc` of success from p0 over the evaluations up to `step`."""

    @property
    def reach(self) -> ReachCount:
        return reach_count(int(np.isfinite(self.first_reach).sum()), len(self.first_reach))


def seed_outcomes(group, threshold: float, until: float | None = None) -> SeedOutcomes | None:
    """The outcomes of a group (eval/analysis/aggregate.py's `Group`) over its evaluations up to step `until`
    (default: all of them), measured at the last step that all of its seeds have there; None when
    its seeds share no step up to `until`."""
    steps = group.steps
    kept = steps <= until if until is not None else np.ones(len(steps), bool)
    if not kept.any():
        return None
    steps, success = steps[kept], group.scores("success_p0")[:, kept]
    step = steps[-1]
    first = []
    for run in group.runs:  # every evaluation of the run up to `step`, not only the common ones
        hits = [row["step"] for row in run.rows if row["step"] <= step and row["success_p0"] >= threshold]
        first.append(min(hits) if hits else math.inf)
    window = steps > (1 - LATE_FRACTION) * step
    return SeedOutcomes(float(step), np.array(first, float), success[:, -1], success[:, window].mean(axis=1),
                        normalised_auc(steps, success))


# --- tests between two groups --------------------------------------------------------------------
def fisher_p(reached_a: int, seeds_a: int, reached_b: int, seeds_b: int) -> float:
    """Two-sided p-value of Fisher's exact test on the 2x2 table of reached / not reached."""
    table = [[reached_a, seeds_a - reached_a], [reached_b, seeds_b - reached_b]]
    return float(scipy.stats.fisher_exact(table).pvalue)


# --- exact permutation distributions -------------------------------------------------------------
GRID_DENOMINATOR = 100_000
"""Values whose fractions need a larger denominator than this are off the grid the exact tests use."""
GRID_SUM = 250_000
"""The exact tests count subsets by their integer score sum up to this size (memory: 8 bytes x seeds x it)."""
MONTE_CARLO_LEVEL = 0.999
"""Confidence of the interval a Monte Carlo p-value is drawn until, around it, no level lies."""
MONTE_CARLO_MOST = 2_000_000
"""Most random splits a Monte Carlo p-value draws."""


def _integer_scores(values: np.ndarray) -> np.ndarray | None:
    """`values` as non-negative integers on a common grid (shifted by the smallest and scaled by the least
    common denominator of their fractions), or None when they are off any grid of `GRID_DENOMINATOR`."""
    fractions = [Fraction(float(v)).limit_denominator(GRID_DENOMINATOR) for v in values]
    if any(abs(float(f) - v) > 1e-12 * max(1.0, abs(v)) for f, v in zip(fractions, values)):
        return None
    scale, low = math.lcm(*(f.denominator for f in fractions)), min(fractions)
    scores = [int((f - low) * scale) for f in fractions]
    return np.array(scores, np.int64) if max(scores) * len(scores) <= GRID_SUM else None


@functools.lru_cache(maxsize=1024)
def _subset_sums(levels: tuple[int, ...], counts: tuple[int, ...], size: int) -> np.ndarray:
    """ways[s]: how many of the `size`-item subsets of a pool (`counts[i]` items scoring `levels[i]`)
    have score sum s. Dynamic programming over the distinct scores (the network algorithm's idea):
    choosing j of the m items at a score adds C(m, j) ways; counts are floats, exact to 2^53 and
    relatively exact to 1e-16 beyond, far below any level a p-value is compared with."""
    total = sum(level * min(count, size) for level, count in zip(levels, counts)) + 1
    ways = np.zeros((size + 1, total))
    ways[0, 0] = 1.0
    for level, count in zip(levels, counts):
        grown = ways.copy()  # j = 0 of these items chosen
        for j in range(1, min(count, size) + 1):
            shift = j * level
            if shift >= total:
                break
            grown[j:, shift:] += math.comb(count, j) * ways[:size + 1 - j, :total - shift]
        ways = grown
    return ways[size]


def _exact_sum_p(scores: np.ndarray, size: int) -> float:
    """Two-sided p of the sum of the first `size` of `scores` over every split of them into `size` and the
    rest: twice the smaller tail, capped at 1 (scipy's `permutation_test` definition)."""
    levels, counts = np.unique(scores, return_counts=True)
    ways = _subset_sums(tuple(int(v) for v in levels), tuple(int(c) for c in counts), size)
    observed = int(scores[:size].sum())
    splits = ways.sum()
    less, greater = ways[:observed + 1].sum() / splits, ways[observed:].sum() / splits
    return float(min(1.0, 2 * min(less, greater)))


def _monte_carlo_sum_p(values: np.ndarray, size: int, seed: int, levels: Sequence[float]) -> float:
    """Two-sided p of the sum of the first `size` of `values` from random splits, drawn in batches of
    `PERMUTATIONS` until the `MONTE_CARLO_LEVEL` Clopper-Pearson interval of each tail leaves every level in
    `levels` (halved, as the p doubles the smaller tail) on one side, or `MONTE_CARLO_MOST` are drawn."""
    rng = np.random.default_rng(seed)
    observed = values[:size].sum()
    tolerance = 1e-12 * max(1.0, abs(observed))
    drawn = less = greater = 0
    while drawn < MONTE_CARLO_MOST:
        sums = rng.permuted(np.tile(values, (PERMUTATIONS, 1)), axis=1)[:, :size].sum(axis=1)
        drawn, less, greater = (drawn + PERMUTATIONS, less + int((sums <= observed + tolerance).sum()),
                                greater + int((sums >= observed - tolerance).sum()))
        tail = min(less, greater)
        interval = scipy.stats.binomtest(tail, drawn).proportion_ci(MONTE_CARLO_LEVEL, method="exact")
        if not any(interval.low <= level / 2 <= interval.high for level in levels):
            break
    return float(min(1.0, 2 * min(less, greater) / drawn))


def permutation_sum_p(a: np.ndarray, b: np.ndarray, seed: int = PERMUTATION_SEED,
                      levels: Sequence[float] = (ALPHA,)) -> float:
    """Two-sided permutation p-value of A's sum among the pooled values (for fixed totals, the difference
    of the means and the rank sum are monotone in it): exact, by counting every split, when the values
    lie on a grid (success rates of finitely many episodes, midranks); otherwise by Monte Carlo, drawn
    until no level of `levels` lies inside the p's 99.9% interval (`_monte_carlo_sum_p`)."""
    pooled = np.concatenate([a, b]).astype(float)
    scores = _integer_scores(pooled)
    if scores is not None:
        return _exact_sum_p(scores, len(a))
    return _monte_carlo_sum_p(pooled, len(a), seed, levels)


def _never_last(steps: np.ndarray, ceiling: float) -> np.ndarray:
    """Steps with `inf` (never reached) replaced by `ceiling`, above every finite step: all tied last."""
    return np.where(np.isfinite(steps), steps, ceiling)


def _ceiling(*steps: np.ndarray) -> float:
    """A step after every finite one of `steps`: where "never" ranks."""
    finite = np.concatenate(steps)
    finite = finite[np.isfinite(finite)]
    return finite.max() + 1 if len(finite) else 0.0


def rank_p(steps_a: Sequence[float], steps_b: Sequence[float], seed: int = PERMUTATION_SEED) -> float:
    """Two-sided Mann-Whitney U test on steps to threshold, `inf` (never) tied in last place, with the
    exact p-value of the permutation distribution of U (the midrank sum of A over every split of the
    seeds, `permutation_sum_p`), so the many ties need no normal approximation and no random draw. 1.0
    when all the values are equal; NaN (no test) when a group has a single seed."""
    a, b = np.asarray(steps_a, float), np.asarray(steps_b, float)
    if min(len(a), len(b)) < 2:
        return math.nan
    both = np.concatenate([a, b])
    if np.all(both == both[0]):  # nothing to rank (every seed never, or all at one step)
        return 1.0
    ranks = scipy.stats.rankdata(_never_last(both, _ceiling(a, b)))
    return permutation_sum_p(ranks[:len(a)], ranks[len(a):], seed)


def permutation_p(a: Sequence[float], b: Sequence[float], seed: int = PERMUTATION_SEED) -> float:
    """Two-sided permutation test of the difference of the means of `a` and `b` (`permutation_sum_p`:
    exact for values on a grid, as success rates are). NaN when a group has a single seed, as `rank_p`."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if min(len(a), len(b)) < 2:
        return math.nan
    if np.all(np.concatenate([a, b]) == a[0]):
        return 1.0
    return permutation_sum_p(a, b, seed)


def holm(p_values: Sequence[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values, in the order given: the k-th smallest of m is multiplied
    by m - k + 1, then made non-decreasing in that order and capped at 1. NaN entries (no test) are
    left out of the family and stay NaN."""
    p = np.asarray(p_values, float)
    adjusted = np.full(p.shape, np.nan)
    tested = np.flatnonzero(~np.isnan(p))
    order = tested[np.argsort(p[tested], kind="stable")]
    m = len(order)
    scaled = p[order] * (m - np.arange(m))
    adjusted[order] = np.minimum(np.maximum.accumulate(scaled), 1.0)
    return adjusted


def probability_of_improvement(a: Sequence[float], b: Sequence[float]) -> float:
    """rliable's probability of improvement of `a` over `b` on one task: P(A > B) + P(A = B) / 2 for
    a seed drawn from each group (the Mann-Whitney U of `a` divided by the number of pairs)."""
    from rliable import metrics  # the report's dependency (the plots extra)

    return float(metrics.probability_of_improvement(np.asarray(a, float)[:, None], np.asarray(b, float)[:, None]))


# --- power ---------------------------------------------------------------------------------------
@functools.cache
def fisher_rejections(seeds_a: int, seeds_b: int, alpha: float = ALPHA) -> np.ndarray:
    """Boolean (seeds_a + 1, seeds_b + 1) array: [x, y] is True when Fisher's two-sided test at level
    `alpha` rejects x of `seeds_a` against y of `seeds_b`. Computed for all tables at once: given the
    total t = x + y, x follows a hypergeometric distribution, and a table's p-value is the probability
    of the tables with that total that are no more likely than it (scipy's definition)."""
    rejects = np.zeros((seeds_a + 1, seeds_b + 1), bool)
    totals = np.arange(seeds_a + seeds_b + 1)
    # every total's probabilities in one call: scipy's per-call overhead, not the arithmetic, is the cost
    pmfs = scipy.stats.hypergeom.pmf(np.arange(seeds_a + 1), seeds_a + seeds_b, totals[:, None], seeds_a)
    for total in totals:
        x = np.arange(max(0, total - seeds_b), min(total, seeds_a) + 1)
        pmf = pmfs[total, x]
        p = (pmf[None, :] <= pmf[:, None] * _RELATIVE_TOLERANCE) @ pmf  # row i: tables no likelier than i
        rejects[x, total - x] = p <= alpha
    return rejects


def power(rate_a: float, rate_b: float, seeds_a: int, seeds_b: int | None = None, alpha: float = ALPHA) -> float:
    """Probability that Fisher's two-sided test at `alpha` rejects when the true reach rates are
    `rate_a` and `rate_b` with `seeds_a` and `seeds_b` (default: as many) seeds: the sum of the
    binomial probabilities of every table it rejects."""
    seeds_b = seeds_a if seeds_b is None else seeds_b
    for rate in (rate_a, rate_b):
        if not 0 <= rate <= 1:
            raise ValueError(f"a reach rate must be in [0, 1], got {rate}")
    chance = np.outer(scipy.stats.binom.pmf(np.arange(seeds_a + 1), seeds_a, rate_a),
                      scipy.stats.binom.pmf(np.arange(seeds_b + 1), seeds_b, rate_b))
    return float(chance[fisher_rejections(seeds_a, seeds_b, alpha)].sum())


def seeds_needed(rate_a: float, rate_b: float, target: float = POWER, alpha: float = ALPHA,
                 most: int = MAX_SEEDS) -> int | None:
    """The fewest seeds per group with which Fisher's test at `alpha` detects reach rates `rate_a`
    against `rate_b` with probability at least `target`; None when even `most` seeds do not."""
    if rate_a == rate_b:
        return None
    return next((n for n in range(2, most + 1) if power(rate_a, rate_b, n, alpha=alpha) >= target), None)


@functools.cache  # a pure function the report asks for once per task and table
def two_look_level(first: int, second: int, alpha: float = ALPHA) -> float:
    """The level to test at, at each of two looks at one comparison (after `first` and again after
    `second` seeds per group), so that the chance either look rejects a true tie is `alpha`: Pocock's
    constant boundary for two looks. It treats the test statistic as normal, so that the statistics of
    the two looks correlate by sqrt(first / second), and integrates their bivariate normal exactly (no
    sampling): at equal spacing (`second` = 2 x `first`) it is Pocock's tabled 0.0294 at 0.05."""
    if not 0 < first < second:
        raise ValueError(f"two looks need 0 < first < second seeds, got first={first}, second={second}")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    r = math.sqrt(first / second)
    spread = math.sqrt(1 - r * r)

    def both_inside(c):  # P(|Z1| < c and |Z2| < c), Z2 = r Z1 + spread x an independent standard normal
        inner = lambda z: scipy.stats.norm.pdf(z) * (scipy.stats.norm.cdf((c - r * z) / spread)  # noqa: E731
                                                      - scipy.stats.norm.cdf((-c - r * z) / spread))
        return scipy.integrate.quad(inner, -c, c, epsabs=1e-12, epsrel=1e-12)[0]

    one_look = scipy.stats.norm.isf(alpha / 2)
    boundary = scipy.optimize.brentq(lambda c: 1 - both_inside(c) - alpha, one_look, one_look + 2, xtol=1e-12)
    return float(2 * scipy.stats.norm.sf(boundary))


# --- a comparison of two groups ------------------------------------------------------------------
TESTS = ("reach", "steps", "final", "late")
"""The tests made for each pair: Fisher's on reach counts, the rank test on steps to threshold, and the
permutation tests on final and on late-window success from p0."""


@dataclasses.dataclass(frozen=True)
class Comparison:
    """Group A against group B, each up to the same step."""

    a: SeedOutcomes
    b: SeedOutcomes
    p: dict[str, float]
    """Raw two-sided p-value of each of `TESTS`."""
    sooner: float
    """P(a seed of A reaches the threshold before one of B) + P(tie) / 2, never-reached seeds tied last."""
    improvement: float
    """Probability of improvement of A over B on late-window success from p0."""
    power: float
    """Power of Fisher's test with these seeds if the true reach rates were the observed ones."""
    seeds_needed: int | None
    """Seeds per group for `POWER` at the observed reach rates; None when they are equal or need more
    than `MAX_SEEDS`."""


def compare(a: SeedOutcomes, b: SeedOutcomes, seed: int = PERMUTATION_SEED) -> Comparison:
    """Every test of `TESTS` on A against B, the effect sizes and the power at the observed reach rates."""
    reach_a, reach_b = a.reach, b.reach
    p = {"reach": fisher_p(reach_a.reached, reach_a.seeds, reach_b.reached, reach_b.seeds),
         "steps": rank_p(a.first_reach, b.first_reach, seed),
         "final": permutation_p(a.final, b.final, seed),
         "late": permutation_p(a.late, b.late, seed)}
    finite = np.concatenate([a.first_reach, b.first_reach])
    ceiling = finite[np.isfinite(finite)].max() + 1 if np.isfinite(finite).any() else 0.0
    sooner = probability_of_improvement(-_never_last(a.first_reach, ceiling), -_never_last(b.first_reach, ceiling))
    return Comparison(a, b, p, sooner, probability_of_improvement(a.late, b.late),
                      power(reach_a.rate, reach_b.rate, reach_a.seeds, reach_b.seeds),
                      seeds_needed(reach_a.rate, reach_b.rate))


def holm_by_test(comparisons: Sequence[Comparison]) -> list[dict[str, float]]:
    """Holm-adjusted p-values, one family per test across all the comparisons given."""
    adjusted = {test: holm([c.p[test] for c in comparisons]) for test in TESTS}
    return [{test: float(adjusted[test][i]) for test in TESTS} for i in range(len(comparisons))]


def decision(comparison: Comparison, adjusted: dict[str, float], name_a: str, name_b: str,
             alpha: float = ALPHA) -> str:
    """What the tests that reject at `alpha` after Holm's correction say, or "undecided" when none does."""
    c = comparison
    better = {"reach": c.a.reach.rate > c.b.reach.rate, "steps": c.sooner > 0.5,
              "final": c.a.final.mean() > c.b.final.mean(), "late": c.a.late.mean() > c.b.late.mean()}
    words = {"reach": "reaches the threshold more often", "steps": "reaches it sooner",
             "final": "ends higher", "late": "is higher late in training"}
    said = {}
    for test in TESTS:
        if adjusted[test] <= alpha:
            said.setdefault(name_a if better[test] else name_b, []).append(words[test])
    phrases = [f"{name} {' and '.join(filter(None, [', '.join(what[:-1]), what[-1]]))}" for name, what in said.items()]
    return "; ".join(phrases) if phrases else "undecided"


# --- effects and equivalence ---------------------------------------------------------------------
EQUIVALENCE_MARGIN = 0.3
"""*No difference found* needs each effect's interval inside +-this: every effect here is a difference of
two proportions or of two success rates, on a scale from -1 to 1."""


@dataclasses.dataclass(frozen=True)
class Effect:
    """A's difference from B on a scale from -1 to 1 (`measure`), and its interval at any confidence."""

    measure: str
    estimate: float
    interval: Callable[[float], tuple[float, float]]
    """Confidence in (0, 1) -> (low, high)."""
    unit_error: float | None = None
    """For an effect with a normal-theory interval: its standard error times the square root of the seeds
    per group (harmonic mean), the error it would have at one seed per group; what `seeds_for_equivalence`
    scales. None for a rate difference, whose power is computed exactly."""


def _wilson(events: np.ndarray | int, seeds: int, confidence: float) -> tuple[np.ndarray, np.ndarray]:
    """Wilson's score interval of a binomial rate (no continuity correction; scipy's "wilson"), for an
    array of event counts at once."""
    z = scipy.stats.norm.isf((1 - confidence) / 2)
    rate = np.asarray(events, float) / seeds
    centre = (rate + z * z / (2 * seeds)) / (1 + z * z / seeds)
    half = z * np.sqrt(rate * (1 - rate) / seeds + z * z / (4 * seeds * seeds)) / (1 + z * z / seeds)
    return centre - half, centre + half


def _newcombe(events_a, seeds_a: int, events_b, seeds_b: int, confidence: float):
    """Newcombe's hybrid score interval (method 10) of rate A - rate B, broadcast over event counts."""
    rate_a, rate_b = np.asarray(events_a, float) / seeds_a, np.asarray(events_b, float) / seeds_b
    (low_a, high_a), (low_b, high_b) = _wilson(events_a, seeds_a, confidence), _wilson(events_b, seeds_b, confidence)
    difference = rate_a - rate_b
    return (difference - np.hypot(rate_a - low_a, high_b - rate_b),
            difference + np.hypot(high_a - rate_a, rate_b - low_b))


def rate_effect(events_a: int, seeds_a: int, events_b: int, seeds_b: int) -> Effect:
    """Rate A minus rate B with Newcombe's interval (`rate_difference` at any confidence)."""
    rate_difference(events_a, seeds_a, events_b, seeds_b)  # refuses counts that cannot be
    return Effect("rate difference", events_a / seeds_a - events_b / seeds_b,
                  lambda c: tuple(float(v) for v in _newcombe(events_a, seeds_a, events_b, seeds_b, c)))


def _t_effect(measure: str, estimate: float, error: float, freedom: float, seeds: float) -> Effect:
    """An effect whose interval is estimate +- t(freedom) x error, clipped to [-1, 1]; a point when the
    error is 0 (every seed of each group alike); `seeds` per group (harmonic mean) made the error."""
    def interval(confidence: float) -> tuple[float, float]:
        half = 0.0 if error == 0 else math.inf if math.isinf(error) else error * scipy.stats.t.isf((1 - confidence) / 2, freedom)
        return max(-1.0, estimate - half), min(1.0, estimate + half)

    return Effect(measure, estimate, interval, error * math.sqrt(seeds))


def _per_group(n_a: int, n_b: int) -> float:
    return 2 / (1 / n_a + 1 / n_b)


SOONER = "Cliff's delta of steps to 0.8 (A sooner)"


def sooner_effect(steps_a: Sequence[float], steps_b: Sequence[float]) -> Effect:
    """Cliff's delta of the steps to threshold, P(A sooner) - P(B sooner) for a seed of each group
    (never tied last; the rate difference when every seed that gets there does so at one step), with
    Brunner and Munzel's interval: their rank estimate of the variance and Welch-Satterthwaite degrees of
    freedom (the statistic of scipy's `brunnermunzel`)."""
    a, b = np.asarray(steps_a, float), np.asarray(steps_b, float)
    ceiling = _ceiling(a, b)
    a, b = _never_last(a, ceiling), _never_last(b, ceiling)
    n_a, n_b = len(a), len(b)
    ranks = scipy.stats.rankdata(np.concatenate([a, b]))
    if min(n_a, n_b) < 2:  # no spread to estimate: the interval is the whole scale
        return _t_effect(SOONER, 2 * (ranks[n_a:].mean() - (n_b + 1) / 2) / n_a - 1, math.inf, 1, _per_group(n_a, n_b))
    spread = [((ranks[part] - scipy.stats.rankdata(x) - ranks[part].mean() + (len(x) + 1) / 2) ** 2).sum() / (len(x) - 1)
              for part, x in ((slice(None, n_a), a), (slice(n_a, None), b))]
    sooner = (ranks[n_a:].mean() - (n_b + 1) / 2) / n_a  # P(A < B) + P(A = B) / 2
    pooled = n_a * spread[0] + n_b * spread[1]
    error = 2 * math.sqrt(pooled) / (n_a * n_b)
    freedom = pooled ** 2 / ((n_a * spread[0]) ** 2 / (n_a - 1) + (n_b * spread[1]) ** 2 / (n_b - 1)) if pooled else math.inf
    return _t_effect(SOONER, 2 * sooner - 1, error, freedom, _per_group(n_a, n_b))


def mean_effect(a: Sequence[float], b: Sequence[float]) -> Effect:
    """Mean of A minus mean of B with Welch's interval."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if min(len(a), len(b)) < 2:  # no spread to estimate: the interval is the whole scale
        return _t_effect("difference in mean", float(a.mean() - b.mean()), math.inf, 1, _per_group(len(a), len(b)))
    var_a, var_b = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    pooled = var_a + var_b
    freedom = pooled ** 2 / (var_a ** 2 / (len(a) - 1) + var_b ** 2 / (len(b) - 1)) if pooled else math.inf
    return _t_effect("difference in mean", float(a.mean() - b.mean()), math.sqrt(pooled), freedom,
                     _per_group(len(a), len(b)))


def equivalence_p(effect: Effect, margin: float = EQUIVALENCE_MARGIN) -> float:
    """p-value of the two one-sided tests (TOST) that the effect lies within +-`margin`: the smallest
    level alpha at which the effect's 1 - 2 alpha interval lies strictly inside the margin (1 when the
    estimate itself does not)."""
    if not -margin < effect.estimate < margin:
        return 1.0

    def overhang(confidence: float) -> float:
        low, high = effect.interval(confidence)
        return max(-margin - low, high - margin)

    least = 1e-12
    if overhang(least) >= 0:  # an interval of unknown width (one seed)
        return 1.0
    if overhang(1 - least) < 0:
        return least / 2
    return float((1 - scipy.optimize.brentq(overhang, least, 1 - least, xtol=1e-14)) / 2)


@functools.cache
def equivalence_power(rate: float, seeds: int, alpha: float, margin: float = EQUIVALENCE_MARGIN) -> float:
    """Probability that the rate difference's Newcombe interval at 1 - 2 `alpha` lies inside +-`margin`
    (TOST rejects) when both groups' true rate is `rate`, `seeds` each: the binomial probabilities of every
    outcome table whose interval does, summed."""
    events = np.arange(seeds + 1)
    low, high = _newcombe(events[:, None], seeds, events[None, :], seeds, 1 - 2 * alpha)
    chance = np.outer(*(2 * [scipy.stats.binom.pmf(events, seeds, rate)]))
    return float(chance[(low > -margin) & (high < margin)].sum())


def seeds_for_equivalence(rate: float, alpha: float, target: float = POWER, margin: float = EQUIVALENCE_MARGIN,
                          most: int = MAX_SEEDS) -> int | None:
    """The fewest seeds per group with which TOST on the rate difference at `alpha` shows equivalence within
    +-`margin` with probability `target` when the two true rates are both `rate`; None beyond `most`."""
    return next((n for n in range(2, most + 1) if equivalence_power(rate, n, alpha, margin) >= target), None)


def seeds_for_equivalence_of(effect: Effect, alpha: float, target: float = POWER,
                             margin: float = EQUIVALENCE_MARGIN, most: int = MAX_SEEDS) -> int | None:
    """The fewest seeds per group with which TOST on `effect` at `alpha` shows equivalence within +-`margin`
    with probability `target` when the true effect is 0 and its error scales as `effect.unit_error` over
    the square root of the seeds (normal approximation: n >= ((z(1 - alpha) + z(1 - (1 - target) / 2))
    x unit error / margin)^2); None beyond `most` or for an effect without a unit error."""
    if effect.unit_error is None or not math.isfinite(effect.unit_error):
        return None
    z = scipy.stats.norm.isf(alpha) + scipy.stats.norm.isf((1 - target) / 2)
    needed = max(2, math.ceil((z * effect.unit_error / margin) ** 2))
    return needed if needed <= most else None
