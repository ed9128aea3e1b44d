"""Start each episode from a start strategy's choice and report back how it went.

`StartSelector` is the bookkeeping for one env: it draws the start index with its own generator,
counts the episode's steps and reports the finished episode to the strategy exactly once.
`StartStateWrapper` puts it around any gymnasium env; the batched trainer (eval/training/runner.py) keeps
one selector per sub-env of a `LavaBridgeVectorEnv`. Both give the same starts and reports.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium
import numpy as np

from lava_bridge_mj.agents.start_strategies import NO_STATE, StartStrategy


def _start_rng(seed: int | None) -> np.random.Generator:
    # A child of the seed's SeedSequence: gymnasium seeds the env's np_random from the same seed,
    # and the child stream is independent of it rather than a copy.
    return np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])


def check_horizon(strategy: StartStrategy, max_episode_steps: int | None) -> None:
    """ValueError unless `strategy.horizon` is None, `max_episode_steps` is None, or the two agree."""
    if strategy.horizon is not None and max_episode_steps is not None and strategy.horizon != max_episode_steps:
        raise ValueError(f"{type(strategy).__name__} horizon={strategy.horizon} differs from the env's "
                         f"max_episode_steps={max_episode_steps}; build it with horizon={max_episode_steps}")


class StartSelector:
    """One env's start choices from `strategy`, and the reports of the episodes they started.

    `choose()` draws an index with the selector's generator and returns the state to reset to, or
    None for the env's own reset (the strategy returned `NO_STATE`, p0). `step(ended, success)` counts
    one env step; when the episode ends, the strategy gets `update(index, length, success=...)`,
    once. `external_start()` marks an episode the strategy did not choose: it is not reported.

    `max_episode_steps` is the env's step limit where it has one: a strategy whose `horizon`
    differs from it is refused with a ValueError naming both, since it would score every episode
    length on the wrong scale. `time_limit` is the running episode's own step limit from
    `strategy.time_limit(start_index)`, capped by `max_episode_steps` (None: the env's limit alone);
    `reaches_time_limit()` says whether the step being taken is the last it allows.
    """

    def __init__(self, strategy: StartStrategy, seed: int | None = None, *,
                 max_episode_steps: int | None = None):
        check_horizon(strategy, max_episode_steps)
        self.strategy = strategy
        self.max_episode_steps = max_episode_steps
        self.time_limit: int | None = None
        self._rng = _start_rng(seed)
        self.start_index = NO_STATE
        self.episode_length = 0
        self._report_pending = False  # an episode the strategy chose is running and not yet reported

    def reseed(self, seed: int) -> None:
        self._rng = _start_rng(seed)

    def choose(self) -> np.ndarray | None:
        """Start a new episode: the candidate state to reset to, or None for the env's own start."""
        self.episode_length = 0
        self.start_index, self._report_pending = self.strategy.sample(self._rng), True
        self._set_time_limit()
        return None if self.start_index == NO_STATE else self.strategy.states[self.start_index].copy()

    def external_start(self) -> None:
        """Start a new episode whose start the strategy did not choose."""
        self.episode_length = 0
        self.start_index, self._report_pending = NO_STATE, False
        self.time_limit = None

    def _set_time_limit(self) -> None:
        limit = None if self.start_index == NO_STATE else self.strategy.time_limit(self.start_index)
        if limit is not None and self.max_episode_steps is not None:
            limit = min(limit, self.max_episode_steps)
        self.time_limit = limit

    def reaches_time_limit(self) -> bool:
        """Whether the step being taken (not yet counted by `step`) is the last `time_limit` allows."""
        return self.time_limit is not None and self.episode_length + 1 >= self.time_limit

    def step(self, ended: bool, success: bool) -> None:
        self.episode_length += 1
        if ended and self._report_pending:
            self._report_pending = False  # exactly once, even if stepped past the end
            self.strategy.update(self.start_index, self.episode_length, success=bool(success))

    def state_dict(self) -> dict[str, Any]:
        """The generator, the current episode and the strategy's learned state, for a resume."""
        return {"rng": self._rng.bit_generator.state, "strategy": self.strategy.state_dict(),
                "start_index": self.start_index, "episode_length": self.episode_length,
                "report_pending": self._report_pending}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self._rng.bit_generator.state = state["rng"]
        self.strategy.load_state_dict(state["strategy"])
        self.start_index, self.episode_length = state["start_index"], state["episode_length"]
        self._report_pending = state["report_pending"]
        if self._report_pending:
            self._set_time_limit()
        else:
            self.time_limit = None


class StartStateWrapper(gymnasium.Wrapper):
    """Reset the wrapped env to `strategy.states[strategy.sample(rng)]` and feed episode lengths back.

    Each `reset()` without options (None or empty) draws an index from `strategy` with the wrapper's
    own `np.random.Generator` and calls `env.reset(options={"state": states[index]})`, or the env's
    plain `reset()` when the strategy returns `NO_STATE` (p0). A reset with explicit options passes
    through untouched and its episode is not reported: the strategy did not choose its start.
    Each episode the strategy chose is reported once, when it terminates or is truncated, as
    `strategy.update(index, length, success=info["is_success"])`, `length` counting its steps.

    The reset info gains `start_index`: the index into `strategy.states`, or `NO_STATE` (-1) when
    the episode did not start from a candidate state.

    A strategy may give an episode a shorter step limit than the env's (`strategy.time_limit(index)`;
    RFCL's reverse curriculum does): the wrapper then returns `truncated=True` on the episode's
    `time_limit`-th step, unless the env terminated it on that step, and reports it as truncated.

    Args:
        env: any gymnasium env whose `reset` accepts `options={"state": s}`.
        strategy: a start strategy (`make_start_strategy`); its `states` are the candidates. Its
            `horizon`, where it has one, must equal the env's step limit (`env.spec.max_episode_steps`,
            set by `gymnasium.make`); ValueError otherwise.
        seed: seeds the wrapper's generator; `reset(seed=...)` reseeds it (and the env).
    """

    def __init__(self, env: gymnasium.Env, strategy: StartStrategy, seed: int | None = None):
        super().__init__(env)
        limit = env.spec.max_episode_steps if env.spec is not None else None
        self.selector = StartSelector(strategy, seed, max_episode_steps=limit)

    @property
    def strategy(self) -> StartStrategy:
        return self.selector.strategy

    @property
    def start_index(self) -> int:
        return self.selector.start_index

    @property
    def episode_length(self) -> int:
        return self.selector.episode_length

    @property
    def time_limit(self) -> int | None:
        """The running episode's step limit set by the strategy (capped by the env's), or None."""
        return self.selector.time_limit

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None:
            self.selector.reseed(seed)
        if options:
            self.selector.external_start()
            obs, info = self.env.reset(seed=seed, options=options)
        else:
            state = self.selector.choose()
            obs, info = self.env.reset(seed=seed, options=None if state is None else {"state": state})
        info["start_index"] = self.selector.start_index
        return obs, info

    def state_dict(self) -> dict[str, Any]:
        return self.selector.state_dict()

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.selector.load_state_dict(state)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        truncated = truncated or (not terminated and self.selector.reaches_time_limit())
        self.selector.step(terminated or truncated, info.get("is_success", False))
        return obs, reward, terminated, truncated, info
