"""Evaluate the policies of a seed-batched agent on a fixed, seeded set of episodes from a named start
distribution.

Episode i starts where `env.reset(seed=seed + i, options={"start": start})` of a single env starts
it, so every method, seed and evaluation point is judged on the same start states. Every member's
episodes (one member is one training seed) run in lockstep in one vector env (`LavaBridgeVectorEnv`,
each episode stepped by the env's own `LavaBridgeTask`; `ResetToStateVectorEnv` for another env), so
the episodes, their terminations (lava or goal at any physics step) and the time limit are a single env's.
An env that reports no success (`envs.reports_success` False) scores its success rate NaN. Each step makes one actor call for every member
at once, on the episodes still running; a member's deterministic actions are those it gives when
called on its own episodes alone, bit for bit (see `OWN_CALL_ROWS`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from lava_bridge_mj import MAX_EPISODE_STEPS
from lava_bridge_mj.state_vector import ResetToStateVectorEnv
from lava_bridge_mj.vector import LavaBridgeVectorEnv

EVAL_SEED = 1_000_000
"""Base seed of the evaluation episodes: far from training seeds, the same for every run."""
EVAL_STARTS = ("p0", "ood")
"""The start distributions every evaluation round runs: the MDP's own and the robustness benchmark's."""
MAX_EVAL_ENVS = 1250
"""Sub-envs of a Lava Bridge evaluation vector env (one shared model, about 450 KiB of MuJoCo data
each): a batch whose episodes need more is evaluated a group of members at a time, with the same results."""
MAX_EVAL_BYTES = MAX_EVAL_ENVS * 450 * 2**10
"""The MuJoCo models and data that the sub-envs of another env's evaluation vector env may hold
together, as much as Lava Bridge's largest: each of its sub-envs is a whole env with its own model
(a PointMaze's is 11 MiB, mostly its skybox texture; the cube's 60 MiB), so fewer members fit."""
OWN_CALL_ROWS = 16
"""A member with fewer running episodes than this gets an actor call of exactly its own row count.

torch's CPU `baddbmm` (the stacked layers' product) computes a product of fewer than 400
multiply-adds (inputs x rows x outputs) with its own loop, which rounds differently from the BLAS
kernel that larger ones take; within the BLAS kernel a row's result does not depend on how many rows
share the call. So members with at least this many rows (16 rows are over the limit for every layer
of 7 or more units) share one call padded to the largest count, and a member with fewer is called
on exactly its own rows, as when it is evaluated alone (tests/test_batched_eval.py checks both)."""


def members_at_once(members: int, episodes: int, env: Any = None) -> int:
    """How many of `members` members an evaluation vector env of `episodes` episodes each runs
    together (at least one): those that fit in MAX_EVAL_ENVS Lava Bridge sub-envs, or, given `env`
    (one sub-env of another env, whose `unwrapped` holds its MuJoCo `model` and `data`), in
    MAX_EVAL_BYTES of those sub-envs' models and data."""
    if env is None:
        fits = MAX_EVAL_ENVS // episodes
    else:
        unwrapped = env.unwrapped
        fits = MAX_EVAL_BYTES // (episodes * (unwrapped.model.nbuffer + unwrapped.data.nbuffer))
    return min(members, max(1, fits))


