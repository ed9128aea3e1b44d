"""SAC training throughput: this package's runner against Stable-Baselines3's SAC, side by side.

Both train on LavaBridge-v0 from p0 with one gradient update per env step, batch 256, a 10,000
transition buffer, the same hidden sizes, one torch thread, on the CPU. Each is warmed up past
its learning start, then timed over the next N steps; the figure is env steps per second.

Usage: python bench/sac_throughput.py [--steps 3000] [--hidden 64 256] [--quick]
Needs stable-baselines3 (pip install stable-baselines3) for the comparison; without it only this
package's figures are printed.
"""

from __future__ import annotations

import argparse
import platform
import tempfile
import time

import gymnasium
import torch

import lava_bridge_mj
from lava_bridge_mj.agents.sac import SACConfig
from lava_bridge_mj.eval.runner import Run, RunConfig

LEARNING_STARTS = 1000


def ours(hidden: int, steps: int) -> float:
    sac = SACConfig(hidden_sizes=(hidden, hidden), batch_size=256, buffer_size=10_000,
                    learning_starts=LEARNING_STARTS)
    warmup = LEARNING_STARTS + 200
    # one evaluation episode per start distribution, at the very end: a small, counted cost
    config = RunConfig(method="sac", seed=0, steps=warmup, eval_every=10**9, eval_episodes=1, sac=sac)
    with tempfile.TemporaryDirectory() as out:
        run = Run(config, out)
        run.train(progress=False)
        run.config.steps = warmup + steps
        start = time.perf_counter()
        run.train(progress=False)
        return steps / (time.perf_counter() - start)


def stable_baselines3(hidden: int, steps: int) -> float | None:
    try:
        from stable_baselines3 import SAC
    except ImportError:
        return None
    env = gymnasium.make(lava_bridge_mj.ENV_ID)
    model = SAC("MlpPolicy", env, policy_kwargs={"net_arch": [hidden, hidden]}, buffer_size=10_000,
                batch_size=256, learning_starts=LEARNING_STARTS, train_freq=1, gradient_steps=1,
                device="cpu", seed=0, verbose=0)
    model.learn(LEARNING_STARTS + 200)
    start = time.perf_counter()
    model.learn(steps, reset_num_timesteps=False)
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="timed env steps per measurement")
    parser.add_argument("--hidden", type=int, nargs="+", default=[64, 256])
    parser.add_argument("--quick", action="store_true", help="a tiny run for CI: figures, not a verdict")
    args = parser.parse_args()
    steps = 100 if args.quick else args.steps
    torch.set_num_threads(1)
    print(f"python {platform.python_version()} | torch {torch.__version__} | 1 torch thread | "
          f"{steps} timed steps, batch 256, one update per step")
    print(f"{'hidden':>8} {'ours steps/s':>14} {'SB3 steps/s':>13} {'ratio':>7}")
    for hidden in args.hidden:
        a = ours(hidden, steps)
        b = stable_baselines3(hidden, steps)
        ratio = f"{a / b:7.2f}" if b else "    n/a"
        print(f"{hidden:>8} {a:>14.0f} {b if b is None else round(b):>13} {ratio}")
    print("target: ours >= 2x SB3 at equal settings")


if __name__ == "__main__":
    main()
