"""SAC training throughput on an external task: this package's trainer at K = 1 and 25 seeds per
process against Stable-Baselines3's SAC on one seed, side by side in one run, on an external task
(PointMaze_Medium-v3 unless --env names another).

As bench/sac_throughput.py on Lava Bridge, timed by its functions: all train from p0 with one
gradient update per env step, batch 256, a 10,000-transition buffer, the same hidden sizes, on the
CPU with the same torch thread count; each is warmed up past its learning start, then timed over the
next N steps. The figure is aggregate seed-steps per second: env steps x seeds / wall time,
everything included (env steps, replay sampling, updates; for this package's trainer one evaluation
episode from p0 and one from ood at the end). SB3 trains on `make_task_env`'s env with its Dict observation flattened
(gymnasium's FlattenObservation), as this package's trainer sees it.

    python bench/external_throughput.py      # writes results/bench/external_throughput.txt
    python bench/external_throughput.py --env cube-single-singletask-task1-v0 --seeds 1 10
                                             # writes results/bench/external_throughput_cube-single-singletask-task1-v0.txt

The output records the one-minute load average when the run began: on a shared machine the absolute
rates fall with the load, and the ratios of one run (every trainer timed under the same load) are the
figures to read.

Usage: python bench/external_throughput.py [--env ID] [--steps 1000] [--hidden 64] [--seeds 1 25] [--threads 1] [--out FILE]
"""

from __future__ import annotations

import argparse
import os
import platform
from pathlib import Path

import gymnasium
import torch

from lava_bridge_mj import EXTERNAL_TASKS, make_task_env
from sac_throughput import BATCH, ours, stable_baselines3  # bench/ is on sys.path when this script runs

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_ENV = "PointMaze_Medium-v3"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default=DEFAULT_ENV, choices=list(EXTERNAL_TASKS), help=f"default: {DEFAULT_ENV}")
    parser.add_argument("--steps", type=int, default=1000, help="timed env steps per measurement")
    parser.add_argument("--hidden", type=int, nargs="+", default=[64])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 25], help="seeds per process (K)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads for every measurement")
    parser.add_argument("--out", type=Path, help="default: results/bench/external_throughput.txt for "
                        f"{DEFAULT_ENV}, else results/bench/external_throughput_ENV.txt")
    args = parser.parse_args()
    suffix = "" if args.env == DEFAULT_ENV else f"_{args.env}"
    out = args.out or ROOT / "results" / "bench" / f"external_throughput{suffix}.txt"
    torch.set_num_threads(args.threads)
    load = os.getloadavg()[0]
    given = {option: value for option, value in (("--env", args.env), ("--steps", args.steps), ("--hidden", args.hidden),
                                                 ("--seeds", args.seeds), ("--threads", args.threads))
             if value != parser.get_default(option[2:])}  # the command that made the file, --out aside
    command = " ".join(["python bench/external_throughput.py", *(
        f"{option} {' '.join(map(str, value)) if isinstance(value, list) else value}" for option, value in given.items())])
    lines = [f"# SAC throughput on {args.env}: this package's trainer against SB3", "",
             f"`{command}`", "",
             f"python {platform.python_version()} | torch {torch.__version__} | {args.threads} torch thread(s) | "
             f"{args.steps} timed steps, batch {BATCH}, one update per step | {os.cpu_count()} CPUs, "
             f"load average {load:.2f} at the start", "",
             "| hidden | trainer | seed-steps/s | x SB3 | x K=1 |", "|---|---|---|---|---|"]
    print("\n".join(lines))
    for hidden in args.hidden:
        sb3 = stable_baselines3(gymnasium.wrappers.FlattenObservation(make_task_env(args.env)), hidden, args.steps)
        if sb3 is None:
            raise SystemExit("bench/external_throughput.py needs stable-baselines3: pip install stable-baselines3")
        lines.append(f"| {hidden} | SB3 SAC | {sb3:.0f} | 1.00 | |")
        print(lines[-1])
        single = None
        for k in args.seeds:
            rate = ours(hidden, k, args.steps, args.env)
            single = single or rate
            lines.append(f"| {hidden} | ours K={k} | {rate:.0f} | {rate / sb3:.2f} | {rate / single:.2f} |")
            print(lines[-1], flush=True)
    out.write_text("\n".join(lines) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
