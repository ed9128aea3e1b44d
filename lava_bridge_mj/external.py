"""Other projects' MuJoCo tasks, each with fixed named starts and an expert: `make_task_env(env_id)`.

`EXTERNAL_TASKS` maps a Gymnasium id to its `ExternalTask`:

- Gymnasium-Robotics' `PointMaze_Large-v3` and `PointMaze_Medium-v3` with a fixed start cell and goal
  cell, a sparse reward, episodes that end at the goal; the expert plans a shortest path over the
  maze's cells and follows it (`MazeExpert`).
- OGBench's `cube-single-singletask-task1-v0` as OGBench defines it; the expert is OGBench's own
  scripted oracle, given the single task's target (`CubeExpert`).

`make_task_env(env_id)` makes the task's env wrapped in `ResetToState` (exact resets to any state it
reports) and `NamedStarts` (resets to the task's named starts, "p0" and "ood"), which carries the
task's `TaskStates` for the start strategies. The projects that define these envs are optional
extras (`pip install 'lava-bridge-mj[robotics]'`, `'lava-bridge-mj[ogbench]'`), imported on first
use: importing this module imports neither.

Experts share one interface (`Expert`): `expert.reset(observation, info)` after each env reset,
then `expert(observation) -> action` for each step; both read only the observation (and the reset
info), so they drive the env from a restored state as from a fresh one.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Protocol

import gymnasium
import mujoco
import numpy as np

from lava_bridge_mj.reset_to_state import PHYSICS_STATE, ResetToState
from lava_bridge_mj.task_states import TaskStates

START_NAMES = ("p0", "ood")
"""The named starts of every external task: "p0" the task's start, "ood" a wider start distribution
that the task defines, out of p0's distribution."""


def import_extra(package: str, extra: str):
    """Import `package`, or raise ImportError naming the package extra that installs it."""
    try:
        return importlib.import_module(package)
    except ImportError as error:
        raise ImportError(f"this task needs the {package} package: pip install 'lava-bridge-mj[{extra}]'") from error


def remove_maze_xml(env: gymnasium.Env) -> gymnasium.Env:
    """`env`, with the MJCF file a Gymnasium-Robotics maze env wrote removed (other envs as they are).

    Each maze env that Gymnasium-Robotics makes writes its model to a new file in the temp directory
    and never removes it: a study's sweeps, which make envs for every run and evaluation, left tens of
    thousands. The env has loaded its model from the file by the time `gymnasium.make` returns, so the
    file can go. Only a file named uniquely (ant_mazeTIMESTAMP.xml) goes: older maze envs write one
    shared name, which another process may be about to load."""
    written = getattr(env.unwrapped, "tmp_xml_file_path", None)
    if written is not None and Path(written).name != "ant_maze.xml":
        Path(written).unlink(missing_ok=True)
    return env


def state_offset(model: mujoco.MjModel, component: mujoco.mjtState) -> int:
    """Where `component` (e.g. `mjSTATE_QPOS`) starts in a `ResetToState` state of `model`:
    `mj_getState` writes the components of `mjSTATE_INTEGRATION` in the order of their bits."""
    before = int(PHYSICS_STATE) & (int(component) - 1)
    return mujoco.mj_stateSize(model, before)


class Expert(Protocol):
    """The interface of every expert: `reset(observation, info)` after each env reset (a restore
    included), then `expert(observation)` for the action to take from that observation."""

    def reset(self, observation: Any, info: dict[str, Any]) -> None: ...

    def __call__(self, observation: Any) -> np.ndarray: ...


