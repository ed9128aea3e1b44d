"""The study's questions (eval/analysis/study.py) on small hand-built groups whose tests are computed by hand:
Fisher's p for all against none of n seeds is 2 / C(2n, n), and so is the exact p of the rank and
permutation tests (2 of the C(2n, n) splits put all the 1s on one side), and Holm's correction
multiplies the k-th smallest of m p-values by m - k + 1."""

import math

import pytest
from conftest import groups_in, write_metric_runs

pytest.importorskip("rliable", reason="the tests use rliable's probability of improvement: pip install -e '.[plots]'")

from lava_bridge_mj.eval.analysis import study  # noqa: E402
from lava_bridge_mj.eval.analysis.report_tables import study_overview, study_section  # noqa: E402

SOLVED = {seed: [0.0, 1.0] for seed in range(10)}
"""Ten seeds at success 1.0 from p0 and ood from step 2,000: all reach 0.8 and all are robust."""
FAILED = {seed: [0.0, 0.0] for seed in range(10)}
FISHER_ALL_AGAINST_NONE = 2 / math.comb(20, 10)  # 1.0825e-05


def answers(tmp_path, runs, looks=None):
    for method, p0_by_seed in runs.items():
        write_metric_runs(tmp_path, method, p0_by_seed)
    return {q.text: q for q in study.answer_questions(groups_in(tmp_path), looks)}


def safety_question(questions):
    [question] = [q for q in questions.values() if q.text.startswith("Does a safety-derived")]
    return question


def test_a_clear_win_is_answered_with_holm_over_the_question_and_newcombes_interval(tmp_path):
    questions = answers(tmp_path, {"auxss": SOLVED, "uniform_ss": FAILED})
    question = safety_question(questions)
    assert len(questions) == 1, "the reverse curriculum's question needs reverse_ss runs"
    faster, robust = [a for a in question.answers if a.part is not None]
    assert (faster.a, faster.b, faster.aspect, robust.aspect) == ("auxss", "uniform_ss", "learns faster", "more robust")
    assert faster.verdict == robust.verdict == "auxss ahead"
    # the family is the whole question's 16 p-values: the two comparisons made give 1.08e-05 four times,
    # the six not run count 1 each; Holm: 1.08e-05 x 16 = 1.73e-04 (the others, x 15, 14 and 13, are
    # raised to it)
    assert faster.part.tests == ("Fisher's test on reach counts p = 1.08e-05 (Holm 0.000173); "
                                 "rank test on steps to 0.8 p = 1.08e-05 (Holm 0.000173)")
    assert robust.part.tests == ("Fisher's test on robust-seed counts p = 1.08e-05 (Holm 0.000173); "
                                 "permutation test on late ood success p = 1.08e-05 (Holm 0.000173)")
    assert FISHER_ALL_AGAINST_NONE * 16 == pytest.approx(1.732e-04, rel=1e-3)
    # all against none: +1 with Newcombe's lower bound 1 - hypot(0.2775, 0.2775) = 0.61 (test_statistics)
    for answer in (faster, robust):
        assert answer.effect.difference == 1 and answer.effect.low == pytest.approx(0.6075, abs=1e-4)
    absent = [a for a in question.answers if a.part is None]
    assert len(absent) == 6 and {a.verdict for a in absent} == {"not run"}
    assert question.summary == "6 not run, 2 auxss ahead"


def test_a_verdict_on_a_partly_trained_study_stands_when_the_other_groups_arrive(tmp_path):
    # AuxSS 7 of 10 against U-SS 0 of 10: Fisher's p = 0.0031 (scipy). Alone in the family of 16 it is
    # multiplied by 16 (0.0495, the rank test's p is smaller): a rejection. The other groups then arrive,
    # tying each other; the family's other p-values fall from 1, and the rejection stands.
    auxss = {s: [0.0, 1.0] if s < 7 else [0.0, 0.0] for s in range(10)}
    before = safety_question(answers(tmp_path, {"auxss": auxss, "uniform_ss": FAILED})).answers[0]
    after = safety_question(answers(tmp_path, {"omega_ss": FAILED, "goaldist_ss": FAILED})).answers[0]
    assert (before.a, before.b, before.aspect) == (after.a, after.b, after.aspect) == ("auxss", "uniform_ss",
                                                                                        "learns faster")
    assert "Fisher's test on reach counts p = 0.0031 (Holm 0.0495)" in before.part.tests
    assert before.verdict == after.verdict == "auxss ahead"
    assert all(a.part is not None for a in safety_question(answers(tmp_path, {})).answers)
    # each comparison makes the number of tests the family counts for one not made
    assert all(len(a.part.tests.split("; ")) == study.TESTS_PER_COMPARISON
               for a in safety_question(answers(tmp_path, {})).answers)


