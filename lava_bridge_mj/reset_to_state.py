"""Reset any MuJoCo-based Gymnasium env to a state it reported: `ResetToState(env)`.

A state is MuJoCo's own (`mujoco.mj_getState` with `mjSTATE_INTEGRATION`: time, qpos, qvel, act,
actuator history, plugin state, controls, applied forces, mocap poses, active equalities, user data
and the constraint solver's warm start) followed by the task state that the env's family keeps
outside the physics and reads for reward, termination or its next action. A `TaskAdapter` per family
declares that task state and how the env computes its observation; nothing is guessed:

- Gymnasium's `MujocoEnv` family (Hopper-v5, Ant-v5, ... and user envs built on `MujocoEnv`, which
  compute observations in `_get_obs()`): no task state. An env of this family that keeps a goal or
  target in a Python attribute rather than in the physics is restored without it.
- Gymnasium-Robotics' PointMaze (`PointMazeEnv`, e.g. PointMaze_Large-v3): the goal (x, y).
- OGBench's cube envs (`CubeEnv`, e.g. cube-single-singletask-task1-v0): the effector pose and pad
  force that its controller and observation read as MuJoCo's step left them (`OGBenchCubeAdapter`);
  the cube targets are mocap poses, physics state already.

Any other env is refused at wrap time unless `ResetToState(env, adapter=...)` gets an adapter.
"""

from __future__ import annotations

import sys
from typing import Any

import gymnasium
import mujoco
import numpy as np

from lava_bridge_mj.checks import REAL_KINDS

PHYSICS_STATE = mujoco.mjtState.mjSTATE_INTEGRATION
"""The MuJoCo state kept: all that `mj_step` reads, the warm start included (without it a replay of
Ant-v5 drifts)."""


class TaskAdapter:
    """How a family of envs computes its observation, and the task state it keeps outside the physics.

    This base class is the adapter of Gymnasium's `MujocoEnv` family: no task state, the observation
    is `env._get_obs()` and the reset info `env._get_reset_info()`. A family's adapter overrides what
    differs. Every method gets the unwrapped env, and a task state of the right size, finite.
    """

    task_state_names: tuple[str, ...] = ()
    """The names of the task-state numbers that follow the physics state, in order."""

    def check_env(self, env: gymnasium.Env) -> None:
        """Raise ValueError if this adapter cannot serve `env`."""
        if not callable(getattr(env, "_get_obs", None)):
            raise ValueError(f"{type(env).__name__} has no _get_obs() to compute its observation for a restored "
                             f"state; pass ResetToState(env, adapter=...) a TaskAdapter for its family")

    def get_task_state(self, env: gymnasium.Env) -> np.ndarray:
        """The task state now: float64 numbers in the order of `task_state_names`."""
        return np.empty(0)

    def set_task_state(self, env: gymnasium.Env, task_state: np.ndarray) -> None:
        """Put `task_state` into `env`; called once the physics state is set, before `mj_forward`."""

    def finish_restore(self, env: gymnasium.Env, task_state: np.ndarray) -> None:
        """Called last, after `mj_forward`: put back derived quantities that the task state records."""

    def observation(self, env: gymnasium.Env) -> Any:
        """The observation the env computes in its current state."""
        return env._get_obs()

    def reset_info(self, env: gymnasium.Env, observation: Any) -> dict[str, Any]:
        """The reset info the env reports for its current state and `observation`."""
        return env._get_reset_info()


class PointMazeAdapter(TaskAdapter):
    """Gymnasium-Robotics' PointMaze: the goal (x, y), which decides reward, termination and success."""

    task_state_names = ("goal_x", "goal_y")
    SUCCESS_RADIUS = 0.45
    """PointMazeEnv's distance to the goal within which the episode counts as a success."""

    def check_env(self, env: gymnasium.Env) -> None:
        pass  # its observation comes from the point env inside it (`observation`)

    def get_task_state(self, env: gymnasium.Env) -> np.ndarray:
        return np.array(env.goal, dtype=np.float64)

    def set_task_state(self, env: gymnasium.Env, task_state: np.ndarray) -> None:
        env.goal = task_state.copy()
        env.update_target_site_pos()  # the goal marker that renders draw

    def observation(self, env: gymnasium.Env) -> dict[str, np.ndarray]:
        point_observation, _ = env.point_env._get_obs()
        return env._get_obs(point_observation)

    def reset_info(self, env: gymnasium.Env, observation: Any) -> dict[str, Any]:
        distance = np.linalg.norm(observation["achieved_goal"] - env.goal)
        return {"success": bool(distance <= self.SUCCESS_RADIUS)}


