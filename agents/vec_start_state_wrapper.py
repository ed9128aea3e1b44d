"""One start strategy for all sub-envs of a Stable-Baselines3 VecEnv.

`StartStateWrapper` inside each sub-env of an SB3 `SubprocVecEnv` would give every worker process its
own pickled copy of the strategy: each copy learns from its worker's episodes alone and the strategy
the user holds never changes. `VecStartStateWrapper` sits around the VecEnv instead, in the process
that trains: it chooses every sub-env's start from the one strategy and reports every finished
episode to it, through one `StartSelector` per sub-env (the same draws and reports as
`StartStateWrapper`).

SB3 resets a sub-env itself, inside `step`, when its episode ends, and that reset takes no options.
The wrapper therefore starts the first episodes through `VecEnv.set_options` and `reset()`, and each
later episode of sub-env i by resetting sub-env i again, to the chosen state, with
`env_method("reset", indices=[i], options={"state": s})`; the observation (and reset info) SB3
returns for it is replaced by that reset's. Where the strategy chose the env's own start (`NO_STATE`),
SB3's reset stands.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from lava_bridge_mj.agents.start_state_wrapper import StartSelector
from lava_bridge_mj.agents.start_strategies import StartStrategy


class VecStartStateWrapper(VecEnvWrapper):
    """Start every sub-env's episodes from one start strategy and feed every episode back to it.

    Sub-env i draws its starts with its own generator, seeded with `seed + i` (as SB3's
    `VecEnv.seed(seed)` seeds sub-env i's env with `seed + i`), so the sub-envs start from different
    states; all draw from, and report to, the same `strategy`. `seed()` reseeds both the envs and the
    generators that way (an SB3 algorithm given `seed=` calls it). After a step, the episodes that
    ended are reported first, in sub-env order, then the next starts are drawn, so each draw sees
    every episode finished so far.

    An episode is reported as `strategy.update(index, length, success=info["is_success"])`, `length`
    counting its steps, once, when it ends. A strategy's shorter step limit for an episode
    (`strategy.time_limit(index)`, RFCL's reverse curriculum) ends it as `StartStateWrapper` does: on
    its `time_limit`-th step, unless the env terminated it then, as a truncation (`done`, with
    `info["TimeLimit.truncated"]` and `info["terminal_observation"]`, as SB3 marks one), and the
    sub-env is reset. Options given with `set_options` pass through to the next `reset()` untouched,
    for the sub-envs they are given to; those episodes are not reported (the strategy did not choose
    their start). Each reset info gains `start_index`, the index into `strategy.states` or `NO_STATE`.

    Args:
        venv: an SB3 VecEnv (`DummyVecEnv`, `SubprocVecEnv`, e.g. from `make_vec_env`) whose envs'
            `reset` accepts `options={"state": s}`; the VecEnv itself, not a VecEnvWrapper such as
            `VecNormalize` (wrap those around this one), since the observations of the sub-envs it
            resets replace those SB3 returns. ValueError otherwise.
        strategy: a start strategy (`make_start_strategy`); its `horizon`, where it has one, must
            equal the envs' step limit (ValueError otherwise).
        seed: sub-env i's generator is seeded with `seed + i`; None: unseeded.
    """

    def __init__(self, venv: VecEnv, strategy: StartStrategy, seed: int | None = None):
        if isinstance(venv, VecEnvWrapper) or not isinstance(venv, VecEnv):
            raise ValueError(f"venv: expected an SB3 VecEnv (DummyVecEnv, SubprocVecEnv), got {type(venv).__name__}; "
                             "wrap VecEnvWrappers such as VecNormalize around VecStartStateWrapper")
        super().__init__(venv)
        spec = venv.get_attr("spec", indices=[0])[0]
        limit = spec.max_episode_steps if spec is not None else None
        self.selectors = [StartSelector(strategy, None if seed is None else seed + i, max_episode_steps=limit)
                          for i in range(self.num_envs)]
        self._given_options: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]

    @property
    def strategy(self) -> StartStrategy:
        return self.selectors[0].strategy

    @property
    def start_indices(self) -> np.ndarray:
        """Each sub-env's running episode's start: an index into `strategy.states`, or `NO_STATE`."""
        return np.array([selector.start_index for selector in self.selectors])

    def seed(self, seed: int | None = None) -> list[int | None]:
        seeds = list(self.venv.seed(seed))  # seed + i for sub-env i (a random seed where seed is None)
        for selector, sub_env_seed in zip(self.selectors, seeds):
            selector.reseed(sub_env_seed)
        return seeds

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        if options is None:
            options = {}
        self._given_options = [dict(o) for o in (options if isinstance(options, list) else [options] * self.num_envs)]

    def reset(self):
        options = []
        for selector, given in zip(self.selectors, self._given_options):
            if given:
                selector.external_start()
                options.append(given)
            else:
                state = selector.choose()
                options.append({} if state is None else {"state": state})
        self._given_options = [{} for _ in range(self.num_envs)]
        self.venv.set_options(options)
        obs = self.venv.reset()
        for i, info in enumerate(self.venv.reset_infos):
            info["start_index"] = self.selectors[i].start_index
        return obs

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        cut = []  # sub-envs whose episode the strategy's own step limit ends: SB3 did not reset them
        for i, selector in enumerate(self.selectors):
            if not dones[i] and selector.reaches_time_limit():
                dones[i] = True
                cut.append(i)
                infos[i]["TimeLimit.truncated"] = True
                infos[i]["terminal_observation"] = _sub_env_obs(obs, i)
            selector.step(bool(dones[i]), infos[i].get("is_success", False))
        for i in np.flatnonzero(dones):
            state = self.selectors[i].choose()
            if state is not None or i in cut:
                options = {} if state is None else {"options": {"state": state}}
                sub_obs, reset_info = self.venv.env_method("reset", indices=[i], **options)[0]
                _set_sub_env_obs(obs, i, sub_obs)
                self.venv.reset_infos[i].clear()  # SubprocVecEnv holds them in a tuple: updated in place
                self.venv.reset_infos[i].update(reset_info)
            self.venv.reset_infos[i]["start_index"] = self.selectors[i].start_index
        return obs, rewards, dones, infos


def _sub_env_obs(obs, i: int):
    if isinstance(obs, dict):
        return {key: value[i].copy() for key, value in obs.items()}
    if isinstance(obs, tuple):
        return tuple(value[i].copy() for value in obs)
    return obs[i].copy()


def _set_sub_env_obs(obs, i: int, sub_obs) -> None:
    # SB3 stores sub-env observations as rows of one array per observation (key): the same layout here
    if isinstance(obs, dict):
        for key in obs:
            obs[key][i] = sub_obs[key]
    elif isinstance(obs, tuple):
        for value, sub_value in zip(obs, sub_obs):
            value[i] = sub_value
    else:
        obs[i] = sub_obs

