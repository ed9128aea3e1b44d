"""eval/analysis/statistics.py against hand-computed and published values and scipy, and the report's tables
built from it on a tiny synthetic results tree."""

import itertools
import math

import numpy as np
import pytest
import scipy.stats

pytest.importorskip("rliable", reason="the report needs the plots extra: pip install -e '.[plots]'")

from test_report import write_run  # noqa: E402

from lava_bridge_mj.eval.analysis import report  # noqa: E402
from lava_bridge_mj.eval.analysis import statistics as stats  # noqa: E402

INF = math.inf


# --- reach counts --------------------------------------------------------------------------------
@pytest.mark.parametrize("reached, low, high", [
    (0, 0.0, 1 - 0.025 ** (1 / 5)),  # 0.5218: the upper bound solves (1 - p)^5 = 0.025
    (5, 0.025 ** (1 / 5), 1.0),  # 0.4782
    (3, 0.1466, 0.9473),  # the published exact interval for 3 of 5
])
def test_clopper_pearson_interval_of_five_seeds(reached, low, high):
    count = stats.reach_count(reached, 5)
    assert (count.reached, count.seeds, count.rate) == (reached, 5, reached / 5)
    assert count.low == pytest.approx(low, abs=5e-5) and count.high == pytest.approx(high, abs=5e-5)


def test_a_reach_count_that_cannot_be_is_refused():
    with pytest.raises(ValueError, match="6 of 5"):
        stats.reach_count(6, 5)


def test_area_under_the_success_curve_by_hand():
    # trapezoids over 0-10 and 10-20: 5 + 10, over the 20 steps spanned
    np.testing.assert_allclose(stats.normalised_auc([0, 10, 20], [[0, 1, 1], [1, 1, 1]]), [0.75, 1.0])
    np.testing.assert_allclose(stats.normalised_auc([5000], [[0.4], [0.6]]), [0.4, 0.6])


# --- the difference of two rates ------------------------------------------------------------------
@pytest.mark.parametrize("counts, low, high", [
    ((56, 70, 48, 80), 0.0524, 0.3339),  # Newcombe (1998), Table II, example (a), method 10
    ((9, 10, 3, 10), 0.1705, 0.8090),  # example (b)
])
def test_rate_difference_interval_is_newcombes_published_one(counts, low, high):
    difference = stats.rate_difference(*counts)
    assert difference.difference == pytest.approx(counts[0] / counts[1] - counts[2] / counts[3])
    assert difference.low == pytest.approx(low, abs=5e-5) and difference.high == pytest.approx(high, abs=5e-5)


def test_rate_difference_of_all_against_none_by_hand():
    # 10 of 10 against 0 of 10: Wilson's lower bound for 10/10 is n / (n + z^2) = 10 / 13.8415 = 0.7225,
    # and the upper bound for 0/10 is z^2 / (n + z^2) = 0.2775; the interval is 1 - hypot(0.2775, 0.2775)
    # to 1 (the other two distances are 0)
    z2 = scipy.stats.norm.ppf(0.975) ** 2
    difference = stats.rate_difference(10, 10, 0, 10)
    assert difference.difference == 1 and difference.high == pytest.approx(1.0)
    assert difference.low == pytest.approx(1 - math.hypot(1 - 10 / (10 + z2), z2 / (10 + z2)))
    assert difference.low == pytest.approx(0.6075, abs=1e-4)
    mirrored = stats.rate_difference(0, 10, 10, 10)
    assert (mirrored.low, mirrored.high) == pytest.approx((-difference.high, -difference.low))


def test_a_rate_that_cannot_be_is_refused():
    with pytest.raises(ValueError, match="11 of 10"):
        stats.rate_difference(11, 10, 0, 10)


# --- tests between two groups --------------------------------------------------------------------
@pytest.mark.parametrize("other, expected", [(15, 910 / 4060), (12, 1.0), (14, 0.5977)])
def test_fisher_on_the_reach_counts_of_fifteen_seeds(other, expected):
    # 12 of 15 against 15 of 15 by hand: of the C(30, 27) = 4060 tables with 27 reached, 12/15 and its
    # mirror 15/12 have C(15, 12) = 455 each and are the least likely: p = 910 / 4060 = 0.224
    assert stats.fisher_p(12, 15, other, 15) == pytest.approx(expected, abs=1e-4)


