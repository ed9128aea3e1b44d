"""The findings' verdicts (eval/analysis/findings.py) and the claims they are made of (eval/analysis/claims.py) on small hand-built
Fisher's p for all against none of n seeds is 2 / C(2n, n); the power and seeds needed come from
eval/analysis/statistics.py's exact power function at the rates a 0.3 difference implies around the pooled rate."""

import math

import pytest
from conftest import groups_in, write_metric_runs

pytest.importorskip("rliable", reason="the tests use rliable's probability of improvement: pip install -e '.[plots]'")

from lava_bridge_mj.eval.analysis import aggregate, claims, findings  # noqa: E402
from lava_bridge_mj.eval.analysis import statistics as stats  # noqa: E402
from lava_bridge_mj.eval.analysis.report_tables import findings_section  # noqa: E402


def two_groups(tmp_path, a, b):
    write_metric_runs(tmp_path, "auxss", a)
    write_metric_runs(tmp_path, "uniform_ss", b)
    [group_a] = aggregate.groups_of(groups_in(tmp_path), "auxss")
    [group_b] = aggregate.groups_of(groups_in(tmp_path), "uniform_ss")
    return group_a, group_b


def settle_one(a, b, matches=False):
    [part] = claims.settle([claims.reach_comparison(a, b, "A against B", matches=matches)])
    return part


def test_a_clear_win_is_supported_and_a_reversed_one_contradicted(tmp_path):
    # 10 of 10 seeds reach 0.8 at step 2,000 against none: Fisher's p = 2 / C(20, 10) = 1.0825e-05, Holm's
    # smallest of two x 2; the rank test's exact p is the same (2 of the C(20, 10) splits are as extreme), Holm
    # raises it to the first's
    a, b = two_groups(tmp_path, {s: [0.0, 1.0] for s in range(10)}, {s: [0.0, 0.0] for s in range(10)})
    assert 2 / math.comb(20, 10) == pytest.approx(1.0825e-05, rel=1e-4)
    part = settle_one(a, b)
    assert part.verdict == claims.SUPPORTED and part.power == ""
    assert part.tests == ("Fisher's test on reach counts p = 1.08e-05 (Holm 2.17e-05); "
                          "rank test on steps to 0.8 p = 1.08e-05 (Holm 2.17e-05)")
    assert "reached 0.8 10/10 [0.69, 1.00] against 0/10 [0.00, 0.31], P(A sooner) = 1.00" in part.measured
    assert settle_one(b, a).verdict == claims.CONTRADICTED


def test_an_effect_at_5_against_5_seeds_is_undecided(tmp_path):
    # 4 of 5 against 1 of 5: Fisher's p = 0.206 (scipy), no rejection; pooled rate 0.5, so the claimed
    # effect is 0.65 against 0.35, which Fisher's test at 0.05 over the comparison's two tests (0.025)
    # detects with 80% power at 56 seeds per group; bounding a rate difference at 0.5 within +-0.3 at 0.05 takes
    # 44, and Cliff's delta of the steps (no spread beyond reached or not, so as noisy as the rate) about as many
    a, b = two_groups(tmp_path, {0: [0, 1], 1: [0, 1], 2: [0, 1], 3: [0, 1], 4: [0, 0]},
                      {0: [0, 1], 1: [0, 0], 2: [0, 0], 3: [0, 0], 4: [0, 0]})
    part = settle_one(a, b)
    assert part.verdict == claims.UNDECIDED
    assert "Fisher's test on reach counts p = 0.206" in part.tests
    assert stats.seeds_needed(0.65, 0.35, alpha=0.025) == 56 and stats.seeds_for_equivalence(0.5, 0.05) == 44
    steps = stats.sooner_effect([2000] * 4 + [math.inf], [2000] + [math.inf] * 4)
    cliff = stats.seeds_for_equivalence_of(steps, 0.05)
    assert 30 < cliff < 60
    assert part.power == ("power 0.01 to detect 0.65 against 0.35 at 0.025; 80% power needs 56 seeds per group for "
                          f"that and 44 and {cliff} to bound the effects within +-0.3 at 0.05 (a rate difference at "
                          "0.50, then the other effect)")
    assert part.seeds_needed == max(56, cliff)


def test_no_difference_with_enough_seeds_is_said_so_and_supports_a_claim_that_they_match(tmp_path):
    # 25 of 25 each at the same step: no test rejects; Newcombe's interval of the rate difference at 90%
    # (TOST at 0.05) is -+(1 - Wilson's lower bound of 25/25), inside +-0.3, and Cliff's delta is 0 with no spread
    a, b = two_groups(tmp_path, {s: [0.0, 1.0] for s in range(25)}, {s: [0.0, 1.0] for s in range(25)})
    z = 1.6448536269514722
    assert 1 - 1 / (1 + z * z / 25) == pytest.approx(0.0977, abs=1e-4)
    part = settle_one(a, b)
    assert part.verdict == claims.NO_DIFFERENCE and part.power == "" and part.seeds_needed is None
    assert part.equivalence.startswith("TOST against +-0.3 at 90.00%: rate difference +0.00 [-0.10, +0.10]")
    assert settle_one(a, b, matches=True).verdict == claims.SUPPORTED


