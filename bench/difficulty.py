"""How hard each Lava Bridge task is, in the paper's sense: the figures the tables of docs/environment.md record.

Per task (`--env ID`, or every task of `lava_bridge_mj.TASKS` by default):
- a uniformly random policy from p0: success rate (must stay below 1%) and how episodes end;
- the scripted expert from p0 and from ood: success rate and mean episode length;
- the task's shipped demo states: the random policy's 4-step lava probability (1 - Omega(s), the
  safety signal Omega-SS and AuxSS rely on), its histogram, and the share of states where it is >= 0.1;
- Omega-SS's max/min sampling ratio over the 150 candidate states a run of each seed in
  `--candidate-seeds` draws (the runner's draw and Omega-SS's own defaults: 32 rollouts of 4 steps,
  seeded with the run's seed, omega floored at 0.05): near 1, Omega-SS is uniform sampling.

The last column, SAC from p0 at 100,000 steps on tuning seeds, comes from training runs, not from
this script: `--sac-runs DIR` (TASK/.../seedN run directories, `results/suite/sac_p0`) appends their
table, each seed's best success from p0 / ood over its evaluations and the share of its training
episodes that reached the goal; `--sac-runs DIR --sac-only` prints just that table, in seconds
(tests/test_results_docs.py checks results/suite/difficulty.md against it).

`--json FILE` also writes every figure printed, per task, as JSON (the settings, the command and the
commit beside them, no timing: the same command gives the same file), which docs/environment.md's
LavaBridge-v0 section is generated from (results/suite/difficulty_LavaBridge-v0.json).

Usage: python bench/difficulty.py [--env ID] [--random-episodes 1000] [--expert-episodes 200]
       [--rollouts 64] [--candidate-seeds 0-4] [--sac-runs DIR [--sac-only]] [--out results/suite/difficulty.md]
       [--json FILE]
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import shlex
import subprocess
import sys
import time
from pathlib import Path

import gymnasium
import numpy as np

import lava_bridge_mj
from lava_bridge_mj.agents.omega_ss import OmegaSS, estimate_random_policy_safety
from lava_bridge_mj.eval.training import run_files

CANDIDATES = 150
"""The runner's default candidate subset (RunConfig.demo_subset)."""
LAVA_PROBABILITY_EDGES = [0, 0.01, 0.1, 0.2, 0.3, 0.5, 1.0001]


def run_episodes(env, policy, episodes: int, start: str, seed: int) -> dict:
    outcomes = {"success": 0, "lava": 0, "truncated": 0}
    lengths = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode, options={"start": start})
        for t in range(1, 10_000):
            obs, _, terminated, truncated, info = env.step(policy(obs))
            if terminated or truncated:
                break
        outcomes["success"] += info["is_success"]
        outcomes["lava"] += info["lava"]
        outcomes["truncated"] += truncated and not terminated
        lengths.append(t)
    return {key: value / episodes for key, value in outcomes.items()} | {"mean_length": float(np.mean(lengths))}


def candidate_states(states: np.ndarray, seed: int) -> np.ndarray:
    """The candidate start states a run of `seed` draws from the demo states (eval/training/runner.py's draw)."""
    rng = np.random.default_rng([seed, 2024])
    return states[np.sort(rng.choice(len(states), size=min(CANDIDATES, len(states)), replace=False))]


def omega_ss_ratio(env, states: np.ndarray, seed: int) -> float:
    """Omega-SS's largest over smallest sampling probability on a run's candidates (its defaults)."""
    weights = OmegaSS.from_env(candidate_states(states, seed), env, seed=seed).weights
    return float(weights.max() / weights.min())