class NamedStarts(gymnasium.Wrapper):
    """Resets a task's env to its named starts, around its `ResetToState`.

    - `reset(seed=..., options={"start": "p0"})` (also `options=None`): the task's own start.
    - `reset(seed=..., options={"start": "ood"})`: a draw from the task's out-of-distribution starts.
    - `reset(seed=..., options={"state": s})`: `ResetToState`'s exact reset to a state `s` that the env
      reported (`info["state"]`).

    A seeded reset gives the same start every time. The task's `TaskStates` is `task_states`, found
    through any wrapper around this one (`gymnasium.Env.get_wrapper_attr("task_states")`).
    """

    start_names = START_NAMES
    """The named starts, as `ResetToStateVectorEnv` (and so the trainer's evaluation) reads them."""

    def __init__(self, env: gymnasium.Env, task: ExternalTask):
        super().__init__(env)
        if not isinstance(env, ResetToState):
            raise ValueError(f"NamedStarts wraps a ResetToState, got {type(env).__name__}")
        self.task = task
        self.task_states = task.task_states(env)
        self.start_rng = np.random.default_rng()  # the draws of "ood"; a seeded reset reseeds it

    # ResetToState's state API, which gymnasium's wrappers do not forward
    @property
    def physics_state_size(self) -> int:
        return self.env.physics_state_size

    @property
    def state_size(self) -> int:
        return self.env.state_size

    def get_state(self) -> np.ndarray:
        return self.env.get_state()

    def check_state(self, state: Any) -> np.ndarray:
        return self.env.check_state(state)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        options = {} if options is None else options
        if not isinstance(options, dict) or not set(options) <= {"start", "state"} or len(options) > 1:
            raise ValueError(f"options must be None, {{'start': name}} with a name of {START_NAMES} or "
                             f"{{'state': s}} with a state the env reported, got {options!r}")
        if seed is not None:
            self.start_rng = np.random.default_rng(seed)
        if "state" in options:
            return self.env.reset(seed=seed, options=options)
        start = options.get("start", "p0")
        if start not in START_NAMES:
            raise ValueError(f"start must be one of {START_NAMES}, got {start!r}")
        return self.task.reset_to_start(self.env, start, seed, self.start_rng)


@dataclass(frozen=True)
class ExternalTask:
    """A task on another project's env: how to make it, its named starts, its states and its expert."""

    env_id: str
    """The Gymnasium id of the env."""
    package: str
    """The package that registers the env."""
    extra: str
    """The package extra of lava-bridge-mj that installs `package`."""
    description: str
    """A paragraph on the task, its starts and its expert."""
    expert_name = "Expert"
    """The class of the task's expert (a Minari dataset of its demos names it)."""

    def spec(self) -> gymnasium.envs.registration.EnvSpec:
        """The env's registered spec (importing the package that registers it)."""
        gymnasium.register_envs(import_extra(self.package, self.extra))
        return gymnasium.spec(self.env_id)

    @property
    def max_episode_steps(self) -> int:
        """The task's episode horizon: the step limit its env registers (800 PointMaze_Large-v3, 600
        PointMaze_Medium-v3, 200 OGBench's cube), the limit training and evaluation episodes have."""
        return int(self.spec().max_episode_steps)

    def make_env(self, time_limit: bool = True, **kwargs) -> gymnasium.Env:
        """`gymnasium.make` of the task's env, with the task's arguments, then `kwargs`; without
        gymnasium's TimeLimit when not `time_limit` (a vector env that counts the steps itself)."""
        spec = self.spec()
        if not time_limit:
            spec = dataclasses.replace(spec, max_episode_steps=None)
        return remove_maze_xml(gymnasium.make(spec, **{**self.env_kwargs(), **kwargs}))

    def env_kwargs(self) -> dict[str, Any]:
        """The arguments the task gives `gymnasium.make`."""
        return {}

    def wrap(self, env: gymnasium.Env) -> gymnasium.Env:
        """Wrappers the task needs inside `ResetToState` (none by default)."""
        return env

    def reset_to_start(self, env: ResetToState, start: str, seed: int | None,
                       rng: np.random.Generator) -> tuple[Any, dict[str, Any]]:
        """Reset `env` to a draw from the named `start`; `rng` draws what the env does not."""
        raise NotImplementedError

    def task_states(self, env: ResetToState) -> TaskStates:
        """What the task declares about its states (`ResetToState` states of `env`)."""
        raise NotImplementedError

    def expert(self, env: gymnasium.Env, seed: int | None = None) -> Expert:
        """The task's expert for `env` (the env made by `make_task_env`)."""
        raise NotImplementedError


