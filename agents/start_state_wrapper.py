"""StartStateWrapper: start each episode from a start strategy's choice and report how it went."""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium
import numpy as np

from lava_bridge_mj.agents.start_strategies import NO_STATE, StartStrategy


def _start_rng(seed: int | None) -> np.random.Generator:
    # A child of the seed's SeedSequence: gymnasium seeds the env's np_random from the same seed,
    # and the child stream is independent of it rather than a copy.
    return np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])


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

    Args:
        env: any gymnasium env whose `reset` accepts `options={"state": s}`.
        strategy: a start strategy (`make_start_strategy`); its `states` are the candidates.
        seed: seeds the wrapper's generator; `reset(seed=...)` reseeds it (and the env).
    """

    def __init__(self, env: gymnasium.Env, strategy: StartStrategy, seed: int | None = None):
        super().__init__(env)
        self.strategy = strategy
        self._rng = _start_rng(seed)
        self.start_index = NO_STATE
        self.episode_length = 0
        self._report_pending = False  # an episode the strategy chose is running and not yet reported

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None:
            self._rng = _start_rng(seed)
        self.episode_length = 0
        if options:
            self.start_index, self._report_pending = NO_STATE, False
            obs, info = self.env.reset(seed=seed, options=options)
        else:
            self.start_index, self._report_pending = self.strategy.sample(self._rng), True
            if self.start_index == NO_STATE:
                obs, info = self.env.reset(seed=seed)
            else:
                state = self.strategy.states[self.start_index].copy()
                obs, info = self.env.reset(seed=seed, options={"state": state})
        info["start_index"] = self.start_index
        return obs, info

    def state_dict(self) -> dict[str, Any]:
        """The wrapper's generator, current episode and its strategy's learned state, for a resume."""
        return {"rng": self._rng.bit_generator.state, "strategy": self.strategy.state_dict(),
                "start_index": self.start_index, "episode_length": self.episode_length,
                "report_pending": self._report_pending}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self._rng.bit_generator.state = state["rng"]
        self.strategy.load_state_dict(state["strategy"])
        self.start_index, self.episode_length = state["start_index"], state["episode_length"]
        self._report_pending = state["report_pending"]

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.episode_length += 1
        if (terminated or truncated) and self._report_pending:
            self._report_pending = False  # exactly once, even if stepped past the end
            self.strategy.update(self.start_index, self.episode_length,
                                 success=bool(info.get("is_success", False)))
        return obs, reward, terminated, truncated, info
