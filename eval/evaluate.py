"""Evaluate a policy on a fixed, seeded set of episodes from a named start distribution.

Episode i starts from `env.reset(seed=seed + i, options={"start": start})`, so every method and
every evaluation point is judged on the same start states. The episodes run in lockstep so that the
policy sees one batch of observations per step (one network call instead of one per episode).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from lava_bridge_mj import MAX_EPISODE_STEPS, LavaBridgeEnv

EVAL_SEED = 1_000_000
"""Base seed of the evaluation episodes: far from training seeds, the same for every run."""


def evaluate(policy: Callable[[np.ndarray], np.ndarray], envs: list[LavaBridgeEnv], start: str,
             seed: int = EVAL_SEED, horizon: int = MAX_EPISODE_STEPS) -> dict[str, float]:
    """Success rate and mean return of `policy` (a batch (n, 4) -> (n, 2) map) over len(envs) episodes."""
    n = len(envs)
    obs = np.stack([env.reset(seed=seed + i, options={"start": start})[0] for i, env in enumerate(envs)])
    running = np.ones(n, dtype=bool)
    returns = np.zeros(n)
    success = np.zeros(n, dtype=bool)
    for _ in range(horizon):
        active = np.flatnonzero(running)
        if active.size == 0:
            break
        actions = policy(obs[active])
        for action, i in zip(actions, active):
            obs[i], reward, terminated, _, info = envs[i].step(action)
            returns[i] += reward
            if terminated:
                running[i] = False
                success[i] = info["is_success"]
    return {"success": float(success.mean()), "return": float(returns.mean())}