class OGBenchCubeAdapter(TaskAdapter):
    """OGBench's cube envs (`ogbench.manipspace.envs.cube_env.CubeEnv`).

    The cube targets are mocap poses and the success flag follows from the cube and target poses
    (the env's `post_step` computes it, as after every step), so neither needs task state. What does:
    two quantities that MuJoCo's step leaves from before its last integration and that the env reads,
    the effector pose (the `pinch` site's position and rotation matrix), from which the next action's
    inverse kinematics start and which the observation shows, and the contact force on the gripper
    pad, which the observation shows. Recomputed for the restored state instead, they would steer the
    arm along another path; put back as recorded, a replay matches bit for bit.

    Not restored: the goal observation that task-mode resets report in `info["goal"]` (OGBench draws
    it with unseeded random actions); it is the one of the reset that the restore follows.
    """

    PAD = "ur5e/robotiq/right_pad"
    """The gripper pad whose contact force the observation shows."""
    task_state_names = ("effector_x", "effector_y", "effector_z", *(f"effector_xmat_{i}" for i in range(9)),
                        *(f"pad_cfrc_ext_{i}" for i in range(6)))

    def check_env(self, env: gymnasium.Env) -> None:
        pass  # its observation is compute_observation() (`observation`)

    def get_task_state(self, env: gymnasium.Env) -> np.ndarray:
        data, site = env.data, env._pinch_site_id
        return np.concatenate([data.site_xpos[site], data.site_xmat[site], data.body(self.PAD).cfrc_ext])

    def set_task_state(self, env: gymnasium.Env, task_state: np.ndarray) -> None:
        env.post_step()  # the success flag (and the cubes' colours) for the restored poses

    def finish_restore(self, env: gymnasium.Env, task_state: np.ndarray) -> None:
        data, site = env.data, env._pinch_site_id
        data.site_xpos[site] = task_state[0:3]
        data.site_xmat[site] = task_state[3:12]
        data.body(self.PAD).cfrc_ext = task_state[12:18]
        env.pre_step()  # the "previous" proprioception in the reset info is the restored one, as after a reset

    def observation(self, env: gymnasium.Env) -> np.ndarray:
        return env.compute_observation()

    def reset_info(self, env: gymnasium.Env, observation: Any) -> dict[str, Any]:
        return env.get_reset_info()


ADAPTERS = (
    ("gymnasium_robotics.envs.maze.point_maze", "PointMazeEnv", PointMazeAdapter),
    ("ogbench.manipspace.envs.cube_env", "CubeEnv", OGBenchCubeAdapter),
    ("gymnasium.envs.mujoco.mujoco_env", "MujocoEnv", TaskAdapter),
)
"""(module, env class, adapter) per family, the first match wins. An env's class lives in a module
already imported, so finding its family imports nothing."""


def adapter_for(env: gymnasium.Env) -> TaskAdapter:
    """The adapter of the family of the unwrapped `env`; ValueError for an env of no known family."""
    for module_name, class_name, adapter in ADAPTERS:
        module = sys.modules.get(module_name)
        if module is not None and isinstance(env, getattr(module, class_name)):
            return adapter()
    families = ", ".join(f"{module}.{name}" for module, name, _ in ADAPTERS)
    raise ValueError(f"no TaskAdapter knows {type(env).__module__}.{type(env).__name__} (known families: "
                     f"{families}); pass ResetToState(env, adapter=...) a TaskAdapter that computes its observation")


