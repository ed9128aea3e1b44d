"""The generated parts of README.md and docs/results.md, written from the study report's answers.json.

A generated part sits between `<!-- generated: NAME -->` and `<!-- end: NAME -->` and is rewritten whole
from docs/report_study/answers.json (which `lava-bridge-bench report` writes beside report.md, from the runs
in results/study): nothing between the markers is typed by hand, so a sentence that summarises a verdict
cannot drift from the data. `make report` runs `python -m lava_bridge_mj.eval.doc_tables` after the
reports; `--check` only says which file is stale (exit 1).

The parts (`PARTS`): the table of answers task by task, the same answers in words, pair by pair, each
task's comparisons with their effect and, where no test decides, the equivalence intervals or the seeds
that would decide, and the seeds each group of the study holds.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Callable
from pathlib import Path

from lava_bridge_mj.eval.arguments import format_seeds

ROOT = Path(__file__).resolve().parent.parent
ANSWERS = Path("docs/report_study/answers.json")
DOCUMENTS = (Path("README.md"), Path("docs/results.md"))
START_DISTRIBUTIONS = ("auxss", "uniform_ss", "omega_ss", "goaldist_ss", "reverse_ss")
_BLOCK = re.compile(r"(<!-- generated: (?P<name>[a-z-]+) -->\n).*?(<!-- end: (?P=name) -->)", re.S)


def answer_table(record: dict) -> list[str]:
    """Per task and question: how many comparisons give each verdict, those a test decided, and the seeds per
    group that would decide the undecided ones."""
    lines = ["| task | question | verdicts | decided | seeds per group to decide the undecided |",
             "|---|---|---|---|---:|"]
    for task, answers in record.items():
        for q in answers["questions"]:
            lines.append(f"| {task} | {q['number']}. {q['short']} | {q['summary']} | "
                         f"{'; '.join(q['decided']) or '-'} | {q['seeds_to_decide']} |")
    return lines


def in_words(record: dict) -> list[str]:
    """One line per pair and aspect: on which tasks which verdict holds."""
    verdicts: dict[tuple[str, str, str], dict[str, list[str]]] = {}
    for task, answers in record.items():
        for c in answers["comparisons"]:
            verdicts.setdefault((c["a"], c["b"], c["aspect"]), {}).setdefault(c["verdict"], []).append(task)
    lines = []
    for (a, b, aspect), tasks in verdicts.items():
        said = "; ".join(f"*{verdict}* on {', '.join(where)}" for verdict, where in tasks.items())
        lines.append(f"- {a} against {b}, {aspect}: {said}.")
    return lines


def comparison_tables(record: dict) -> list[str]:
    """Per task, every comparison: its effect, its verdict, and what stands behind a verdict no test gave."""
    lines = []
    for task, answers in record.items():
        lines += [f"**{task}** (report section [{task}](report_study/report.md#{task.lower()}))", "",
                  "| A against B | aspect | effect: A - B [95% CI] | where no test rejects: equivalence at the level "
                  "read, or the seeds to decide | verdict |", "|---|---|---:|---|---|"]
        for c in answers["comparisons"]:
            effect = "-" if c["effect"] is None else "{:+.2f} [{:+.2f}, {:+.2f}]".format(*c["effect"])
            behind = "; ".join(filter(None, [c["equivalence"], c["seeds_to_decide"]])) or "-"
            lines.append(f"| {c['a']} against {c['b']} | {c['aspect']} | {effect} | {behind} | **{c['verdict']}** |")
        lines.append("")
    return lines[:-1]


def seeds_table(record: dict) -> list[str]:
    """The seeds each start distribution's group holds, per task."""
    lines = ["| task | " + " | ".join(START_DISTRIBUTIONS) + " |", "|---|" + "---|" * len(START_DISTRIBUTIONS)]
    for task, answers in record.items():
        seeds = answers["seeds"]
        cells = [f"{format_seeds(seeds[m])} ({len(seeds[m])})" if m in seeds else "-" for m in START_DISTRIBUTIONS]
        lines.append(f"| {task} | " + " | ".join(cells) + " |")
    return lines


PARTS: dict[str, Callable[[dict], list[str]]] = {
    "study-answers": answer_table, "study-in-words": in_words, "study-comparisons": comparison_tables,
    "study-seeds": seeds_table}


def fill(text: str, record: dict) -> str:
    """`text` with every generated part rewritten from `record`; ValueError naming an unknown part."""
    def part(match: re.Match) -> str:
        name = match["name"]
        if name not in PARTS:
            raise ValueError(f"unknown generated part {name!r}; known: {', '.join(PARTS)}")
        return match.group(1) + "\n".join(PARTS[name](record)) + "\n" + match.group(3)

    return _BLOCK.sub(part, text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lava_bridge_mj.eval.doc_tables", description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 if a document is stale")
    args = parser.parse_args(argv)
    record = json.loads((ROOT / ANSWERS).read_text())
    stale = []
    for document in DOCUMENTS:
        text = (ROOT / document).read_text()
        filled = fill(text, record)
        if filled != text:
            stale.append(str(document))
            if not args.check:
                (ROOT / document).write_text(filled)
    if args.check and stale:
        print(f"stale generated parts in {', '.join(stale)}: run `make report`", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