def measure(env_id: str, args: argparse.Namespace) -> dict:
    """Print one task's figures and return them all (what `--json` writes)."""
    env = gymnasium.make(env_id)
    layout = env.unwrapped.layout
    rng = np.random.default_rng(0)
    random_policy = lambda obs: rng.uniform(-1, 1, 2).astype(np.float32)  # noqa: E731
    expert = lava_bridge_mj.ScriptedExpert(env)
    print(f"== {env_id}: {lava_bridge_mj.TASK_DOCS[env_id]}")
    r = run_episodes(env, random_policy, args.random_episodes, "p0", seed=0)
    print(f"random policy from p0 ({args.random_episodes} episodes): success {r['success']:.2%}, "
          f"lava {r['lava']:.2%}, timed out {r['truncated']:.2%}, mean length {r['mean_length']:.0f}")
    row = {"task": env_id, "random": r}
    for start_name in ("p0", "ood"):
        e = run_episodes(env, expert.act, args.expert_episodes, start_name, seed=10_000)
        print(f"expert from {start_name} ({args.expert_episodes} episodes): success {e['success']:.2%}, "
              f"lava {e['lava']:.2%}, mean length {e['mean_length']:.0f}")
        row[f"expert_{start_name}"] = e

    states = lava_bridge_mj.load_demos(args.demos, env_id=env_id)["observations"]
    omega = estimate_random_policy_safety(env, states, k=4, rollouts=args.rollouts, seed=0)
    lava_probability = 1 - omega
    bridge = layout.bridge
    on_bridge = np.abs(states[:, 0] - bridge.x) <= bridge.half_x
    counts, _ = np.histogram(lava_probability, bins=LAVA_PROBABILITY_EDGES)
    row["unsafe"] = float(np.mean(lava_probability >= 0.1))
    edges = LAVA_PROBABILITY_EDGES
    unsafe_x = states[lava_probability >= 0.1, 0]
    row["demo_states"] = {
        "count": len(states), "demos": args.demos, "on_bridge": float(on_bridge.mean()),
        "unsafe_on_bridge": float(np.mean(lava_probability[on_bridge] >= 0.1)),
        "unsafe_off_bridge": float(np.mean(lava_probability[~on_bridge] >= 0.1)),
        "unsafe_x": [float(unsafe_x.min()), float(unsafe_x.max())] if len(unsafe_x) else None,
        "bridge_x": [float(bridge.x - bridge.half_x), float(bridge.x + bridge.half_x)],
        # [low, high, count]; every bin is [low, high) but the last, [low, 1]
        "lava_probability_histogram": [[lo, min(hi, 1), int(count)] for lo, hi, count in zip(edges[:-1], edges[1:], counts)]}
    demo = row["demo_states"]
    print(f"demo states ({len(states)}, demos {args.demos}): on the bridge {demo['on_bridge']:.1%}; "
          f"4-step random lava probability >= 0.1: {row['unsafe']:.1%} "
          f"(on the bridge: {demo['unsafe_on_bridge']:.1%}, off it: {demo['unsafe_off_bridge']:.1%})")
    print("  lava probability histogram:")
    for lo, hi, count in zip(edges[:-1], edges[1:], counts):
        print(f"    [{lo:.2f}, {min(hi, 1):.2f}{']' if hi > 1 else ')'}: {count}")
    if len(unsafe_x):
        print(f"  states with lava probability >= 0.1 lie at x in [{unsafe_x.min():.2f}, {unsafe_x.max():.2f}] "
              f"(bridge: [{bridge.x - bridge.half_x:g}, {bridge.x + bridge.half_x:g}])")
    ratios = [omega_ss_ratio(env.unwrapped, states, seed) for seed in args.candidate_seeds]
    row["omega_ratios"] = ratios
    print(f"Omega-SS max/min sampling ratio, seeds {format_seeds(args.candidate_seeds)}: "
          + ", ".join(f"{ratio:.1f}" for ratio in ratios))
    env.close()
    return row


def format_seeds(seeds: list[int]) -> str:
    contiguous = seeds == list(range(seeds[0], seeds[-1] + 1))
    return f"{seeds[0]}-{seeds[-1]}" if contiguous and len(seeds) > 1 else ",".join(map(str, seeds))


