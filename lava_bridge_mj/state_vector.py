"""ResetToStateVectorEnv: K copies of any MuJoCo Gymnasium env, stepped as `LavaBridgeVectorEnv` steps
Lava Bridge, so that the trainer (eval/training/runner.py) and its evaluation run every method on any such env.

Each sub-env is `ResetToState(gymnasium.make(env_id, **env_kwargs))` (an external task's:
`lava_bridge_mj.external.make_task_env(env_id)`, with its "p0" and "ood") without gymnasium's TimeLimit: the
vector env counts each episode's steps itself and truncates at `max_episode_steps` (the spec's), so a
checkpoint can restore how far an episode had gone. What the learners see is the same for every env:

- observations flattened to float64 vectors in `gymnasium.spaces.flatten` order (a Dict observation's
  keys sorted, as gymnasium's `Dict` space keeps them; each Box flattened in C order);
- actions in [-1, 1] per coordinate (the learners' tanh range), rescaled linearly to the env's Box
  bounds before the env takes them;
- success: `info["success"]` or `info["is_success"]` of the sub-env's step; an env that reports
  neither has `reports_success` False, and the trainer records its success rates as NaN, never 0.

Reset options (all optional, one of "state" / "start"), as LavaBridgeVectorEnv's:
    {"state": array (K, state size)}  reset sub-env i to the full state state[i] (ResetToState's)
    {"start": "p0" | NAME}            "p0": the env's own reset; another name, a start the env declares
                                      in its attribute `start_names` (on the env or a wrapper), passed to
                                      it as `reset(options={"start": NAME})`
    {"reset_mask": bool (K,)}         reset only these sub-envs; with "state", rows of the others are ignored
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from lava_bridge_mj.checks import check_integer, check_real_array
from lava_bridge_mj.reset_to_state import ResetToState
from lava_bridge_mj.vector import reset_mask, sub_env_seeds

def env_spec(env_id: str) -> gymnasium.envs.registration.EnvSpec:
    """The registered spec of `env_id`; "module:Id" imports the module first (it registers Id), as
    `gymnasium.make` does. ValueError naming an id gymnasium does not know."""
    from lava_bridge_mj.external import EXTERNAL_TASKS

    if env_id in EXTERNAL_TASKS:
        return EXTERNAL_TASKS[env_id].spec()
    module, _, name = env_id.rpartition(":")
    try:
        if module:
            importlib.import_module(module)
        return gymnasium.spec(name)
    except (ImportError, gymnasium.error.Error) as error:
        raise ValueError(f"unknown env_id {env_id!r}: {error}") from None


def make_state_env(env_id: str, time_limit: bool = True, **env_kwargs: Any) -> gymnasium.Env:
    """`ResetToState(gymnasium.make(env_id, **env_kwargs))`; without gymnasium's TimeLimit when not
    `time_limit`. ValueError naming `env_id` for an id gymnasium does not know or an env ResetToState
    cannot serve. An external task (`lava_bridge_mj.external.EXTERNAL_TASKS`) is its `make_task_env`:
    the task's arguments, its named starts and its `task_states`."""
    from lava_bridge_mj.external import EXTERNAL_TASKS, make_task_env, remove_maze_xml

    if env_id in EXTERNAL_TASKS:
        return make_task_env(env_id, time_limit=time_limit, **env_kwargs)
    spec = env_spec(env_id)
    if not time_limit:
        spec = dataclasses.replace(spec, max_episode_steps=None)
    env = remove_maze_xml(gymnasium.make(spec, disable_env_checker=True, **env_kwargs))
    try:
        return ResetToState(env)
    except ValueError as error:
        env.close()
        raise ValueError(f"{env_id}: {error}") from None


def declared_start_names(env: gymnasium.Env) -> tuple[str, ...]:
    """The named starts `env` offers: "p0" (its own reset) and those it declares in `start_names`."""
    try:
        declared = tuple(env.get_wrapper_attr("start_names"))
    except AttributeError:
        declared = ()
    return ("p0", *(name for name in declared if name != "p0"))


