"""LavaBridgeVectorEnv: K LavaBridge-v0 episodes on one compiled MuJoCo model, one MjData each.

`gymnasium.make_vec("LavaBridge-v0", num_envs=K)` returns it (the spec's `vector_entry_point`).
It behaves exactly like `gymnasium.vector.SyncVectorEnv` over K `gymnasium.make("LavaBridge-v0")`
envs (tests/test_vector_env.py checks step by step): sub-env i is seeded with `seed + i`, episodes
truncate at `max_episode_steps`, and the autoreset is gymnasium's default, next-step: the step after an
episode ends resets that sub-env (from p0) and returns its first observation with reward 0. With
`autoreset_mode=AutoresetMode.SAME_STEP` a sub-env is reset (from p0) in the step that ends its episode,
as SyncVectorEnv does in that mode: the step returns the new episode's first observation, and the
ended episode's last observation and info in `info["final_obs"]` and `info["final_info"]`. Pass the
mode as a keyword: `gymnasium.make_vec("LavaBridge-v0", num_envs=K, autoreset_mode=AutoresetMode.SAME_STEP)`
(gymnasium's `make_vec` gives `vector_kwargs` to its own vector envs only, and refuses them for every
env's `vector_entry_point`). It saves
what the generic wrapper pays for: K compiled models, K wrapper stacks, per-env info dictionaries.
Each sub-env's MjData is stepped, reset and observed by `task`, the same `LavaBridgeTask` that a
single env drives its one MjData with.

Reset options (all optional, one of "state" / "start"):
    {"state": array (K, 4)}      reset sub-env i to state[i]
    {"start": "p0" | "ood"}      sample every reset sub-env from a named start distribution
    {"reset_mask": bool (K,)}    reset only these sub-envs (the others keep going); with "state",
                                 rows of the others are ignored
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from lava_bridge_mj.checks import check_integer, check_real_array
from lava_bridge_mj.lava_bridge import MAX_EPISODE_STEPS, check_env_arguments
from lava_bridge_mj.starts import START_NAMES
from lava_bridge_mj.task_physics import LavaBridgeTask

VECTOR_RESET_KEYS = ("state", "start", "reset_mask")


def reset_mask(options: Any, num_envs: int) -> np.ndarray:
    """The sub-envs a vector reset with `options` resets (`reset_mask`, default all), after checking the
    options: a dict of VECTOR_RESET_KEYS, not both 'state' and 'start'. Shared by both vector envs."""
    if not isinstance(options, dict):
        raise ValueError(f"reset options must be a dict, got {type(options).__name__}")
    unknown = set(options) - set(VECTOR_RESET_KEYS)
    if unknown:
        raise ValueError(f"unknown reset options {sorted(unknown)}; expected some of {VECTOR_RESET_KEYS}")
    if "state" in options and "start" in options:
        raise ValueError("reset options 'state' and 'start' conflict: give one")
    if "reset_mask" not in options:
        return np.ones(num_envs, dtype=bool)
    mask = np.asarray(options["reset_mask"])
    if mask.shape != (num_envs,) or mask.dtype != bool:
        raise ValueError(f"reset_mask must be a bool array of shape ({num_envs},), got {options['reset_mask']!r}")
    return mask


def sub_env_seeds(seed: int | list[int | None] | None, num_envs: int) -> list[int | None]:
    """Each sub-env's reset seed: none, `seed + i` for one seed (as SyncVectorEnv seeds its sub-envs),
    or one per sub-env."""
    if seed is None:
        return [None] * num_envs
    if not isinstance(seed, (list, tuple)):
        seed = check_integer("seed", seed, 0)
        return [seed + i for i in range(num_envs)]
    if len(seed) != num_envs:
        raise ValueError(f"expected {num_envs} seeds, got {len(seed)}")
    return [None if s is None else check_integer("seed", s, 0) for s in seed]


class LavaBridgeVectorEnv(VectorEnv):
    """K LavaBridge-v0 envs stepped together; see the module docstring for the semantics.

    Args:
        num_envs: K.
        max_episode_steps: the time limit (500, the paper's horizon).
        autoreset_mode: `AutoresetMode.NEXT_STEP` (the default) or `AutoresetMode.SAME_STEP` (or their
            values, "NextStep" and "SameStep").
        **env_kwargs: LavaBridgeEnv's arguments (rewards, Layout fields), shared by every sub-env.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
    reports_success = True
    """Every step's info holds "is_success" (the goal reached), as ResetToStateVectorEnv's does where its env reports it."""
    start_names = START_NAMES
    """The named starts of reset(options={"start": ...})."""

    def __init__(self, num_envs: int = 1, max_episode_steps: int = MAX_EPISODE_STEPS,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, **env_kwargs: Any):
        self.num_envs = check_integer("num_envs", num_envs, 1)
        self.max_episode_steps = check_integer("max_episode_steps", max_episode_steps, 1)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        if "render_mode" in env_kwargs and env_kwargs["render_mode"] is not None:
            raise ValueError("LavaBridgeVectorEnv does not render; for frames use gymnasium.make_vec(..., "
                             "vectorization_mode='sync', render_mode='rgb_array') or a single LavaBridgeEnv")
        env_kwargs.pop("render_mode", None)
        # the model, rewards, state checks, dynamics and start distributions that every sub-env shares
        self.task: LavaBridgeTask = check_env_arguments(**env_kwargs).task
        self.datas = [mujoco.MjData(self.task.model) for _ in range(num_envs)]
        self.single_observation_space = self.task.observation_space
        self.single_action_space = self.task.action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.rngs = [seeding.np_random()[0] for _ in range(num_envs)]
        self.episode_steps = np.zeros(num_envs, dtype=np.int64)
        self.autoreset = np.zeros(num_envs, dtype=bool)  # sub-env ended last step: the next step resets it
        self.render_mode = None

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None):
        mask, starts = self._parse_reset_options(options or {})  # raises before anything changes
        seeds = sub_env_seeds(seed, self.num_envs)
        for i in np.flatnonzero(mask):
            if seeds[i] is not None:
                self.rngs[i] = seeding.np_random(seeds[i])[0]
            self._reset_one(i, starts[i])
        self.autoreset[mask] = False
        return self._observations(), self._info(np.zeros(self.num_envs, bool), np.zeros(self.num_envs, bool))

    def step(self, actions):
        # checked as a whole before any sub-env moves, so a bad row leaves every sub-env where it was
        actions = check_real_array("actions", actions, (self.num_envs, 2))
        task = self.task
        rewards = np.zeros(self.num_envs)
        lava = np.zeros(self.num_envs, dtype=bool)
        success = np.zeros(self.num_envs, dtype=bool)
        for i, data in enumerate(self.datas):
            if self.autoreset[i]:
                self._reset_one(i, "p0")
                continue
            rewards[i], lava[i], success[i] = task.step(data, actions[i])
            self.episode_steps[i] += 1
        terminated = lava | success
        truncated = ~terminated & ~self.autoreset & (self.episode_steps >= self.max_episode_steps)
        ended = terminated | truncated
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self.autoreset = ended
            return self._observations(), rewards, terminated, truncated, self._info(success, lava)
        # same step: the ended episodes' last observations and infos go to final_obs / final_info, as
        # SyncVectorEnv puts them (object array and presence masks), and their sub-envs start again
        info = {}
        if ended.any():
            last = self._observations()
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(ended):
                final_obs[i] = last[i]
                self._reset_one(i, "p0")
            final_info = {"is_success": success & ended, "_is_success": ended.copy(), "lava": lava & ended,
                          "_lava": ended.copy()}
            info = {"final_obs": final_obs, "_final_obs": ended.copy(), "final_info": final_info,
                    "_final_info": ended.copy()}
            success, lava = success & ~ended, lava & ~ended  # a new episode's info, as its reset gives
        return self._observations(), rewards, terminated, truncated, {**info, **self._info(success, lava)}

    # --- pieces ---------------------------------------------------------------------------------
    def _reset_one(self, i: int, start: str | tuple[np.ndarray, np.ndarray]) -> None:
        if isinstance(start, str):
            start = self.task.sample_start(start, self.rngs[i])
        self.task.set_state(self.datas[i], *start)
        self.episode_steps[i] = 0

    def _parse_reset_options(self, options: dict[str, Any]) -> tuple[np.ndarray, list]:
        """(which sub-envs reset, each one's start: a distribution name or a checked (qpos, qvel))."""
        mask = reset_mask(options, self.num_envs)
        if "state" in options:
            # finiteness is checked per reset row below: rows of the other sub-envs are ignored
            states = check_real_array("reset option 'state'", options["state"], (self.num_envs, 4), finite=False)
            starts = [self.task.check_state(s[:2], s[2:]) if m else None for s, m in zip(states, mask)]
        else:
            starts = [self.task.check_start_name(options.get("start", "p0"))] * self.num_envs
        return mask, starts

    def _observations(self) -> np.ndarray:
        return self.task.observations(self.datas)

    def _info(self, success: np.ndarray, lava: np.ndarray) -> dict[str, np.ndarray]:
        every = np.ones(self.num_envs, dtype=bool)  # gymnasium's vector info: a value and a presence mask
        return {"is_success": success, "_is_success": every, "lava": lava, "_lava": every.copy()}

    def step_episodes(self, indices: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Step the sub-envs `indices` with `actions` (no time limit, no autoreset: the caller keeps
        count, as evaluation does); (rewards, terminated, success), one per index."""
        rewards = np.zeros(len(indices))
        terminated = np.zeros(len(indices), dtype=bool)
        success = np.zeros(len(indices), dtype=bool)
        for n, (j, action) in enumerate(zip(indices, actions)):
            rewards[n], lava, success[n] = self.task.step(self.datas[j], action)
            terminated[n] = lava or success[n]
        return rewards, terminated, success

    def episode_observations(self, indices: np.ndarray) -> np.ndarray:
        """The observations of the sub-envs `indices`."""
        return self.task.observations([self.datas[j] for j in indices])

    def get_state(self) -> np.ndarray:
        """The physics states (K, 4): identical to the observations."""
        return self._observations()


def check_autoreset_mode(mode: Any) -> AutoresetMode:
    """`mode` as an AutoresetMode the vector env runs (next step or same step); ValueError naming it otherwise."""
    supported = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
    try:
        checked = AutoresetMode(mode)
    except ValueError:
        checked = None
    if checked not in supported:
        raise ValueError(f"autoreset_mode must be one of {[m.value for m in supported]} (gymnasium.vector."
                         f"AutoresetMode), got {mode!r}")
    return checked
