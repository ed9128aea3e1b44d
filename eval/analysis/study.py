"""The study's questions on one task, each comparison decided by a stated test at a stated level.

The package exists to answer, task by task, which start-state distribution over demonstration states
makes SAC learn fastest and most robustly. `answer_questions(groups)` asks two questions of the groups
of one task:

1. **Does a safety-derived start distribution beat the undirected ones?** AuxSS and Omega-SS, each
   against U-SS and GoalDist-SS: four pairs.
2. **AuxSS or RFCL's reverse curriculum?** AuxSS against RFCL: one pair, against `rfcl` (RFCL as
   published, its forward stage included) where the task has rfcl runs, else against `reverse_ss`.

Each pair is compared on two aspects, as eval/analysis/claims.py compares them (matched seeds, each pair up to
the last evaluation step both groups have):

- *learns faster*: reaching p0 success 0.8 more often or sooner (Fisher's exact test on the reach
  counts, the rank test on the steps to 0.8 with "never" tied last);
- *more robust*: more seeds whose mean late-window success from ood is at least 0.5 (Fisher's exact
  test), or a higher mean of it (permutation test).

The claim "A is ahead of B" is settled by the claims' rule (`claims.settle`): A ahead when a test
rejects with A ahead and none with B ahead, B ahead the other way round; when no test rejects, *no
difference found* where the equivalence tests bound both effects within +-0.3 at the study's level, else
*undecided* with the seeds per group that would decide it at that level. The
p-values of one question on one task form one Holm family (eight comparisons, 16 p-values, for the
first question; two and four for the second); tasks are separate questions. The family is the whole
question even while some of its groups are still training: a comparison not made yet counts its p-values
as 1 (`claims.settle`), so a verdict given on a partly trained study stands when the rest arrives.

Beside each verdict stands the effect: the rate of A minus the rate of B of the binary outcome behind
Fisher's test (seeds reaching 0.8, or robust seeds), with Newcombe's 95% interval
(`statistics.rate_difference`), so a negative answer says how large a difference the seeds leave
possible.

A study that reads the same comparisons twice, after a first batch of seeds and again after a seed
extension of the groups still undecided, looks at each comparison twice, and at 0.05 per look the
chance that either look rejects a true tie is about 0.086 (for normally distributed test statistics).
Given the two looks' seeds per group (`looks`), each comparison a test decides at 0.05 is also settled
at `statistics.two_look_level(*looks)`, Pocock's level for each of two looks that keeps both together
at 0.05 (0.0284 for 20 and 49 seeds); one that does not hold there reads *A ahead at 0.05 only*, and
a seed extension trains its groups on too. A comparison no test decides is read at that level only:
its equivalence tests, and the seeds that would decide it.

Groups are each method's default configuration with 0.5K demo transitions (`claims.pick`); a pair
whose groups are not both present is reported as not run.
"""

from __future__ import annotations

import collections
import dataclasses
import math

from lava_bridge_mj.eval.analysis import statistics as stats
from lava_bridge_mj.eval.analysis.aggregate import Group
from lava_bridge_mj.eval.analysis.claims import (CONTRADICTED, NOT_RUN, SUPPORTED, TESTS_PER_COMPARISON, UNDECIDED, Part, pick,
                                                 reach_comparison, robust_comparison, settle)

SAFETY = ("auxss", "omega_ss")
"""Start distributions derived from how safe a demo state is to start from."""
UNDIRECTED = ("uniform_ss", "goaldist_ss")
"""Start distributions that ignore safety: uniform over demo states, or by distance to the goal."""
QUESTIONS = (
    ("safety-derived against undirected",
     "Does a safety-derived start distribution (AuxSS, Omega-SS) beat uniform and goal-distance starts "
     "(U-SS, GoalDist-SS)?", tuple((a, b) for a in SAFETY for b in UNDIRECTED)),
    ("AuxSS against RFCL", "AuxSS or {rfcl}?", (("auxss", ("rfcl", "reverse_ss")),)),
)
"""Each question's short name, its text and the (A, B) pairs that answer it, A the side the question
asks about. A side given as a tuple of methods is the first of them that has a group on the task (the
last when none has): RFCL as published stands in for the reverse curriculum where it was run, and the
text names the one read ({rfcl}: RFCL_NAMES)."""
RFCL_NAMES = {"rfcl": "RFCL as published (rfcl: its reverse and forward curricula)",
              "reverse_ss": "RFCL's reverse curriculum (reverse_ss)"}