class ResetToStateVectorEnv(VectorEnv):
    """K `ResetToState`-wrapped copies of the gymnasium env `env_id`; see the module docstring.

    Args:
        env_id: a gymnasium id whose env `ResetToState` serves (Hopper-v5,
            gymnasium_robotics:PointMaze_UMaze-v3, ...): "module:Id" imports the module first.
        num_envs: K.
        max_episode_steps: the time limit; default the spec's (ValueError when it has none).
        **env_kwargs: `gymnasium.make`'s keyword arguments for every sub-env.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, env_id: str, num_envs: int = 1, max_episode_steps: int | None = None, **env_kwargs: Any):
        self.num_envs = check_integer("num_envs", num_envs, 1)
        self.envs = [make_state_env(env_id, time_limit=False, **env_kwargs) for _ in range(num_envs)]
        limit = env_spec(env_id).max_episode_steps if max_episode_steps is None else max_episode_steps
        if limit is None:
            raise ValueError(f"{env_id} registers no max_episode_steps; give max_episode_steps")
        self.max_episode_steps = check_integer("max_episode_steps", limit, 1)
        env = self.envs[0]
        if not isinstance(env.action_space, spaces.Box) or len(env.action_space.shape) != 1 or not (
                np.isfinite(env.action_space.low).all() and np.isfinite(env.action_space.high).all()):
            raise ValueError(f"{env_id}'s action space must be a bounded 1-D Box, got {env.action_space}")
        self.env_observation_space = env.observation_space
        self.low = env.action_space.low.astype(np.float64)
        self.high = env.action_space.high.astype(np.float64)
        flat = spaces.flatten_space(env.observation_space)
        self.single_observation_space = spaces.Box(flat.low.astype(np.float64), flat.high.astype(np.float64),
                                                   dtype=np.float64)
        self.single_action_space = spaces.Box(-1.0, 1.0, env.action_space.shape, dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.start_names = declared_start_names(env)
        self.state_size = env.state_size
        self.reports_success = False  # set by the first step or reset whose info reports success
        self.episode_steps = np.zeros(num_envs, dtype=np.int64)
        self.autoreset = np.zeros(num_envs, dtype=bool)
        self.observations = np.zeros((num_envs, self.single_observation_space.shape[0]))
        self.render_mode = None

    @property
    def rngs(self) -> list[np.random.Generator]:
        """Each sub-env's own random generator (what its resets draw from)."""
        return [env.unwrapped.np_random for env in self.envs]

    def env_action(self, action: np.ndarray) -> np.ndarray:
        """An action in [-1, 1] rescaled to the env's Box bounds, in the env's dtype."""
        scaled = self.low + (np.asarray(action, dtype=np.float64) + 1.0) * 0.5 * (self.high - self.low)
        return scaled.astype(self.envs[0].action_space.dtype)

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None):
        mask, starts = self._parse_reset_options(options or {})  # raises before anything changes
        seeds = sub_env_seeds(seed, self.num_envs)
        for i in np.flatnonzero(mask):
            self._reset_one(i, starts[i], seeds[i])
        self.autoreset[mask] = False
        return self.observations.copy(), {}

    def step(self, actions):
        actions = check_real_array("actions", actions, (self.num_envs, *self.single_action_space.shape))
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        success = np.zeros(self.num_envs, dtype=bool)
        for i in range(self.num_envs):
            if self.autoreset[i]:
                self._reset_one(i, "p0", None)
                continue
            rewards[i], terminated[i], success[i] = self._step_one(i, actions[i])
        truncated = ~terminated & ~self.autoreset & (self.episode_steps >= self.max_episode_steps)
        self.autoreset = terminated | truncated
        every = np.ones(self.num_envs, dtype=bool)
        return self.observations.copy(), rewards, terminated, truncated, {"is_success": success, "_is_success": every}

    def step_episodes(self, indices: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Step the sub-envs `indices` with `actions` (no time limit, no autoreset: the caller keeps
        count, as evaluation does); (rewards, terminated, success), one per index."""
        results = np.array([self._step_one(j, action) for j, action in zip(indices, actions)], dtype=np.float64)
        results = results.reshape(len(indices), 3)
        return results[:, 0], results[:, 1].astype(bool), results[:, 2].astype(bool)

    def episode_observations(self, indices: np.ndarray) -> np.ndarray:
        """The flat observations of the sub-envs `indices`."""
        return self.observations[indices]

    def get_state(self) -> np.ndarray:
        """The full states (K, state size), ResetToState's."""
        return np.stack([env.get_state() for env in self.envs])

    def close_extras(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close()

    # --- pieces ---------------------------------------------------------------------------------
    def _step_one(self, i: int, action: np.ndarray) -> tuple[float, bool, bool]:
        obs, reward, terminated, _, info = self.envs[i].step(self.env_action(action))
        self.observations[i] = spaces.flatten(self.env_observation_space, obs)
        self.episode_steps[i] += 1
        return float(reward), bool(terminated), self._success(info)

    def _success(self, info: dict) -> bool:
        value = info.get("success", info.get("is_success"))
        self.reports_success |= value is not None
        return bool(value) if value is not None else False

    def _reset_one(self, i: int, start: str | np.ndarray, seed: int | None) -> None:
        if isinstance(start, np.ndarray):
            options = {"state": start}
        else:
            options = None if start == "p0" else {"start": start}
        obs, info = self.envs[i].reset(seed=seed, options=options)
        self._success(info)
        self.observations[i] = spaces.flatten(self.env_observation_space, obs)
        self.episode_steps[i] = 0

    def _parse_reset_options(self, options: dict[str, Any]) -> tuple[np.ndarray, list]:
        """(which sub-envs reset, each one's start: a start name or a checked full state)."""
        mask = reset_mask(options, self.num_envs)
        if "state" in options:
            states = check_real_array("reset option 'state'", options["state"], (self.num_envs, self.state_size),
                                      finite=False)
            return mask, [self.envs[i].check_state(s) if m else None for i, (s, m) in enumerate(zip(states, mask))]
        start = options.get("start", "p0")
        if start not in self.start_names:
            raise ValueError(f"unknown start {start!r}; this env offers {list(self.start_names)} (an env declares "
                             f"more in its attribute start_names)")
        return mask, [start] * self.num_envs