# --- PointMaze -----------------------------------------------------------------------------------
class MazePlanner:
    """Shortest paths over the free cells of a Gymnasium-Robotics `Maze` (4-connected): a
    breadth-first search from each goal cell asked for, kept."""

    def __init__(self, maze):
        self.maze = maze
        self._steps_to_goal: dict[tuple[int, int], np.ndarray] = {}

    def free_cells(self) -> list[tuple[int, int]]:
        """Every (row, column) of the maze that is not a wall."""
        return [(i, j) for i, row in enumerate(self.maze.maze_map) for j, cell in enumerate(row) if cell != 1]

    def cell(self, xy: np.ndarray) -> tuple[int, int]:
        """The (row, column) of the cell holding the point `xy`."""
        return tuple(int(x) for x in self.maze.cell_xy_to_rowcol(xy))

    def steps_to_goal(self, goal_cell: tuple[int, int]) -> np.ndarray:
        """Cell steps from each cell to `goal_cell` on a shortest path (-1: a wall or unreachable)."""
        goal_cell = (int(goal_cell[0]), int(goal_cell[1]))
        if goal_cell not in self._steps_to_goal:
            free = set(self.free_cells())
            steps = np.full((self.maze.map_length, self.maze.map_width), -1, dtype=np.int64)
            steps[goal_cell] = 0
            queue = deque([goal_cell])
            while queue:
                i, j = queue.popleft()
                for neighbour in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)):
                    if neighbour in free and steps[neighbour] < 0:
                        steps[neighbour] = steps[i, j] + 1
                        queue.append(neighbour)
            self._steps_to_goal[goal_cell] = steps
        return self._steps_to_goal[goal_cell]

    def next_cell(self, cell: tuple[int, int], goal_cell: tuple[int, int]) -> tuple[int, int]:
        """The neighbour of `cell` one step nearer `goal_cell` (`cell` itself in the goal cell)."""
        steps = self.steps_to_goal(goal_cell)
        i, j = cell
        if steps[i, j] < 0:
            raise ValueError(f"cell {cell} is a wall or cannot reach the goal cell {goal_cell}")
        for neighbour in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)):
            if steps[i, j] > 0 and steps[neighbour] == steps[i, j] - 1:
                return neighbour
        return cell


