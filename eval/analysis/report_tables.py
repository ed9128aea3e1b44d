"""The report's Markdown tables, each a list of lines: the runs, the last evaluation, the late-training
window, steps to threshold, reach counts, the pairwise tests, the paper's findings and the study's
questions.

Each takes the groups of one task (and the curves or settings it needs) and returns the table's
lines, text and rows; eval/analysis/aggregate.py and eval/analysis/statistics.py hold the arithmetic.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from lava_bridge_mj.eval.analysis import statistics as stats
from lava_bridge_mj.eval.analysis.aggregate import Curve, Group, late_means, steps_to_threshold
from lava_bridge_mj.eval.analysis.claims import ALPHA, EFFECT, MOST, POWER, ROBUST
from lava_bridge_mj.eval.analysis.findings import check_findings, common_step
from lava_bridge_mj.eval.analysis.report_groups import comparison_pairs
from lava_bridge_mj.eval.analysis.study import QUESTIONS, Question
from lava_bridge_mj.eval.analysis.summary import THRESHOLD


def _interval(curve: Curve, digits: int = 2) -> str:
    if not len(curve.steps) or not np.isfinite(curve.iqm[-1]):
        return "-"
    return f"{curve.iqm[-1]:.{digits}f} [{curve.low[-1]:.{digits}f}, {curve.high[-1]:.{digits}f}]"


def _steps(value: float) -> str:
    return f"{value:,.0f}" if math.isfinite(value) else "not reached"


def runs_table(groups: list[Group]) -> list[str]:
    lines = ["| group | seeds | evaluations used (last step) |", "|---|---|---:|"]
    for g in groups:
        steps = g.steps
        ragged = "" if len(set(g.last_steps)) == 1 else \
            f"; seeds stop at {min(g.last_steps):,.0f}-{max(g.last_steps):,.0f}, later evaluations not shown"
        last = f"{steps[-1]:,.0f}" if len(steps) else "none in common"
        lines.append(f"| {g.label} | {len(g.runs)}: {', '.join(map(str, g.seeds))} | {len(steps)} ({last}{ragged}) |")
    return lines


def last_evaluation_table(groups: list[Group], curves: dict[str, dict[str, Curve]]) -> list[str]:
    lines = ["IQM [95% CI] across seeds at the last step all of a group's seeds have.", "",
             "| group | seeds | step | success from p0 | success from ood | training return |",
             "|---|---:|---:|---:|---:|---:|"]
    for g in groups:
        c = curves[g.label]
        step = f"{c['success_p0'].steps[-1]:,.0f}" if len(c["success_p0"].steps) else "-"
        lines.append(f"| {g.label} | {len(g.runs)} | {step} | {_interval(c['success_p0'])} | "
                     f"{_interval(c['success_ood'])} | {_interval(c['train_return'], 3)} |")
    return lines


def late_table(groups: list[Group], reps: int) -> list[str]:
    lines = ["Each seed's mean over its evaluations in the last third of the group's steps (past two thirds of "
             "the last one), then the IQM [95% CI] across seeds: where a group ended up, without the swing of a "
             "single evaluation.", "",
             "| group | seeds | evaluations (steps) | success from p0 | success from ood |", "|---|---:|---|---:|---:|"]
    for g in groups:
        late = late_means(g, ("success_p0", "success_ood"), reps=reps)
        window = late["success_p0"].steps
        steps = f"{len(window)} ({window[0]:,.0f}-{window[-1]:,.0f})" if len(window) else "-"
        cells = [f"{m.iqm:.2f} [{m.low:.2f}, {m.high:.2f}]" if math.isfinite(m.iqm) else "-" for m in late.values()]
        lines.append(f"| {g.label} | {len(g.runs)} | {steps} | {' | '.join(cells)} |")
    return lines


def threshold_table(groups: list[Group], threshold: float) -> list[str]:
    lines = ["Per seed, the first evaluation at or above the threshold. Median and IQM are over all seeds, a seed "
             "that never got there counting as infinitely late: they read *not reached* when such seeds reach the "
             "middle of the distribution.", "",
             "| group | reached | median | IQM | per seed (seed: step) |", "|---|---:|---:|---:|---|"]
    for g in groups:
        t = steps_to_threshold(g, threshold)
        per_seed = ", ".join(f"{seed}: {_steps(step) if math.isfinite(step) else 'never'}"
                             for seed, step in t.per_seed.items())
        lines.append(f"| {g.label} | {t.reached} of {len(t.per_seed)} | {_steps(t.median)} | {_steps(t.iqm)} | "
                     f"{per_seed} |")
    return lines


def _ci(reach: stats.ReachCount) -> str:
    return f"{reach.reached} of {reach.seeds} [{reach.low:.2f}, {reach.high:.2f}]"


def _p(raw: float, adjusted: float) -> str:
    return f"{raw:.3g} ({adjusted:.3g})" if math.isfinite(raw) else "-"


def reach_table(groups: list[Group], threshold: float) -> list[str]:
    lines = [f"Per group, the seeds whose success from p0 reached {threshold:g} at some evaluation, with the exact "
             f"(Clopper-Pearson) {stats.CONFIDENCE:.0%} interval of the reach rate, and the area under each seed's "
             f"success-from-p0 curve divided by the steps it spans (1 = success 1.0 at every evaluation), averaged "
             f"over seeds.", "",
             "| group | up to step | reached [95% CI of the rate] | area under the success curve |",
             "|---|---:|---:|---:|"]
    for g in groups:
        outcomes = stats.seed_outcomes(g, threshold)
        if outcomes is None:
            lines.append(f"| {g.label} | - | - | - |")
            continue
        lines.append(f"| {g.label} | {outcomes.step:,.0f} | {_ci(outcomes.reach)} | {outcomes.auc.mean():.2f} |")
    return lines


def counted(number: int, noun: str) -> str:
    """"1 group", "3 groups"."""
    return f"{number} {noun}{'' if number == 1 else 's'}"


def pairwise_section(groups: list[Group], threshold: float, all_pairs: bool = False) -> list[str]:
    """The pairwise table: every test of eval/analysis/statistics.py for each of `comparison_pairs` (every pair of
    `groups` with `all_pairs`)."""
    compared, skipped = [], []
    pairs = list(itertools.combinations(groups, 2)) if all_pairs else comparison_pairs(groups)
    for a, b in pairs:
        until = min(a.steps[-1], b.steps[-1]) if len(a.steps) and len(b.steps) else None
        outcomes = [stats.seed_outcomes(g, threshold, until) for g in (a, b)] if until is not None else [None]
        if None in outcomes:
            skipped.append(f"{a.label} against {b.label}")
            continue
        compared.append((a, b, stats.compare(*outcomes)))
    not_compared = ["", f"*Not compared (no evaluation step in common): {'; '.join(skipped)}.*"] if skipped else []
    if not compared:  # the method paragraph would describe an empty table
        return ["*No pairs to compare here.*", *not_compared]
    lines = [f"Each pair up to the last step both groups have. Two-sided p-values, raw and (in brackets) "
             f"Holm-adjusted across the {counted(len(compared), 'pair')} of this table, one family per column: "
             f"Fisher's exact test on the reach counts; Mann-Whitney U on the steps to {threshold:g}, a seed that "
             f"never got there tied last; permutation tests of the difference in mean final and late-window success "
             f"from p0 (the last third of the steps). Rank and permutation p-values are exact: every split of the "
             f"seeds is counted. P(A > B) is rliable's probability of improvement on late-window success. "
             f"Power is that of Fisher's test at {stats.ALPHA:g} with these seeds if the observed reach rates were "
             f"the true ones; seeds needed is the fewest seeds per group that give {stats.POWER:.0%} power there "
             f"(exact, by enumerating the binomial outcomes; '> {stats.MAX_SEEDS}' beyond); both read '-' when the "
             f"observed rates are equal. The verdict names each test that rejects at {stats.ALPHA:g} after the "
             f"correction, and is *undecided* when none does: the groups are then not ranked (this table tests no "
             f"equivalence, so it never says *no difference found*). A "
             f"group of one seed gets no rank or permutation test ('-')."]
    needed = stats.seeds_needed(0.5, 0.8)
    lines[0] += (f" For reference, a reach rate of 0.8 against 0.5 needs {needed} seeds per group "
                 f"for {stats.POWER:.0%} power." if needed else "")
    lines += ["", "| A | B | up to step | reached A, B | reach p | steps p | final p | late p | P(A > B) | power | "
                  "seeds needed | verdict |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for (a, b, c), adjusted in zip(compared, stats.holm_by_test([c for _, _, c in compared])):
        equal = c.a.reach.rate == c.b.reach.rate  # no difference to detect
        power = "-" if equal else f"{c.power:.2f}"
        needed = "-" if equal else str(c.seeds_needed) if c.seeds_needed is not None else f"> {stats.MAX_SEEDS}"
        cells = [a.label, b.label, f"{c.a.step:,.0f}", f"{c.a.reach.reached}/{c.a.reach.seeds}, "
                 f"{c.b.reach.reached}/{c.b.reach.seeds}", *(_p(c.p[t], adjusted[t]) for t in stats.TESTS),
                 f"{c.improvement:.2f}", power, needed, stats.decision(c, adjusted, a.label, b.label)]
        lines.append("| " + " | ".join(cells) + " |")
    return lines + not_compared


_NO_DIFFERENCE_RULE = (
    f"Where no test rejects: *no difference found* when the two one-sided tests (TOST) bound both effects of "
    f"the comparison within +-{stats.EQUIVALENCE_MARGIN:g} (the rate difference of the count test; Cliff's delta "
    f"of the steps to 0.8, or the difference in mean late-window success from ood, of the other), Holm-corrected "
    f"across the family's comparisons, the intervals at the level of each comparison's Holm step shown beside "
    f"it; *undecided* otherwise, with the seeds per group that would give {POWER:.0%} power at the family's "
    f"strictest levels both to detect a difference of {EFFECT:g} in the rate (Fisher's test) and to bound a tie "
    f"within the margin (eval/analysis/claims.py states the rules).")


def _unrejected(part) -> str:
    """What a comparison no test decides says: its equivalence intervals, and the seeds to decide it."""
    return "; ".join(filter(None, [part.equivalence, part.power])) or "-"


def findings_section(groups: list[Group], heading: str = "##") -> list[str]:
    """The paper's findings, each decided by the tests eval/analysis/claims.py and eval/analysis/findings.py state, and the tests
    behind them."""
    step = common_step(groups)
    cut = f" Online methods are compared up to step {step:,.0f}, the last that all of them have." if step else ""
    found = check_findings(groups)
    tested = [part.tests.count("Holm") for f in found for part in f.parts if part.tests]
    lines = [f"Each claim decided by the tests written in eval/analysis/claims.py and eval/analysis/findings.py (default "
             f"configurations only but in finding 8). A comparison uses matched seeds, those both groups have, "
             f"each up to the last step both have; its two-sided p-values are Holm-corrected as one family, the "
             f"{sum(tested)} p-values of the {len(tested)} comparisons of this table, and a test rejects at "
             f"{ALPHA:g}. {_NO_DIFFERENCE_RULE} A claim about one group uses the exact 95% interval of its rate "
             f"against {MOST:g}.{cut}", "",
             "| # | claim | verdict |", "|---:|---|---|"]
    lines += [f"| {f.number} | {f.claim} | **{f.verdict}** |" for f in found]
    lines += ["", f"{heading}# The tests behind the verdicts", "",
              "| # | claim tested (A against B) | measured | tests: p (Holm-adjusted) | where no test rejects: "
              "equivalence, or the seeds to decide | verdict |", "|---:|---|---|---|---|---|"]
    lines += [f"| {f.number} | {part.claim} | {part.measured} | {part.tests or '-'} | {_unrejected(part)} | "
              f"**{part.verdict}** |" for f in found for part in f.parts]
    return lines


def study_section(questions: list[Question], heading: str = "##") -> list[str]:
    """The study's questions answered on one task (`study.answer_questions`), each comparison with its
    tests, effect and verdict; empty when none of the questions' pairs was run."""
    if not questions:
        return []
    lines = [f"Each question is answered by the comparisons eval/analysis/study.py states, on each method's default "
             f"configuration with 0.5K demo transitions: A against B on matched seeds (those both groups have, "
             f"each up to the last step both have), *learns faster* by Fisher's exact test on the seeds reaching "
             f"{THRESHOLD:g} and the rank test on the steps to it, *more robust* by Fisher's exact test on the "
             f"seeds whose late-window success from ood is at least {ROBUST:g} and the permutation test on that "
             f"success. Two-sided p-values, Holm-corrected as one family per question (a comparison not run yet "
             f"counts its p-values as 1, so a verdict stands when its runs arrive), reject at {ALPHA:g}. "
             f"The effect is A's rate minus B's of the outcome behind Fisher's test, with Newcombe's 95% "
             f"interval; it describes the size, the tests decide (Fisher's test conditions on the total and is "
             f"the more conservative, so at a few seeds the interval can leave 0 out while no test rejects). "
             f"{_NO_DIFFERENCE_RULE}"]
    looks = questions[0].looks
    if looks is not None:
        lines[-1] += (f" The study reads its comparisons twice, at {looks[0]} and again at {looks[1]} seeds per group "
                      f"(a seed extension of the groups still undecided), so each verdict is also checked at "
                      f"{stats.two_look_level(*looks):.4f}, Pocock's level for each of two looks that keeps both "
                      f"together at {ALPHA:g}: *A ahead at {ALPHA:g} only* where a test rejects at {ALPHA:g} and "
                      f"none at that level.")
    for number, question in enumerate(questions, 1):
        lines += ["", f"{heading}# {number}. {question.text}", "", f"**{question.summary}.**", "",
                  "| A against B | aspect | measured | effect: A - B [95% CI] | tests: p (Holm-adjusted) | "
                  "where no test rejects: equivalence, or the seeds to decide | verdict |", "|---|---|---|---:|---|---|---|"]
        for answer in question.answers:
            part, effect = answer.part, answer.effect
            effect_text = f"{effect.difference:+.2f} [{effect.low:+.2f}, {effect.high:+.2f}]" if effect else "-"
            lines.append(f"| {answer.a} against {answer.b} | {answer.aspect} | {part.measured if part else '-'} | "
                         f"{effect_text} | {(part.tests if part else '') or '-'} | "
                         f"{_unrejected(answer.read) if part else '-'} | **{answer.verdict}** |")
    return lines


