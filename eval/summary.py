"""Summarise run directories as a Markdown table: one row per seed, then the batch.

    python -m lava_bridge_mj.eval.summary runs/calib/auxss_lava0 [more directories ...]

Each directory is a run directory (holding metrics.csv) or holds run directories one level down (a
--seeds batch). Per seed: the first evaluation step with success from p0 >= the threshold (0.8, the
paper's steps-to-threshold), the best p0 success and its step, and p0 / ood success at the last
evaluation. Per batch: how many seeds reached the threshold, and the means of the last evaluation.

`--start-room STEP` adds the mean probability the start strategy put on candidate states inside the
start room (where every p0 episode begins) over its logged evaluations up to STEP, from the run's
start_weights.npz: docs/results.md's measure of how much a strategy still practises the p0 starts
while it learns. Where the run logged its training episodes (episodes.csv), it also adds how many
training episodes started in the start room up to STEP and what share of them reached the goal:
whether a seed that does not learn from p0 never tried from there, or tried and failed.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from lava_bridge_mj.layout import Layout

THRESHOLD = 0.8


def read_metrics(run_dir: Path) -> list[dict[str, float]]:
    with open(run_dir / "metrics.csv") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def run_dirs(path: Path) -> list[Path]:
    """`path` itself if it is a run directory, else its run subdirectories in seed order."""
    if (path / "metrics.csv").exists():
        return [path]
    found = [d for d in path.iterdir() if (d / "metrics.csv").exists()]
    if not found:
        raise ValueError(f"{path} holds no metrics.csv, directly or one level down")
    return sorted(found, key=lambda d: (len(d.name), d.name))


def seed_summary(rows: list[dict[str, float]], threshold: float = THRESHOLD) -> dict[str, float]:
    reached = [r["step"] for r in rows if r["success_p0"] >= threshold]
    best = max(rows, key=lambda r: (r["success_p0"], -r["step"]))
    return {"steps_to_threshold": reached[0] if reached else math.nan,
            "best_p0": best["success_p0"], "best_step": best["step"],
            "last_step": rows[-1]["step"], "last_p0": rows[-1]["success_p0"], "last_ood": rows[-1]["success_ood"]}


def in_start_room(run_dir: Path, positions: np.ndarray) -> np.ndarray:
    """Which of `positions` ((n, 2+) arrays, x and y first) lie in the start room of the run's layout."""
    env = json.loads((run_dir / "config.json").read_text()).get("env", {})
    layout_fields = {f.name for f in dataclasses.fields(Layout)}
    room = Layout(**{k: v for k, v in env.items() if k in layout_fields}).start_room
    return (np.abs(positions[:, 0] - room.x) <= room.half_x) & (np.abs(positions[:, 1] - room.y) <= room.half_y)


def start_room_episodes(run_dir: Path, until: float) -> tuple[int, float]:
    """(training episodes that started in the start room and ended at steps <= `until`, the share of
    them that reached the goal); (0, nan) when the run has no episode log or no such episode."""
    path = run_dir / "episodes.csv"
    if not path.exists():
        return 0, math.nan
    with open(path) as f:
        log = [row for row in csv.DictReader(f) if float(row["step"]) <= until]
    if not log:
        return 0, math.nan
    starts = np.array([[float(r["start_x"]), float(r["start_y"])] for r in log])
    success = np.array([float(r["success"]) for r in log])[in_start_room(run_dir, starts)]
    return len(success), float(success.mean()) if len(success) else math.nan


def start_room_share(run_dir: Path, until: float) -> float:
    """Mean probability of drawing a start-room candidate, over the evaluations logged at steps <=
    `until`; nan when the run logged no candidate distribution that early (p0 methods log none)."""
    path = run_dir / "start_weights.npz"
    if not path.exists():
        return math.nan
    with np.load(path) as logged:
        steps, states, probabilities = logged["steps"], logged["states"], logged["probabilities"]
    early = steps <= until
    if probabilities.size == 0 or not early.any():
        return math.nan
    return float(probabilities[early][:, in_start_room(run_dir, states)].sum(axis=1).mean())


def markdown(path: Path, threshold: float = THRESHOLD, start_room_until: float | None = None) -> str:
    room = start_room_until is not None
    lines = [f"`{path}`", "",
             f"| run | first step p0 >= {threshold:g} | best p0 (step) | p0 / ood at the last evaluation |"
             + (f" start-room share to {start_room_until:,.0f} | start-room training episodes (success) |"
                if room else ""),
             "|---|---:|---:|---:|" + ("---:|---:|" if room else "")]
    summaries, shares, episodes = [], [], []
    for run in run_dirs(path):
        s = seed_summary(read_metrics(run), threshold)
        summaries.append(s)
        first = "never" if math.isnan(s["steps_to_threshold"]) else f"{s['steps_to_threshold']:,.0f}"
        shares.append(start_room_share(run, start_room_until) if room else math.nan)
        episodes.append(start_room_episodes(run, start_room_until) if room else (0, math.nan))
        count, success = episodes[-1]
        share = f" {_number(shares[-1])} | {count} ({_number(success)}) |" if room else ""
        lines.append(f"| {run.name} | {first} | {s['best_p0']:.2f} ({s['best_step']:,.0f}) | "
                     f"{s['last_p0']:.2f} / {s['last_ood']:.2f} (at {s['last_step']:,.0f}) |" + share)
    solved = sum(not math.isnan(s["steps_to_threshold"]) for s in summaries)
    mean = lambda key: sum(s[key] for s in summaries) / len(summaries)  # noqa: E731
    lines.append(f"| **all {len(summaries)}** | {solved} of {len(summaries)} reached it | "
                 f"mean {mean('best_p0'):.2f} | mean {mean('last_p0'):.2f} / {mean('last_ood'):.2f} |"
                 + (f" mean {_number(np.mean(shares))} | {_pooled(episodes)} |" if room else ""))
    return "\n".join(lines)


def _number(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.2f}"


def _pooled(episodes: list[tuple[int, float]]) -> str:
    """All seeds' start-room training episodes together: their count and success share."""
    total = sum(count for count, _ in episodes)
    if total == 0:
        return "0 (-)"
    return f"{total} ({_number(sum(count * success for count, success in episodes if count) / total)})"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dirs", nargs="+", type=Path, help="run directories or directories of them")
    parser.add_argument("--threshold", type=float, default=THRESHOLD, help="p0 success that counts as solved")
    parser.add_argument("--start-room", type=float, metavar="STEP", dest="start_room_until",
                        help="add each run's mean start-room share of its start distribution, and its "
                             "start-room training episodes and their success, up to STEP")
    args = parser.parse_args(argv)
    if args.start_room_until is not None and not args.start_room_until > 0:
        parser.error(f"--start-room must be a step > 0, got {args.start_room_until}")
    for path in args.dirs:
        if not path.is_dir():
            parser.error(f"{path} is not a directory")
        try:
            print(markdown(path, args.threshold, args.start_room_until), end="\n\n")
        except ValueError as error:
            parser.error(str(error))


if __name__ == "__main__":
    main()