def test_the_power_functions_rejection_tables_are_fishers():
    for seeds_a, seeds_b in itertools.product(range(1, 8), repeat=2):
        rejects = stats.fisher_rejections(seeds_a, seeds_b)
        for x, y in itertools.product(range(seeds_a + 1), range(seeds_b + 1)):
            p = scipy.stats.fisher_exact([[x, seeds_a - x], [y, seeds_b - y]]).pvalue
            assert rejects[x, y] == (p <= 0.05), (x, seeds_a, y, seeds_b, p)


def test_holm_by_hand():
    # sorted 0.005, 0.01, 0.03, 0.04 times 4, 3, 2, 1: 0.02, 0.03, 0.06, 0.04 -> running maximum 0.06
    np.testing.assert_allclose(stats.holm([0.01, 0.04, 0.03, 0.005]), [0.03, 0.06, 0.06, 0.02])
    np.testing.assert_allclose(stats.holm([0.02, 0.9]), [0.04, 0.9])
    np.testing.assert_allclose(stats.holm([0.6, 0.7]), [1.0, 1.0])  # 1.2, then at least that, capped at 1
    adjusted = stats.holm([0.02, math.nan, 0.04])  # a pair without that test is not in the family
    assert math.isnan(adjusted[1]) and adjusted[[0, 2]].tolist() == pytest.approx([0.04, 0.04])


def _brute_force_rank_p(a, b):
    """Two-sided p of U over every split of the pooled values, never (inf) tied last."""
    pooled = np.concatenate([a, b])
    ranks = scipy.stats.rankdata(pooled)  # inf ties with inf, above every step
    expected = len(a) * (len(pooled) + 1) / 2
    observed = abs(ranks[:len(a)].sum() - expected)
    splits = list(itertools.combinations(range(len(pooled)), len(a)))
    extreme = sum(abs(ranks[list(s)].sum() - expected) >= observed - 1e-9 for s in splits)
    return extreme / len(splits)


def test_rank_test_ties_never_last_and_matches_every_split():
    a, b = [1000, 2000, INF], [3000, INF, INF]
    # ranks 1, 2, 5 against 3, 5, 5 (the three nevers share ranks 4-6): rank sum 8 against 10.5 expected;
    # 8 of the 20 splits are that far from it
    assert stats.rank_p(a, b) == pytest.approx(0.4)
    assert stats.rank_p(a, b) == pytest.approx(_brute_force_rank_p(np.array(a), np.array(b)))
    a, b = [5000, 6000, 7000, INF], [1000, 2000, 9000, INF, INF]
    assert stats.rank_p(a, b) == pytest.approx(_brute_force_rank_p(np.array(a), np.array(b)))
    # never is later than any step: a seed at 10^9 steps ranks like one that never got there
    assert stats.rank_p([1000, INF], [2000, 3000]) == stats.rank_p([1000, 1e9], [2000, 3000])
    assert stats.rank_p([INF, INF], [INF, INF, INF]) == 1.0
    assert math.isnan(stats.rank_p([1000], [2000, 3000]))  # one seed: no test (scipy needs two)


def _brute_force_sum_p(a, b):
    """Twice the smaller tail of A's sum over every split of the pooled values: scipy's two-sided p."""
    pooled = np.concatenate([a, b])
    sums = np.array([pooled[list(s)].sum() for s in itertools.combinations(range(len(pooled)), len(a))])
    observed = np.sum(a)
    return min(1.0, 2 * min(np.mean(sums <= observed + 1e-9), np.mean(sums >= observed - 1e-9)))


def test_permutation_test_by_hand_and_exact_on_every_split():
    # three 1s against three 0s: 2 of the C(6, 3) = 20 splits give a difference as large
    assert stats.permutation_p([1, 1, 1], [0, 0, 0]) == pytest.approx(0.1)
    assert stats.permutation_p([0.5, 0.5], [0.5, 0.5, 0.5]) == 1.0
    assert math.isnan(stats.permutation_p([1.0], [0.0, 0.0]))
    rng = np.random.default_rng(0)
    for _ in range(10):  # success rates of 20 episodes averaged over 3 evaluations: a grid of 1/60
        a, b = rng.integers(0, 61, 7) / 60, rng.integers(0, 61, 6) / 60
        assert stats.permutation_p(a, b) == pytest.approx(_brute_force_sum_p(a, b), rel=1e-12)


