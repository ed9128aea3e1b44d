"""JSRL (Uchendu et al., 2023, "Jump-Start Reinforcement Learning"), curriculum variant.

A guide policy learned offline from the demos (BC or IQL) acts for the first h steps of every
training episode; then the SAC learner takes over. Every transition trains the learner, and
evaluation always runs the learner alone. The curriculum shrinks h in stages as the learner succeeds:

    h_i = round(initial_horizon * (1 - i / stages)),   i = 0, 1, ..., stages   (h_stages = 0)

and the run moves from stage i to i + 1 once the last `window` training episodes at stage i reached
the goal at a rate of at least `threshold`. The default initial horizon, 170 steps, is the median
length of the expert's demonstrations from p0 to the goal (7,500-transition set: 45 episodes,
median 170, mean 167): at stage 0 the guide alone would nearly finish the task.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .configs import JSRLConfig
from .seed_batch import stack_batches


class JSRLCurriculum:
    """One seed's position in the curriculum: the stage, and the successes seen at it."""

    def __init__(self, config: JSRLConfig):
        self.config = config
        self.stage = 0
        self.results: list[bool] = []  # successes of the training episodes at the current stage

    @property
    def horizon(self) -> int:
        """h: how many steps the guide acts at the start of an episode at the current stage."""
        c = self.config
        return round(c.initial_horizon * (1 - self.stage / c.stages))

    def record(self, success: bool) -> None:
        """Count a finished training episode; advance a stage when the last `window` episodes at this
        stage succeeded at a rate >= threshold."""
        c = self.config
        self.results.append(bool(success))
        recent = self.results[-c.window:]
        if self.stage < c.stages and len(recent) == c.window and sum(recent) >= c.threshold * c.window:
            self.stage += 1
            self.results = []

    def state_dict(self) -> dict[str, Any]:
        return {"stage": self.stage, "results": list(self.results)}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.stage, self.results = state["stage"], list(state["results"])


class JSRLGuide:
    """JSRL's guide for a batch of seeds: an offline learner (one per seed, stacked like the online
    learner) fitted to the demo transitions before the first online step, then acting for the first
    h steps of each training episode; each seed follows its own curriculum."""

    def __init__(self, config: JSRLConfig, learner: Any, seeds: Sequence[int]):
        self.config, self.learner, self.seeds = config, learner, tuple(seeds)
        self.curricula = [JSRLCurriculum(config) for _ in self.seeds]
        self.trained = False

    def fit(self, demos: Any, batch_size: int) -> None:
        """`guide_steps` updates on minibatches of the demo transitions, each seed with its own stream."""
        rngs = [np.random.default_rng([seed, 17]) for seed in self.seeds]
        for _ in range(self.config.guide_steps):
            self.learner.update(stack_batches([demos.sample(batch_size, rng) for rng in rngs]))
        self.trained = True

    def act(self, obs: np.ndarray, episode_lengths: Sequence[int], actions: Any) -> Any:
        """`actions` (one per seed) with the guide's deterministic action in place of the learner's
        for every seed whose episode is shorter than its curriculum's horizon."""
        guided = [length < curriculum.horizon for length, curriculum in zip(episode_lengths, self.curricula)]
        if not any(guided):
            return actions
        guide_actions = self.learner.act(obs, deterministic=True)
        return [g if use else a for use, g, a in zip(guided, guide_actions, actions)]

    def seed_state(self, i: int) -> dict[str, Any]:
        """Seed i's guide for its checkpoint: the learner's slice, whether it is fitted, the curriculum."""
        return {"guide": self.learner.seed_state(i), "guide_trained": self.trained,
                "curriculum": self.curricula[i].state_dict()}

    def load_seed_states(self, states: Sequence[dict[str, Any]]) -> None:
        self.learner.load_seed_states([state["guide"] for state in states])
        self.trained = all(state["guide_trained"] for state in states)
        for curriculum, state in zip(self.curricula, states):
            curriculum.load_state_dict(state["curriculum"])
