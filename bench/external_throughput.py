"""SAC training throughput on an external task: this package's trainer at K = 1 and 25 seeds per
process against Stable-Baselines3's SAC on one seed, side by side in one run, on PointMaze_Medium-v3.

As bench/sac_throughput.py on Lava Bridge, timed by its functions: all train from p0 with one
gradient update per env step, batch 256, a 10,000-transition buffer, the same hidden sizes, on the
CPU with the same torch thread count; each is warmed up past its learning start, then timed over the
next N steps. The figure is aggregate seed-steps per second: env steps x seeds / wall time,
everything included (env steps, replay sampling, updates; for this package's trainer one evaluation
episode from p0 and one from ood at the end). SB3 trains on `make_task_env`'s env with its Dict observation flattened
(gymnasium's FlattenObservation), as this package's trainer sees it.

    python bench/external_throughput.py      # writes results/bench/external_throughput.txt

Usage: python bench/external_throughput.py [--steps 1000] [--hidden 64] [--seeds 1 25] [--threads 1] [--out FILE]
"""

from __future__ import annotations

import argparse
import platform
from pathlib import Path

import gymnasium
import torch

from lava_bridge_mj import make_task_env
from sac_throughput import BATCH, ours, stable_baselines3  # bench/ is on sys.path when this script runs

ROOT = Path(__file__).resolve().parent.parent
ENV_ID = "PointMaze_Medium-v3"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000, help="timed env steps per measurement")
    parser.add_argument("--hidden", type=int, nargs="+", default=[64])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 25], help="seeds per process (K)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads for every measurement")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "bench" / "external_throughput.txt")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    lines = [f"# SAC throughput on {ENV_ID}: this package's trainer against SB3", "",
             "`python bench/external_throughput.py`", "",
             f"python {platform.python_version()} | torch {torch.__version__} | {args.threads} torch thread(s) | "
             f"{args.steps} timed steps, batch {BATCH}, one update per step", "",
             "| hidden | trainer | seed-steps/s | x SB3 | x K=1 |", "|---|---|---|---|---|"]
    print("\n".join(lines))
    for hidden in args.hidden:
        sb3 = stable_baselines3(gymnasium.wrappers.FlattenObservation(make_task_env(ENV_ID)), hidden, args.steps)
        if sb3 is None:
            raise SystemExit("bench/external_throughput.py needs stable-baselines3: pip install stable-baselines3")
        lines.append(f"| {hidden} | SB3 SAC | {sb3:.0f} | 1.00 | |")
        print(lines[-1])
        single = None
        for k in args.seeds:
            rate = ours(hidden, k, args.steps, ENV_ID)
            single = single or rate
            lines.append(f"| {hidden} | ours K={k} | {rate:.0f} | {rate / sb3:.2f} | {rate / single:.2f} |")
            print(lines[-1], flush=True)
    args.out.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