def test_the_reverse_curriculum_ahead_is_said_so_and_its_question_is_a_family_of_its_own(tmp_path):
    alone = safety_question(answers(tmp_path / "alone", {"auxss": SOLVED, "uniform_ss": FAILED}))
    questions = answers(tmp_path / "both", {"auxss": FAILED, "uniform_ss": FAILED, "reverse_ss": SOLVED})
    [reverse] = [q for q in questions.values() if "reverse curriculum" in q.text]
    assert [(a.a, a.b, a.verdict) for a in reverse.answers] == [("auxss", "reverse_ss", "reverse_ss ahead")] * 2
    assert reverse.answers[0].effect.difference == -1
    # two comparisons in the family, so Holm multiplies the smallest p by 4 as above, not by 6
    assert "(Holm 4.33e-05)" in reverse.answers[0].part.tests
    # auxss and uniform_ss both fail: nothing rejects, and ten seeds bound no difference within +-0.3 (Newcombe's
    # interval of 0/10 against 0/10 at 95% is +-0.28 and wider at the family's level): undecided
    [tie] = [a for a in safety_question(questions).answers if a.part and a.aspect == "learns faster"]
    assert tie.verdict == "undecided" and tie.effect.difference == 0
    assert tie.part.power.startswith("power ") and "80% power needs" in tie.part.power
    assert alone.answers[0].part.tests != tie.part.tests


def test_a_weak_effect_at_five_seeds_is_undecided_with_its_interval(tmp_path):
    # 4 of 5 against 1 of 5: Fisher's p = 0.206 (scipy), no rejection; the difference 0.6 has Newcombe's
    # interval from Wilson's intervals of 0.8 [0.376, 0.964] and 0.2 [0.036, 0.624]
    auxss = {s: [0.0, 1.0] if s < 4 else [0.0, 0.0] for s in range(5)}
    uniform = {s: [0.0, 1.0] if s < 1 else [0.0, 0.0] for s in range(5)}
    faster = safety_question(answers(tmp_path, {"auxss": auxss, "uniform_ss": uniform})).answers[0]
    assert faster.verdict == "undecided"
    assert faster.effect.difference == pytest.approx(0.6)
    assert faster.effect.low == pytest.approx(0.6 - math.hypot(0.8 - 0.3755, 0.6245 - 0.2), abs=2e-3)
    assert faster.effect.high == pytest.approx(0.6 + math.hypot(0.9638 - 0.8, 0.2 - 0.0362), abs=2e-3)
    assert faster.effect.low < 0 < faster.effect.high


def test_groups_that_share_no_seed_are_named_so_and_tasks_are_not_mixed(tmp_path):
    questions = answers(tmp_path, {"auxss": {0: [0.0, 1.0]}, "uniform_ss": {1: [0.0, 1.0]}})
    assert {a.verdict for a in safety_question(questions).answers[:2]} == {"no seed in common"}
    write_metric_runs(tmp_path, "uniform_ss", {2: [0.0, 1.0]}, env_id="LavaBridgeNarrow-v0")
    with pytest.raises(ValueError, match="per task.*LavaBridgeNarrow-v0"):
        study.answer_questions(groups_in(tmp_path))