def table(rows: list[dict], args: argparse.Namespace) -> str:
    seeds = format_seeds(args.candidate_seeds)
    lines = [
        f"| task | random policy from p0: success (lava / timeout) | expert success p0 / ood | expert mean "
        f"length p0 / ood (steps) | demo states with 4-step lava probability >= 0.1 | Omega-SS max/min "
        f"sampling ratio, median [range] over seeds {seeds} |",
        "|---|---|---|---|---|---|",
    ]
    for row in rows:
        r, p0, ood = row["random"], row["expert_p0"], row["expert_ood"]
        ratios = row["omega_ratios"]
        lines.append(
            f"| `{row['task']}` | {r['success']:.2%} ({r['lava']:.1%} / {r['truncated']:.1%}) "
            f"| {p0['success']:.0%} / {ood['success']:.0%} | {p0['mean_length']:.0f} / {ood['mean_length']:.0f} "
            f"| {row['unsafe']:.1%} | {np.median(ratios):.1f} [{min(ratios):.1f}, {max(ratios):.1f}] |")
    return "\n".join(lines)


def code_version() -> str:
    """The checkout's commit, marked dirty when tracked files differ from it ('unknown' outside git)."""
    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True,
                                text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return commit + (" (with uncommitted changes)" if dirty else "")


def parse_seeds(text: str) -> list[int]:
    """'0-4' or '0,3,5-7' -> sorted seeds; argparse turns the ValueError into a usage error."""
    seeds = set()
    for part in text.split(","):
        low, _, high = part.partition("-")
        if not (low.isdigit() and (not high or high.isdigit())) or (high and int(high) < int(low)):
            raise ValueError(text)
        seeds.update(range(int(low), int(high or low) + 1))
    return sorted(seeds)


