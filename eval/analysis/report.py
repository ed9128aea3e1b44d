"""`lava-bridge-bench report DIR [--out OUT]`: the paper's figures and tables from a sweep directory.

    lava-bridge-bench report runs/sweep                 # writes runs/sweep/report/
    python -m lava_bridge_mj.eval.analysis.report runs/sweep --out paper_figures

Runs are found under DIR at any depth by their config.json and metrics.csv and grouped by configuration
(eval/analysis/aggregate.py: task, method and demo set, plus any other setting that differs). OUT receives, each
as a PNG (and a PDF with --pdf; named TASK_NAME, with one part of report.md per task, when DIR holds runs of
several tasks):
    benchmark          training return and success from p0 and from ood versus steps, every method
                       (its 0.5K-demo runs where it has them): the paper's benchmark comparison
    demo_size          the same for the methods that have both 0.5K and 7.5K runs (solid and dashed)
    start_distributions  AuxSS, Omega-SS, U-SS and GoalDist-SS: the start-distribution study (not drawn when
                       its groups are the benchmark's, which then shows it already)
    maze               the maze (walls, lava, goal, p0 blobs, ood spots, the candidate demo states) and
                       an AuxSS run's start-state probabilities on those states at a few evaluations
    maze_reverse_ss    the same for a reverse_ss run (RFCL's reverse curriculum), when DIR has one: its
                       start state on each demo episode moving back from the goal, then p0
                       (both maze figures for the Lava Bridge tasks only: another task's part, such as an
                       external task's, says they are skipped)
and report.md, which embeds the PNGs (relative links) with its tables: how far each reverse_ss seed's
curriculum came (when it reached p0, or how far back along the demo episodes its starts were), IQM and
95% CI at the last evaluation per group, the steps to p0 success >= 0.8 with how many seeds got there, the reach counts
with exact intervals and the area under the success curve, the pairwise tests of `comparison_pairs`
(eval/analysis/statistics.py: exact and rank tests, Holm-corrected, with the power of each), the paper's findings
(LavaBridge-v0 only, eval/analysis/findings.py) and the study's questions on each task with the start
distributions' runs (eval/analysis/study.py: verdicts with effect sizes and their intervals), with a report
on several tasks opening on one table of every task's answers. Lines are IQMs
across seeds, bands their 95% stratified-bootstrap CIs (rliable). A figure none of whose methods is in
DIR is skipped with a line in report.md saying so. For the offline methods (bc, iql) a step is a
gradient step, not an env step; their legend entries say so.

Everything is drawn into a temporary directory inside OUT and moved into place only once all of it
is written, report.md last: an error (a damaged run file, a full disk) leaves OUT as it was. A
start_weights.npz that cannot be read is skipped with a warning (on stderr and in report.md), the
maze figure taking its start weights from another run: that run's metrics, and so its curves and
tables, are intact, and one damaged side file should not cost the whole report.

This module builds and publishes the report and is the command; eval/analysis/report_groups.py chooses the
groups of each figure and test, eval/analysis/report_figures.py draws, eval/analysis/report_tables.py writes the tables.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import signal
import sys
import tempfile
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import lava_bridge_mj
from lava_bridge_mj.eval.training.atomic import nearest_existing
from lava_bridge_mj.eval.analysis.aggregate import (BOOTSTRAP_REPS, BOOTSTRAP_SEED, METRICS, THRESHOLD, Group, RunRecord,
                                                    find_runs, group_runs, iqm_curves)
from lava_bridge_mj.eval.arguments import format_seeds, in_main_thread as _in_main_thread, positive_int as _positive_int
from lava_bridge_mj.eval.arguments import seed_list, two_looks
from lava_bridge_mj.eval.arguments import raise_keyboard_interrupt as _interrupt
from lava_bridge_mj.eval.analysis.report_figures import curves_figure, maze_figure, maze_layout, save_figure
from lava_bridge_mj.eval.analysis.report_groups import START_STUDY, benchmark_groups, demo_size_groups, weights_run
from lava_bridge_mj.eval.analysis.report_tables import (counted, findings_section, last_evaluation_table, late_table,
                                                        pairwise_section, reach_table, runs_table, study_overview, study_section,
                                                        threshold_table)
from lava_bridge_mj.eval.analysis.study import Question, answer_questions, answers_record
from lava_bridge_mj.eval.analysis.summary import CurriculumStall, curriculum_progress, curriculum_stall, read_start_weights
from lava_bridge_mj.external import EXTERNAL_TASKS
from lava_bridge_mj.tasks import DEFAULT_ENV_ID, SUITE

MAX_REPS = 100_000
"""Most bootstrap resamples: twice rliable's 50,000, which take 3.6-3.9 s of CPU per group and metric
on 25 seeds x 30 steps (eval/analysis/aggregate.py)."""
WEIGHT_SNAPSHOTS = 4
"""Evaluations of the AuxSS run whose start-state probabilities the maze figure paints."""


def build_report(roots: Path | Sequence[Path], out: Path, threshold: float = THRESHOLD, reps: int = BOOTSTRAP_REPS,
                 runs: list[RunRecord] | None = None, budget: int | None = None,
                 seeds: list[int] | None = None, all_pairs: bool = False,
                 looks: tuple[int, int] | None = None, task_seeds: dict[str, list[int]] | None = None,
                 pdf: bool = False) -> Path:
    """Write every figure (PNG, and PDF with `pdf`) and report.md for the runs under `roots` (one directory
    or several; or `runs`, found there already) into `out`; returns report.md's path. `budget`, `seeds` and `task_seeds`
    select evaluations and runs as `find_runs` does; `all_pairs` tests every pair of a task's groups in the
    pairwise table instead of `comparison_pairs`'s; `looks` (first, second seeds per group) checks the
    study's verdicts at the two-look level too (eval/analysis/study.py). ValueError when a root holds no such run or a run's
    files cannot be used, OSError when `out` cannot be written: either way `out` is left as it was
    (everything is written into a temporary directory there first). Warnings (start weights that
    cannot be read) go to stderr and into report.md."""
    roots = [Path(roots)] if isinstance(roots, (str, Path)) else [Path(root) for root in roots]
    if runs is None:
        runs = [run for root in roots for run in find_runs(root, budget, seeds, task_seeds)]
    groups = group_runs(runs)
    curves = {g.label: iqm_curves(g, METRICS, reps=reps) for g in groups}
    made = [d for d in (out, *out.parents) if not d.exists()]
    out.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".report-", dir=out))
    try:
        warnings = _write_report(staging, roots, groups, curves, threshold, reps, budget, seeds, all_pairs, looks,
                                 task_seeds, pdf)
        for warning in warnings:
            print(f"lava-bridge-bench report: warning: {warning}", file=sys.stderr)
        _publish(staging, out)
    except BaseException as error:
        if isinstance(error, OSError) and error.filename and Path(error.filename).parent == staging:
            error.filename = str(out / Path(error.filename).name)  # the file the user asked for
        shutil.rmtree(staging, ignore_errors=True)
        for directory in made:  # innermost first; only those this call made, and only while empty
            try:
                directory.rmdir()
            except OSError:
                break
        raise
    shutil.rmtree(staging, ignore_errors=True)
    return out / "report.md"


def _publish(staging: Path, out: Path) -> None:
    """Move every file written in `staging` into `out`, report.md last (renames within one filesystem:
    no space needed, nothing half-written), then make the renames durable."""
    from lava_bridge_mj.eval.training.atomic import fsync_directory

    for path in sorted(staging.iterdir(), key=lambda p: (p.name == "report.md", p.name)):
        os.replace(path, out / path.name)
    fsync_directory(out)


def _write_report(out: Path, roots: list[Path], groups: list[Group], curves: dict, threshold: float, reps: int,
                  budget: int | None, seeds: list[int] | None, all_pairs: bool = False,
                  looks: tuple[int, int] | None = None, task_seeds: dict[str, list[int]] | None = None,
                  pdf: bool = False) -> list[str]:
    """Every figure and report.md into `out`; returns the warnings. Runs of one task make the report's
    sections; runs of several tasks make one part per task (figures named TASK_NAME), since methods are
    compared within a task only, after a table of every task's answers to the study's questions."""
    from lava_bridge_mj.eval.training.atomic import atomic_write_text

    warnings: list[str] = []
    where = ", ".join(f"`{root}`" for root in roots)
    selection = [f"evaluations up to step {budget:,}" if budget is not None else "",
                 f"seeds {format_seeds(sorted(seeds))}" if seeds is not None else ""]
    selection = " and ".join(part for part in selection if part)
    if task_seeds:
        selection += (" (" if selection else "every seed (") + "; ".join(
            f"{task}: seeds {format_seeds(sorted(chosen))}" for task, chosen in task_seeds.items()) + ")"
    tasks = list(dict.fromkeys(g.task for g in groups))
    title = f"{tasks[0]} report" if len(tasks) == 1 else f"Report on {len(tasks)} tasks ({', '.join(tasks)})"
    lines = [f"# {title}: {where}" + (f", {selection}" if selection else ""), "",
             f"{counted(sum(len(g.runs) for g in groups), 'run')} in {counted(len(groups), 'group')} "
             f"(one configuration each; eval/analysis/aggregate.py says how runs are grouped). Lines and table entries "
             f"are interquartile means (IQM) across seeds; bands and brackets are 95% stratified-bootstrap "
             f"confidence intervals (rliable, {reps:,} resamples, bootstrap seed {BOOTSTRAP_SEED}). Curves use "
             f"the evaluation steps that every seed of a group has. For bc and iql a step is a gradient step on "
             f"the demos.", "",
             *runs_table(groups)]
    # the study's questions are asked at its threshold only, once per task
    answers = {task: answer_questions([g for g in groups if g.task == task], looks) if threshold == THRESHOLD else []
               for task in tasks}
    record = answers_record(answers, groups)
    if record:
        atomic_write_text(out / "answers.json", json.dumps(record, indent=1) + "\n")
    overview = study_overview(answers) if len(tasks) > 1 else []
    if overview:
        lines.extend(["", "## The study's answers, task by task", "", *overview])
    for task in tasks:
        mine = [g for g in groups if g.task == task]
        if len(tasks) == 1:
            lines.extend(_task_sections(mine, answers[task], curves, threshold, reps, where, out, warnings, "##", "",
                                        all_pairs, pdf))
        else:
            lines.extend(["", f"## {task}", "",
                          f"{counted(sum(len(g.runs) for g in mine), 'run')} in {counted(len(mine), 'group')}."])
            lines.extend(_task_sections(mine, answers[task], curves, threshold, reps, where, out, warnings, "###",
                                        f"{task}_", all_pairs, pdf))
    atomic_write_text(out / "report.md", "\n".join(lines) + "\n")
    return warnings


MAZE_STRATEGIES = {"auxss": "AuxSS", "reverse_ss": "reverse_ss"}
LOG_READ_METHODS = ("reverse_ss",)
"""The methods whose episode logs the report reads (`_curriculum_lines`: how each seed's curriculum
stalled); results/study keeps no other method's logs (the Makefile's STUDY_KEEP_LOGS)."""
"""The start strategies whose start-state probabilities the report paints on the maze, with their
names in its text: AuxSS always (the paper's figure), RFCL's reverse curriculum when it has runs."""


def _maze_section(groups: list[Group], threshold: float, where: str, out: Path, warnings: list[str],
                  name: str = "maze", method: str = "auxss", pdf: bool = False) -> list[str]:
    """Draw NAME.png (and NAME.pdf with `pdf`): the maze and the start-state probabilities of a `method`
    run; the report's paragraph about it. A start_weights.npz that cannot be read is passed over, with a line in
    `warnings`."""
    weights: dict[Path, tuple | None] = {}
    strategy = MAZE_STRATEGIES[method]

    def usable(run: RunRecord) -> bool:
        if run.path not in weights:
            try:
                weights[run.path] = read_start_weights(run.path / "start_weights.npz")
            except ValueError as error:
                weights[run.path] = None
                warnings.append(f"{error}. The maze figure does not use it.")
        return weights[run.path] is not None

    chosen = weights_run(groups, threshold, usable, method)
    source = chosen or next((r for g in groups for r in g.runs
                             if (r.path / "start_weights.npz").is_file() and usable(r)), None)
    states, snapshots = None, []
    if source is not None:  # every run's start_weights.npz holds its candidate states
        steps, states, probabilities = weights[source.path]
    if chosen is not None:  # only the evaluations the report keeps (see --budget)
        kept = steps <= chosen.rows[-1]["step"]
        steps, probabilities = steps[kept], probabilities[kept]
        success = {row["step"]: row["success_p0"] for row in chosen.rows}
        picks = np.unique(np.linspace(0, len(steps) - 1, min(WEIGHT_SNAPSHOTS, len(steps))).round().astype(int))
        snapshots = [(float(steps[i]), success.get(float(steps[i]), math.nan), probabilities[i]) for i in picks]
        caption = (f"start weights of {chosen.method} seed {chosen.seed} ({chosen.path}); "
                   f"{len(states)} candidate demo states")
        text = (f"The maze (walls grey, lava orange, goal red, p0 blobs green, ood spots blue) with the {len(states)} "
                f"candidate demo states, then {strategy}'s start-state probabilities on them at {len(snapshots)} "
                f"evaluations of `{chosen.path}` (seed {chosen.seed}).")
        from_p0 = [f"{step:,.0f}" for step, _, p in snapshots if not p.any()]
        if from_p0:  # a strategy that has moved on to p0 puts no weight on any demo state
            text += f" At step{'s' * (len(from_p0) > 1)} {', '.join(from_p0)} every episode starts from p0."
    else:
        with_states = f" with the {len(states)} candidate demo states" if states is not None else ""
        caption = "the maze" + with_states
        text = (f"The maze{with_states}. *No {strategy} run with start_weights.npz in {where}: the start weights "
                f"are not shown.*")
    layout = maze_layout(source or groups[0].runs[0])
    save_figure(maze_figure(layout, states, snapshots, caption), out, name, pdf)
    notes = [f"*Skipped: {warning}*" for warning in warnings]
    return [text, *(["", *notes] if notes else []), "", f"![The maze and {strategy} start weights]({name}.png)",
            *_pdf_link(name, pdf)]


def _pdf_link(name: str, pdf: bool) -> list[str]:
    """report.md's link to figure `name`'s PDF, when the report writes one."""
    return ["", f"[PDF]({name}.pdf)"] if pdf else []


def _curriculum_lines(groups: list[Group], warnings: list[str]) -> list[str]:
    """The paragraph and table of how far each reverse_ss seed's curriculum came (`curriculum_progress`).
    A start_weights.npz that cannot be read is passed over, with a line in `warnings`."""
    rows, stall_rows = [], []
    for group in benchmark_groups(groups, LOG_READ_METHODS):
        done, cells, stalls = 0, [], {}
        for run in group.runs:
            if not (run.path / "start_weights.npz").is_file():
                cells.append(f"{run.seed}: -")
                continue
            try:
                step, back = curriculum_progress(run.path, run.rows[-1]["step"])
                stall = curriculum_stall(run.path, run.rows[-1]["step"])
            except ValueError as error:
                if not any(warning.startswith(str(error)) for warning in warnings):  # once, where the map named it
                    warnings.append(f"{error}. The curriculum tables do not use it.")
                cells.append(f"{run.seed}: unreadable")
                continue
            done += step is not None
            cells.append(f"{run.seed}: " + (f"{step:,.0f}" if step is not None else
                                            f"{math.floor(100 * back)}% back" if back is not None else "not done"))
            if stall is not None:
                stalls[run.seed] = stall
        rows.append(f"| {group.label} | {done} of {len(group.runs)} | {', '.join(cells)} |")
        if stalls:
            stall_rows.append(_stall_row(group.label, stalls))
    lines = ["How far each seed's curriculum came: the first evaluation from which every episode started from p0 "
             "(the curriculum done), or, where it was not done by the seed's last evaluation, how far back along "
             "the goal-reaching demo episodes its starts then were: the mean over the episodes of the start's "
             "distance from the episode's last state, as a share of the episode (0% at the last state, 100% at "
             "the first).", "",
             "| group | curriculum done | per seed (seed: step done, or how far back) |", "|---|---:|---|", *rows]
    if stall_rows:
        lines += ["", "Where a seed's curriculum was not done, how the training episodes from its starts at its last "
                  "evaluation ended (a start only moves back, so these are all the episodes from it): at the goal, "
                  "at the episode's step limit (the curriculum's shortened one, capped by the env's), or in lava "
                  "(the only other way an episode ends). Shares are of the episodes pooled over the seeds; a seed "
                  "counts as *mostly at the time limit* when more of its episodes ended there than in lava. A seed "
                  "with no episode from its last starts had just moved them back when it stopped: still moving, "
                  "not stalled.", "",
                  "| group | unfinished seeds | episodes | at the goal | at the time limit | in lava | mostly at the "
                  "time limit | per seed (seed: episodes, share at the time limit / in lava) |",
                  "|---|---:|---:|---:|---:|---:|---:|---|", *stall_rows]
    return lines


def _stall_row(label: str, stalls: dict[int, CurriculumStall]) -> str:
    """One group's row of the table of how its unfinished curricula's last episodes ended."""
    episodes = sum(s.episodes for s in stalls.values())
    shares = [f"{sum(getattr(s, name) for s in stalls.values()) / episodes:.2f}" if episodes else "-"
              for name in ("goal", "time_limit", "lava")]
    mostly = sum(s.time_limit > s.lava for s in stalls.values())
    cells = ", ".join(f"{seed}: {s.episodes:,}, {s.time_limit / s.episodes:.2f} / {s.lava / s.episodes:.2f}"
                      if s.episodes else f"{seed}: none since its starts last moved" for seed, s in stalls.items())
    return f"| {label} | {len(stalls)} | {episodes:,} | {' | '.join(shares)} | {mostly} of {len(stalls)} | {cells} |"


def _task_sections(groups: list[Group], questions: list[Question], curves: dict, threshold: float, reps: int,
                   where: str, out: Path, warnings: list[str], heading: str, prefix: str,
                   all_pairs: bool = False, pdf: bool = False) -> list[str]:
    """The figures and tables of the groups of one task, with its answers to the study's questions,
    under `heading`-level titles, figure files named `prefix` + name (PDFs too with `pdf`)."""
    from lava_bridge_mj.eval.training.config import METHODS

    lines: list[str] = []
    drawn: dict[str, list[Group]] = {}  # figure title -> its groups

    def add_figure(name: str, title: str, chosen: list[Group], about: str, skipped: str,
                   wanted: tuple[str, ...] = ()) -> None:
        lines.extend(["", f"{heading} {title}", ""])
        if not chosen:
            lines.append(f"*Skipped: {skipped}*")
            return
        lines.append(about)
        missing = [m for m in wanted if m not in {g.method for g in chosen}]
        if missing:
            lines.append(f"Not in this directory: {', '.join(missing)}.")
        # the same groups in the same order draw the same curves, legend and colours: only the title would differ
        same = next((earlier for earlier, shown in drawn.items()
                     if len(shown) == len(chosen) and all(a is b for a, b in zip(shown, chosen))), None)
        if same is not None:
            lines.extend(["", f"The same groups as the {same.lower()} above: its figure shows them."])
            return
        drawn[title] = chosen
        save_figure(curves_figure(chosen, curves, title), out, prefix + name, pdf)
        lines.extend(["", f"![{title}]({prefix}{name}.png)", *_pdf_link(prefix + name, pdf)])

    add_figure("benchmark", "Benchmark comparison", benchmark_groups(groups),
               "Every method, with 0.5K demo transitions where it has runs with them.", "no runs.", METHODS)
    add_figure("demo_size", "Demo-size study: 0.5K vs 7.5K", demo_size_groups(groups),
               "The methods with runs on both demo sets; solid lines 0.5K, dashed 7.5K.",
               "no method has runs with both 0.5K and 7.5K demo transitions.")
    add_figure("start_distributions", "Start-distribution study", benchmark_groups(groups, START_STUDY),
               "SAC trained from each start-state distribution over the demo states (the same random subset of "
               "them for all but reverse_ss, whose candidates are whole demo episodes).",
               f"none of {', '.join(START_STUDY)} has runs here.", START_STUDY)
    maze = groups[0].task in lava_bridge_mj.TASKS  # another env has no maze to draw its start states on
    lines.extend(["", f"{heading} The maze and AuxSS's start weights", ""])
    if maze:
        lines.extend(_maze_section(groups, threshold, where, out, warnings, prefix + "maze", pdf=pdf))
    else:
        lines.append(f"*Skipped: {groups[0].task} is not a Lava Bridge maze, whose picture the start weights are "
                     f"drawn on; neither AuxSS's start weights nor the reverse curriculum's progress are shown.*")
    curricula = benchmark_groups(groups, ("reverse_ss",))
    if maze and any((run.path / "start_weights.npz").is_file() for g in curricula for run in g.runs):
        skipped: list[str] = []  # its own, so the AuxSS section's notes are not repeated under it
        lines.extend(["", f"{heading} The reverse curriculum's start states", "",
                      *_maze_section(groups, threshold, where, out, skipped, prefix + "maze_reverse_ss", "reverse_ss",
                                     pdf),
                      "", *_curriculum_lines(groups, skipped)])
        warnings.extend(skipped)
    lines.extend(["", f"{heading} At the last evaluation", "", *last_evaluation_table(groups, curves)])
    lines.extend(["", f"{heading} Over the last third of training", "", *late_table(groups, reps)])
    lines.extend(["", f"{heading} Steps to p0 success >= {threshold:g}", "", *threshold_table(groups, threshold)])
    lines.extend(["", f"{heading} Seeds reaching p0 success >= {threshold:g}", "", *reach_table(groups, threshold)])
    lines.extend(["", f"{heading} Pairwise tests", "", *pairwise_section(groups, threshold, all_pairs)])
    if threshold == THRESHOLD and groups[0].task == DEFAULT_ENV_ID:  # the paper's claims: 0.8, its maze
        lines.extend(["", f"{heading} The paper's findings", "", *findings_section(groups, heading)])
    study = study_section(questions, heading)
    if study:
        lines.extend(["", f"{heading} The study's questions", "", *study])
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="lava-bridge-bench report",
        description="Regenerate the paper's figures (PNG, and PDF with --pdf) and a Markdown report with IQM/CI tables "
                    "from a directory of runs (found at any depth by config.json and metrics.csv).")
    parser.add_argument("dirs", metavar="DIR", type=Path, nargs="+",
                        help="directory holding runs, e.g. a sweep's output; several are reported together")
    parser.add_argument("--out", type=Path, default=None, help="where to write the figures and report.md "
                        "(default: DIR/report of the first DIR)")
    parser.add_argument("--threshold", type=float, default=THRESHOLD,
                        help="p0 success that counts as solved, for steps-to-threshold (default: %(default)s)")
    parser.add_argument("--reps", type=int, default=BOOTSTRAP_REPS,
                        help=f"bootstrap resamples per confidence interval, 1-{MAX_REPS:,} (default: %(default)s)")
    parser.add_argument("--budget", type=_positive_int, default=None,
                        help="only evaluations at or before this step, e.g. 100000 to compare runs extended to "
                             "300000 with runs stopped at 100000 (default: every evaluation)")
    parser.add_argument("--seeds", type=seed_list, default=None,
                        help="only these seeds' runs, e.g. 0-4 or 0,3,5-7 (default: every run)")
    parser.add_argument("--task-seeds", type=task_seed_list, action="append", default=[], metavar="TASK=SEEDS",
                        help="this task's runs at these seeds instead of --seeds', e.g. "
                             "LavaBridgeTwoCrossings-v0=0-19 for a task whose seed extension is still training; "
                             "once per task (default: every task at --seeds)")
    parser.add_argument("--all-pairs", action="store_true",
                        help="test every pair of a task's groups in the pairwise table, e.g. each variant against "
                             "every other method too (default: the pairs the study and the paper's comparisons "
                             "need, each variant against its method's default)")
    parser.add_argument("--looks", type=two_looks, default=None, metavar="FIRST,SECOND",
                        help="the seeds per group at which a study reads its comparisons, first and after a seed "
                             "extension, e.g. 20,49: each verdict is also checked at Pocock's two-look level "
                             "(default: one look)")
    parser.add_argument("--pdf", action="store_true",
                        help="also write each figure as a PDF, for print (default: PNG only)")
    args = parser.parse_args(argv)
    if not 1 <= args.reps <= MAX_REPS:
        parser.error(f"--reps must be in 1-{MAX_REPS:,}, got {args.reps}")
    if not 0 <= args.threshold <= 1:
        parser.error(f"--threshold must be a success rate in [0, 1], got {args.threshold}")
    twice = sorted(task for task, count in Counter(task for task, _ in args.task_seeds).items() if count > 1)
    if twice:
        parser.error(f"--task-seeds names each task once, got {', '.join(twice)} more than once")
    task_seeds = dict(args.task_seeds)
    out = args.out if args.out is not None else args.dirs[0] / "report"
    unwritable = _unwritable(out)
    if unwritable:
        return _error(f"--out {out} {unwritable}")
    try:
        # before writing
        runs = [run for root in args.dirs for run in find_runs(root, args.budget, args.seeds, task_seeds)]
        group_runs(runs)  # refuses a seed given twice
        absent = sorted(set(task_seeds) - {run.task for run in runs})
        if absent:
            raise ValueError(f"--task-seeds names {', '.join(absent)}, which has no run of those seeds in "
                             f"{', '.join(str(d) for d in args.dirs)}")
    except ValueError as error:
        return _error(str(error))
    unchanged = f"{out} is left as it was" if out.exists() else "nothing written"
    previous = signal.signal(signal.SIGTERM, _interrupt) if _in_main_thread() else None
    try:
        report = build_report(args.dirs, out, args.threshold, args.reps, runs, args.budget, args.seeds,
                              args.all_pairs, args.looks, task_seeds, args.pdf)
    except ValueError as error:  # a run's files cannot be used (its config makes no maze, ...)
        return _error(f"{error}; {unchanged}")
    except OSError as error:  # a full disk, a directory that turned read-only, ...
        return _error(f"cannot write the report into {out}: {error.strerror or error} ({error.filename}); "
                      f"{unchanged}")
    except KeyboardInterrupt:
        return _error(f"interrupted; {unchanged}", code=130)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    print(f"wrote {report} and its figures from {len(runs)} runs")
    return 0


def task_seed_list(text: str) -> tuple[str, list[int]]:
    """An argparse type: 'TASK=SEEDS', a task of the suite and a seed list as --seeds takes it."""
    task, equals, seeds = text.partition("=")
    if not equals or not seeds.strip():
        raise argparse.ArgumentTypeError(f"expected TASK=SEEDS such as LavaBridgeTwoCrossings-v0=0-19, got {text!r}")
    if task not in SUITE and task not in EXTERNAL_TASKS:
        raise argparse.ArgumentTypeError(f"expected a task of the suite ({', '.join(SUITE)}) or an external task "
                                         f"({', '.join(EXTERNAL_TASKS)}) before '=', got {task!r}")
    return task, seed_list(seeds)


def _unwritable(out: Path) -> str | None:
    """Why files cannot be written into directory `out` (to be made where missing), or None."""
    if out.exists() and not out.is_dir():
        return "exists and is not a directory"
    existing = nearest_existing(out)
    if not existing.is_dir():
        return f"cannot be made: {existing} is not a directory"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"cannot be written: {existing} is not a writable directory" if existing == out else \
            f"cannot be made: {existing} is not a writable directory"
    return None


def _error(message: str, code: int = 2) -> int:
    print(f"lava-bridge-bench report: error: {message}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
