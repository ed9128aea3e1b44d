"""Summarise run directories as a Markdown table: one row per seed, then the batch.

    lava-bridge-bench summary runs/calib/auxss_lava0 [more directories ...]

Each directory is a run directory (holding metrics.csv) or holds run directories one level down (a
--seeds batch). Per seed: the first evaluation step with success from p0 >= the threshold (0.8, the
paper's steps-to-threshold), the best p0 success and its step, and p0 / ood success at the last
evaluation. Per batch: how many seeds reached the threshold, and the means of the last evaluation.

`--start-room STEP` adds the mean probability the start strategy put on candidate states inside the
start room (where every p0 episode begins) over its logged evaluations up to STEP, from the run's
start_weights.npz: docs/results.md's measure of how much a strategy still practises the p0 starts
while it learns. Where the run logged its training episodes (episodes.csv.gz), it also adds how many
training episodes started in the start room up to STEP and what share of them reached the goal:
whether a seed that does not learn from p0 never tried from there, or tried and failed. A run of
another task than the Lava Bridge ones (an external task) has no start room: its cells say so.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import math
import sys
from pathlib import Path

import numpy as np

import lava_bridge_mj
from lava_bridge_mj.agents.reverse_curriculum import goal_reaching_demos
from lava_bridge_mj.eval.training import run_files
from lava_bridge_mj.eval.training.run_files import read_csv, read_metrics
from lava_bridge_mj.layout import Layout

THRESHOLD = 0.8
EPISODE_COLUMNS = ("step", "start_x", "start_y", "success")
"""The episode log columns the start-room count needs."""


def read_start_weights(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(steps, states, probabilities) of a start_weights.npz (eval/training/runner.py): at evaluation i, the
    start strategy's probability of each candidate state (none for a p0 method). ValueError naming the
    file when it cannot be read or does not hold that."""
    try:
        with np.load(path) as saved:  # allow_pickle stays off: a foreign file cannot run code
            steps, states, probabilities = (np.asarray(saved[key]) for key in ("steps", "states", "probabilities"))
    except KeyError as error:
        raise ValueError(f"{path} lacks the array {error}: not start weights as the trainer writes them; move it "
                         "aside or restore it") from None
    except Exception as error:  # noqa: BLE001 - a damaged file fails in many ways (BadZipFile, EOFError, ...)
        reason = (str(error).splitlines() or [""])[0]
        raise ValueError(f"{path} is damaged ({type(error).__name__}: {reason}); move it aside or restore it") from None
    shapes_agree = (steps.ndim == 1 and states.ndim == 2 and states.shape[1] >= 2 and probabilities.ndim == 2
                    and probabilities.shape[0] == len(steps) and probabilities.shape[1] in (0, len(states)))
    if not shapes_agree:
        raise ValueError(f"{path} holds arrays of shapes steps {steps.shape}, states {states.shape}, probabilities "
                         f"{probabilities.shape} that do not fit together; move it aside or restore it")
    return steps, states, probabilities


def read_config(run_dir: Path) -> dict:
    """config.json of a run directory (`run_files.read_config`); ValueError naming the file when it is
    missing, unreadable or not a JSON object."""
    config = run_files.read_config(run_dir)
    if config is None:
        raise ValueError(f"{run_dir / 'config.json'} cannot be read: it does not exist")
    return config

def run_dirs(path: Path) -> list[Path]:
    """`path` itself if it is a run directory, else its run subdirectories in seed order."""
    if (path / "metrics.csv").exists():
        return [path]
    try:
        found = [d for d in path.iterdir() if (d / "metrics.csv").exists()]
    except OSError as error:
        raise ValueError(f"{path} cannot be listed: {error.strerror or error}") from None
    if not found:
        raise ValueError(f"{path} holds no metrics.csv, directly or one level down")
    return sorted(found, key=lambda d: (len(d.name), d.name))


def seed_summary(rows: list[dict[str, float]], threshold: float = THRESHOLD) -> dict[str, float]:
    reached = [r["step"] for r in rows if r["success_p0"] >= threshold]
    best = max(rows, key=lambda r: (r["success_p0"], -r["step"]))
    return {"steps_to_threshold": reached[0] if reached else math.nan,
            "best_p0": best["success_p0"], "best_step": best["step"],
            "last_step": rows[-1]["step"], "last_p0": rows[-1]["success_p0"], "last_ood": rows[-1]["success_ood"]}