def test_exact_tests_take_no_random_draw_and_match_scipy_on_49_against_49_seeds():
    rng = np.random.default_rng(1)
    a, b = rng.integers(0, 201, 49) / 200, rng.integers(0, 201, 49) / 200
    a[:5] = 1.0  # shift A up
    p = stats.permutation_p(a, b)
    assert p == stats.permutation_p(a, b, seed=1) == stats.permutation_p(a, b, seed=2)  # the seed is never read
    # scipy's Monte Carlo estimate of the same p lands within its own sampling error of the exact value
    sampled = scipy.stats.permutation_test((a, b), lambda x, y, axis: x.mean(axis) - y.mean(axis), vectorized=True,
                                           n_resamples=20_000, rng=np.random.default_rng(3)).pvalue
    assert abs(sampled - p) < 4 * math.sqrt(p * (1 - p) / 20_000) + 1e-4
    steps = np.where(rng.random(49) < 0.6, rng.integers(1, 31, 49) * 10_000.0, INF)
    other = np.where(rng.random(49) < 0.3, rng.integers(1, 31, 49) * 10_000.0, INF)
    assert stats.rank_p(steps, other) == stats.rank_p(steps, other, seed=7)
    ceiling = 1e9
    sampled = scipy.stats.mannwhitneyu(np.where(np.isinf(steps), ceiling, steps), np.where(np.isinf(other), ceiling, other),
                                       method=scipy.stats.PermutationMethod(n_resamples=20_000,
                                                                            rng=np.random.default_rng(4))).pvalue
    exact = stats.rank_p(steps, other)
    assert abs(sampled - exact) < 4 * math.sqrt(exact * (1 - exact) / 20_000) + 1e-4


def test_values_off_every_grid_fall_back_to_draws_that_leave_the_level_on_one_side():
    rng = np.random.default_rng(0)
    a, b = rng.uniform(0.3, 1, 8), rng.uniform(0, 0.8, 8)  # C(16, 8) = 12,870 splits, irrational-looking values
    assert stats._integer_scores(np.concatenate([a, b])) is None
    exact = _brute_force_sum_p(a, b)
    sampled = [stats.permutation_p(a, b, seed=s) for s in range(5)]
    assert all(abs(p - exact) < 0.02 for p in sampled)
    # every seed's p lands on the same side of 0.05, as the exact p does
    assert len({p <= 0.05 for p in sampled + [exact]}) == 1


def test_effects_intervals_are_newcombes_brunner_munzels_and_welchs():
    # Newcombe's interval at 95% is rate_difference's
    effect = stats.rate_effect(28, 49, 17, 49)
    difference = stats.rate_difference(28, 49, 17, 49)
    assert effect.estimate == pytest.approx(difference.difference)
    assert effect.interval(0.95) == pytest.approx((difference.low, difference.high), abs=1e-12)
    # Brunner-Munzel: at confidence 1 - p the interval of Cliff's delta just touches 0 (p from scipy)
    a, b = [10_000, 20_000, 20_000, 30_000, INF, INF], [20_000, 30_000, INF, INF, INF]
    effect = stats.sooner_effect(a, b)
    p = scipy.stats.brunnermunzel(np.where(np.isinf(a), 1e9, a), np.where(np.isinf(b), 1e9, b)).pvalue
    assert effect.estimate > 0 and effect.interval(1 - p)[0] == pytest.approx(0, abs=1e-9)
    # Cliff's delta by hand: of the 30 pairs A sooner in 17, B sooner in 6, 7 tied
    assert effect.estimate == pytest.approx((17 - 6) / 30)
    x, y = [0.1, 0.4, 0.5, 0.9], [0.0, 0.2, 0.2]
    welch = scipy.stats.ttest_ind(x, y, equal_var=False).confidence_interval(0.9)
    assert stats.mean_effect(x, y).interval(0.9) == pytest.approx((welch.low, welch.high))


def test_equivalence_p_is_the_level_at_which_the_interval_touches_the_margin():
    effect = stats.rate_effect(20, 49, 21, 49)
    p = stats.equivalence_p(effect)
    low, high = effect.interval(1 - 2 * p)
    assert max(-0.3 - low, high - 0.3) == pytest.approx(0, abs=1e-9)
    assert stats.equivalence_p(stats.rate_effect(28, 49, 17, 49)) > p  # further from 0, less equivalent
    assert stats.equivalence_p(stats.rate_effect(20, 49, 5, 49)) == 1.0  # estimate outside the margin
    assert stats.equivalence_p(stats.mean_effect([0.5, 0.5], [0.5, 0.5])) < 1e-11  # no spread: a point