def study_overview(answers: dict[str, list[Question]]) -> list[str]:
    """One table of the study's answers on several tasks (task -> `study.answer_questions` of its
    groups): per task and question the verdict counts and the comparisons a test decided, a question
    none of whose pairs was run on a task said to be not run. Empty when no task answers any question."""
    answered = {task: {q.short: q for q in questions} for task, questions in answers.items() if questions}
    if not answered:
        return []
    lines = ["Each task's answers to the study's questions, from its section \"The study's questions\" below: "
             "how many of a question's comparisons give each verdict, the comparisons a test decided, and the "
             "seeds per group that would decide the *undecided* comparisons at the question's levels (their range; "
             "'-' where none is): what more seeds for the task would have to reach.", "",
             "| task | question | verdicts | decided | seeds needed where undecided |", "|---|---|---|---|---:|"]
    looks = next(q.looks for questions in answered.values() for q in questions.values())
    if looks is not None:
        level = stats.two_look_level(*looks)
        lines[0] += (f" *At {ALPHA:g} only*: decided at {ALPHA:g} but not at {level:.4f}, the level for each of the "
                     f"study's two looks ({looks[0]} and {looks[1]} seeds per group).")
    for task, questions in answered.items():
        for number, (short, _, _) in enumerate(QUESTIONS, 1):
            question = questions.get(short)
            lines.append(f"| {task} | {number}. {short} | {question.summary if question else 'not run'} | "
                         f"{'; '.join(question.decided) if question and question.decided else '-'} | "
                         f"{question.seeds_to_decide if question else '-'} |")
    return lines