def has_start_room(run_dir: Path) -> bool:
    """True for a run of a Lava Bridge task, whose maze has the start room the start-room measures count
    in; another task (an external task, any other env) has none."""
    return read_config(run_dir).get("env_id", lava_bridge_mj.ENV_ID) in lava_bridge_mj.TASKS


def in_start_room(run_dir: Path, positions: np.ndarray) -> np.ndarray:
    """Which of `positions` ((n, 2+) arrays, x and y first) lie in the start room of the run's layout."""
    config = read_config(run_dir)
    env = config.get("env", {})
    if not isinstance(env, dict):
        raise ValueError(f"{run_dir / 'config.json'}: env must be a JSON object of layout settings, got {env!r}")
    layout_fields = {f.name for f in dataclasses.fields(Layout)}
    try:
        task = lava_bridge_mj.task_layout(config.get("env_id", lava_bridge_mj.ENV_ID))
        room = dataclasses.replace(task, **{k: v for k, v in env.items() if k in layout_fields}).start_room
    except (TypeError, ValueError) as error:
        raise ValueError(f"{run_dir / 'config.json'}: its env settings make no maze ({error})") from None
    return (np.abs(positions[:, 0] - room.x) <= room.half_x) & (np.abs(positions[:, 1] - room.y) <= room.half_y)


def start_room_episodes(run_dir: Path, until: float) -> tuple[int, float]:
    """(training episodes that started in the start room and ended at steps <= `until`, the share of
    them that reached the goal); (0, nan) when the run has no episode log or no such episode."""
    path = run_files.episode_log_file(run_dir)
    if path is None:
        return 0, math.nan
    log = [row for row in read_csv(path, EPISODE_COLUMNS, run_files.read_episode_log) if row["step"] <= until]
    if not log:
        return 0, math.nan
    starts = np.array([[r["start_x"], r["start_y"]] for r in log])
    success = np.array([r["success"] for r in log])[in_start_room(run_dir, starts)]
    return len(success), float(success.mean()) if len(success) else math.nan


def start_room_share(run_dir: Path, until: float) -> float:
    """Mean probability of drawing a start-room candidate, over the evaluations logged at steps <=
    `until`; nan when the run logged no candidate distribution that early (p0 methods log none)."""
    path = run_dir / "start_weights.npz"
    if not path.exists():
        return math.nan
    steps, states, probabilities = read_start_weights(path)
    early = steps <= until
    if probabilities.size == 0 or not early.any():
        return math.nan
    return float(probabilities[early][:, in_start_room(run_dir, states)].sum(axis=1).mean())


@functools.lru_cache(maxsize=None)
def _demo_episode_ids(demos: int, env_id: str) -> tuple[np.ndarray, np.ndarray]:
    """The goal-reaching demo episodes a reverse_ss run of this demo set and task starts from, and their ids."""
    return goal_reaching_demos(lava_bridge_mj.load_demos(demos, env_id=env_id))


def _curriculum_starts(run_dir: Path, until: float):
    """(done, starts, episode_states, ids) of a reverse_ss run by step `until`, from its start_weights.npz:
    `done` the first evaluation step from which every episode started from p0 (None if none by
    `until`); where it was not done, `starts` holds each goal-reaching demo episode's start index (into
    `episode_states`) at the last evaluation by `until`. `starts` is None when the curriculum was done,
    nothing was logged by `until`, or the file's candidates are not the run's demo episodes."""
    path = run_dir / "start_weights.npz"
    steps, states, probabilities = read_start_weights(path)
    kept = steps <= until
    steps, probabilities = steps[kept], probabilities[kept]
    from_p0 = ~probabilities.any(axis=1) if probabilities.size else np.ones(len(steps), dtype=bool)
    if from_p0.any():
        return float(steps[np.argmax(from_p0)]), None, None, None
    if not len(steps):
        return None, None, None, None
    config = read_config(run_dir)
    episode_states, ids = _demo_episode_ids(int(config.get("demos", 500)),
                                            str(config.get("env_id", lava_bridge_mj.ENV_ID)))
    if episode_states.shape != states.shape or not np.array_equal(episode_states, states):
        return None, None, None, None
    starts = []
    for episode in np.unique(ids):
        rows = np.flatnonzero(ids == episode)
        start = np.flatnonzero(probabilities[-1, rows] > 0)
        if len(start) != 1:
            raise ValueError(f"{path}: demo episode {episode} has {len(start)} start states at step "
                             f"{steps[-1]:,.0f}, not one: not a reverse curriculum's start weights")
        starts.append(int(rows[start[0]]))
    return None, np.array(starts), episode_states, ids


