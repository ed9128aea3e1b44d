"""SAC training throughput: this package's trainer at K = 1, 5, 25 seeds per process against
Stable-Baselines3's SAC on one seed, side by side in one run.

All train on LavaBridge-v0 from p0 with one gradient update per env step, batch 256, a 10,000
transition buffer, the same hidden sizes, on the CPU with the same torch thread count. Each is warmed
up past its learning start, then timed over the next N steps. The figure is aggregate seed-steps per
second: env steps x seeds / wall time, everything included (env steps, replay sampling, updates).

The last column is the fraction of this machine's matmul rate the training achieves: the update's
multiply-adds (counted from the network shapes, below) per second, over the FLOP rate of one large
float32 matrix product measured in the same run.

Usage: python bench/sac_throughput.py [--steps 2000] [--hidden 64 256] [--seeds 1 5 25] [--threads 1] [--quick]
Needs stable-baselines3 (pip install stable-baselines3) for the comparison; without it only this
package's figures are printed.
"""

from __future__ import annotations

import argparse
import platform
import tempfile
import time
from pathlib import Path

import gymnasium
import torch

import lava_bridge_mj
from lava_bridge_mj.agents.sac import SACConfig
from lava_bridge_mj.eval.training.runner import RunConfig, train

LEARNING_STARTS = 1000
BATCH = 256


def update_flops(hidden: int, obs_dim: int = 4, act_dim: int = 2) -> float:
    """Floating-point operations of one SAC update of one seed (matrix products only, 2 per multiply-add).

    With A = one actor forward pass and Q = one Q-network forward pass, per sample: the target takes
    A + 2Q, the critic loss 2Q forward and about 4Q backward, the actor loss A + 2Q forward, 2Q to carry
    the gradient back through the frozen critics to the action, and 2A backward: 4A + 12Q in all.
    """
    mlp = lambda d_in, d_out: d_in * hidden + hidden * hidden + hidden * d_out  # noqa: E731
    actor, q = mlp(obs_dim, 2 * act_dim), mlp(obs_dim + act_dim, 1)
    return 2.0 * BATCH * (4 * actor + 12 * q)


def matmul_flops_per_second(size: int = 1024, repeats: int = 20) -> float:
    a, b = torch.randn(size, size), torch.randn(size, size)
    a @ b
    start = time.perf_counter()
    for _ in range(repeats):
        a @ b
    return 2.0 * size**3 * repeats / (time.perf_counter() - start)


def ours(hidden: int, seeds: int, steps: int, env_id: str = lava_bridge_mj.ENV_ID) -> float:
    """This package's trainer on task `env_id`, `seeds` seeds in one process: seed-steps per second."""
    sac = SACConfig(hidden_sizes=(hidden, hidden), batch_size=BATCH, buffer_size=10_000,
                    learning_starts=LEARNING_STARTS)
    warmup = LEARNING_STARTS + 200
    # one evaluation episode per start distribution, at the very end: a small, counted cost
    config = RunConfig(env_id=env_id, method="sac", steps=warmup, eval_every=10**9, eval_episodes=1, sac=sac)
    with tempfile.TemporaryDirectory() as out:
        run = train(config, [Path(out) / f"seed{s}" for s in range(seeds)], seeds=range(seeds), progress=False)
        run.config.steps = warmup + steps  # the configs share the stopping point through run.config
        start = time.perf_counter()
        run.train(progress=False)
        return seeds * steps / (time.perf_counter() - start)


def stable_baselines3(env: gymnasium.Env, hidden: int, steps: int) -> float | None:
    """Stable-Baselines3's SAC on `env`, one seed, with the same settings: steps per second; None
    without stable-baselines3."""
    try:
        from stable_baselines3 import SAC
    except ImportError:
        return None
    model = SAC("MlpPolicy", env, policy_kwargs={"net_arch": [hidden, hidden]}, buffer_size=10_000,
                batch_size=BATCH, learning_starts=LEARNING_STARTS, train_freq=1, gradient_steps=1,
                device="cpu", seed=0, verbose=0)
    model.learn(LEARNING_STARTS + 200)
    start = time.perf_counter()
    model.learn(steps, reset_num_timesteps=False)
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="timed env steps per measurement")
    parser.add_argument("--hidden", type=int, nargs="+", default=[64, 256])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 5, 25], help="seeds per process (K)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads for every measurement")
    parser.add_argument("--quick", action="store_true", help="a tiny run for CI: figures, not a verdict")
    args = parser.parse_args()
    steps = 20 if args.quick else args.steps
    seed_counts = [1, 2] if args.quick else args.seeds
    hiddens = [16] if args.quick else args.hidden
    torch.set_num_threads(args.threads)
    peak = matmul_flops_per_second(256 if args.quick else 1024)
    print(f"python {platform.python_version()} | torch {torch.__version__} | {args.threads} torch thread(s) | "
          f"{steps} timed steps, batch {BATCH}, one update per step | matmul {peak / 1e9:.1f} GFLOP/s")
    print(f"{'hidden':>7} {'trainer':>12} {'seed-steps/s':>13} {'x SB3':>7} {'x K=1':>7} {'of matmul':>10}")
    for hidden in hiddens:
        sb3 = stable_baselines3(gymnasium.make(lava_bridge_mj.ENV_ID), hidden, steps)
        if sb3 is not None:
            print(f"{hidden:>7} {'SB3 SAC':>12} {sb3:>13.0f} {1.0:>7.2f} {'':>7} "
                  f"{sb3 * update_flops(hidden) / peak:>10.1%}")
        single = None
        for k in seed_counts:
            rate = ours(hidden, k, steps)
            single = single or rate
            vs_sb3 = f"{rate / sb3:7.2f}" if sb3 else "    n/a"
            print(f"{hidden:>7} {f'ours K={k}':>12} {rate:>13.0f} {vs_sb3} {rate / single:>7.2f} "
                  f"{rate * update_flops(hidden) / peak:>10.1%}")
    print("targets: K=1 >= 2x SB3; K=25 >= 5x SB3 (stretch 10x) at equal network size")


if __name__ == "__main__":
    main()