def test_equivalence_power_by_hand_on_two_seeds_and_seeds_for_equivalence():
    # two seeds a group at a true rate of 0.5: only tables whose Newcombe interval at 90% lies inside +-0.9
    rate, seeds, alpha, margin = 0.5, 2, 0.05, 0.9
    events = np.arange(3)
    low, high = stats._newcombe(events[:, None], 2, events[None, :], 2, 0.9)
    chance = np.outer([0.25, 0.5, 0.25], [0.25, 0.5, 0.25])
    assert stats.equivalence_power(rate, seeds, alpha, margin) == pytest.approx(chance[(low > -0.9) & (high < 0.9)].sum())
    n = stats.seeds_for_equivalence(0.5, 0.01)
    assert stats.equivalence_power(0.5, n, 0.01) >= 0.8 > stats.equivalence_power(0.5, n - 1, 0.01)
    assert stats.seeds_for_equivalence(0.5, 0.001) > n  # a stricter level needs more seeds


def test_probability_of_improvement_by_hand():
    # pairs: 3 > 4? no; 5 > 4, 7 > 4, 7 > 6 yes: 3 of 6
    assert stats.probability_of_improvement([3, 5, 7], [4, 6]) == pytest.approx(0.5)
    # 1 vs 0: 4 wins, 2 + 2 ties counting half, 1 loss: (4 + 2) / 9
    assert stats.probability_of_improvement([1, 1, 0], [0, 0, 1]) == pytest.approx(6 / 9)
    assert stats.probability_of_improvement([1, 1], [0, 0]) == 1.0


# --- power ---------------------------------------------------------------------------------------
def test_power_by_hand_on_four_and_three_seeds():
    # with 4 seeds per group Fisher rejects only 4/4 against 0/4 (p = 2 / 70) and its mirror
    assert stats.power(0.9, 0.1, 4) == pytest.approx(0.9 ** 8 + 0.1 ** 8)
    # with 3 it rejects nothing: 3/3 against 0/3 has p = 2 / 20
    assert stats.power(1.0, 0.0, 3) == 0.0


def test_power_of_fifteen_seeds_against_fifteen():
    # the figure the study was planned from: 0.8 against 0.4 is detected about 45% of the time
    assert stats.power(0.8, 0.4, 15) == pytest.approx(0.45, abs=0.01)
    assert stats.power(0.5, 0.5, 15) <= 0.05  # at equal rates it rejects at most alpha of the time


def test_power_grows_with_the_difference_and_seeds_needed_falls():
    rates = np.linspace(0.4, 1.0, 13)
    powers = [stats.power(rate, 0.4, 15) for rate in rates]
    assert all(later >= earlier for earlier, later in zip(powers, powers[1:]))
    needed = [stats.seeds_needed(rate, 0.4) for rate in (0.7, 0.8, 0.9, 1.0)]
    assert all(later < earlier for earlier, later in zip(needed, needed[1:]))
    n = stats.seeds_needed(0.8, 0.4)
    assert stats.power(0.8, 0.4, n) >= 0.8 > stats.power(0.8, 0.4, n - 1)
    assert stats.seeds_needed(0.5, 0.5) is None
    assert stats.seeds_needed(0.8, 0.78, most=30) is None  # not within 30 seeds
    with pytest.raises(ValueError, match="1.5"):
        stats.power(1.5, 0.5, 10)


# --- the report's tables -------------------------------------------------------------------------
def _tree(root):
    """AuxSS: all 5 seeds reach 0.8 (at step 3,000 or 4,000); U-SS: 1 of 5 does, late; GoalDist-SS: 4 of 5
    do, like AuxSS's best seeds."""
    for seed in range(5):
        write_run(root / "auxss" / f"seed{seed}", seed=seed, p0=[0.0, 0.4, 0.9 if seed < 3 else 0.6, 1.0])
        write_run(root / "uss" / f"seed{seed}", method="uniform_ss", seed=seed,
                  p0=[0.0, 0.1, 0.2, 0.9 if seed == 0 else 0.3])
        write_run(root / "goaldist" / f"seed{seed}", method="goaldist_ss", seed=seed,
                  p0=[0.0, 0.4, 0.9, 1.0] if seed else [0.0, 0.2, 0.5, 0.5])