def curriculum_progress(run_dir: Path, until: float) -> tuple[float | None, float | None]:
    """How far a reverse_ss run's curriculum had come by step `until`, from its start_weights.npz.

    Returns (done, back): `done` is the first evaluation step from which every episode started from p0
    (no weight on any demo state), None if none by `until`; `back`, where the curriculum was not done,
    is how far its starts had moved back along the demo episodes at the last evaluation by `until`: the
    mean over the episodes of (last index - start index) / last index, 0 with every start at its
    episode's last state, 1 with every start at its first. `back` is None when the file's candidates
    are not the run's goal-reaching demo episodes (nothing to measure along) or it logged no evaluation
    by `until`. ValueError naming the file when it cannot be read or does not hold one start per episode.
    """
    done, starts, _, ids = _curriculum_starts(run_dir, until)
    if starts is None:
        return done, None
    shares = []
    for episode, start in zip(np.unique(ids), starts):
        rows = np.flatnonzero(ids == episode)
        shares.append((rows[-1] - start) / max(len(rows) - 1, 1))
    return None, float(np.mean(shares))


@dataclasses.dataclass(frozen=True)
class CurriculumStall:
    """How the training episodes from an unfinished curriculum's last starts ended."""

    episodes: int
    goal: int
    time_limit: int
    """Ended without the goal at the episode's step limit (the curriculum's shortened one, else the env's)."""
    lava: int
    """Ended without the goal before its limit: lava, the task's only other termination."""


def curriculum_stall(run_dir: Path, until: float) -> CurriculumStall | None:
    """Where a reverse_ss run's curriculum was not done by step `until`: how the training episodes that
    started from its starts at the last evaluation by then (the episode log, up to `until`) ended. A start
    index only moves back, so these are every episode from it. None when the curriculum was done, there is
    no episode log, or its starts cannot be told (`curriculum_progress`'s None). The step limit of each
    episode is the curriculum's own (`ReverseCurriculumSS.time_limit`, with the settings the run recorded
    in provenance.json), capped by the env's; ValueError naming the run when those settings do not make one
    (a setting the strategy no longer takes)."""
    import gymnasium

    from lava_bridge_mj.agents.reverse_curriculum import ReverseCurriculumSS

    _, starts, episode_states, ids = _curriculum_starts(run_dir, until)
    path = run_files.episode_log_file(run_dir)
    if starts is None or path is None:
        return None
    sessions = run_files.read_provenance(run_dir)
    config = read_config(run_dir)
    settings = (sessions[-1].get("strategy") if sessions else None) or config.get("strategy") or {}
    try:
        curriculum = ReverseCurriculumSS(episode_states, ids, **settings)
    except (TypeError, ValueError) as error:  # a setting recorded by code that had it, or a bad value
        raise ValueError(f"{run_dir}: the recorded reverse_ss settings {settings} do not make a reverse "
                         f"curriculum here ({error})") from error
    env_limit = gymnasium.spec(str(config.get("env_id", lava_bridge_mj.ENV_ID))).max_episode_steps
    limits = {int(start): min(curriculum.time_limit(int(start)) or env_limit, env_limit) for start in starts}
    log = [row for row in read_csv(path, EPISODE_COLUMNS + ("start_index", "length"), run_files.read_episode_log)
           if row["step"] <= until and int(row["start_index"]) in limits]
    goal = sum(row["success"] > 0 for row in log)
    time_limit = sum(row["success"] == 0 and row["length"] >= limits[int(row["start_index"])] for row in log)
    return CurriculumStall(len(log), goal, time_limit, len(log) - goal - time_limit)