ASPECTS = (("learns faster", reach_comparison), ("more robust", robust_comparison))
NO_COMMON_SEEDS = "no seed in common"
AT_ONE_LOOK_ONLY = f"at {stats.ALPHA:g} only"
"""Appended to a verdict that rejects at 0.05 but not at the two-look level."""


@dataclasses.dataclass(frozen=True)
class Answer:
    """One comparison of one question: A against B on one aspect."""

    a: str
    b: str
    aspect: str
    part: Part | None
    """The tested claim (eval/analysis/claims.py); None when a group is not run or the two share no seed."""
    effect: stats.RateDifference | None
    """Rate of A minus rate of B of the outcome behind Fisher's test, with its 95% interval."""
    absent: str = NOT_RUN
    """Why there is no `part`."""
    two_looks: Part | None = None
    """The same comparison settled at the two-look level, when the study's looks are given."""

    @property
    def ahead(self) -> tuple[str, str] | None:
        """(the side ahead, the side behind) where a test decided the comparison, else None."""
        verdict = self.part.verdict if self.part is not None else None
        return {SUPPORTED: (self.a, self.b), CONTRADICTED: (self.b, self.a)}.get(verdict)

    @property
    def at_one_look_only(self) -> bool:
        """A test decided the comparison at 0.05, and none does at the two-look level."""
        return (self.ahead is not None and self.two_looks is not None
                and self.two_looks.verdict not in (SUPPORTED, CONTRADICTED))

    @property
    def read(self) -> Part | None:
        """The part the verdict stands on: a difference a test finds at 0.05 (with a note where it does not
        hold at the two-look level); otherwise the reading at the study's level, the two-look one where
        the study has two looks, which is what bounds a *no difference found* and sizes an *undecided*."""
        return self.part if self.ahead or self.two_looks is None else self.two_looks

    @property
    def verdict(self) -> str:
        """Who is ahead, or why neither is: the claims' verdict read as an answer."""
        if self.part is None:
            return self.absent
        if not self.ahead:
            return self.read.verdict
        return f"{self.ahead[0]} ahead" + (f" {AT_ONE_LOOK_ONLY}" if self.at_one_look_only else "")


@dataclasses.dataclass(frozen=True)
class Question:
    short: str
    text: str
    answers: list[Answer]
    looks: tuple[int, int] | None = None
    """The seeds per group of the study's two readings, when its verdicts are checked at the two-look level."""

    @property
    def summary(self) -> str:
        """How many comparisons give each verdict, most frequent first: '3 auxss ahead, 5 not enough ...'."""
        counts = collections.Counter(answer.verdict for answer in self.answers)  # ties: first seen first
        return ", ".join(f"{n} {verdict}" for verdict, n in counts.most_common())

    @property
    def decided(self) -> list[str]:
        """The comparisons a test decided, one line per pair and winner: 'auxss ahead of uniform_ss:
        learns faster, more robust'."""
        aspects: dict[tuple[str, str], list[str]] = {}
        for answer in self.answers:
            if answer.ahead:
                aspects.setdefault(answer.ahead, []).append(
                    answer.aspect + (f" ({AT_ONE_LOOK_ONLY})" if answer.at_one_look_only else ""))
        return [f"{ahead} ahead of {behind}: {', '.join(names)}" for (ahead, behind), names in aspects.items()]

    @property
    def seeds_to_decide(self) -> str:
        """The seeds per group that would decide the *undecided* comparisons at the question's levels
        (`claims.seeds_to_decide`), as a range: '21 to 48'; '-' when none is undecided.
        What a seed extension of this task needs, the most demanding comparison setting it."""
        needed = [a.read.seeds_needed for a in self.answers if a.part is not None and a.verdict == UNDECIDED]
        if not needed:
            return "-"
        shown = [f"> {stats.MAX_SEEDS}" if n is None else str(n)
                 for n in (min(needed, key=_beyond_last), max(needed, key=_beyond_last))]
        return shown[0] if shown[0] == shown[1] else f"{shown[0]} to {shown[1]}"


