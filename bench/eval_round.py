"""One evaluation round of a seed batch, the per-seed way and the batched way, side by side.

A round is every seed's deterministic policy on `--episodes` p0 and `--episodes` ood episodes. Two
ways, on the same actors:

  per seed  the loop the trainer ran before batched evaluation: seed by seed and start by start, one
            single env per episode, stepped one by one, and each step one call of the seed's policy
            (`agent.policy(i)`, which runs every member of the stacked actor on that seed's rows)
  batched   eval/training/evaluate.py's `evaluate`, as the trainer runs it now: every seed's episodes of one
            start distribution in one LavaBridgeVectorEnv, one actor call per step for all seeds

Both run on untrained actors (SAC's, default 64x64; their deterministic pushes mostly hold the ball
against a wall until the time limit: the longest round) and on behaviour-cloned ones (`--bc-updates`
updates on the 500-transition demo set, 64x64, trained through the trainer), which steer along the
demos' path instead.
A third run is the batched way with the env's walls-only path switched off for it (a step that may
touch a wall but neither lava nor the goal then runs the checked per-physics-step loop, as every such
step did before `LavaBridgeTask.clear_of_hazards`); the per-seed way runs without it too, so it is
the trainer's evaluation as it was before both changes.
The results of the ways are compared, seed by seed, and must be equal. Times are wall time and
this process's CPU time (`time.process_time`, which other programs on a shared machine do not
inflate); the ratio is the per-seed round's seconds over the batched round's.

    python bench/eval_round.py                 # 25 seeds, 50 + 50 episodes (tens of minutes under load)
    python bench/eval_round.py --quick         # 2 seeds, 2 + 2 episodes, 50 steps: a smoke test
"""

from __future__ import annotations

import argparse
import contextlib
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
import torch

from lava_bridge_mj.eval.training.evaluate import EVAL_SEED, EVAL_STARTS, MAX_EVAL_ENVS, evaluate
from lava_bridge_mj.eval.training.runner import RunConfig, make_agent, train
from lava_bridge_mj.vector import LavaBridgeVectorEnv
from difficulty import code_version  # bench/ is on sys.path when this script runs


def per_seed_round(agent, envs, horizon):
    """The per-seed evaluation the trainer ran before batching (its code, for comparison)."""
    scores = {start: {} for start in EVAL_STARTS}
    for k in range(agent.num_seeds):
        policy = agent.policy(k)
        for start in EVAL_STARTS:
            n = len(envs)
            obs = np.stack([env.reset(seed=EVAL_SEED + i, options={"start": start})[0] for i, env in enumerate(envs)])
            running, returns, success = np.ones(n, dtype=bool), np.zeros(n), np.zeros(n, dtype=bool)
            for _ in range(horizon):
                active = np.flatnonzero(running)
                if active.size == 0:
                    break
                actions = policy(obs[active])
                if not np.isfinite(actions).all():
                    raise ValueError(f"seed {k}'s actions are not finite")
                for action, i in zip(actions, active):
                    obs[i], reward, terminated, _, info = envs[i].step(action)
                    returns[i] += reward
                    if terminated:
                        running[i] = False
                        success[i] = info["is_success"]
            scores[start][k] = {"success": float(success.mean()), "return": float(returns.mean())}
    return scores


def batched_round(agent, envs, episodes, horizon):
    scores = {}
    for start in EVAL_STARTS:
        scores[start], diverged = evaluate(agent, envs, start, episodes, horizon=horizon)
        assert not diverged, diverged
    return scores


@contextlib.contextmanager
def without_walls_only_path(tasks):
    """The tasks' steps as before the walls-only path: `clear_of_hazards` never holds (bench only)."""
    for task in tasks:
        task.clear_of_hazards = lambda data: False
    try:
        yield
    finally:
        for task in tasks:
            del task.clear_of_hazards


def timed(function, *args):
    wall, cpu = time.perf_counter(), time.process_time()
    result = function(*args)
    return result, time.perf_counter() - wall, time.process_time() - cpu


def behaviour_cloned(seeds: int, updates: int):
    """A BC agent of `seeds` seeds (64x64 actor) after `updates` updates, trained through the trainer."""
    config = RunConfig(method="bc", steps=updates, eval_every=updates, eval_episodes=1, bc={"hidden_sizes": [64, 64]})
    with tempfile.TemporaryDirectory() as out:
        return train(config, [Path(out) / f"seed{s}" for s in range(seeds)], seeds=range(seeds), progress=False).agent


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=25)
    parser.add_argument("--episodes", type=int, default=50, help="per start distribution")
    parser.add_argument("--horizon", type=int, default=500)
    parser.add_argument("--bc-updates", type=int, default=1000, help="0: untrained actors only")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--quick", action="store_true", help="2 seeds, 2 + 2 episodes, 50 steps, 20 BC updates")
    args = parser.parse_args(argv)
    if args.quick:
        args.seeds, args.episodes, args.horizon, args.bc_updates = 2, 2, 50, 20
    torch.set_num_threads(args.threads)
    commit = code_version()
    given = sys.argv[1:] if argv is None else argv
    print(f"# python bench/eval_round.py {' '.join(given)}".rstrip() + f" (commit {commit}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())})")
    print(f"python {platform.python_version()} | torch {torch.__version__} | mujoco {mujoco.__version__} | "
          f"numpy {np.__version__} | {args.threads} torch thread(s) | {os.cpu_count()} CPUs, load average at "
          f"start {os.getloadavg()[0]:.1f} (a shared machine: other programs ran beside it; compare the ratios)")
    print(f"round: {args.seeds} seeds x ({args.episodes} p0 + {args.episodes} ood episodes), horizon {args.horizon}")

    config = RunConfig(method="auxss")
    singles = [config.make_env() for _ in range(args.episodes)]
    vector = LavaBridgeVectorEnv(min(args.seeds, max(1, MAX_EVAL_ENVS // args.episodes)) * args.episodes,
                                 **config.env_kwargs())
    agents = {"untrained SAC actors (64x64)": make_agent(config, list(range(args.seeds)))}
    if args.bc_updates:
        agents[f"BC actors, {args.bc_updates} updates (64x64)"] = behaviour_cloned(args.seeds, args.bc_updates)

    print(f"\n{'actors':<34} {'p0 / ood success':>17} {'per seed: wall, CPU s':>22} "
          f"{'batched, checked near walls: wall, CPU s':>41} {'batched: wall, CPU s':>21} "
          f"{'ratio CPU per seed / batched':>29} {'ratio CPU checked / batched':>28}  results")
    for name, agent in agents.items():
        with without_walls_only_path([env.unwrapped.task for env in singles]):
            old, old_wall, old_cpu = timed(per_seed_round, agent, singles, args.horizon)
        with without_walls_only_path([vector.task]):
            checked, checked_wall, checked_cpu = timed(batched_round, agent, vector, args.episodes, args.horizon)
        new, new_wall, new_cpu = timed(batched_round, agent, vector, args.episodes, args.horizon)
        success = " / ".join(f"{np.mean([s['success'] for s in new[start].values()]):.2f}" for start in EVAL_STARTS)
        same = "identical" if old == new == checked else "DIFFERENT"
        print(f"{name:<34} {success:>17} {old_wall:>12.1f}, {old_cpu:>7.1f} {checked_wall:>31.1f}, {checked_cpu:>7.1f} "
              f"{new_wall:>11.1f}, {new_cpu:>7.1f} {old_cpu / new_cpu:>29.2f} {checked_cpu / new_cpu:>28.2f}  {same}",
              flush=True)


if __name__ == "__main__":
    main()