def markdown(path: Path, threshold: float = THRESHOLD, start_room_until: float | None = None) -> str:
    room = start_room_until is not None
    lines = [f"`{path}`", "",
             f"| run | first step p0 >= {threshold:g} | best p0 (step) | p0 / ood at the last evaluation |"
             + (f" start-room share to {start_room_until:,.0f} | start-room training episodes (success) |"
                if room else ""),
             "|---|---:|---:|---:|" + ("---:|---:|" if room else "")]
    summaries, shares, episodes, roomless = [], [], [], {}
    for run in run_dirs(path):
        rows = read_metrics(run)
        if not rows:
            raise ValueError(f"{run / 'metrics.csv'} holds no evaluation yet: nothing to summarise")
        s = seed_summary(rows, threshold)
        summaries.append(s)
        first = "never" if math.isnan(s["steps_to_threshold"]) else f"{s['steps_to_threshold']:,.0f}"
        share = ""
        if room and not has_start_room(run):  # nothing to count in: no number, rather than a made-up 0
            roomless.setdefault(read_config(run)["env_id"], []).append(run.name)
            share = " no start room | no start room |"
        elif room:
            shares.append(start_room_share(run, start_room_until))
            episodes.append(start_room_episodes(run, start_room_until))
            count, success = episodes[-1]
            share = f" {_number(shares[-1])} | {count} ({_number(success)}) |"
        lines.append(f"| {run.name} | {first} | {s['best_p0']:.2f} ({s['best_step']:,.0f}) | "
                     f"{s['last_p0']:.2f} / {s['last_ood']:.2f} (at {s['last_step']:,.0f}) |" + share)
    solved = sum(not math.isnan(s["steps_to_threshold"]) for s in summaries)
    mean = lambda key: sum(s[key] for s in summaries) / len(summaries)  # noqa: E731
    lines.append(f"| **all {len(summaries)}** | {solved} of {len(summaries)} reached it | "
                 f"mean {mean('best_p0'):.2f} | mean {mean('last_p0'):.2f} / {mean('last_ood'):.2f} |"
                 + (f" mean {_number(np.mean(shares))} | {_pooled(episodes)} |" if room and shares else
                    " no start room | no start room |" if room else ""))
    for task, runs in roomless.items():
        lines += ["", f"{task} is not a Lava Bridge maze: it has no start room, and {', '.join(runs)} "
                      f"{'has' if len(runs) == 1 else 'have'} no start-room measures."]
    return "\n".join(lines)


def _number(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.2f}"


def _pooled(episodes: list[tuple[int, float]]) -> str:
    """All seeds' start-room training episodes together: their count and success share."""
    total = sum(count for count, _ in episodes)
    if total == 0:
        return "0 (-)"
    return f"{total} ({_number(sum(count * success for count, success in episodes if count) / total)})"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="lava-bridge-bench summary", description=__doc__.splitlines()[0])
    parser.add_argument("dirs", nargs="+", type=Path, help="run directories or directories of them")
    parser.add_argument("--threshold", type=float, default=THRESHOLD,
                        help="p0 success that counts as solved, in [0, 1] (default: %(default)s)")
    parser.add_argument("--start-room", type=float, metavar="STEP", dest="start_room_until",
                        help="add each run's mean start-room share of its start distribution, and its "
                             "start-room training episodes and their success, up to STEP")
    args = parser.parse_args(argv)
    if not 0 <= args.threshold <= 1:
        parser.error(f"--threshold must be a success rate in [0, 1], got {args.threshold}")
    if args.start_room_until is not None and not 0 < args.start_room_until < math.inf:
        parser.error(f"--start-room must be a step > 0, got {args.start_room_until}")
    tables = []
    for path in args.dirs:  # every table first: an error prints one line and no half output
        try:
            if not path.is_dir():
                raise ValueError(f"{path} is not a directory")
            tables.append(markdown(path, args.threshold, args.start_room_until))
        except ValueError as error:
            print(f"{parser.prog}: error: {error}", file=sys.stderr)
            return 2
    for table in tables:
        print(table, end="\n\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
