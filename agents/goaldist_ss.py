"""GoalDist-SS, a dynamic start strategy: sample demo states near the goal first, then ever more evenly.

State i is drawn with probability proportional to exp(-d_i / T), d_i its distance to the goal: from a
goal position, or by a function of the states that the task supplies (`TaskStates.goal_distance`).
The temperature T grows geometrically, so the distribution moves from the states next to the goal
towards uniform over all of them: per finished episode up to a cap (schedule "episodes"), or over
the run's training steps from the initial temperature to the cap at the end of the budget (schedule
"budget", the paper's "gradually over the course of training").
"""

from __future__ import annotations

import math
from typing import Any, Callable, Sequence

import numpy as np

from .checks import check_integer, check_number, check_real_array
from .start_strategies import StartStrategy, StrategyContext


SCHEDULES = ("episodes", "budget")
"""How GoalDist-SS's temperature rises: per finished episode, or over the run's training budget."""


class GoalDistSS(StartStrategy):
    """GoalDist-SS (dynamic): weights `exp(-d(s, goal) / T)`, with the temperature T rising per episode.

    d is the distance of a state to the goal: the Euclidean distance from its first `len(goal)`
    coordinates to `goal` (LavaBridge's (x, y)), or `goal_distance(states)`. Early, near-goal states
    dominate; as T grows the distribution flattens towards uniform. The schedule is geometric,
    `T = min(temperature * temperature_growth ** episodes, max_temperature)` (schedule "episodes"), or
    `T = temperature * (max_temperature / temperature) ** min(steps / budget, 1)` with `steps` the
    training steps of the episodes finished so far (schedule "budget"): how peaked the weights are
    depends on d / T, so equal multiplicative steps flatten it at an even pace. `weights` are
    shifted so the state nearest the goal has weight 1 (`exp(-(d - d.min()) / T)`), which changes no
    probability but keeps a small T from underflowing every weight to zero.

    Args:
        states: (n, d) candidate start states, of any length d.
        goal: the goal position, compared with each state's first `len(goal)` coordinates;
            LavaBridge-v0's is `env.unwrapped.layout.goal`. Give it or `goal_distance`; a run takes
            the one its task declares (`TaskStates.goal` or `TaskStates.goal_distance`).
        temperature: T before the first episode (in units of d), > 0. Default 0.5: a state 2 m further
            from the goal is e^4 ~ 55x less likely.
        temperature_growth: factor per finished episode, >= 1 (1 keeps T fixed). Default 1.005: T
            grows 100x, from 0.5 m to 50 m, in about 920 episodes, well inside a 300k-step run; chosen
            on tuning seeds (docs/calibration.md, section 5).
        max_temperature: the cap on T, >= temperature; T stays there once reached. Default 50:
            across LavaBridge-v0's ~10 m from the start room's far wall to the goal, weights then
            differ by at most e^0.2 ~ 1.2x.
        schedule: "episodes" (T grows by `temperature_growth` per finished episode) or "budget" (T
            reaches `max_temperature` at `budget` training steps; `temperature_growth` is unused).
            With "budget" on LavaBridge-v0, weights come within 1.5x of uniform (T = 25 m) after 85%
            of the budget; with "episodes" and the defaults, after about 800 episodes.
        budget: the training steps of schedule "budget" (a run supplies its `steps`), >= 1; None
            with schedule "episodes".
        goal_distance: for a task whose goal is no point in the leading coordinates: a function from
            the (n, d) states to their n finite distances to the goal (smaller is nearer), called once.
            A function, not a setting: the run's recorded settings leave it out.
    """

    name = "goaldist_ss"
    description = "goal-distance weighted, flattening over time"
    unrecorded = ("goal_distance",)

    def __init__(self, states: Any, goal: Sequence[float] | None = None, temperature: float = 0.5,
                 temperature_growth: float = 1.005, max_temperature: float = 50.0, schedule: str = "episodes",
                 budget: int | None = None, goal_distance: Callable[[np.ndarray], Any] | None = None):
        super().__init__(states)
        if (goal is None) == (goal_distance is None):
            raise ValueError("GoalDist-SS needs the distance to the goal: exactly one of goal= (a goal position) "
                             "or goal_distance= (a function from the states to their distances), "
                             f"got {'both' if goal is not None else 'neither'}")
        self.goal = None if goal is None else self._check_goal(goal)
        self.initial_temperature = check_number("temperature", temperature)
        self.temperature_growth = check_number("temperature_growth", temperature_growth, 1, low_inclusive=True)
        self.max_temperature = check_number("max_temperature", max_temperature)
        if self.max_temperature < self.initial_temperature:
            raise ValueError(f"max_temperature={max_temperature!r} must be >= temperature={temperature!r}")
        if schedule not in SCHEDULES:
            raise ValueError(f"schedule must be one of {SCHEDULES}, got {schedule!r}")
        if (schedule == "budget") != (budget is not None):
            raise ValueError(f"budget= goes with schedule='budget' (the training steps over which T rises), "
                             f"got schedule={schedule!r} and budget={budget!r}")
        self.schedule = schedule
        self.budget = None if budget is None else check_integer("budget", budget, 1)
        if goal_distance is None:
            distance = np.linalg.norm(self._states[:, :len(self.goal)] - self.goal, axis=1)
        else:
            distance = self._call_goal_distance(goal_distance)
        self._excess_distance = distance - distance.min()
        self.episodes = 0
        self.steps = 0  # training steps of the finished episodes
        self._refresh_weights()

    def _check_goal(self, goal: Any) -> np.ndarray:
        dim = self._states.shape[1]
        sequence = isinstance(goal, (list, tuple)) or (isinstance(goal, np.ndarray) and goal.ndim >= 1)
        size = len(goal) if sequence else 0
        if not 1 <= size <= dim:
            raise ValueError(f"goal must be a position of 1 to {dim} numbers (compared with the states' first "
                             f"coordinates), got {goal!r}")
        return check_real_array("goal", goal, (size,)).astype(np.float64)

    def _call_goal_distance(self, goal_distance: Callable[[np.ndarray], Any]) -> np.ndarray:
        if not callable(goal_distance):
            raise ValueError(f"goal_distance must be a function from states (n, d) to n distances, "
                             f"got {goal_distance!r}")
        distance = np.asarray(goal_distance(self.states), dtype=np.float64)  # a read-only view: it cannot edit them
        if distance.shape != (len(self._states),) or not np.isfinite(distance).all():
            raise ValueError(f"goal_distance must return one finite distance per state, shape "
                             f"({len(self._states)},), got {distance if distance.size <= 8 else distance.shape}")
        return distance

    @classmethod
    def fill_params(cls, params: dict[str, Any], states: Any, context: StrategyContext) -> dict[str, Any]:
        """The task's goal (`TaskStates.goal` or `goal_distance`) unless given, and the run's training
        steps as the budget of schedule "budget"; ValueError naming what a task without a goal lacks."""
        params = dict(params)
        task = context.task
        if "goal" not in params and "goal_distance" not in params and task is not None:
            if task.goal is None and task.goal_distance is None:
                raise ValueError("start strategy 'goaldist_ss' weighs states by their distance to the task's goal, "
                                 "and the task declares none: give its TaskStates a goal_distance (a function from "
                                 "the states to their distances) or a goal (a position in the states' first "
                                 "coordinates), or pass goal= or goal_distance=")
            if task.goal is not None:
                params["goal"] = task.goal
            else:
                params["goal_distance"] = task.goal_distance
        if params.get("schedule") == "budget" and context.budget is not None:
            params.setdefault("budget", context.budget)
        return params

    @classmethod
    def budget_tied(cls, params: dict[str, Any]) -> bool:
        """Schedule "budget" without a `budget` of its own spreads T over the run's training steps."""
        return params.get("schedule") == "budget" and "budget" not in params

    @property
    def temperature(self) -> float:
        """The current T."""
        if self.schedule == "budget":
            progress = min(self.steps / self.budget, 1.0)
            return self.initial_temperature * (self.max_temperature / self.initial_temperature) ** progress
        # in log space, so many episodes cannot overflow growth ** episodes
        log_t = math.log(self.initial_temperature) + self.episodes * math.log(self.temperature_growth)
        return min(math.exp(min(log_t, 700.0)), self.max_temperature)

    def _refresh_weights(self) -> None:
        self._weights[:] = np.exp(-self._excess_distance / self.temperature)

    def update(self, index: int, episode_length: int, success: bool = False) -> None:
        """Count the episode and its steps; the temperature follows them."""
        self._check_episode(index, episode_length)
        self.episodes += 1
        self.steps += int(episode_length)
        self._refresh_weights()

    def _learned_state(self) -> dict[str, Any]:
        return {"episodes": self.episodes, "steps": self.steps}

    def _load_learned_state(self, state: dict[str, Any]) -> None:
        episodes = state["episodes"]
        if not (isinstance(episodes, (int, np.integer)) and episodes >= 0):
            raise ValueError(f"state_dict episodes must be an integer >= 0, got {episodes!r}")
        steps = state.get("steps", 0)  # a checkpoint from before the budget schedule: unused then
        if not (isinstance(steps, (int, np.integer)) and steps >= 0):
            raise ValueError(f"state_dict steps must be an integer >= 0, got {steps!r}")
        self.episodes, self.steps = int(episodes), int(steps)
        self._refresh_weights()
