"""What a task tells the start strategies about its states: `TaskStates`.

The strategies (agents/) take states of any length; what a state's coordinates mean is the task's to
say: which coordinates are a position, where the goal is or how far a state is from it, and on what
scale AuxSS's kernel compares coordinates. A task declares that in a `TaskStates`, attached to its
env as the attribute `task_states` (on the env or on any wrapper around it), or given to a run
directly (`StrategyContext(task=...)`, agents/start_strategies.py):

    TaskStates(goal_distance=lambda states: np.abs(states[:, 1] - 10.0))  # a foreign env's declaration
    lava_bridge_mj.LavaBridgeEnv().task_states  # LavaBridge's: position (x, y), its goal, raw kernel scale

`task_states_of(env)` reads an env's declaration; an env that declares none gets `TaskStates()`,
whose defaults suit a generic state.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from lava_bridge_mj.checks import check_real_array


def check_coordinates(name: str, value: Any, dim: int | None = None) -> tuple[int, ...]:
    """`value` as a tuple of distinct coordinate indices (integers >= 0, and < `dim` when given), at
    least one; ValueError naming `name` otherwise."""
    items = tuple(value) if isinstance(value, (list, tuple, np.ndarray)) else None
    valid = (items is not None and len(items) > 0 and len(set(items)) == len(items)
             and all(isinstance(i, numbers.Integral) and not isinstance(i, bool) and i >= 0
                     and (dim is None or i < dim) for i in items))
    if not valid:
        within = "" if dim is None else f" below the state's {dim} coordinates"
        raise ValueError(f"{name} must be a non-empty list of distinct coordinate indices >= 0{within}, got {value!r}")
    return tuple(int(i) for i in items)


def coordinate_spread(states: np.ndarray) -> np.ndarray:
    """Each coordinate's standard deviation over `states` (n, d), and 1 for a coordinate that is the
    same in every state (no spread to divide by): the generic scale of AuxSS's kernel."""
    spread = np.std(np.asarray(states, dtype=np.float64), axis=0)
    return np.where(spread > 0, spread, 1.0)


@dataclass(frozen=True)
class TaskStates:
    """What a task declares about its states for the start strategies; every field is optional.

    A strategy that needs a field the task leaves out says so, naming the field, when it is built.

    Attributes:
        position: the state coordinates (indices) of the agent's position. AuxSS's
            `kernel_dims="position"` measures distances on them. None: the task names no position.
        goal: the goal position, compared with the state's first `len(goal)` coordinates (LavaBridge's
            (x, y) lead its state). GoalDist-SS weighs each state by its Euclidean distance to it.
        goal_distance: for a goal that is not a point in the leading coordinates: a function from an
            (n, d) array of states to their n distances to the goal (finite; smaller is nearer).
            GoalDist-SS uses it instead of `goal`; declare at most one of the two. Neither: the task
            has no goal that GoalDist-SS can use, and it refuses the task, naming both.
        kernel_scale: AuxSS's `state_scale`, one positive divisor per state coordinate, applied
            before distances. None: `coordinate_spread` of the candidate states, each coordinate's
            standard deviation over them, so that coordinates in different units (metres, radians,
            velocities) count alike. LavaBridge declares (1, 1, 1, 1): its metres and m/s already
            weigh position and velocity alike (docs/design.md, section 2).
    """

    position: tuple[int, ...] | None = None
    goal: tuple[float, ...] | None = None
    goal_distance: Callable[[np.ndarray], Any] | None = None
    kernel_scale: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.position is not None:
            object.__setattr__(self, "position", check_coordinates("position", self.position))
        if self.goal is not None:
            goal = check_real_array("goal", self.goal, (np.size(self.goal),))
            if goal.size == 0:
                raise ValueError("goal must hold at least one coordinate, got an empty goal")
            object.__setattr__(self, "goal", tuple(float(x) for x in goal))
            leading = tuple(range(len(self.goal)))
            if self.position is not None and self.position != leading:
                raise ValueError(f"goal is compared with the state's first {len(self.goal)} coordinates {leading}, "
                                 f"but position is {self.position}: declare goal_distance (a function of the "
                                 f"states) instead of goal")
        if self.goal_distance is not None and not callable(self.goal_distance):
            raise ValueError(f"goal_distance must be a function from states (n, d) to n distances, "
                             f"got {self.goal_distance!r}")
        if self.goal is not None and self.goal_distance is not None:
            raise ValueError("declare goal (a goal position) or goal_distance (a function of the states), not both")
        if self.kernel_scale is not None:
            scale = check_real_array("kernel_scale", self.kernel_scale, (np.size(self.kernel_scale),))
            if scale.size == 0 or not (scale > 0).all():
                raise ValueError(f"kernel_scale must be positive finite numbers, one per state coordinate, "
                                 f"got {self.kernel_scale!r}")
            object.__setattr__(self, "kernel_scale", tuple(float(x) for x in scale))

    def kernel_scale_for(self, states: np.ndarray) -> tuple[float, ...]:
        """AuxSS's `state_scale` for the candidate `states` (n, d): `kernel_scale`, or their spread."""
        dim = np.shape(states)[1]
        if self.kernel_scale is None:
            return tuple(float(x) for x in coordinate_spread(states))
        if len(self.kernel_scale) != dim:
            raise ValueError(f"the task's kernel_scale has {len(self.kernel_scale)} numbers, but its states have "
                             f"{dim} coordinates")
        return self.kernel_scale


def task_states_of(env: Any) -> TaskStates:
    """The `TaskStates` that `env` declares in its attribute `task_states`, looked up through its
    wrappers (gymnasium's `get_wrapper_attr`), or `TaskStates()` for an env that declares none."""
    try:
        declared = env.get_wrapper_attr("task_states") if hasattr(env, "get_wrapper_attr") else env.task_states
    except AttributeError:
        return TaskStates()
    if not isinstance(declared, TaskStates):
        raise ValueError(f"{type(env).__name__}.task_states must be a TaskStates, got {declared!r}")
    return declared