def test_the_report_section_shows_each_comparison_with_its_effect_and_nothing_without_the_methods(tmp_path):
    write_metric_runs(tmp_path, "auxss", SOLVED)
    write_metric_runs(tmp_path, "uniform_ss", FAILED)
    lines = study_section(study.answer_questions(groups_in(tmp_path)))
    assert "### 1. Does a safety-derived start distribution (AuxSS, Omega-SS) beat uniform and goal-distance " \
           "starts (U-SS, GoalDist-SS)?" in lines
    assert "**6 not run, 2 auxss ahead.**" in lines
    [row] = [line for line in lines if line.startswith("| auxss against uniform_ss | learns faster")]
    assert "| +1.00 [+0.61, +1.00] |" in row and row.endswith("| - | **auxss ahead** |")
    assert "| omega_ss against goaldist_ss | more robust | - | - | - | - | **not run** |" in lines
    write_metric_runs(tmp_path / "sac", "sac", FAILED)
    assert study_section(study.answer_questions(groups_in(tmp_path / "sac"))) == []


def test_the_overview_names_each_tasks_decisions_and_the_questions_not_run(tmp_path):
    # the decoy: AuxSS wins both aspects against U-SS; the narrow maze: the reverse curriculum beats AuxSS
    write_metric_runs(tmp_path / "decoy", "auxss", SOLVED, env_id="LavaBridgeDecoy-v0")
    write_metric_runs(tmp_path / "decoy", "uniform_ss", FAILED, env_id="LavaBridgeDecoy-v0")
    write_metric_runs(tmp_path / "narrow", "auxss", FAILED, env_id="LavaBridgeNarrow-v0")
    write_metric_runs(tmp_path / "narrow", "reverse_ss", SOLVED, env_id="LavaBridgeNarrow-v0")
    answers = {task: study.answer_questions(groups_in(tmp_path / folder))
               for task, folder in (("LavaBridgeDecoy-v0", "decoy"), ("LavaBridgeNarrow-v0", "narrow"))}
    answers["LavaBridge-v0"] = []  # a task with none of the study's start distributions: no row
    rows = [line for line in study_overview(answers) if line.startswith("| LavaBridge")]
    assert rows == [
        "| LavaBridgeDecoy-v0 | 1. safety-derived against undirected | 6 not run, 2 auxss ahead | "
        "auxss ahead of uniform_ss: learns faster, more robust | - |",
        "| LavaBridgeDecoy-v0 | 2. AuxSS against RFCL | not run | - | - |",
        # the narrow maze's auxss fails against nothing: its first question's pairs need U-SS or GoalDist-SS
        "| LavaBridgeNarrow-v0 | 1. safety-derived against undirected | not run | - | - |",
        "| LavaBridgeNarrow-v0 | 2. AuxSS against RFCL | 2 reverse_ss ahead | "
        "reverse_ss ahead of auxss: learns faster, more robust | - |",
    ]
    assert study_overview({"LavaBridge-v0": []}) == []


def test_the_seeds_a_question_needs_span_its_undecided_comparisons_at_the_familys_levels(tmp_path):
    # AuxSS and U-SS solve every seed: tied, so at 0.05 over the question's 16 p-values Fisher's test is asked to
    # detect 1.00 against 0.70 around the pooled rate 1, and the equivalence test at 0.05 over its 8 comparisons
    # to bound a difference at a rate of 1 within +-0.3; Omega-SS solves 5 of 10 (Fisher p = 0.0325 against
    # U-SS, far from rejecting after Holm over 16): pooled 0.75, so 0.90 against 0.60. A decided comparison
    # asks for nothing.
    half = {seed: [0.0, 1.0] if seed < 5 else [0.0, 0.0] for seed in range(10)}
    question = safety_question(answers(tmp_path, {"auxss": SOLVED, "uniform_ss": SOLVED, "omega_ss": half}))
    undecided = {(a.a, a.aspect): a.part.seeds_needed for a in question.answers if a.part is not None}
    assert {a.verdict for a in question.answers if a.part is not None} == {"undecided"}
    tied = max(study.stats.seeds_needed(1.0, 0.7, alpha=0.05 / 16), study.stats.seeds_for_equivalence(1.0, 0.05 / 8))
    assert undecided[("auxss", "learns faster")] == undecided[("auxss", "more robust")] == tied
    omega = [a for a in question.answers if (a.a, a.b, a.aspect) == ("omega_ss", "uniform_ss", "learns faster")][0]
    cliff = study.stats.sooner_effect([2000.0] * 5 + [math.inf] * 5, [2000.0] * 10)  # Omega-SS against U-SS
    wider = max(study.stats.seeds_needed(0.9, 0.6, alpha=0.05 / 16), study.stats.seeds_for_equivalence(0.75, 0.05 / 8),
                study.stats.seeds_for_equivalence_of(cliff, 0.05 / 8))
    assert omega.read.seeds_needed == wider
    assert undecided[("omega_ss", "learns faster")] == wider and wider > tied
    assert question.seeds_to_decide == f"{tied} to {wider}"
    assert study_overview({"LavaBridge-v0": [question]})[-2].endswith(f"| {tied} to {wider} |")
    # all decided: nothing to add
    decided = safety_question(answers(tmp_path / "decided", {"auxss": SOLVED, "uniform_ss": FAILED}))
    assert decided.seeds_to_decide == "-"