def test_mismatched_seed_sets_are_cut_to_the_common_seeds_and_step(tmp_path):
    # A: seeds 0-9 to step 2,000 (0-4 reach 0.8 at 2,000). B: seeds 0-4 and 20-24 to step 3,000, all reaching
    # 0.8 only at 3,000. Unmatched that is 5 of 10 against 10 of 10; on the seeds both have (0-4), up to
    # the step both have (2,000), 5 of 5 against 0 of 5: Fisher's p = 2 / C(10, 5) = 0.00794
    a, b = two_groups(tmp_path, {s: [0.0, 1.0] if s < 5 else [0.0, 0.0] for s in range(10)},
                      {s: [0.0, 0.0, 1.0] for s in [*range(5), *range(20, 25)]})
    matched_a, matched_b = claims.matched(a, b)
    assert matched_a.seeds == matched_b.seeds == [0, 1, 2, 3, 4]
    assert list(matched_a.steps) == list(matched_b.steps) == [1000, 2000]
    part = settle_one(a, b)
    assert "seeds 0-4 to step 2,000: reached 0.8 5/5 [0.48, 1.00] against 0/5 [0.00, 0.52]" in part.measured
    assert "Fisher's test on reach counts p = 0.00794" in part.tests and 2 / math.comb(10, 5) == pytest.approx(0.00794,
                                                                                                              abs=1e-5)
    # no seed in common: no comparison
    write_metric_runs(tmp_path / "other", "auxss", {7: [1.0]})
    [lonely] = groups_in(tmp_path / "other")
    assert claims.matched(lonely, b) is None and claims.reach_comparison(lonely, b, "x") is None


def test_claims_about_one_group_use_the_exact_interval_against_one_half():
    few = claims.one_group("few escape", 0, 10, few=True)  # [0, 0.31]: below 0.5
    assert few.verdict == claims.SUPPORTED and few.measured == "0/10 [0.00, 0.31] of the seeds"
    # 0 of 5 gives [0, 0.52]; 0 of 6 gives [0, 0.46], the fewest seeds that decide
    five = claims.one_group("few escape", 0, 5, few=True)
    assert five.verdict == claims.UNDECIDED and "6 seeds would place the interval on one side of 0.5" in five.power
    assert claims.one_group("few escape", 9, 10, few=True).verdict == claims.CONTRADICTED
    assert claims.one_group("most do", 9, 10, few=False).verdict == claims.SUPPORTED


def test_check_findings_holm_corrects_across_findings_and_names_what_is_missing(tmp_path):
    write_metric_runs(tmp_path, "sac", {s: [0.0, 0.1] for s in range(10)})
    write_metric_runs(tmp_path, "auxss", {s: [0.0, 1.0] for s in range(10)})
    write_metric_runs(tmp_path, "hysac", {s: [0.0, 0.0] for s in range(10)})
    write_metric_runs(tmp_path, "auxss", {s: [0.0, 1.0] for s in range(5)}, strategy={"ema": 0.5})  # a variant: finding 8
    groups = groups_in(tmp_path)
    found = {f.number: f for f in findings.check_findings(groups)}
    assert [f.number for f in found.values()] == list(range(1, 9))
    assert found[1].verdict == claims.SUPPORTED  # no seed exceeds 0.1: 0/10 [0.00, 0.31]
    # four p-values in the family (finding 2's two and finding 8's two, the latter 1.0): 1.08e-05 x 4
    [tested, not_run] = found[2].parts
    assert tested.verdict == claims.SUPPORTED and "(Holm 4.33e-05)" in tested.tests
    # the baselines not run are named, and the finding stands on the one that was
    assert not_run.measured == "hysac (7.5K), jsrl (0.5K), jsrl (7.5K)" and not_run.verdict == findings.NOT_RUN
    assert found[2].verdict == claims.SUPPORTED
    assert found[3].verdict == findings.MISSING and found[3].parts[0].measured == "hysac_auxss (0.5K)"
    assert found[5].verdict == findings.MISSING and "omega_ss (0.5K)" in found[5].measured
    # the variant on seeds 0-4 against AuxSS's seeds 0-4 only: 5 of 5 each, too few seeds to tell
    [ablation] = found[8].parts
    assert found[8].verdict == claims.UNDECIDED and "seeds 0-4 to step 2,000" in ablation.measured
    text = "\n".join(findings_section(groups))
    assert "| 1 | SAC from p0 stays near 0% success within the budget | **supported** |" in text
    assert "the 4 p-values of the 2 comparisons of this table" in text


def test_findings_stop_online_methods_at_the_step_all_of_them_have(tmp_path):
    write_metric_runs(tmp_path, "auxss", {s: [0.0, 0.0, 0.0, 1.0] for s in range(3)})
    write_metric_runs(tmp_path, "omega_ss", {s: [0.0, 0.0] for s in range(3)})
    groups = groups_in(tmp_path)
    assert findings.common_step(groups) == 2000
    found = {f.number: f for f in findings.check_findings(groups)}
    # AuxSS's success from ood at 4,000 is past Omega-SS's last step and must not count
    later = found[4].parts[1]
    assert "seeds 0-2 to step 2,000: mean late-window success from ood 0.00 against 0.00" in later.measured
    assert "| 4 |" in "\n".join(findings_section(groups)) and "up to step 2,000" in "\n".join(findings_section(groups))