def sac_from_p0(root: Path) -> str:
    """The SAC-from-p0 section of the difficulty table, from the runs under root/TASK/ (any depth)."""
    rows, seeds, missing, counts = [], set(), [], set()
    for env_id in lava_bridge_mj.TASKS:
        runs = {int(path.parent.name.removeprefix("seed")): path.parent
                for path in sorted((root / env_id).rglob("metrics.csv"))}
        if not runs:
            missing.append(f"`{env_id}`")
            continue
        cells, reached, episodes = {}, 0, 0
        for seed, run in runs.items():
            with open(run / "metrics.csv") as f:
                evaluations = list(csv.DictReader(f))
            counts.add(len(evaluations))
            cells[seed] = " / ".join(f"{max(float(r[f'success_{start}']) for r in evaluations):.2f}"
                                     for start in ("p0", "ood"))
            log = run_files.read_episode_log(run_files.episode_log_file(run)).decode()
            outcomes = [int(r["success"]) for r in csv.DictReader(io.StringIO(log))]
            reached, episodes = reached + sum(outcomes), episodes + len(outcomes)
        seeds.update(runs)
        rows.append((env_id, cells, "none" if not reached else f"{reached:,} of {episodes:,} ({reached / episodes:.1%})"))
    order = sorted(seeds)
    lines = ["## SAC from p0 (tuning seeds " + format_seeds(order) + ", 100,000 steps, evaluation every 10,000 "
             "with 50 episodes per start distribution)", "",
             f"Runs in `{root.as_posix()}/` (command and commits in `results/README.md`); this section is "
             f"`python bench/difficulty.py --sac-runs {root.as_posix()} --sac-only`. Best success from p0 / ood "
             f"over all {' or '.join(map(str, sorted(counts)))} evaluations, and the share of training episodes that "
             "reached the goal:", "",
             "| task | " + " | ".join(f"seed {s}" for s in order) + " | training episodes reaching the goal |",
             "|---|" + "---|" * len(order) + "---|"]
    lines += [f"| `{env_id}` | " + " | ".join(cells.get(s, "-") for s in order) + f" | {share} |"
              for env_id, cells, share in rows]
    if missing:
        lines += ["", f"No runs here for {', '.join(missing)}."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", action="append", metavar="ID",
                        help=f"a task to measure (repeatable); default: all of {', '.join(lava_bridge_mj.TASKS)}")
    parser.add_argument("--random-episodes", type=int, default=1000)
    parser.add_argument("--expert-episodes", type=int, default=200)
    parser.add_argument("--rollouts", type=int, default=64, help="random rollouts per demo state")
    parser.add_argument("--demos", type=int, default=500, choices=(500, 7500))
    parser.add_argument("--candidate-seeds", type=parse_seeds, default="0-4", metavar="SEEDS",
                        help="run seeds whose candidate states give Omega-SS's sampling ratio (default 0-4)")
    parser.add_argument("--sac-runs", type=Path, metavar="DIR",
                        help="append the SAC-from-p0 table of the runs under DIR/TASK/ (results/suite/sac_p0)")
    parser.add_argument("--sac-only", action="store_true", help="with --sac-runs: print only that table")
    parser.add_argument("--out", type=Path, help="also write the table, with the command and commit, to this file")
    parser.add_argument("--json", type=Path, metavar="FILE",
                        help="also write every measurement, per task, with the settings, command and commit, as JSON")
    args = parser.parse_args(argv)
    if args.sac_runs is not None and not args.sac_runs.is_dir():
        parser.error(f"--sac-runs {str(args.sac_runs)!r} is not a directory")
    if args.sac_only:
        if args.sac_runs is None or args.out or args.json:
            parser.error("--sac-only needs --sac-runs and prints the table; it writes no --out or --json")
        print(sac_from_p0(args.sac_runs), end="")
        return
    env_ids = args.env or list(lava_bridge_mj.TASKS)
    for env_id in env_ids:
        if env_id not in lava_bridge_mj.TASKS:
            parser.error(f"--env {env_id!r} is not a task; expected one of {', '.join(lava_bridge_mj.TASKS)}")
    for name in ("random_episodes", "expert_episodes", "rollouts"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be at least 1, got {getattr(args, name)}")
    version = code_version()  # before the run: what the figures came from

    start = time.perf_counter()
    rows = [measure(env_id, args) for env_id in env_ids]
    text = table(rows, args)
    print()
    print(text)
    print(f"({time.perf_counter() - start:.0f} s)")
    command = shlex.join(["python", "bench/difficulty.py", *(sys.argv[1:] if argv is None else argv)])
    if args.json:
        settings = {"random_episodes": args.random_episodes, "expert_episodes": args.expert_episodes,
                    "rollouts": args.rollouts, "demos": args.demos, "candidate_seeds": args.candidate_seeds}
        record = {"command": command, "commit": version, "settings": settings,
                  "tasks": {row["task"]: {key: value for key, value in row.items() if key != "task"} for row in rows}}
        write_atomically(args.json, json.dumps(record, indent=1) + "\n")
        print(f"wrote {args.json}")
    if args.out:
        header = (f"# Difficulty of the Lava Bridge tasks\n\n`{command}` at commit {version}, "
                  f"{time.perf_counter() - start:.0f} s.\n\n"
                  f"Random policy: {args.random_episodes} episodes from p0; expert: {args.expert_episodes} episodes "
                  f"from p0 and from ood; lava probability: {args.rollouts} random 4-step rollouts per state of "
                  f"each task's {args.demos}-transition demo set; Omega-SS: its default 32 rollouts per candidate "
                  f"state, the {CANDIDATES} candidates of each seed's run.\n\n")
        sac = "" if args.sac_runs is None else "\n" + sac_from_p0(args.sac_runs)
        write_atomically(args.out, header + text + "\n" + sac)
        print(f"wrote {args.out}")


def write_atomically(path: Path, text: str) -> None:
    """Write `text` to `path` through a temporary file beside it, so a crash leaves the old file whole."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)


if __name__ == "__main__":
    main()
