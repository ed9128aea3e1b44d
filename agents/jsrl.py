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

from dataclasses import dataclass
from typing import Any

from .checks import check_integer, check_number


@dataclass
class JSRLConfig:
    """JSRL's guide and curriculum."""

    guide: str = "iql"
    """The offline learner that becomes the guide: "iql" (the JSRL paper's choice) or "bc"; trained
    with the run's `iql` or `bc` hyperparameters on the run's demo set."""
    guide_steps: int = 20_000
    """Gradient steps of the guide on the demos, before the first online step."""
    initial_horizon: int = 170
    """h at stage 0: steps the guide acts at the start of each episode."""
    stages: int = 10
    """Number of shrinking steps from initial_horizon to 0."""
    window: int = 20
    """Training episodes at a stage whose success rate decides whether to advance."""
    threshold: float = 0.5
    """Success rate over the window that advances the curriculum."""

    def __post_init__(self) -> None:
        if self.guide not in ("iql", "bc"):
            raise ValueError(f"guide must be 'iql' or 'bc', got {self.guide!r}")
        self.guide_steps = check_integer("guide_steps", self.guide_steps, 0)
        self.initial_horizon = check_integer("initial_horizon", self.initial_horizon, 0)
        self.stages = check_integer("stages", self.stages, 1)
        self.window = check_integer("window", self.window, 1)
        self.threshold = check_number("threshold", self.threshold, 0, 1, low_inclusive=True)


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