def evaluate(agent: Any, envs: LavaBridgeVectorEnv | ResetToStateVectorEnv, start: str, episodes: int,
             members: Sequence[int] | None = None, seed: int = EVAL_SEED,
             horizon: int = MAX_EPISODE_STEPS) -> tuple[dict[int, dict[str, float]], dict[int, str]]:
    """Success rate and mean return of each member's deterministic policy over `episodes` episodes
    from `start`.

    `agent` is a seed-batched agent (agents/seed_batch.py): `agent.act(obs, deterministic=True)` maps
    observations (K, rows, obs size) to actions (K, rows, action size), member k acting on obs[k], K = `agent.num_seeds`,
    numpy in and out whatever the agent's torch device (one transfer each way per step).
    `members` (default: all K) are evaluated, `envs.num_envs // episodes` of them at a time.

    Returns (scores, diverged): scores[k] = {"success": ..., "return": ...} for each member whose
    actions stayed finite; diverged[k] describes the non-finite action that stopped member k's episodes
    (the other members' episodes go on unchanged: members never mix).
    """
    members = list(range(agent.num_seeds)) if members is None else [int(k) for k in members]
    per_group = envs.num_envs // episodes
    if per_group < 1:
        raise ValueError(f"{episodes} episodes need {episodes} sub-envs, the vector env has {envs.num_envs}")
    scores: dict[int, dict[str, float]] = {}
    diverged: dict[int, str] = {}
    for first in range(0, len(members), per_group):
        group = members[first:first + per_group]
        group_scores, group_diverged = _evaluate_group(agent, envs, start, episodes, group, seed, horizon)
        scores.update(group_scores)
        diverged.update(group_diverged)
    return scores, diverged


def _evaluate_group(agent, envs: LavaBridgeVectorEnv, start: str, episodes: int, members: list[int],
                    seed: int, horizon: int) -> tuple[dict[int, dict[str, float]], dict[int, str]]:
    """`evaluate` for members that fit in `envs` together: sub-env g * episodes + i runs members[g]'s episode i."""
    total = len(members) * episodes
    owner = np.repeat(members, episodes)  # the member each sub-env's episode belongs to
    in_use = np.arange(envs.num_envs) < total
    seeds = [seed + j % episodes if j < total else None for j in range(envs.num_envs)]
    obs = envs.reset(seed=seeds, options={"start": start, "reset_mask": in_use})[0][:total]
    act_dim = envs.single_action_space.shape[0]
    running = np.ones(total, dtype=bool)
    returns = np.zeros(total)
    success = np.zeros(total, dtype=bool)
    diverged: dict[int, str] = {}
    for _ in range(horizon):
        active = np.flatnonzero(running)
        if active.size == 0:
            break
        actions = _act(agent, obs[active], owner[active], act_dim)
        finite = np.isfinite(actions).all(axis=1)
        if not finite.all():
            for k in np.unique(owner[active][~finite]):
                first_row = actions[owner[active] == k][0]
                diverged[int(k)] = f"its evaluation policy's actions are not finite ({first_row})"
                running[owner == k] = False
            keep = running[active]
            active, actions = active[keep], actions[keep]
        rewards, ended, reached = envs.step_episodes(active, actions)
        for j, reward, end, hit in zip(active.tolist(), rewards, ended, reached):
            returns[j] += reward
            if end:
                running[j] = False
                success[j] = hit
        obs[active] = envs.episode_observations(active)
    scores = {}
    for g, k in enumerate(members):
        if k in diverged:
            continue
        episodes_of_k = slice(g * episodes, (g + 1) * episodes)
        rate = float(success[episodes_of_k].mean()) if envs.reports_success else float("nan")
        scores[k] = {"success": rate, "return": float(returns[episodes_of_k].mean())}
    return scores, diverged


def _act(agent, obs: np.ndarray, owners: np.ndarray, act_dim: int = 2) -> np.ndarray:
    """The deterministic actions (n, act_dim) for observations `obs` (n, obs size), row r acted on by member owners[r]
    (owners sorted, as the sub-envs are): one `agent.act` call for the members with at least
    OWN_CALL_ROWS rows, one per row count below it."""
    members, first, counts = np.unique(owners, return_index=True, return_counts=True)
    position = np.arange(len(owners)) - np.repeat(first, counts)  # each row's place in its member's rows
    calls = [(counts >= OWN_CALL_ROWS, None)] + [(counts == c, c) for c in np.unique(counts[counts < OWN_CALL_ROWS])]
    actions = np.empty((len(owners), act_dim), dtype=np.float32)
    for chosen, rows in calls:
        if not chosen.any():
            continue
        selected = np.isin(owners, members[chosen])
        batch = np.zeros((agent.num_seeds, rows or counts[chosen].max(), obs.shape[1]))
        batch[owners[selected], position[selected]] = obs[selected]
        actions[selected] = agent.act(batch, deterministic=True)[owners[selected], position[selected]]
    return actions
