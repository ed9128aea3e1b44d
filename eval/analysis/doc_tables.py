"""The generated parts of the documentation, written from the committed data.

A generated part sits between `<!-- generated: NAME -->` and `<!-- end: NAME -->` and is rewritten whole
from the data it names: nothing between the markers is typed by hand, so a table or a sentence that
quotes a result cannot drift from the data. Each part (`PARTS`) is a source, which reads committed files
under the repository root, and a render function, which turns what the source read into markdown lines:

- README.md and docs/results.md: the study's answers, from docs/report_study/answers.json (which
  `lava-bridge-bench report` writes beside report.md, from the runs in results/study): the table of
  answers task by task, the same answers in words, each task's comparisons with their effect and, where no
  test decides, the equivalence intervals or the seeds that would decide, and the seeds each group holds;
- docs/environment.md: the difficulty table, from results/suite/difficulty.md (what `bench/difficulty.py
  --out` writes) and the SAC-from-p0 runs in results/suite/sac_p0; LavaBridge-v0's measured difficulty,
  from results/suite/difficulty_LavaBridge-v0.json (what `bench/difficulty.py --json` writes);
- docs/speed.md and docs/sweeps.md: the speed tables and the single-seed path's figures, from the bench
  outputs in results/bench/*.txt, and the network-size table, from the AuxSS runs in results/netsize and
  results/calibration/auxss_lava0;
- docs/training.md: what the TensorBoard sink costs, from results/bench/tracking_cost.txt;
- docs/index.md: why the main job trains 80,000 steps, from the runs in results/main_budget (`make
  main-budget`): per budget, the seeds of AuxSS and of SAC from p0 that reached p0 success 0.8 by then;
- results/INDEX.md: per folder of runs under results/, the methods, seeds, runs, commits, platform and
  training time, from each run's config.json, provenance.json and metrics.csv (and, for runs made before
  provenance.json was recorded, the commits results/code_before_provenance.json notes).

`make report` runs `python -m lava_bridge_mj.eval.analysis.doc_tables` after the reports; `--check` writes nothing
and exits 1 naming each stale document.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from lava_bridge_mj.eval.analysis import statistics
from lava_bridge_mj.eval.arguments import format_seeds

ROOT = Path(__file__).resolve().parents[2]
ANSWERS = Path("docs/report_study/answers.json")
DIFFICULTY = Path("results/suite/difficulty.md")
LAVA_BRIDGE_DIFFICULTY = Path("results/suite/difficulty_LavaBridge-v0.json")
SAC_FROM_P0 = Path("results/suite/sac_p0")
BENCH = Path("results/bench")
RESULTS = Path("results")
INDEX = Path("results/INDEX.md")
CODE_BEFORE_PROVENANCE = Path("results/code_before_provenance.json")
"""Folder -> the commits noted for its runs made before provenance.json was recorded."""
DOCUMENTS = (Path("README.md"), Path("docs/results.md"), Path("docs/environment.md"), Path("docs/speed.md"),
             Path("docs/sweeps.md"), Path("docs/index.md"), Path("docs/training.md"), Path("docs/external-tasks.md"), INDEX)
START_DISTRIBUTIONS = ("auxss", "uniform_ss", "omega_ss", "goaldist_ss", "reverse_ss")
_BLOCK = re.compile(r"(<!-- generated: (?P<name>[a-z0-9-]+) -->\n).*?(<!-- end: (?P=name) -->)", re.S)


class SourceError(ValueError):
    """A committed data file lacks what a generated part is made from."""


def _matches(pattern: str, text: str, where: str) -> list[tuple[str, ...]]:
    """Every match of the line `pattern` in `text`; SourceError naming `where` when none does."""
    found = re.findall(pattern, text, re.MULTILINE)
    if not found:
        raise SourceError(f"{where} holds no line like {pattern!r}")
    return found


def _number(text: str) -> float:
    return float(text.replace(",", ""))


# --- the study's answers (docs/report_study/answers.json) ---------------------------------------------------

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
    """The seeds each start distribution's group holds, per task; and RFCL's, where a task has rfcl runs (the
    second question then reads AuxSS against it, eval/analysis/study.py)."""
    columns = START_DISTRIBUTIONS + (("rfcl",) if any("rfcl" in a["seeds"] for a in record.values()) else ())
    lines = ["| task | " + " | ".join(columns) + " |", "|---|" + "---|" * len(columns)]
    for task, answers in record.items():
        seeds = answers["seeds"]
        cells = [f"{format_seeds(seeds[m])} ({len(seeds[m])})" if m in seeds else "-" for m in columns]
        lines.append(f"| {task} | " + " | ".join(cells) + " |")
    return lines


# --- the difficulty table (results/suite/difficulty.md and the SAC-from-p0 runs) ----------------------------

def read_difficulty(text: str) -> tuple[list[str], list[list[str]]]:
    """The header cells and the task rows of the first table `bench/difficulty.py --out` writes."""
    table = re.search(r"^(\| task \|.*)\n\|[-|]+\|\n((?:\|.*\n?)+)", text, re.MULTILINE)
    if table is None:
        raise SourceError("the difficulty file holds no table starting '| task |'")
    cells = lambda line: [cell.strip() for cell in line.strip().strip("|").split("|")]  # noqa: E731
    return cells(table[1]), [cells(line) for line in table[2].splitlines()]


def best_p0_success(runs: dict[str, list[Path]]) -> dict[str, tuple[float, list[int], int]]:
    """Task -> (best success from p0 over every evaluation of every run, the runs' seeds, their last step)."""
    best = {}
    for task, metrics in runs.items():
        rows = {path: list(csv.DictReader(path.read_text().splitlines())) for path in metrics}
        seeds = sorted(json.loads((path.parent / "config.json").read_text())["seed"] for path in metrics)
        best[task] = (max(float(r["success_p0"]) for rs in rows.values() for r in rs), seeds,
                      max(int(r["step"]) for rs in rows.values() for r in rs))
    return best


def difficulty_source(root: Path) -> tuple[list[str], list[list[str]], dict]:
    header, rows = read_difficulty((root / DIFFICULTY).read_text())
    runs = {row[0].strip("`"): sorted((root / SAC_FROM_P0 / row[0].strip("`")).rglob("metrics.csv")) for row in rows}
    return header, rows, best_p0_success({task: found for task, found in runs.items() if found})


def difficulty_table(data: tuple[list[str], list[list[str]], dict]) -> list[str]:
    """The difficulty file's table with a last column: SAC from p0, its best success from p0 and seeds."""
    header, rows, sac = data
    steps = {step for _, _, step in sac.values()}
    budget = f" at {steps.pop():,} steps" if len(steps) == 1 else ""
    lines = ["| " + " | ".join(header + [f"SAC from p0{budget}: best success from p0"]) + " |",
             "|---" * (len(header) + 1) + "|"]
    for row in rows:
        task = row[0].strip("`")
        cell = "-"
        if task in sac:
            success, seeds, _ = sac[task]
            cell = f"{success:.2f} (seeds {format_seeds(seeds)})"
        lines.append("| " + " | ".join(row + [cell]) + " |")
    return lines


def lava_bridge_difficulty_source(root: Path) -> dict:
    record = json.loads((root / LAVA_BRIDGE_DIFFICULTY).read_text())
    if "LavaBridge-v0" not in record.get("tasks", {}):
        raise SourceError(f"{LAVA_BRIDGE_DIFFICULTY} holds no figures of LavaBridge-v0")
    return record


def lava_bridge_difficulty(record: dict) -> list[str]:
    """`bench/difficulty.py --json` for LavaBridge-v0: its command and settings, how random and expert
    episodes end, where the demo states' 4-step lava probability is high, and that probability's histogram."""
    settings, task = record["settings"], record["tasks"]["LavaBridge-v0"]
    r, p0, ood, demo = task["random"], task["expert_p0"], task["expert_ood"], task["demo_states"]
    where = "" if demo["unsafe_x"] is None else "; all at x in [{:.2f}, {:.2f}]".format(*demo["unsafe_x"])
    bins = demo["lava_probability_histogram"]
    while len(bins) > 1 and bins[-1][2] == 0:  # empty bins at the top: "none above"
        bins = bins[:-1]
    last = len(demo["lava_probability_histogram"]) - 1
    counts = [f"{count} in [{low:g}, {high:g}{']' if i == last else ')'}" for i, (low, high, count) in enumerate(bins)]
    above = ", none above" if len(bins) <= last else ""
    return [f"`{record['command']}` ({settings['random_episodes']:,} random episodes, {settings['expert_episodes']:,} "
            f"expert episodes per start distribution, {settings['rollouts']} random rollouts per demo state):", "",
            "| measure | value |", "|---|---|",
            f"| uniformly random policy from p0: success | **{r['success']:.2%}** of {settings['random_episodes']:,} "
            "episodes |",
            f"| uniformly random policy from p0: ends in lava / times out | {r['lava']:.1%} / {r['truncated']:.1%} "
            f"(mean length {r['mean_length']:.0f} steps) |",
            f"| scripted expert from p0 / from ood: success | {p0['success']:.0%} / {ood['success']:.0%} of "
            f"{settings['expert_episodes']:,} episodes each (mean length {p0['mean_length']:.0f} / "
            f"{ood['mean_length']:.0f} steps) |",
            f"| demo states ({demo['demos']} set) on the bridge | {demo['on_bridge']:.1%} |",
            f"| demo states whose 4-step random-action lava probability is >= 0.1 | {task['unsafe']:.1%} "
            f"({demo['unsafe_on_bridge']:.1%} of bridge states, {demo['unsafe_off_bridge']:.1%} of the others"
            f"{where}) |", "",
            f"Histogram of the 4-step random-action lava probability (1 - Omega) over the {demo['count']} demo "
            "states:",
            ", ".join(counts) + above + "."]


# --- the speed tables (results/bench/*.txt) -----------------------------------------------------------------

def bench_text(name: str) -> Callable[[Path], str]:
    def source(root: Path) -> str:
        return (root / BENCH / name).read_text()
    source.__name__ = name
    return source


PROTOCOL_LAYOUTS = {
    "sweep": "`lava-bridge-bench sweep --methods auxss --seeds 0-24 --workers 2 --threads 1`: two processes of 13 "
             "and 12 seeds",
    "train": "`lava-bridge-bench --method auxss --seeds 0-24 --threads 2`: one process of 25 seeds"}


def protocol_table(text: str) -> list[str]:
    """bench/protocol_throughput.py: each layout's wall and CPU seconds, its throughput and its share of the target."""
    rows = _matches(r"^(\w+) \(working tree\)\s+([\d.]+)\s+([\d.]+)\s+(\d+)\s+([\d.]+)", text,
                    "protocol_throughput.txt")
    [target] = _matches(r"^target: ([\d,]+) seed-steps/s", text, "protocol_throughput.txt")
    best = max(int(r[3]) for r in rows)
    lines = ["| layout | wall s | CPU s | seed-steps/s, evaluation included | x the " + target + " target |",
             "|---|---:|---:|---:|---:|"]
    for case, wall, cpu, rate, share in rows:
        shown = f"**{rate}**" if int(rate) == best else rate
        lines.append(f"| {PROTOCOL_LAYOUTS.get(case, case)} | {_number(wall):,.0f} | {_number(cpu):,.0f} | {shown} "
                     f"| {share} |")
    return lines


ENV_LOOPS = {"a": '`gymnasium.make("LavaBridge-v0").step`', "b": "`env.unwrapped.step`",
             "c": "`mj_step` x 10, Python loop", "d": "`mj_step(nstep=10)`"}


def env_loops_table(text: str) -> list[str]:
    """bench/env_throughput.py: the env's step with and without wrappers beside raw mj_step."""
    rows = _matches(r"^\(([a-d])\) .+?\s{2,}([\d,]+)\s+([\d.]+)\s+[\d,]+$", text, "env_throughput.txt")
    return ["| loop | env steps/s | us per env step |", "|---|---:|---:|"] + [
        f"| ({letter}) {ENV_LOOPS[letter]} | {rate} | {us} |" for letter, rate, us in rows]


FREE_MOTION = {"env.unwrapped.step": "`env.unwrapped.step`", "make_vec native, K=25": "native vector env, K = 25",
               "(d) mj_step(nstep=10), for scale": "raw `mj_step(nstep=10)`, for scale"}


def free_motion_table(text: str) -> list[str]:
    """bench/env_throughput.py: steps/s with every physics step checked and with the free-motion path."""
    block = text[text.index("before / after the free-motion path"):]
    lines = ["| loop | checked every physics step: env steps/s | free-motion path: env steps/s | after / before |",
             "|---|---:|---:|---:|"]
    for label, checked, free, ratio in _matches(r"^(\S.*?)\s{2,}([\d,]+)(?:\s+([\d,]+)\s+([\d.]+))?$",
                                                block, "env_throughput.txt, free-motion block"):
        lines.append(f"| {FREE_MOTION.get(label, label)} | {checked} | {free} | {ratio} |")
    return lines


def vector_table(text: str) -> list[str]:
    """bench/env_throughput.py: the native vector env and SyncVectorEnv against raw mj_step(nstep=10)."""
    [raw] = [_number(r) for r in _matches(r"^\(d\) mj_step\(nstep=10\)\s+([\d,]+)", text, "env_throughput.txt")]
    vector = {(kind, int(k)): _number(rate) for kind, k, rate in
              _matches(r"^\([ef]\) (make_vec native|SyncVectorEnv), K=(\d+)\s+([\d,]+)", text, "env_throughput.txt")}
    native = {k: rate for (kind, k), rate in vector.items() if kind == "make_vec native"}
    sync = {k: rate for (kind, k), rate in vector.items() if kind == "SyncVectorEnv"}
    top, rest = max(native), sorted((k for k in native if k != max(native)), reverse=True)
    lines = ["| loop | env steps/s | x raw `mj_step(nstep=10)` |", "|---|---:|---:|",
             f"| raw `mj_step(nstep=10)`, one MjData | {raw:,.0f} | 1.00 |",
             f'| `gymnasium.make_vec("LavaBridge-v0", num_envs={top})` (native `LavaBridgeVectorEnv`) '
             f"| {native[top]:,.0f} | {native[top] / raw:.2f} |",
             f"| `SyncVectorEnv` of {top} `gymnasium.make` envs | {sync[top]:,.0f} | {sync[top] / raw:.2f} |"]
    if rest:
        lines.append("| native, " + " / ".join(f"K = {k}" for k in rest) + " | "
                     + " / ".join(f"{native[k]:,.0f}" for k in rest) + " | "
                     + " / ".join(f"{native[k] / raw:.2f}" for k in rest) + " |")
    return lines


def profile_parts(text: str) -> tuple[dict[str, tuple[float, float]], dict[str, int]]:
    """bench/profile_training.py's output: part -> (seconds, share in %), and the job's sizes."""
    parts = {label: (float(seconds), float(share)) for label, seconds, share in
             _matches(r"^\s*(\S.*?)\s{2,}([\d.]+)\s+([\d.]+)%$", text, "profile_training.txt")}
    [job] = _matches(r"^job: \w+, (\d+) seeds, (\d+) steps \(updates from step \d+: (\d+)\), one evaluation round "
                     r"of (\d+) p0 \+ (\d+) ood", text, "profile_training.txt")
    seeds, steps, updates, p0, ood = map(int, job)
    return parts, {"seeds": seeds, "steps": steps, "updates": updates, "episodes": p0 + ood}


def profile_table(text: str) -> list[str]:
    """bench/profile_training.py: seconds and share of the job per part, some of its parts summed."""
    parts, job = profile_parts(text)
    rows = [
        (f"update ({job['updates']:,} batched updates)", ["update: total"]),
        ("- TD target (actor and target critics, no gradient)", ["update: TD target (actor + target critics, no grad)"]),
        ("- critics (forward, backward, Adam)", ["update: critics (forward, backward, Adam)"]),
        ("- actor (forward through the critics, backward, Adam)",
         ["update: actor (forward through critics, backward, Adam)"]),
        ("- entropy coefficient; Polyak step and statistics",
         ["update: alpha (loss, backward, Adam)", "update: Polyak step of target critics, statistics"]),
        ("- (of these, the three Adam steps)", ["of which Adam steps (3 optimisers)"]),
        (f"training env steps (vector env, {job['seeds'] * job['steps']:,} sub-env steps)",
         ["train: env step (vector env)"]),
        ("replay sampling (per-seed samples, stacked)", ["train: replay sampling"]),
        ("actor forward for acting", ["train: actor forward (acting)"]),
        ("resets, storing transitions, checkpoints, loop",
         ["train: episode resets", "train: store transitions", "checkpoints", "other (training loop, bookkeeping)"]),
        (f"evaluation round ({job['seeds']} seeds x {job['episodes']} episodes)", ["eval: total"]),
        ("- single-env steps", ["eval: env step (single envs)"]),
        ("- actor forward (each seed's policy called on its own)", ["eval: actor forward"]),
        ("- resets, bookkeeping, metric and policy files",
         ["eval: env reset", "eval: rest (loop, episode bookkeeping, metric and policy files)"])]
    lines = ["| part | seconds | share of the job |", "|---|---:|---:|"]
    for label, names in rows:
        missing = [name for name in names if name not in parts]
        if missing:
            raise SourceError(f"profile_training.txt has no part {missing[0]!r}")
        seconds, share = (sum(parts[name][i] for name in names) for i in (0, 1))
        lines.append(f"| {label} | {seconds:.1f} | {share:.1f}% |")
    return lines


EVAL_ACTORS = {"untrained SAC actors": "untrained SAC actors",
               "BC actors, 300 updates": "behaviour-cloned actors, 300 updates"}
_EVAL_ROW = (r"^(untrained SAC actors|BC actors, \d+ updates) \((\d+x\d+)\)\s+[\d.]+ / [\d.]+\s+(.*?)"
             r"\s+(?:identical|differ)$")


def _eval_rows(block: str) -> list[tuple[str, list[float]]]:
    return [(f"{EVAL_ACTORS.get(actors, actors)}, {size}", [float(x) for x in re.findall(r"[\d.]+", rest)])
            for actors, size, rest in _matches(_EVAL_ROW, block, "eval_round.txt")]


def eval_round_table(text: str) -> list[str]:
    """bench/eval_round.py, the run without the walls-only path: CPU seconds per seed and batched."""
    earlier = text[text.index("## earlier"):]
    lines = ["| actors | per seed: CPU s | batched: CPU s | per seed / batched |", "|---|---:|---:|---:|"]
    for label, (_, seed_cpu, _, batched_cpu, _, ratio) in _eval_rows(earlier):
        lines.append(f"| {label} | {seed_cpu:.1f} | {batched_cpu:.1f} | {ratio:.2f} |")
    return lines


def walls_only_table(text: str) -> list[str]:
    """bench/eval_round.py: CPU seconds per seed, batched with the checked loop, batched with the walls-only path."""
    latest = text.split("## earlier")[0]
    lines = ["| actors | per seed, checked loop near walls: CPU s | batched, checked near walls: CPU s | batched, "
             "walls-only path: CPU s | per seed / batched | checked / walls-only |", "|---|---:|---:|---:|---:|---:|"]
    for label, (_, seed_cpu, _, checked_cpu, _, walls_cpu, ratio, walls_ratio) in _eval_rows(latest):
        lines.append(f"| {label} | {seed_cpu:.1f} | {checked_cpu:.1f} | {walls_cpu:.1f} | {ratio:.2f} "
                     f"| {walls_ratio:.2f} |")
    return lines


def update_speed_table(text: str) -> list[str]:
    """bench/update_speed.py: ms per update of the reference and this tree, per number of seeds."""
    lines = ["| seeds K | before: ms per update | in-place ReLU: ms per update | before / after | weights after the "
             "timed updates |", "|---:|---:|---:|---:|---|"]
    for k, this, ref, _, ratio, weights in _matches(
            r"^\s*(\d+)\s+([\d.]+)\s+([\d.]+)\s+(\d+)\s+([\d.]+)\s+(identical|differ)$", text, "update_speed.txt"):
        lines.append(f"| {k} | {ref} | {this} | {ratio} | {weights} |")
    return lines


def sac_throughput_rows(text: str) -> dict[str, tuple[int, str]]:
    """bench/sac_throughput.py's output: trainer -> (seed-steps/s, x SB3)."""
    return {trainer: (int(rate), ratio) for trainer, rate, ratio in
            _matches(r"^\s*\d+\s+(SB3 SAC|ours K=\d+)\s+(\d+)\s+([\d.]+)", text, "sac_throughput output")}


def sac_throughput_table(texts: tuple[str, str]) -> list[str]:
    """bench/sac_throughput.py with 1 and 2 torch threads: seed-steps/s and x SB3 per trainer."""
    one, two = (sac_throughput_rows(text) for text in texts)
    best = max(rate for rate, _ in [*one.values(), *two.values()])
    label = lambda t: "Stable-Baselines3 SAC, one seed" if t == "SB3 SAC" else (  # noqa: E731
        "ours, K = 1" if t == "ours K=1" else f"ours, K = {t.split('=')[1]} seeds in one process")
    cell = lambda row: ("", "") if row is None else (  # noqa: E731
        (f"**{row[0]}**", f"**{row[1]}**") if row[0] == best else (str(row[0]), row[1]))
    lines = ["| trainer | 1 torch thread: seed-steps/s | x SB3 | 2 torch threads: seed-steps/s | x SB3 |",
             "|---|---:|---:|---:|---:|"]
    for trainer in dict.fromkeys([*one, *two]):
        lines.append(f"| {label(trainer)} | " + " | ".join([*cell(one.get(trainer)), *cell(two.get(trainer))]) + " |")
    return lines


def sac_throughput_source(root: Path) -> tuple[str, str]:
    return tuple((root / BENCH / f"sac_throughput_64_t{threads}.txt").read_text() for threads in (1, 2))


def external_tasks(text: str) -> list[str]:
    """bench/external_tasks.py: per task and policy, success and mean length from p0 and from ood; then the env
    steps/s of random actions per task."""
    rows: dict[tuple[str, str], dict[str, tuple[str, str]]] = {}
    for task, policy, start, _, success, length in _matches(
            r"^\| (\S+) \| (\w+) \| (p0|ood) \| (\d+) \| ([\d.]+) \| ([\d.]+) \|$", text, "external_tasks.txt"):
        rows.setdefault((task, policy), {})[start] = (success, length)
    lines = ["| task | policy | success from p0 | mean length from p0 | success from ood | mean length from ood |",
             "|---|---|---:|---:|---:|---:|"]
    for (task, policy), starts in rows.items():
        cells = [value for start in ("p0", "ood") for value in starts.get(start, ("-", "-"))]
        lines.append(f"| {task} | {policy} | " + " | ".join(cells) + " |")
    rates = _matches(r"^(\S+): ([\d,]+) env steps/s of random actions", text, "external_tasks.txt")
    return lines + ["", "Env steps/s of random actions through `make_task_env`'s wrappers: "
                    + ", ".join(f"{rate} on {task}" for task, rate in rates) + "."]


STUDY_SEED_STEPS = 10 * 300_000
"""The cost unit of the external tasks' throughput table: 10 seeds trained to the largest budget a study may use."""


def external_throughput_source(root: Path) -> dict[str, str]:
    """bench/external_throughput.py's outputs: task -> its file's text, the default task's file first."""
    files = sorted((root / BENCH).glob("external_throughput*.txt"), key=lambda f: (f.stem != "external_throughput", f.name))
    if not files:
        raise SourceError(f"no {BENCH}/external_throughput*.txt: run `python bench/external_throughput.py`")
    return {_matches(r"^# SAC throughput on (\S+):", f.read_text(), f.name)[0]: f.read_text() for f in files}


def external_throughput(texts: dict[str, str]) -> list[str]:
    """bench/external_throughput.py per task: seed-steps/s, the ratios to SB3 and to one seed, and the hours 10
    seeds x 300,000 steps take at that rate; then each run's command and load."""
    lines = ["| task | trainer | seed-steps/s | x SB3 | x K=1 | hours per 10 seeds x 300,000 steps |",
             "|---|---|---:|---:|---:|---:|"]
    notes = []
    for task, text in texts.items():
        for trainer, rate, sb3, single in _matches(r"^\| \d+ \| (SB3 SAC|ours K=\d+) \| (\d+) \| ([\d.]+) \| ?([\d.]*) ?\|$",
                                                   text, f"external_throughput on {task}"):
            lines.append(f"| {task} | {trainer} | {rate} | {sb3} | {single} | {STUDY_SEED_STEPS / int(rate) / 3600:.1f} |")
        command = _matches(r"^`(python bench/external_throughput\.py[^`]*)`$", text, f"external_throughput on {task}")[0]
        load = re.search(r"load average ([\d.]+) at the start", text)
        notes.append(f"`{command}`" + (f" (one-minute load average {load[1]} as it began)" if load else
                                       " (measured beside other processes; load not recorded)"))
    return lines + ["", "Made by " + "; ".join(notes) + "."]


def memory_source(root: Path) -> dict[str, str]:
    """bench/memory.py's outputs: memory.txt (the comparison with a reference) first, then memory_*.txt."""
    files = sorted((root / BENCH).glob("memory*.txt"), key=lambda f: (f.stem != "memory", f.name))
    if not files:
        raise SourceError(f"no {BENCH}/memory*.txt: run `python bench/memory.py`")
    return {f.name: f.read_text() for f in files}


def memory_table(texts: dict[str, str]) -> list[str]:
    """bench/memory.py: every task and seed count's peak resident set size (and the reference code's, where the
    run compared), in one table; then each run's command, the code it measured and the load."""
    lines = ["| task | K | evaluation sub-envs at once | peak RSS (MiB) | reference code's peak RSS (MiB) | "
             "metrics.csv against the reference |", "|---|---:|---:|---:|---:|---|"]
    notes = []
    for name, text in texts.items():
        for row in _matches(r"^\| (\S+-v\d+ \|.*)\|$", text, name):
            cells = [cell.strip() for cell in row.split("|")]
            task, k, envs, rss = cells[:4]
            ref_rss, same = (cells[5], cells[7]) if len(cells) == 8 else ("-", "-")
            lines.append(f"| {task} | {k} | {envs} | {rss} | {ref_rss} | {same} |")
        [command] = _matches(r"^\$ (python bench/memory\.py.*)$", text, name)
        [(code, dirty, ref)] = _matches(r"^code: ([0-9a-f]{7})[0-9a-f]*( \(with uncommitted changes\))?"
                                        r"(?:; ref: ([0-9a-f]{7}))?", text, name)
        [load] = _matches(r"one-minute load average ([\d.]+) as it began$", text, name)
        measured = f"code {code}{dirty}" + (f" against {ref}" if ref else "")
        notes.append(f"`{command}` ({measured}; one-minute load average {load} as it began)")
    return lines + ["", "Made by " + "; ".join(notes) + "."]


WAIT_POLICIES = {"PASSIVE (CLI default)": "`PASSIVE` (what the CLI sets)",
                 "libgomp default": "libgomp's default (before)"}


def threads_table(text: str) -> list[str]:
    """bench/threads_under_load.py, its first run: steps/s idle and beside a busy process per OpenMP wait policy."""
    first = text.split("\n\n")[0]
    lines = ["| OpenMP wait policy | idle: steps/s | beside a busy process: steps/s | busy / idle |",
             "|---|---:|---:|---:|"]
    rows = _matches(r"^(PASSIVE \(CLI default\)|libgomp default)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)$", first,
                    "threads_under_load.txt")
    for policy, idle, loaded, ratio in rows:
        lines.append(f"| {WAIT_POLICIES[policy]} | {idle} | {loaded} | {ratio} |")
    return lines


def sweep_scaling_table(text: str) -> list[str]:
    """bench/sweep_scaling.py, every run in the file: wall time per backend and its speed-up over one worker."""
    runs = [dict((case, (float(wall), float(jobs), ratio)) for case, wall, jobs, ratio in
                 _matches(r"^(local, 1 worker|local, 2 workers|Ray, local cluster of 2 CPUs)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)x",
                          run, "sweep_scaling.txt")) for run in re.split(r"^# run \d+.*$", text, flags=re.MULTILINE)[1:]]
    names = " / ".join(f"run {i}" for i in range(1, len(runs) + 1))
    lines = [f"| backend | wall time, {names} | x 1 worker |", "|---|---:|---:|"]
    for case in runs[0]:
        wall = " / ".join(f"{run[case][0]:.1f} s" for run in runs)
        if case.startswith("Ray"):
            wall += " (jobs alone " + " / ".join(f"{run[case][1]:.1f} s" for run in runs) + ")"
        lines.append(f"| {case} | {wall} | " + " / ".join(run[case][2] for run in runs) + " |")
    return lines


def single_seed_runs(text: str) -> list[dict]:
    """bench/single_seed_speed.py's reports in the file (one per `$ command` line): the command, the reference,
    the repeats, each tree's median and single runs in steps/s, and the ratio this tree / reference."""
    runs = []
    for report in re.split(r"^(?=\$ )", text, flags=re.MULTILINE)[1:]:
        [(command, ref)] = _matches(r"^\$ (.*)\n.*; ref: (\w+)$", report, "single_seed_speed.txt")
        [(steps, repeats)] = _matches(r"^single-seed SAC from p0, 64x64, (\d+) steps .*median of (\d+)", report,
                                      "single_seed_speed.txt")
        trees = {name: (float(median), [float(v) for v in values.split(", ")]) for name, median, values in
                 _matches(r"^\s*(this tree|\w+):\s+([\d.]+) steps/s\s+runs: (.*)$", report, "single_seed_speed.txt")}
        [ratio] = _matches(r"^\s*ratio this tree / \w+: ([\d.]+)$", report, "single_seed_speed.txt")
        if set(trees) != {"this tree", ref}:
            raise SourceError(f"single_seed_speed.txt: a report times {sorted(trees)}, not this tree and {ref}")
        runs.append({"command": command, "ref": ref, "steps": int(steps), "repeats": int(repeats), "trees": trees,
                     "ratio": ratio})
    if not runs:
        raise SourceError("single_seed_speed.txt holds no report starting '$ python bench/single_seed_speed.py'")
    return runs


def speed_verdict(ratio: float, here_runs: list[float], ref_runs: list[float]) -> str:
    """Slower only when every single run of this tree was slower than every one of the reference's: a lower
    median inside the two trees' overlapping spreads is not told apart from load."""
    if ratio >= 1:
        return "this tree was not slower"
    if max(here_runs) >= min(ref_runs):
        return "this tree's median was lower, within the overlap of the two trees' single runs"
    return "this tree was slower"


def single_seed_speed(text: str) -> list[str]:
    """bench/single_seed_speed.py: per report, the ratio this tree / the reference, the medians and the spread."""
    said, command = [], None
    for run in single_seed_runs(text):
        (here, here_runs), (ref, ref_runs) = run["trees"]["this tree"], run["trees"][run["ref"]]
        gave = "run again, it gave" if run["command"] == command else f"`{run['command']}` gave"
        command = run["command"]
        said.append(f"{gave} **{run['ratio']}** (this tree {here:.1f} steps/s, {run['ref']} "
                    f"{ref:.1f}; medians of {run['repeats']} runs of {run['steps']:,} steps each, single runs "
                    f"{min(here_runs):.1f}-{max(here_runs):.1f} and {min(ref_runs):.1f}-{max(ref_runs):.1f} steps/s): "
                    + speed_verdict(float(run["ratio"]), here_runs, ref_runs))
    return ["; ".join(said) + "."]


def tracking_cost(text: str) -> list[str]:
    """bench/tracking_cost.py: the time in the logging calls and the sink's work replayed alone, the side-by-side
    medians and the spread of single runs, and the share at a write every 100 steps."""
    where = "tracking_cost.txt"
    [command] = _matches(r"^\$ (.*)$", text, where)
    [(seeds, steps, every)] = _matches(r"^at commit .*?; auxss, (\d+) seed\(s\) batched, (\d+) steps, .*?; "
                                       r"TensorBoard every (\d+) steps", text, where)
    repeats = _matches(r"^\s*repeat \d+: (\w+)\s+[\d.]+ s wall,\s+([\d.]+) s CPU$", text, where)
    runs = {way: [float(cpu) for w, cpu in repeats if w == way] for way in ("without", "tensorboard")}
    medians = {kind: (float(a), float(b), float(ratio)) for kind, a, b, ratio in _matches(
        r"^median (wall|CPU)\s+time without sinks\s+([\d.]+) s, with TensorBoard\s+([\d.]+) s: ratio ([\d.]+)$",
        text, where)}
    [(call_ms, wall_share)] = _matches(r"^time in the logging calls\s+([\d.]+) ms per write of .*: ([\d.]+)% of", text,
                                       where)
    [(replay_ms, cpu_share)] = _matches(r"^the sink's whole work, replayed\s+([\d.]+) ms CPU per write of .*: "
                                        r"([\d.]+)% of", text, where)
    (wall_0, wall_1, wall_ratio), (cpu_0, cpu_1, cpu_ratio) = medians["wall"], medians["CPU"]
    often = int(every) / 100
    return [f"`{command}` (AuxSS, {seeds} seeds batched, {int(steps):,} steps, {len(runs['without'])} runs each way "
            f"with and without `--log tensorboard` writing every {int(every):,} steps, alternating) measured "
            f"{call_ms} ms in the loop's logging calls per write of the {seeds} seeds' scalars, **{wall_share}%** of "
            f"the logged runs' wall time, and the sink's whole work replayed alone (its writer thread's included) "
            f"{replay_ms} ms of CPU per write, {cpu_share}% of the runs' CPU time. The same run's side-by-side "
            f"medians: wall {wall_0:.0f} s without the sink and {wall_1:.0f} s with it, CPU {cpu_0:.1f} s and "
            f"{cpu_1:.1f} s (ratios {wall_ratio:.2f} and {cpu_ratio:.2f}); single runs ranged from "
            f"{min(runs['without']):.1f} to {max(runs['without']):.1f} s of CPU without the sink and from "
            f"{min(runs['tensorboard']):.1f} to {max(runs['tensorboard']):.1f} s with it."
            + (f" `--log-every 100` writes {often:g} times as often, about {often * float(wall_share):.2f}% of the "
               "wall time here." if often > 1 else "")]


NETSIZE_RUNS = (Path("results/calibration/auxss_lava0"), Path("results/netsize/auxss-h128"),
                Path("results/netsize/auxss-h256"))
"""AuxSS at 64 (the calibration's runs), 128 and 256 hidden units."""
NETSIZE_SEEDS = (100, 101, 102)


def netsize_source(root: Path) -> list[tuple[int, dict[int, list[tuple[int, float]]]]]:
    """Per folder of NETSIZE_RUNS: its hidden units and, per seed, (step, success from p0) at every evaluation."""
    groups = []
    for folder in NETSIZE_RUNS:
        curves = {}
        for seed in NETSIZE_SEEDS:
            run = root / folder / f"seed{seed}"
            with (run / "metrics.csv").open() as f:
                curves[seed] = [(int(r["step"]), float(r["success_p0"])) for r in csv.DictReader(f)]
        hidden = json.loads((run / "config.json").read_text())["sac"]["hidden_sizes"][0]
        groups.append((hidden, curves))
    return groups


def netsize_table(groups: list[tuple[int, dict[int, list[tuple[int, float]]]]], threshold: float = 0.8) -> list[str]:
    """Per network width, each seed's first evaluation with success from p0 >= `threshold` (else its best
    success where above 0), and how many seeds reached it within the shortest group's budget."""
    budget = min(curve[-1][0] for _, curves in groups for curve in curves.values())
    seeds = sorted({seed for _, curves in groups for seed in curves})
    lines = ["| hidden units | " + " | ".join(f"seed {s}" for s in seeds) + f" | reached by {budget // 1000}k |",
             "|---:|" + "---:|" * (len(seeds) + 1)]
    for hidden, curves in groups:
        cells, reached = [], 0
        for seed in seeds:
            first = next((step for step, success in curves[seed] if success >= threshold), None)
            best = max(success for _, success in curves[seed])
            end = curves[seed][-1][0]
            reached += first is not None and first <= budget
            cells.append(f"{first // 1000}k" if first is not None else
                         f"not by {end // 1000}k" + (f" ({best:.2f})" if best > 0 else ""))
        lines.append(f"| {hidden} | " + " | ".join(cells) + f" | {reached} of {len(seeds)} |")
    return lines


@dataclass(frozen=True)
class BudgetRuns:
    """Two groups of runs in one folder, a demo strategy's (first) and SAC's from p0, read at several budgets."""
    folder: Path
    budgets: tuple[int, ...]
    groups: tuple[tuple[str, str], tuple[str, str]] = (("auxss-d500", "AuxSS"), ("sac-d500", "SAC from p0"))


MAIN_BUDGET = BudgetRuns(Path("results/main_budget"), (40_000, 50_000, 60_000, 70_000, 80_000))
"""The main job's groups at evaluations every 5,000 steps (`make main-budget`)."""
EXTERNAL_SCREENING = Path("results/external_screening")
"""The external tasks' screening on the tuning seeds (`make external-screening`), a folder per task."""
SCREENING_BUDGETS = tuple(range(25_000, 300_001, 25_000))
SCREENED_TASKS = ("PointMaze_Medium-v3", "PointMaze_Large-v3")
"""The external tasks screened (the cube is left out for its cost: docs/external-tasks.md)."""
SCREENING_RULE = (4, 1)
"""A task's study budget: the first screening budget by which at least 4 of the 5 seeds of the demo
strategy, and at most 1 of SAC's from p0, have reached p0 success 0.8 (`screening_budget`)."""

Curves = dict[str, dict[int, list[tuple[int, float]]]]


def budget_source(runs: BudgetRuns) -> Callable[[Path], tuple[BudgetRuns, Curves]]:
    """A part's source: per group of `runs`, per seed, (step, success from p0) at every evaluation."""
    def source(root: Path) -> tuple[BudgetRuns, Curves]:
        groups = {}
        for folder, _ in runs.groups:
            curves = {}
            for run in sorted((root / runs.folder / folder).glob("seed*")):
                with (run / "metrics.csv").open() as f:
                    curves[int(run.name[4:])] = [(int(r["step"]), float(r["success_p0"])) for r in csv.DictReader(f)]
            if not curves:
                raise SourceError(f"{runs.folder / folder} holds no runs (seedN folders)")
            groups[folder] = curves
        return runs, groups
    source.__name__ = f"budget_source({runs.folder})"
    return source


def first_reached(groups: Curves, threshold: float) -> dict[str, dict[int, int | None]]:
    """Per group, per seed: the step of its first evaluation with success from p0 >= `threshold` (None: never)."""
    return {folder: {seed: next((step for step, success in curve if success >= threshold), None)
                     for seed, curve in curves.items()} for folder, curves in groups.items()}


def reached_by(firsts: dict[int, int | None], budget: int) -> int:
    return sum(first is not None and first <= budget for first in firsts.values())


def budget_table(data: tuple[BudgetRuns, Curves], threshold: float = 0.8) -> list[str]:
    """Each seed's first evaluation with success from p0 >= `threshold`, then per budget how many seeds of
    each group had reached it, and Fisher's exact p of the difference."""
    runs, groups = data
    firsts = first_reached(groups, threshold)
    (folder_a, name_a), (folder_b, name_b) = runs.groups
    lines = ["| | " + " | ".join(f"seed {s}" for s in sorted(firsts[folder_a])) + " |",
             "|---|" + "---:|" * len(firsts[folder_a])]
    for folder, name in runs.groups:
        ends = {seed: curve[-1][0] for seed, curve in groups[folder].items()}
        lines.append(f"| {name}: first step at p0 success >= {threshold} | " + " | ".join(
            f"{first:,}" if first is not None else f"not by {ends[seed]:,}"
            for seed, first in sorted(firsts[folder].items())) + " |")
    lines += ["", f"| budget | {name_a}: seeds reached | {name_b}: seeds reached | Fisher's exact p |", "|---:|---:|---:|---:|"]
    for budget in runs.budgets:
        (a, n_a), (b, n_b) = ((reached_by(firsts[folder], budget), len(firsts[folder])) for folder, _ in runs.groups)
        lines.append(f"| {budget:,} | {a} of {n_a} | {b} of {n_b} | {statistics.fisher_p(a, n_a, b, n_b):.3g} |")
    return lines


def screening_budget(data: tuple[BudgetRuns, Curves], threshold: float = 0.8) -> int | None:
    """The first budget of the screening by which SCREENING_RULE holds, or None: the demo strategy solves
    the task there and SAC from p0 does not. Every seed of both groups must have been evaluated to it."""
    runs, groups = data
    firsts = first_reached(groups, threshold)
    (demo, _), (sac, _) = runs.groups
    at_least, at_most = SCREENING_RULE
    trained_to = min(curve[-1][0] for curves in groups.values() for curve in curves.values())
    return next((budget for budget in runs.budgets if budget <= trained_to and reached_by(firsts[demo], budget)
                 >= at_least and reached_by(firsts[sac], budget) <= at_most), None)


def screening_table(data: tuple[BudgetRuns, Curves], threshold: float = 0.8) -> list[str]:
    """`budget_table` for one external task's screening, then the budget its rule picks."""
    runs, groups = data
    budget = screening_budget(data, threshold)
    trained_to = min(curve[-1][0] for curves in groups.values() for curve in curves.values())
    verdict = (f"the study's budget: **{budget:,} steps**" if budget is not None else
               f"**no budget up to {trained_to:,} steps**: this task does not separate a demo strategy from SAC from p0")
    return budget_table(data, threshold) + ["", f"By the screening rule, {verdict}."]


# --- the results index (results/*/.../config.json, provenance.json, metrics.csv) ----------------------------

@dataclass
class RunRecord:
    """What the index says of one run: its folder, config and provenance, and its last evaluation's wall time."""
    folder: str
    method: str
    seed: int
    sessions: list[dict]
    wall_time: float | None


def run_folder(relative: Path) -> str:
    """The folder of runs a run belongs to: the first two levels under results/ for runs deeper than that
    (results/study/LavaBridge-v0/auxss-d500/seed0 -> study/LavaBridge-v0), the first otherwise."""
    parts = relative.parts
    return "/".join(parts[:2] if len(parts) >= 3 else parts[:1])


def read_runs(results: Path) -> list[RunRecord]:
    """Every run under `results` (a directory with metrics.csv and config.json)."""
    records = []
    for metrics in sorted(results.rglob("metrics.csv")):
        run = metrics.parent
        config = json.loads((run / "config.json").read_text())
        provenance = run / "provenance.json"
        sessions = json.loads(provenance.read_text()) if provenance.exists() else []
        with metrics.open() as f:
            rows = list(csv.DictReader(f))
        wall = rows[-1].get("wall_time") if rows else None
        records.append(RunRecord(run_folder(run.relative_to(results)), config["method"], int(config["seed"]),
                                 sessions, float(wall) if wall not in (None, "") else None))
    return records


def _commit(session: dict) -> str:
    git = session.get("code", {}).get("git", {})
    return "unknown" if not git.get("commit") else git["commit"][:7] + ("+" if git.get("dirty") else "")


def results_index(data: tuple[list[RunRecord], dict[str, str]]) -> list[str]:
    """Per folder of runs: methods, seeds, runs, commits, platform and summed wall time. The commits are those
    the runs' provenance.json records and, for runs without one, those noted for the folder (`noted`)."""
    runs, noted = data
    lines = ["| folder | methods | seeds | runs | commits | platform | training wall time, summed over runs |",
             "|---|---|---|---:|---|---|---:|"]
    folders: dict[str, list[RunRecord]] = {}
    for run in runs:
        folders.setdefault(run.folder, []).append(run)
    for folder, members in sorted(folders.items()):
        sessions = sorted((s for run in members for s in run.sessions), key=lambda s: s.get("started", ""))
        commits = list(dict.fromkeys(_commit(s) for s in sessions))
        unrecorded = sum(not run.sessions for run in members)
        if unrecorded:
            commits.append(f"{unrecorded} run{'s' if unrecorded > 1 else ''} without provenance.json"
                           + (f", noted as {noted[folder]}" if folder in noted else ""))
        code = [s.get("code", {}) for s in sessions]
        machines = dict.fromkeys(" ".join(filter(None, [c.get("platform"), c.get("processor")])) for c in code)
        walls = [run.wall_time for run in members if run.wall_time is not None]
        hours = f"{sum(walls) / 3600:,.1f} h" if walls else "-"
        if walls and len(walls) < len(members):
            hours += f" ({len(walls)} runs)"
        methods, seeds = sorted({r.method for r in members}), sorted({r.seed for r in members})
        lines.append(f"| `{folder}/` | {', '.join(methods)} | {format_seeds(seeds)} | {len(members)} | "
                     f"{', '.join(commits) or '-'} | {'; '.join(m for m in machines if m) or '-'} | {hours} |")
    return lines


# --- the parts and the mechanism ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Part:
    """A generated part: `source` reads committed files under the repository root, `render` makes the lines."""
    source: Callable[[Path], object]
    render: Callable[[object], list[str]]


def answers_source(root: Path) -> dict:
    return json.loads((root / ANSWERS).read_text())


def results_source(root: Path) -> tuple[list[RunRecord], dict[str, str]]:
    noted = root / CODE_BEFORE_PROVENANCE
    notes = json.loads(noted.read_text()) if noted.exists() else {}
    return read_runs(root / RESULTS), {folder: note for folder, note in notes.items() if not folder.startswith("_")}


PARTS: dict[str, Part] = {
    "study-answers": Part(answers_source, answer_table), "study-in-words": Part(answers_source, in_words),
    "study-comparisons": Part(answers_source, comparison_tables), "study-seeds": Part(answers_source, seeds_table),
    "difficulty": Part(difficulty_source, difficulty_table),
    "difficulty-lava-bridge": Part(lava_bridge_difficulty_source, lava_bridge_difficulty),
    "speed-protocol": Part(bench_text("protocol_throughput.txt"), protocol_table),
    "speed-env-loops": Part(bench_text("env_throughput.txt"), env_loops_table),
    "speed-free-motion": Part(bench_text("env_throughput.txt"), free_motion_table),
    "speed-profile": Part(bench_text("profile_training.txt"), profile_table),
    "speed-eval-round": Part(bench_text("eval_round.txt"), eval_round_table),
    "speed-walls-only": Part(bench_text("eval_round.txt"), walls_only_table),
    "speed-update": Part(bench_text("update_speed.txt"), update_speed_table),
    "speed-sac-throughput": Part(sac_throughput_source, sac_throughput_table),
    "speed-vector-env": Part(bench_text("env_throughput.txt"), vector_table),
    "external-tasks": Part(bench_text("external_tasks.txt"), external_tasks),
    "external-throughput": Part(external_throughput_source, external_throughput),
    "external-memory": Part(memory_source, memory_table),
    "speed-threads": Part(bench_text("threads_under_load.txt"), threads_table),
    "speed-single-seed": Part(bench_text("single_seed_speed.txt"), single_seed_speed),
    "tracking-cost": Part(bench_text("tracking_cost.txt"), tracking_cost),
    "speed-netsize": Part(netsize_source, netsize_table),
    "sweep-scaling": Part(bench_text("sweep_scaling.txt"), sweep_scaling_table),
    "main-budget": Part(budget_source(MAIN_BUDGET), budget_table),
    **{f"screening-{task.lower().replace('_', '-')}": Part(budget_source(BudgetRuns(EXTERNAL_SCREENING / task, SCREENING_BUDGETS)), screening_table)
       for task in SCREENED_TASKS},
    "results-index": Part(results_source, results_index)}


def fill(text: str, root: Path = ROOT) -> str:
    """`text` with every generated part rewritten from the committed data under `root`; ValueError naming an
    unknown part."""
    read: dict[Callable, object] = {}

    def part(match: re.Match) -> str:
        name = match["name"]
        if name not in PARTS:
            raise ValueError(f"unknown generated part {name!r}; known: {', '.join(PARTS)}")
        source = PARTS[name].source
        if source not in read:
            read[source] = source(root)
        return match.group(1) + "\n".join(PARTS[name].render(read[source])) + "\n" + match.group(3)

    return _BLOCK.sub(part, text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lava_bridge_mj.eval.analysis.doc_tables", description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 if a document is stale")
    args = parser.parse_args(argv)
    stale = []
    for document in DOCUMENTS:
        text = (ROOT / document).read_text()
        filled = fill(text, ROOT)
        if filled != text:
            stale.append(str(document))
            if not args.check:
                (ROOT / document).write_text(filled)
    if args.check and stale:
        print(f"stale generated parts in {', '.join(stale)}: run `python -m lava_bridge_mj.eval.analysis.doc_tables`",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