def _side(groups: list[Group], side: str | tuple[str, ...]) -> tuple[str, Group | None]:
    """The method that stands on one side of a pair, and its group (`pick`); for a tuple of methods, the
    first one with a group, else the last one (not run)."""
    methods = (side,) if isinstance(side, str) else side
    for method in methods:
        group = pick(groups, method)
        if group is not None:
            return method, group
    return methods[-1], None


def _beyond_last(needed: int | None) -> float:
    """Orders seeds-needed counts with None (beyond the largest count computed) last."""
    return math.inf if needed is None else needed


def answer_questions(groups: list[Group], looks: tuple[int, int] | None = None) -> list[Question]:
    """The study's questions on the groups of one task; a question none of whose pairs was run is left
    out. `looks`: the seeds per group of the study's two readings (first, second), to settle each
    comparison at the two-look level as well."""
    two_look_alpha = stats.two_look_level(*looks) if looks is not None else None
    if len({g.task for g in groups}) > 1:
        raise ValueError(f"the study's questions are asked per task, got groups of "
                         f"{sorted({g.task for g in groups})}")
    questions = []
    for short, text, pairs in QUESTIONS:
        drafts, pending = [], []
        for sides in pairs:
            (a, ga), (b, gb) = (_side(groups, side) for side in sides)
            for aspect, comparison in ASPECTS:
                item = comparison(ga, gb, f"{a} {aspect} than {b}") if ga and gb else None
                drafts.append((a, b, aspect, item, NO_COMMON_SEEDS if ga and gb else NOT_RUN))
                pending += [item] if item is not None else []
        if all(absent == NOT_RUN for *_, absent in drafts):
            continue
        # one Holm family per question, the comparisons not made counted in it
        untested = len(drafts) - len(pending)
        settled = iter(settle(pending, untested=untested))
        strict = iter(settle(pending, untested=untested, alpha=two_look_alpha) if looks is not None
                      else [None] * len(pending))
        answers = [Answer(a, b, aspect, next(settled) if item else None,
                          stats.rate_difference(*item.counts) if item else None, absent,
                          next(strict) if item else None)
                   for a, b, aspect, item, absent in drafts]
        read = next((b for a, b, *_ in drafts if b in RFCL_NAMES), "reverse_ss")
        questions.append(Question(short, text.format(rfcl=RFCL_NAMES[read]), answers, looks))
    return questions


def answers_record(answers: dict[str, list[Question]], groups: list[Group]) -> dict:
    """The study's answers as plain data (the report writes it as answers.json, from which the README's and
    docs/results.md's generated tables are made): per task, every comparison's verdict, effect and what
    stands behind it, and the seeds of each start distribution's group."""
    def comparison(question_number: int, answer: Answer) -> dict:
        read = answer.read
        return {"question": question_number, "a": answer.a, "b": answer.b, "aspect": answer.aspect,
                "verdict": answer.verdict, "ahead": list(answer.ahead) if answer.ahead else None,
                "at_one_look_only": answer.at_one_look_only,
                "effect": [answer.effect.difference, answer.effect.low, answer.effect.high] if answer.effect else None,
                "measured": read.measured if read else None, "tests": read.tests if read else None,
                "equivalence": read.equivalence if read else None, "seeds_to_decide": read.power if read else None,
                "seeds_needed": read.seeds_needed if read else None}

    record = {}
    for task, questions in answers.items():
        if not questions:
            continue
        numbers = {short: number for number, (short, _, _) in enumerate(QUESTIONS, 1)}
        record[task] = {
            "looks": list(questions[0].looks) if questions[0].looks else None,
            "questions": [{"number": numbers[q.short], "short": q.short, "text": q.text, "summary": q.summary,
                           "decided": q.decided, "seeds_to_decide": q.seeds_to_decide} for q in questions],
            "comparisons": [comparison(numbers[q.short], a) for q in questions for a in q.answers],
            "seeds": {g.method: sorted(g.seeds) for g in groups if g.task == task and pick([g], g.method) is g},
        }
    return record
