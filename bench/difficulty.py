"""How hard LavaBridge-v0 is, in the paper's sense: the figures the README records.

- a uniformly random policy from p0: success rate and fraction of episodes that end in lava;
- the scripted expert from p0 and from ood: success rate and episode length;
- the shipped demo states: the distribution of the random policy's 4-step lava probability
  (1 - Omega(s), the safety signal Omega-SS and AuxSS rely on), and the fraction on the bridge.

Usage: python bench/difficulty.py [--random-episodes 1000] [--expert-episodes 200] [--rollouts 64]
"""

from __future__ import annotations

import argparse
import time

import gymnasium
import numpy as np

import lava_bridge_mj
from lava_bridge_mj.agents.start_strategies import estimate_random_policy_safety


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--random-episodes", type=int, default=1000)
    parser.add_argument("--expert-episodes", type=int, default=200)
    parser.add_argument("--rollouts", type=int, default=64, help="random rollouts per demo state")
    parser.add_argument("--demos", type=int, default=500, choices=(500, 7500))
    args = parser.parse_args()

    env = gymnasium.make(lava_bridge_mj.ENV_ID)
    rng = np.random.default_rng(0)
    random_policy = lambda obs: rng.uniform(-1, 1, 2).astype(np.float32)  # noqa: E731
    expert = lava_bridge_mj.ScriptedExpert(env)
    start = time.perf_counter()
    r = run_episodes(env, random_policy, args.random_episodes, "p0", seed=0)
    print(f"random policy from p0 ({args.random_episodes} episodes): success {r['success']:.2%}, "
          f"lava {r['lava']:.2%}, timed out {r['truncated']:.2%}, mean length {r['mean_length']:.0f}")
    for start_name in ("p0", "ood"):
        e = run_episodes(env, expert.act, args.expert_episodes, start_name, seed=10_000)
        print(f"expert from {start_name} ({args.expert_episodes} episodes): success {e['success']:.2%}, "
              f"lava {e['lava']:.2%}, mean length {e['mean_length']:.0f}")

    states = lava_bridge_mj.load_demos(args.demos)["observations"]
    omega = estimate_random_policy_safety(env, states, k=4, rollouts=args.rollouts, seed=0)
    lava_probability = 1 - omega
    on_bridge = np.abs(states[:, 0]) <= env.unwrapped.layout.bridge_length / 2
    edges = [0, 0.01, 0.1, 0.2, 0.3, 0.5, 1.0001]
    counts, _ = np.histogram(lava_probability, bins=edges)
    print(f"demo states ({len(states)}, demos {args.demos}): on the bridge {on_bridge.mean():.1%}; "
          f"4-step random lava probability >= 0.1: {np.mean(lava_probability >= 0.1):.1%} "
          f"(on the bridge: {np.mean(lava_probability[on_bridge] >= 0.1):.1%}, "
          f"off it: {np.mean(lava_probability[~on_bridge] >= 0.1):.1%})")
    print("  lava probability histogram:")
    for lo, hi, count in zip(edges[:-1], edges[1:], counts):
        print(f"    [{lo:.2f}, {min(hi, 1):.2f}{']' if hi > 1 else ')'}: {count}")
    unsafe_x = states[lava_probability >= 0.1, 0]
    if len(unsafe_x):
        print(f"  states with lava probability >= 0.1 lie at x in [{unsafe_x.min():.2f}, {unsafe_x.max():.2f}] "
              f"(bridge: [-{env.unwrapped.layout.bridge_length / 2}, {env.unwrapped.layout.bridge_length / 2}])")
    print(f"({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