def test_report_writes_the_reach_counts_and_the_pairwise_tests(tmp_path):
    _tree(tmp_path / "runs")
    assert report.main([str(tmp_path / "runs"), "--reps", "50", "--out", str(tmp_path / "out")]) == 0
    text = (tmp_path / "out" / "report.md").read_text()
    # the area under AuxSS's curves: 1.8 / 3 for seeds 0-2 (trapezoids 0.2 + 0.65 + 0.95), 1.5 / 3 for 3-4
    assert "| auxss (0.5K) | 4,000 | 5 of 5 [0.48, 1.00] | 0.56 |" in text
    assert "| uniform_ss (0.5K) | 4,000 | 1 of 5 [0.01, 0.72] |" in text
    assert "| goaldist_ss (0.5K) | 4,000 | 4 of 5 [0.28, 0.99] |" in text
    cells = [[cell.strip() for cell in line.strip("|").split("|")] for line in text.splitlines()]
    rows = {tuple(row[:2]): row for row in cells if len(row) == 12 and row[0] not in ("A", "---")}
    assert list(rows) == [("auxss (0.5K)", "uniform_ss (0.5K)"), ("auxss (0.5K)", "goaldist_ss (0.5K)"),
                          ("uniform_ss (0.5K)", "goaldist_ss (0.5K)")]
    # 5 of 5 against 1 of 5: p = 10 / 210 by hand, times 3 pairs (Holm's smallest) = 0.143
    auxss_uss = rows["auxss (0.5K)", "uniform_ss (0.5K)"]
    assert auxss_uss[2:5] == ["4,000", "5/5, 1/5", f"{10 / 210:.3g} ({30 / 210:.3g})"]
    # late window (steps 3,000 and 4,000): every AuxSS seed (0.95 or 0.8) above every U-SS one (0.55 or
    # 0.25), so P(A > B) = 1 and only that split and its mirror are as extreme: p = 2 / C(10, 5) = 2 / 252,
    # the smallest late p of the three pairs, so Holm multiplies it by 3
    assert auxss_uss[7] == f"{2 / 252:.3g} ({6 / 252:.3g})" and auxss_uss[8] == "1.00"
    # not more often after the correction (0.143), but higher late
    assert auxss_uss[11].startswith("auxss (0.5K) ") and "is higher late in training" in auxss_uss[11]
    assert "more often" not in auxss_uss[11]
    assert rows["auxss (0.5K)", "goaldist_ss (0.5K)"][11] == "undecided"
    assert "Holm-adjusted across the 3 pairs" in text


def test_two_look_level_is_pococks_boundary_and_keeps_the_overall_error_at_alpha():
    # Pocock (1977), two equally spaced looks at 0.05 overall: boundary 2.178, nominal level 0.0294 at each
    assert stats.two_look_level(10, 20) == pytest.approx(0.0294, abs=5e-5)
    assert stats.two_look_level(20, 40) == pytest.approx(stats.two_look_level(10, 20), rel=1e-9)
    # looks so far apart their statistics are nearly independent: 1 - (1 - level)^2 = alpha
    assert stats.two_look_level(1, 10**8) == pytest.approx(1 - math.sqrt(0.95), abs=1e-5)
    # the study's looks, 20 then 49 seeds: sampled correlated statistics reject a true tie at either look 5% of
    # the time at this level (and about 8.6% at 0.05 per look)
    level = stats.two_look_level(20, 49)
    assert 0.0254 < level < 0.0294
    rng = np.random.default_rng(0)
    first = rng.standard_normal(2_000_000)
    second = math.sqrt(20 / 49) * first + math.sqrt(29 / 49) * rng.standard_normal(first.size)
    either = lambda c: np.mean((np.abs(first) > c) | (np.abs(second) > c))  # noqa: E731
    assert either(scipy.stats.norm.isf(level / 2)) == pytest.approx(0.05, abs=6e-4)
    assert either(scipy.stats.norm.isf(0.025)) == pytest.approx(0.086, abs=1e-3)


@pytest.mark.parametrize("first, second, alpha", [(20, 20, 0.05), (0, 49, 0.05), (49, 20, 0.05), (20, 49, 1.5)])
def test_two_look_level_rejects_looks_out_of_order_and_levels_outside_0_1(first, second, alpha):
    with pytest.raises(ValueError, match=rf"{first}|{alpha}"):
        stats.two_look_level(first, second, alpha)


def test_seeds_for_equivalence_of_an_effect_scale_its_error_per_seed_by_hand():
    # Welch's interval of two groups of four: the error at one seed per group is the standard error x 2
    x, y = [0.0, 0.5, 0.5, 1.0], [0.25, 0.25, 0.75, 0.75]
    effect = stats.mean_effect(x, y)
    error = math.sqrt(np.var(x, ddof=1) / 4 + np.var(y, ddof=1) / 4)
    assert effect.unit_error == pytest.approx(error * 2)
    z = scipy.stats.norm.isf(0.01) + scipy.stats.norm.isf(0.1)
    assert stats.seeds_for_equivalence_of(effect, 0.01) == math.ceil((z * error * 2 / 0.3) ** 2)
    assert stats.seeds_for_equivalence_of(stats.rate_effect(2, 4, 1, 4), 0.01) is None  # rates: exact power instead