class MazeExpert:
    """Gymnasium-Robotics' PointMaze: the shortest path over the maze's free cells, followed.

    Each call finds the ball's cell and the goal's cell (from the observation's `achieved_goal` and
    `desired_goal`) and aims at the centre of the next cell on a shortest path (`MazePlanner`), or at
    the goal itself once in the goal's cell. The straight line from anywhere in a cell to the centre of
    a neighbouring free cell stays within the two cells, so the ball never aims across a wall. The
    action is a force: a velocity toward the aim point (`position_gain` times the distance, at most
    `max_speed`) tracked with `velocity_gain`, clipped to the action bounds.
    """

    def __init__(self, maze, action_space: gymnasium.spaces.Box, *, max_speed: float = 3.0,
                 position_gain: float = 6.0, velocity_gain: float = 1.5):
        self.planner = MazePlanner(maze)
        self.action_space = action_space
        self.max_speed, self.position_gain, self.velocity_gain = max_speed, position_gain, velocity_gain

    def aim(self, position: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """The point the ball heads for: the next cell's centre, or the goal in the goal's cell."""
        cell = self.planner.cell(position)
        following = self.planner.next_cell(cell, self.planner.cell(goal))
        if following == cell:
            return np.asarray(goal, dtype=np.float64)
        return self.planner.maze.cell_rowcol_to_xy(following)

    def reset(self, observation: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        pass  # stateless: every action follows from the observation

    def __call__(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        position, velocity = observation["achieved_goal"], observation["observation"][2:4]
        desired = self.position_gain * (self.aim(position, observation["desired_goal"]) - position)
        speed = np.linalg.norm(desired)
        if speed > self.max_speed:
            desired *= self.max_speed / speed
        action = self.velocity_gain * (desired - velocity)
        return np.clip(action, self.action_space.low, self.action_space.high).astype(self.action_space.dtype)


@dataclass(frozen=True)
class PointMazeTask(ExternalTask):
    """A PointMaze with a fixed start cell and goal cell (row, column of the maze map)."""

    start_cell: tuple[int, int] = (1, 1)
    goal_cell: tuple[int, int] = (1, 1)
    expert_name = "MazeExpert"  # the expert's class, as a Minari dataset of its demos names it

    def env_kwargs(self) -> dict[str, Any]:
        return {"continuing_task": False, "reward_type": "sparse"}

    def ood_cells(self, maze) -> list[tuple[int, int]]:
        """The "ood" start cells: every free cell but the start cell and the goal cell."""
        return [cell for cell in MazePlanner(maze).free_cells() if cell not in (self.start_cell, self.goal_cell)]

    def reset_to_start(self, env, start, seed, rng):
        cell = self.start_cell
        if start == "ood":
            cells = self.ood_cells(env.unwrapped.maze)
            cell = cells[rng.integers(len(cells))]
        return env.reset(seed=seed, options={"reset_cell": np.array(cell), "goal_cell": np.array(self.goal_cell)})

    def task_states(self, env: ResetToState) -> TaskStates:
        unwrapped = env.unwrapped
        qpos = state_offset(unwrapped.model, mujoco.mjtState.mjSTATE_QPOS)
        position = (qpos, qpos + 1)  # the ball's x, y: its two slide joints lead qpos
        goal = (env.physics_state_size, env.physics_state_size + 1)  # the task state (goal_x, goal_y)
        # AuxSS's kernel on raw metres, as on Lava Bridge: sigma 0.3 m within a cell of 1 m
        return TaskStates(position=position, goal_distance=MazeDistance(unwrapped.maze, position, goal),
                          kernel_scale=(1.0,) * env.state_size)

    def expert(self, env: gymnasium.Env, seed: int | None = None) -> MazeExpert:
        return MazeExpert(env.unwrapped.maze, env.action_space)


class MazeDistance:
    """GoalDist-SS's distance of PointMaze states to their goal: the length of the path the expert
    takes, from the ball to the next cell's centre on a shortest path over the cells, from cell centre
    to cell centre up to the goal's cell, and from its centre to the goal; in the goal's cell, the
    straight distance to the goal."""

    def __init__(self, maze, position: tuple[int, int], goal: tuple[int, int]):
        self.planner = MazePlanner(maze)
        self.position, self.goal = list(position), list(goal)

    def __call__(self, states: np.ndarray) -> np.ndarray:
        planner, maze = self.planner, self.planner.maze
        distances = np.empty(len(states))
        for k, (position, goal) in enumerate(zip(states[:, self.position], states[:, self.goal])):
            cell, goal_cell = planner.cell(position), planner.cell(goal)
            steps = planner.steps_to_goal(goal_cell)[cell]
            if steps <= 0:
                distances[k] = np.linalg.norm(goal - position)  # in the goal's cell (or walled in: straight)
                continue
            following = maze.cell_rowcol_to_xy(planner.next_cell(cell, goal_cell))
            distances[k] = (np.linalg.norm(following - position) + (steps - 1) * maze.maze_size_scaling
                            + np.linalg.norm(goal - maze.cell_rowcol_to_xy(goal_cell)))
        return distances


# --- OGBench cube --------------------------------------------------------------------------------
class SeededCubeReset(gymnasium.Wrapper):
    """Seeded resets of OGBench's task-mode cube envs that reproduce their state.

    To preview the goal, OGBench's task-mode reset steps the env twice with unseeded random actions
    (`CubeEnv.initialize_episode`, through an action space made anew at each use), then puts back
    positions and velocities, but leaves the solver warm start and the controls of those steps. Two
    resets with one seed then report different states (`info["state"]`), and the warm start is the
    first step's initial guess of the solver. This wrapper zeros both, as `mj_resetData` leaves them
    (the first step sets every control anew). The goal observation of the reset info
    (`info["goal"]`) still varies.
    """

    def reset(self, *, seed=None, options=None):
        _, info = self.env.reset(seed=seed, options=options)
        unwrapped = self.env.unwrapped
        unwrapped.data.qacc_warmstart[:] = 0.0
        unwrapped.data.ctrl[:] = 0.0
        return unwrapped.compute_observation(), {**info, **unwrapped.get_reset_info()}


class CubeExpert:
    """OGBench's scripted cube oracle (`ogbench.manipspace.oracles.markov.cube_markov.CubeMarkovOracle`,
    the one OGBench collects its datasets with), driving the single task toward its target.

    The oracle is written for OGBench's data-collection mode and reads the effector, gripper and cube
    poses and the target from the step info; here they come from the observation (OGBench's
    `CubeEnv.compute_observation` layout, `decode`) and the task's target (its goal position, yaw 0).
    After the cube is placed it moves the arm to a final pose, which OGBench draws from numpy's global
    generator; here from this expert's own, seeded by `seed`.
    """

    XYZ_CENTER, XYZ_SCALE, GRIPPER_SCALE = np.array([0.425, 0.0, 0.0]), 10.0, 3.0
    """How `CubeEnv.compute_observation` centres and scales positions and the gripper opening."""

    def __init__(self, env: gymnasium.Env, seed: int | None = None):
        oracles = import_extra("ogbench.manipspace.oracles.markov.cube_markov", "ogbench")
        self.env = env
        self.oracle = oracles.CubeMarkovOracle(env=env)
        self.rng = np.random.default_rng(seed)
        self.target = None

    def decode(self, observation: np.ndarray) -> dict[str, Any]:
        """The step-info entries the oracle reads, from a single-cube observation."""
        yaw = np.arctan2(observation[16], observation[15])
        block_yaw = np.arctan2(observation[27], observation[26])
        return {
            "proprio/effector_pos": observation[12:15] / self.XYZ_SCALE + self.XYZ_CENTER,
            "proprio/effector_yaw": np.array([yaw]),
            "proprio/gripper_opening": observation[17:18] / self.GRIPPER_SCALE,
            "proprio/gripper_contact": observation[18:19],
            "privileged/block_0_pos": observation[19:22] / self.XYZ_SCALE + self.XYZ_CENTER,
            "privileged/block_0_quat": observation[22:26],
            "privileged/block_0_yaw": np.array([block_yaw]),
            "privileged/target_block": 0,
            "privileged/target_block_pos": self.target,
            "privileged/target_block_yaw": np.zeros(1),  # the task's targets are upright, yaw 0
        }

    def reset(self, observation: np.ndarray, info: dict[str, Any]) -> None:
        self.target = np.array(self.env.unwrapped.cur_task_info["goal_xyzs"][0], dtype=np.float64)
        state = np.random.get_state()  # the oracle's reset draws from numpy's global generator: leave it be
        self.oracle.reset(observation, info)
        np.random.set_state(state)
        self.oracle._final_pos = self.rng.uniform(*self.env.unwrapped._arm_sampling_bounds)
        self.oracle._final_yaw = self.rng.uniform(-np.pi, np.pi)

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        if self.target is None:
            raise ValueError("call expert.reset(observation, info) after each env reset, before the first action")
        return self.oracle.select_action(observation, self.decode(observation)).astype(np.float32)


@dataclass(frozen=True)
class CubeTask(ExternalTask):
    """An OGBench single-cube task as OGBench defines it; "ood" places the cube anywhere in OGBench's
    object sampling area (`ood_bounds`, any yaw), at least `ood_clearance` from the target."""

    ood_bounds: tuple[tuple[float, float], tuple[float, float]] = ((0.3, -0.3), (0.55, 0.3))
    """(x, y) low and high of the "ood" cube positions: `ManipSpaceEnv._object_sampling_bounds`."""
    ood_clearance: float = 0.1
    """The least distance from an "ood" cube to the target (success is within 0.04)."""
    kernel_unit: float = 0.1
    """AuxSS's kernel scale of every state coordinate (`TaskStates.kernel_scale`), in metres."""
    expert_name = "CubeExpert"

    def wrap(self, env: gymnasium.Env) -> gymnasium.Env:
        return SeededCubeReset(env)

    def cube_qpos(self, env: ResetToState) -> int:
        """Where the cube's free joint (position, then orientation quaternion) starts in a state."""
        model = env.unwrapped.model
        return state_offset(model, mujoco.mjtState.mjSTATE_QPOS) + int(model.joint("object_joint_0").qposadr[0])

    def reset_to_start(self, env, start, seed, rng):
        observation, info = env.reset(seed=seed)
        if start == "p0":
            return observation, info
        target = np.asarray(env.unwrapped.cur_task_info["goal_xyzs"][0])
        while True:
            xy = rng.uniform(*self.ood_bounds)
            if np.linalg.norm(xy - target[:2]) >= self.ood_clearance:
                break
        yaw = rng.uniform(0.0, 2 * np.pi)
        state, cube = info["state"].copy(), self.cube_qpos(env)
        state[cube:cube + 7] = [*xy, target[2], np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
        return env.reset(options={"state": state})

    def task_states(self, env: ResetToState) -> TaskStates:
        cube = self.cube_qpos(env)
        mocap = env.unwrapped._cube_target_mocap_ids[0]
        target = state_offset(env.unwrapped.model, mujoco.mjtState.mjSTATE_MOCAP_POS) + 3 * int(mocap)
        position, target = (cube, cube + 1, cube + 2), [target, target + 1, target + 2]

        def goal_distance(states: np.ndarray) -> np.ndarray:
            """The cube's distance to its target (OGBench's success: at most 0.04)."""
            return np.linalg.norm(states[:, list(position)] - states[:, target], axis=1)

        # AuxSS's kernel in decimetres: its sigma of 0.3 is 3 cm, the cube's size and success radius
        return TaskStates(position=position, goal_distance=goal_distance,
                          kernel_scale=(self.kernel_unit,) * env.state_size)

    def expert(self, env: gymnasium.Env, seed: int | None = None) -> CubeExpert:
        return CubeExpert(env, seed=seed)


EXTERNAL_TASKS: dict[str, ExternalTask] = {task.env_id: task for task in (
    PointMazeTask(
        "PointMaze_Large-v3", "gymnasium_robotics", "robotics",
        "Gymnasium-Robotics' large point maze (9 x 12 cells, 1 m each): a force-actuated ball starts in cell "
        "(1, 1), the top left, and must reach the goal in cell (7, 10), the bottom right, 15 cell steps away "
        "by the shortest path; both positions get the env's own uniform noise of +-0.25 m. Sparse reward 1 "
        "within 0.45 m of the goal, where the episode ends (continuing_task=False); 800 steps at most. "
        "p0: the start cell; ood: any other free cell but the goal's. Expert: MazeExpert, a shortest path "
        "over the cells followed by a velocity-tracking controller.",
        start_cell=(1, 1), goal_cell=(7, 10)),
    PointMazeTask(
        "PointMaze_Medium-v3", "gymnasium_robotics", "robotics",
        "Gymnasium-Robotics' medium point maze (8 x 8 cells, 1 m each): the ball starts in cell (1, 1) and "
        "must reach the goal in cell (6, 6), 10 cell steps away; positions get the env's noise of "
        "+-0.25 m. Sparse reward, episodes end at the goal, 600 steps at most. p0: the start cell; ood: any "
        "other free cell but the goal's. Expert: MazeExpert.",
        start_cell=(1, 1), goal_cell=(6, 6)),
    CubeTask(
        "cube-single-singletask-task1-v0", "ogbench", "ogbench",
        "OGBench's single-cube pick-and-place, task 1, as OGBench defines it: a UR5e arm with a Robotiq "
        "gripper (5-D relative end-effector actions) must move a 4 cm cube from (0.425, 0.1) to the target "
        "(0.425, -0.1); success (reward 0, else -1) when the cube is within 4 cm of the target, where the "
        "episode ends; 200 steps at most. p0: OGBench's reset (a random arm pose, the cube within 1 cm of "
        "its start, any yaw); ood: the cube anywhere in OGBench's object area (x 0.3 to 0.55, y -0.3 to "
        "0.3, any yaw), at least 10 cm from the target. Expert: OGBench's scripted Markov cube oracle.",
    ),
)}
"""The external tasks by Gymnasium id."""


def make_task_env(env_id: str, time_limit: bool = True, **kwargs) -> NamedStarts:
    """The env of the external task `env_id` (a key of `EXTERNAL_TASKS`): `gymnasium.make` with the
    task's arguments and `kwargs`, wrapped in `ResetToState` and `NamedStarts`; without gymnasium's
    TimeLimit when not `time_limit`.

    ValueError for an id of no external task; ImportError naming the extra to install when the
    package that defines the env is missing.
    """
    if env_id not in EXTERNAL_TASKS:
        raise ValueError(f"{env_id!r} is not an external task; expected one of {sorted(EXTERNAL_TASKS)}")
    task = EXTERNAL_TASKS[env_id]
    return NamedStarts(ResetToState(task.wrap(task.make_env(time_limit, **kwargs))), task)


def run_episode(env: gymnasium.Env, policy: Callable[[Any], np.ndarray] | None, *, seed: int | None = None,
                options: dict[str, Any] | None = None) -> tuple[bool, int]:
    """One episode of `policy` (an `Expert`, or None for uniform random actions seeded by `seed`):
    (whether it succeeded, `info["success"]` of its last step; its length in steps)."""
    observation, info = env.reset(seed=seed, options=options)
    if policy is None:
        env.action_space.seed(seed)
    else:
        policy.reset(observation, info)
    steps, success = 0, False
    while True:
        action = env.action_space.sample() if policy is None else policy(observation)
        observation, _, terminated, truncated, info = env.step(action)
        steps, success = steps + 1, bool(info["success"])
        if terminated or truncated:
            return success, steps