class ResetToState(gymnasium.Wrapper, gymnasium.utils.RecordConstructorArgs):
    """Reset a MuJoCo-based env to any state it reported: `env.reset(options={"state": s})`.

    `env`'s unwrapped env must hold a MuJoCo `model` and `data` and be of a family that `adapter_for`
    knows, or come with an `adapter`; ValueError otherwise. Wrappers inside this one must not change
    observations (a restore returns the unwrapped env's own): wrap observation wrappers around it.

    A state is a 1-D float64 array of `state_size` numbers: MuJoCo's `mjSTATE_INTEGRATION` state of
    the env's model, then the task state `adapter.task_state_names`. States carry no tag of their
    model: one of another model is refused when its size differs, not otherwise.

    - Every `reset` and `step` puts the state after it in `info["state"]` (a copy).
    - `reset(seed=..., options=...)` without "state" is the env's own reset, passed through.
    - `reset(seed=..., options={"state": s, **env_options})` checks `s` first (ValueError naming the
      problem; the env is left as it was, its episode can go on). Then it resets the env with `seed`
      and `env_options` (wrappers and the env start an episode, `seed` seeds the env's generator),
      and puts `s` back: physics, task state, the derived quantities (`mj_forward`, then
      `mj_rnePostConstraint` for the contact forces that steps leave and observations such as
      Ant's read), the warm start as recorded. It returns the observation and the reset info that the
      env computes for `s`, with "state": `s` exactly.
    - Replaying the recorded actions from a restored state reproduces the recorded states,
      observations, rewards and terminations bit for bit, but for what an env computes from derived
      quantities (body positions, contact forces): MuJoCo's step leaves them from before its last
      integration, a restore recomputes them for the restored state. So the observation a restore
      returns and the reward of the first step after it can differ from the recording's; every state
      and observation from the first step on matches. Among Gymnasium's v5 envs: Ant-v5 (the first
      forward reward, from the torso position it starts from, and the observation's contact forces),
      Humanoid-v5 (the first reward and the observation), HumanoidStandup-v5, Pusher-v5 and
      Reacher-v5 (the observation); the others restore exactly.
    - The env's random generator is not part of the state: what the env draws after a restore
      follows `seed` and the draws of the reset, not the recording.
    """

    def __init__(self, env: gymnasium.Env, adapter: TaskAdapter | None = None):
        gymnasium.utils.RecordConstructorArgs.__init__(self, adapter=adapter)  # so env.spec can remake it
        gymnasium.Wrapper.__init__(self, env)
        unwrapped = env.unwrapped
        for name, kind in (("model", mujoco.MjModel), ("data", mujoco.MjData)):
            try:
                value = getattr(unwrapped, name)
            except Exception as error:  # an OGBench env before its first reset raises ValueError
                raise ValueError(f"ResetToState needs an env whose unwrapped env holds a MuJoCo model and data; "
                                 f"{type(unwrapped).__name__}.{name} is not available: {error}") from error
            if not isinstance(value, kind):
                raise ValueError(f"ResetToState needs an env whose unwrapped env holds a MuJoCo model and data; "
                                 f"{type(unwrapped).__name__}.{name} is a {type(value).__name__}, "
                                 f"not a mujoco.{kind.__name__}")
        self.adapter = adapter_for(unwrapped) if adapter is None else adapter
        self.adapter.check_env(unwrapped)
        inner = env
        while isinstance(inner, gymnasium.Wrapper):
            if isinstance(inner, gymnasium.ObservationWrapper):
                raise ValueError(f"{type(inner).__name__} inside ResetToState changes observations, but a restore "
                                 f"returns the env's own; wrap {type(inner).__name__} around ResetToState instead")
            inner = inner.env

    # model and data are looked up on each use: OGBench compiles new ones when its model changes
    @property
    def physics_state_size(self) -> int:
        """The number of MuJoCo state values at the start of a state."""
        return mujoco.mj_stateSize(self.env.unwrapped.model, PHYSICS_STATE)

    @property
    def state_size(self) -> int:
        """The size of a state: the MuJoCo part, then the task part."""
        return self.physics_state_size + len(self.adapter.task_state_names)

    def get_state(self) -> np.ndarray:
        """The env's state now, as `info["state"]` reports it: a float64 copy."""
        unwrapped = self.env.unwrapped
        physics = np.empty(self.physics_state_size)
        mujoco.mj_getState(unwrapped.model, unwrapped.data, physics, PHYSICS_STATE)
        return np.concatenate([physics, self.adapter.get_task_state(unwrapped)])

    def check_state(self, state: Any) -> np.ndarray:
        """`state` as a new float64 array; ValueError naming the problem unless it is a state of this env."""
        try:
            array = np.array(state)
        except (TypeError, ValueError):  # e.g. ragged nested lists
            array = np.empty(0, dtype=object)
        physics_size, names = self.physics_state_size, self.adapter.task_state_names
        expected = (f"{physics_size + len(names)} numbers: {physics_size} of MuJoCo's state of "
                    f"{type(self.env.unwrapped).__name__}'s model, then the task state {names}")
        if array.dtype.kind not in REAL_KINDS:
            raise ValueError(f"state must be real numbers, {expected}; got {state!r}")
        if array.shape != (physics_size + len(names),):
            raise ValueError(f"state must have shape ({physics_size + len(names)},), {expected}; got shape "
                             f"{array.shape} (a state of another model or env?)")
        bad = np.flatnonzero(~np.isfinite(array))
        if bad.size:
            raise ValueError(f"state must be finite, got {array[bad].tolist()} at indices {bad.tolist()}")
        return array.astype(np.float64)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if not isinstance(options, dict) or "state" not in options:  # the env's own reset
            observation, info = self.env.reset(seed=seed, options=options)
            return observation, {**info, "state": self.get_state()}
        state = self.check_state(options["state"])  # before anything changes
        env_options = {key: value for key, value in options.items() if key != "state"}
        _, info = self.env.reset(seed=seed, options=env_options or None)
        unwrapped = self.env.unwrapped
        model, data = unwrapped.model, unwrapped.data
        physics, task_state = state[:self.physics_state_size], state[self.physics_state_size:]
        mujoco.mj_setState(model, data, physics, PHYSICS_STATE)
        self.adapter.set_task_state(unwrapped, task_state)
        mujoco.mj_forward(model, data)
        mujoco.mj_rnePostConstraint(model, data)
        mujoco.mj_setState(model, data, physics, PHYSICS_STATE)  # the warm start as recorded, whatever forward did
        self.adapter.finish_restore(unwrapped, task_state)
        observation = self.adapter.observation(unwrapped)
        info = {**info, **self.adapter.reset_info(unwrapped, observation), "state": self.get_state()}
        return observation, info

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        info["state"] = self.get_state()
        return observation, reward, terminated, truncated, info
