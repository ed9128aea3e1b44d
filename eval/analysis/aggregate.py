"""Aggregate run directories: interquartile means across seeds with stratified-bootstrap 95% CIs.

A run is any directory, at any depth under the one given, that holds both `config.json` and a
`metrics.csv` with at least one row (eval/training/runner.py writes them); names of directories are not read.

**Groups.** Runs are grouped by task (config.json's `env_id`), method and demo set first, labelled like
`auxss (0.5K)`, with ` on TASK` added for a task other than LavaBridge-v0. Runs of one
task, method and demo set whose configurations differ in anything else (every config.json entry but `seed`
and `steps`, nested sections flattened to dotted names such as `strategy.sigma` or `sac.hidden_sizes`) are split
further (`Group.settings` holds the entries that differ, `default` standing for a run that leaves a
free-form entry such as `strategy.sigma` out). The label names the entries that are not RunConfig's
defaults: `auxss (0.5K) [strategy.sigma=0.2]` beside plain `auxss (0.5K)`, so the default
configuration always reads as the method itself, and two groups never share a label. An entry a
config.json lacks because it predates the field counts as RunConfig's current default. A group
therefore holds the seeds of exactly one configuration, never a mix. `steps` is a budget, not a configuration: a run extended from 100,000 to
300,000 steps has the same first evaluations as one stopped at 100,000 (eval/training/runner.py), so both
join one group. `find_runs(root, budget=N)` keeps only evaluations at or before step N, which puts
runs of different budgets on one footing (steps to threshold included); `seeds=` keeps only those seeds.

**Curves.** Per group, metric (success_p0, success_ood, train_return) and evaluation step: the
interquartile mean (IQM, the 25%-trimmed mean) across seeds and its 95% percentile confidence interval
from rliable's stratified bootstrap over seeds (`rliable.library.get_interval_estimates`, with
`rliable.metrics.aggregate_iqm`'s estimator applied to each step). Only the steps every seed of the
group has evaluated are used, so a curve never mixes different seed sets. A step at which some seed
has no value (train_return when no training episode ended since the last evaluation, or an offline
method) has no estimate (NaN). rliable draws its resamples from NumPy's global generator whatever
`random_state` it is given, so the bootstrap runs under a fixed global seed (`BOOTSTRAP_SEED`,
restored afterwards): a report is reproducible bit for bit. `BOOTSTRAP_REPS` = 2,000 resamples, not
rliable's 50,000: on 25 seeds x 30 steps of uniform random scores the bounds of the two differed by
0.0025 in median and 0.010 at most (intervals about 0.3 wide), while 50,000 take 25 times as long.

**Late-training means.** Per group and metric, each seed's mean over the evaluations in the last
third of the group's common steps (those past two thirds of its last one: 210,000-300,000 of
300,000, 70,000-100,000 of 100,000), then the IQM across seeds with the same bootstrap CI: where a
group ended up, without the single evaluation's swing.

**Steps to threshold.** Per seed, the first evaluation step with success_p0 >= 0.8 (eval/analysis/summary.py's
definition); per group, how many seeds ever reached it, and the median and IQM over *all* seeds with a
seed that never reached it counted as infinitely late. A median or IQM that a never-reached seed
enters is therefore infinite ("not reached"), rather than an optimistic number over the lucky seeds.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from collections import defaultdict
from collections.abc import Collection, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import scipy.stats

from lava_bridge_mj.eval.analysis.summary import THRESHOLD, read_config, seed_summary
from lava_bridge_mj.eval.training.run_files import read_metrics
from lava_bridge_mj.tasks import DEFAULT_ENV_ID, SUITE, TASKS

METRICS = ("success_p0", "success_ood", "train_return")
"""The metrics with curves: success rate from p0 and from ood, and the training return."""
BOOTSTRAP_SEED = 2024
BOOTSTRAP_REPS = 2_000
LATE_FRACTION = 1 / 3
"""`late_means` averages each seed over the last third of its evaluations (210k-300k of 300k)."""


@dataclasses.dataclass(frozen=True)
class RunRecord:
    """One run directory: its configuration and its evaluation rows."""

    path: Path
    config: dict[str, Any]
    rows: list[dict[str, float]]

    @property
    def seed(self) -> int:
        return int(self.config.get("seed", 0))

    @property
    def method(self) -> str:
        return str(self.config.get("method", "?"))

    @property
    def demos(self) -> int | str:
        """The shipped set's size, or a demo file's path."""
        demos = self.config.get("demos", 500)
        return demos if isinstance(demos, str) else int(demos)

    @property
    def task(self) -> str:
        """The run's task; a config.json from before `env_id` existed is LavaBridge-v0's."""
        return str(self.config.get("env_id", DEFAULT_ENV_ID))


def find_runs(root: str | Path, budget: float | None = None, seeds: Collection[int] | None = None,
              task_seeds: Mapping[str, Collection[int]] | None = None) -> list[RunRecord]:
    """Every run directory under `root` (itself included), in path order; with `budget`, only the
    evaluations at or before that step (a run with none left is dropped); with `seeds`, only those
    seeds' runs; with `task_seeds` (task -> seeds), a task named there keeps its own seeds instead of
    `seeds` (a study reads a task whose seed extension is still training at its first seeds). ValueError
    when no run is left, or when a config.json or metrics.csv cannot be read (naming the file)."""
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"{root} is not a directory")
    runs = []
    try:
        config_files = sorted(root.rglob("config.json"))
    except OSError as error:
        raise ValueError(f"{root} cannot be searched for runs: {error}") from None
    for config_file in config_files:
        directory = config_file.parent
        if not (directory / "metrics.csv").is_file():
            continue
        config = read_config(directory)  # ValueErrors name the file
        for key, kind, what in (("seed", int, "an integer"), ("demos", (int, str), "an integer or a demo file's path"),
                                ("method", str, "a name")):
            if key in config and (not isinstance(config[key], kind) or isinstance(config[key], bool)):
                raise ValueError(f"{config_file}: {key} must be {what}, got {config[key]!r}")
        _check_run_config(config, config_file)
        rows = read_metrics(directory)
        if budget is not None:
            rows = [row for row in rows if row["step"] <= budget]
        run = RunRecord(directory, config, rows)
        chosen = (task_seeds or {}).get(run.task, seeds)
        if rows and (chosen is None or config.get("seed") in chosen):
            runs.append(run)
    if not runs:
        chosen = "".join([f" with evaluations at or before step {budget:,.0f}" if budget is not None else "",
                          f" of seeds {sorted(seeds)}" if seeds is not None else "",
                          "".join(f" ({task}: seeds {sorted(kept)})" for task, kept in (task_seeds or {}).items())])
        raise ValueError(f"{root} holds no run directory (config.json with metrics.csv){chosen} at any depth")
    return runs


def _check_run_config(config: dict[str, Any], config_file: Path) -> None:
    """ValueError naming `config_file` unless its config names a known method (every run's config.json
    does) and, where it has them, evaluation episodes in RunConfig's range: what the report reads and
    counts by. Not the whole RunConfig check, which builds the task's env for each of many runs."""
    from lava_bridge_mj.checks import check_integer
    from lava_bridge_mj.eval.training.config import MAX_EVAL_EPISODES, METHODS

    if config.get("method") not in METHODS:
        found = f"unknown method {config['method']!r}" if "method" in config else "no method"
        raise ValueError(f"{config_file}: {found}; expected one of {', '.join(METHODS)}")
    if "eval_episodes" in config:
        try:
            check_integer("eval_episodes", config["eval_episodes"], 1, MAX_EVAL_EPISODES)
        except ValueError as error:
            raise ValueError(f"{config_file}: {error}") from None


