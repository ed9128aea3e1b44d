"""The external tasks (lava_bridge_mj/external.py) measured: each expert against a random policy.

Per task of `EXTERNAL_TASKS` (or `--env ID`):
- the task's expert and a uniformly random policy, from p0 and from ood: success rate and mean
  episode length over `--episodes` episodes (seeds 0, 1, ...; `--cube-episodes` for the OGBench cube,
  whose steps cost more);
- env steps/s of random actions through the wrappers (`make_task_env`: NamedStarts, ResetToState and
  gymnasium.make's own), resetting from p0 when an episode ends, in this process's CPU time.

    python bench/external_tasks.py                  # 100 episodes each, writes results/bench/external_tasks.txt
    python bench/external_tasks.py --quick --out X  # 2 episodes each, 200 timed steps: a smoke test
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lava_bridge_mj.external import EXTERNAL_TASKS, START_NAMES, make_task_env, run_episode  # noqa: E402

warnings.filterwarnings("ignore", message=".*precision lowered by casting to float32")  # OGBench's Box bounds


def rates(env, policy, episodes: int, start: str) -> tuple[float, float]:
    """(success rate, mean episode length) of `policy` over `episodes` seeded episodes from `start`."""
    outcomes = [run_episode(env, policy, seed=seed, options={"start": start}) for seed in range(episodes)]
    return float(np.mean([s for s, _ in outcomes])), float(np.mean([n for _, n in outcomes]))


def steps_per_second(env, steps: int) -> float:
    """Env steps/s of random actions, resetting from p0 when an episode ends (CPU time)."""
    env.reset(seed=0)
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(steps)]
    begin = time.process_time()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / (time.process_time() - begin)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", action="append", help="a task of EXTERNAL_TASKS (repeat for several; default all)")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per policy and start (default 100)")
    parser.add_argument("--cube-episodes", type=int, default=100, help="the same for the OGBench cube (default 100)")
    parser.add_argument("--steps", type=int, default=20_000, help="timed random steps per task (default 20000)")
    parser.add_argument("--quick", action="store_true", help="2 episodes each and 200 timed steps")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "bench" / "external_tasks.txt",
                        help="where to write the table (default results/bench/external_tasks.txt)")
    args = parser.parse_args(argv)
    for env_id in args.env or ():
        if env_id not in EXTERNAL_TASKS:
            parser.error(f"--env {env_id!r} is not an external task; expected one of {sorted(EXTERNAL_TASKS)}")
    if min(args.episodes, args.cube_episodes, args.steps) < 1:
        parser.error("--episodes, --cube-episodes and --steps must be at least 1")
    if args.quick:
        args.episodes = args.cube_episodes = 2
        args.steps = 200

    lines = ["| task | policy | start | episodes | success rate | mean episode length |", "|---|---|---|---|---|---|"]
    speeds = []
    for env_id in args.env or EXTERNAL_TASKS:
        env = make_task_env(env_id)
        episodes = args.cube_episodes if env_id.startswith("cube") else args.episodes
        for name, policy in (("expert", EXTERNAL_TASKS[env_id].expert(env, seed=0)), ("random", None)):
            for start in START_NAMES:
                success, length = rates(env, policy, episodes, start)
                lines.append(f"| {env_id} | {name} | {start} | {episodes} | {success:.2f} | {length:.1f} |")
                print(lines[-1], flush=True)
        speeds.append(f"{env_id}: {steps_per_second(env, args.steps):,.0f} env steps/s of random actions "
                      f"through make_task_env's wrappers ({args.steps} steps)")
        print(speeds[-1], flush=True)
        env.close()

    command = "python bench/external_tasks.py" + "".join(f" {shlex.quote(a)}" for a in (argv or sys.argv[1:]))
    text = (f"# External tasks: experts and random policies\n\n`{command}`\n\n"
            f"Episodes use seeds 0, 1, ...; an episode ends at the goal or at the env's step limit. "
            f"Steps/s in this process's CPU time (single-threaded loops).\n\n"
            + "\n".join(lines) + "\n\n" + "\n".join(speeds) + "\n")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_name(args.out.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(args.out)


if __name__ == "__main__":
    main()