def test_no_difference_found_needs_both_effects_inside_the_margin_at_the_level_read(tmp_path):
    # 40 seeds a group, all reaching 0.8 at the same step: both effects are 0 with tight intervals, so the
    # equivalence test decides *no difference found* at 0.05, and its intervals are shown beside it
    solved = {seed: [0.0, 1.0] for seed in range(40)}
    question = safety_question(answers(tmp_path, {"auxss": solved, "uniform_ss": solved}))
    tie = question.answers[0]
    assert tie.verdict == "no difference found" and tie.part.seeds_needed is None
    assert tie.part.equivalence.startswith("TOST against +-0.3 at ")
    assert "rate difference +0.00 [" in tie.part.equivalence and "Cliff's delta" in tie.part.equivalence
    # at the two-look level the family's Holm steps are stricter; 40 seeds still bound it (the interval is
    # the Wilson interval of 40/40 against it: 1 - lower bound < 0.3 at 1 - 2 x 0.0284 / 8)
    strict = safety_question(answers(tmp_path, {}, looks=(20, 49))).answers[0]
    assert strict.verdict == "no difference found" and strict.read is strict.two_looks
    # half of A's seeds reach 0.8 a step later: the rate difference is 0 but Cliff's delta is -0.5, outside the
    # margin, so the comparison is not equivalent, though no test rejects it at the family's level
    later = {seed: [0.0, 0.0, 1.0] if seed < 3 else [0.0, 1.0, 1.0] for seed in range(6)}
    early = {seed: [0.0, 1.0, 1.0] for seed in range(6)}
    apart = safety_question(answers(tmp_path / "apart", {"auxss": later, "uniform_ss": early})).answers[0]
    assert apart.effect.difference == 0 and apart.verdict == "undecided"
    assert "Cliff's delta of steps to 0.8 (A sooner) -0.50" in apart.part.equivalence


def test_with_two_looks_a_verdict_that_rejects_at_005_only_says_so_and_a_clear_one_stands(tmp_path):
    # AuxSS 7 of 10 against U-SS 0 of 10 in the family of 16: Holm-adjusted Fisher p 0.0495 (above), below 0.05
    # but above the two-look level 0.0284 of 20 and 49 seeds; all against none (Holm 0.000173) is below both
    auxss = {s: [0.0, 1.0] if s < 7 else [0.0, 0.0] for s in range(10)}
    one_look = safety_question(answers(tmp_path / "near", {"auxss": auxss, "uniform_ss": FAILED}))
    near = safety_question(answers(tmp_path / "near", {}, looks=(20, 49)))
    assert one_look.answers[0].verdict == "auxss ahead" and one_look.answers[0].two_looks is None
    assert near.answers[0].verdict == "auxss ahead at 0.05 only"
    assert near.answers[0].two_looks.verdict == "undecided"
    assert near.decided[0].startswith("auxss ahead of uniform_ss: learns faster (at 0.05 only)")
    assert near.answers[0].part == one_look.answers[0].part  # the 0.05 reading is unchanged
    clear = safety_question(answers(tmp_path / "clear", {"auxss": SOLVED, "uniform_ss": FAILED}, looks=(20, 49)))
    assert [a.verdict for a in clear.answers[:2]] == ["auxss ahead", "auxss ahead"]
    section = " ".join(study_section([near]))
    assert "at 20 and again at 49 seeds per group" in section and "0.0284" in section
    assert "*At 0.05 only*" in study_overview({"LavaBridge-v0": [near]})[0]