def demos_label(demos: int | str) -> str:
    """500 -> '0.5K', 7500 -> '7.5K' (the paper's names of the demo sets); a demo file: its name."""
    return Path(demos).name if isinstance(demos, str) else f"{demos / 1000:g}K"


def _flatten(values: dict[str, Any], prefix: str = "") -> dict[str, str]:
    """Nested config -> {dotted name: JSON text of the value} (hashable and comparable); an empty
    section adds nothing."""
    flat = {}
    for key, value in values.items():
        if isinstance(value, dict):
            flat.update(_flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = json.dumps(value, sort_keys=True)
    return flat


@functools.cache
def default_settings() -> dict[str, str]:
    """RunConfig's defaults, flattened to dotted names like a config.json's entries."""
    from lava_bridge_mj.eval.training.config import RunConfig

    return _flatten(RunConfig().to_dict())


@dataclasses.dataclass
class Group:
    """The seeds of one configuration. `settings` holds the config entries (dotted names, JSON text)
    that set it apart from other groups of the same task, method and demo set; empty when there are none."""

    method: str
    demos: int | str
    settings: dict[str, str]
    runs: list[RunRecord]
    task: str = DEFAULT_ENV_ID

    @property
    def changed_settings(self) -> dict[str, str]:
        """The settings that are not RunConfig's defaults: empty for the default configuration."""
        defaults = default_settings()
        return {k: v for k, v in self.settings.items() if v != defaults.get(k, "default")}

    @property
    def label(self) -> str:
        extra = ", ".join(f"{k}={v}" for k, v in self.changed_settings.items())
        task = f" on {self.task}" if self.task != DEFAULT_ENV_ID else ""
        return f"{self.method} ({demos_label(self.demos)})" + (f" [{extra}]" if extra else "") + task

    @property
    def seeds(self) -> list[int]:
        return [run.seed for run in self.runs]

    @property
    def steps(self) -> np.ndarray:
        """The evaluation steps every seed of the group has."""
        common = set.intersection(*({row["step"] for row in run.rows} for run in self.runs))
        return np.array(sorted(common))

    @property
    def last_steps(self) -> list[float]:
        """Each seed's last evaluation step (they differ while a sweep is still running)."""
        return [run.rows[-1]["step"] for run in self.runs]

    def scores(self, metric: str) -> np.ndarray:
        """(seeds, steps) array of `metric` at the group's common steps."""
        steps = self.steps
        table = []
        for run in self.runs:
            by_step = {row["step"]: row.get(metric, math.nan) for row in run.rows}
            table.append([by_step[step] for step in steps])
        return np.array(table, dtype=float).reshape(len(self.runs), len(steps))


def group_runs(runs: list[RunRecord]) -> list[Group]:
    """Runs grouped by configuration (see the module docstring), in the suite's task order, then the
    runner's method order, then demo set, then label; each group's runs in seed order."""
    from lava_bridge_mj.eval.training.config import METHODS

    # an entry a config.json lacks (written before the field existed) counts as today's default
    defaults = default_settings()
    by_base: dict[tuple[str, str, int], list[RunRecord]] = defaultdict(list)
    for run in runs:
        by_base[run.task, run.method, run.demos].append(run)
    groups = []
    for (task, method, demos), members in by_base.items():
        flats = [{k: v for k, v in {**defaults, **_flatten(run.config)}.items()
                  if k not in ("seed", "steps", "env_id")} for run in members]
        names = sorted(set().union(*flats))
        differing = [name for name in names if len({flat.get(name, "default") for flat in flats}) > 1]
        split: dict[tuple, list[RunRecord]] = defaultdict(list)
        for run, flat in zip(members, flats):
            split[tuple(flat.get(name, "default") for name in differing)].append(run)
        for values, group_members in split.items():
            group_members.sort(key=lambda run: (run.seed, str(run.path)))
            for a, b in zip(group_members, group_members[1:]):
                if a.seed == b.seed:  # one seed counted twice would narrow every interval
                    raise ValueError(f"seed {a.seed} of one configuration ({method}, {demos} demos on {task}) is in "
                                     f"two run directories, {a.path} and {b.path}; report each run once")
            groups.append(Group(method, demos, dict(zip(differing, values)), group_members, task))
    order = {method: i for i, method in enumerate(METHODS)}
    # the study's tasks in SUITE's order (easy to hard), then the other registered ones
    tasks = {task: i for i, task in enumerate(dict.fromkeys((*SUITE, *TASKS)))}
    groups.sort(key=lambda g: (tasks.get(g.task, len(tasks)), g.task, order.get(g.method, len(order)), g.method,
                               (isinstance(g.demos, str), str(g.demos) if isinstance(g.demos, str) else g.demos),
                               g.label))
    return groups



def groups_of(groups: list[Group], method: str, demos: int | None = None) -> list[Group]:
    """The groups of `method` (only those on demo set `demos` when given), in the order given: the one
    place where groups are picked by their method's name."""
    key = (method,) if demos is None else (method, demos)
    return [g for g in groups if (g.method, g.demos)[:len(key)] == key]

def iqm(scores: np.ndarray) -> np.ndarray:
    """IQM over the leading (seed) axis of a (seeds, ...) or (seeds, tasks, ...) array, for every
    remaining column: `rliable.metrics.aggregate_iqm` (a 25%-trimmed mean over runs and tasks) applied
    column by column, in one vectorised call because the bootstrap calls it thousands of times.

    The arithmetic is `scipy.stats.trim_mean(x, 0.25, axis=0)`'s, step for step (the same partition,
    the same mean, so the same bits), without the argument handling around it, which would cost more
    than the arithmetic at the bootstrap's thousands of calls."""
    runs_and_tasks = scores.reshape(-1, *scores.shape[2:]) if scores.ndim > 2 else scores
    seeds = len(runs_and_tasks)
    cut = int(0.25 * seeds)
    return np.partition(runs_and_tasks, (cut, seeds - cut - 1), axis=0)[cut:seeds - cut].mean(axis=0)


@contextmanager
def _global_numpy_seed(seed: int):
    state = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(state)


@dataclasses.dataclass(frozen=True)
class Curve:
    """IQM across seeds with its 95% CI at each step; NaN where some seed has no value."""

    steps: np.ndarray
    iqm: np.ndarray
    low: np.ndarray
    high: np.ndarray
    seeds: int


def iqm_curves(group: Group, metrics: tuple[str, ...] = METRICS, reps: int = BOOTSTRAP_REPS,
               seed: int = BOOTSTRAP_SEED) -> dict[str, Curve]:
    """Per metric: the group's IQM across seeds at each common step, with 95% stratified-bootstrap CIs.

    The metrics are bootstrapped in one call (their columns side by side), which is what rliable does
    for one metric at many steps: every (seed slot, column) entry is resampled independently."""
    steps = group.steps
    if not len(steps):  # the seeds share no evaluation step: nothing to aggregate
        empty = np.zeros(0)
        return {metric: Curve(steps, empty, empty, empty, len(group.runs)) for metric in metrics}
    table = np.concatenate([group.scores(metric) for metric in metrics], axis=1)  # (seeds, metrics * steps)
    point, low, high = _iqm_intervals(table, reps, seed)
    curves = {}
    for i, metric in enumerate(metrics):
        cut = slice(i * len(steps), (i + 1) * len(steps))
        curves[metric] = Curve(steps, point[cut], low[cut], high[cut], len(group.runs))
    return curves


def _iqm_intervals(table: np.ndarray, reps: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IQM and 95% CI bounds of every column of a (seeds, columns) table, rliable's stratified
    bootstrap under the fixed global seed; NaN for a column where some seed has no value."""
    from rliable import library as rly  # imported here: the report's dependency, not the trainer's

    missing = ~np.isfinite(table).all(axis=0)
    scores = np.where(np.isfinite(table), table, 0.0)[:, None, :]  # rliable's (runs, tasks, ...) layout
    with _global_numpy_seed(seed):
        points, intervals = rly.get_interval_estimates({"group": scores}, iqm, reps=reps)
    point, (low, high) = points["group"], intervals["group"]
    return tuple(np.where(missing, np.nan, values) for values in (point, low, high))


@dataclasses.dataclass(frozen=True)
class WindowMean:
    """IQM across seeds of each seed's mean over the evaluations at `steps`, with its 95% CI."""

    steps: np.ndarray
    iqm: float
    low: float
    high: float


def late_window(group: Group, fraction: float = LATE_FRACTION) -> np.ndarray:
    """The group's common evaluation steps in the last `fraction` of its training: those past
    (1 - fraction) x its last common step."""
    steps = group.steps
    return steps[steps > (1 - fraction) * steps[-1]] if len(steps) else steps


def late_means(group: Group, metrics: tuple[str, ...] = METRICS, fraction: float = LATE_FRACTION,
               reps: int = BOOTSTRAP_REPS, seed: int = BOOTSTRAP_SEED) -> dict[str, WindowMean]:
    """Per metric: each seed's mean over `late_window`'s evaluations, then the IQM across seeds with
    its 95% stratified-bootstrap CI. One evaluation of 50 episodes swings by 0.2-0.4 between
    neighbours on a single seed; the window's mean says where a group ended with far less of that."""
    window = late_window(group, fraction)
    if not len(window):
        return {metric: WindowMean(window, math.nan, math.nan, math.nan) for metric in metrics}
    columns = np.isin(group.steps, window)
    table = np.stack([group.scores(metric)[:, columns].mean(axis=1) for metric in metrics], axis=1)
    point, low, high = _iqm_intervals(table, reps, seed)
    return {metric: WindowMean(window, float(point[i]), float(low[i]), float(high[i]))
            for i, metric in enumerate(metrics)}


@dataclasses.dataclass(frozen=True)
class ThresholdSteps:
    """When each seed first reached success_p0 >= threshold, and what that says about the group."""

    threshold: float
    per_seed: dict[int, float]
    """seed -> first evaluation step at or above the threshold; math.inf if it never got there."""

    @property
    def reached(self) -> int:
        return sum(math.isfinite(step) for step in self.per_seed.values())

    @property
    def median(self) -> float:
        """Median over all seeds, never-reached ones counted as infinitely late (then possibly inf)."""
        return float(np.median(list(self.per_seed.values())))

    @property
    def iqm(self) -> float:
        """IQM over all seeds, never-reached ones counted as infinitely late: inf when one of them falls
        in the middle half."""
        return float(scipy.stats.trim_mean(list(self.per_seed.values()), 0.25))


def steps_to_threshold(group: Group, threshold: float = THRESHOLD) -> ThresholdSteps:
    """Per seed of `group` (all of its evaluations), the first step with success_p0 >= threshold."""
    per_seed = {}
    for run in group.runs:
        first = seed_summary(run.rows, threshold)["steps_to_threshold"]
        per_seed[run.seed] = math.inf if math.isnan(first) else first
    return ThresholdSteps(threshold, per_seed)
