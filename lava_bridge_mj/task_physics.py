"""LavaBridgeTask: the rules of one Lava Bridge task on its compiled MuJoCo model.

What `LavaBridgeEnv` and `LavaBridgeVectorEnv` share lives here, once: checking a state, putting an
MjData in a state, advancing one env step (frame_skip physics steps, lava and goal checked after each),
the rewards, the observation and the start distributions. The task owns the `MjModel`; every MjData is
the caller's (the single env holds one, the vector env one per sub-env), so the task is the model's
counterpart of dm_control's Task/Physics split: the envs hold the episode bookkeeping, the task the
physics and the rules.

    task = LavaBridgeTask(Layout())
    data = mujoco.MjData(task.model)
    task.set_state(data, *task.check_state((-4.5, 0.0), (0.0, 0.0)))
    reward, lava, success = task.step(data, task.check_action([1.0, 0.0]))
    task.observation(data)  # (x, y, vx, vy)
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from lava_bridge_mj.checks import REAL_KINDS, check_number, check_real_array
from lava_bridge_mj.layout import Layout
from lava_bridge_mj.mjcf import load_model
from lava_bridge_mj.starts import START_NAMES, start_distribution

LAVA, GOAL = 1, 2
"""What a contact with a geom means (0: nothing, e.g. a wall)."""


class LavaBridgeTask:
    """One Lava Bridge task (a `Layout` and its rewards) on the MjModel compiled from the layout.

    Args:
        layout: the geometry and physics.
        goal_reward, lava_reward, step_reward: the reward on reaching the goal, on touching lava and
            otherwise; finite numbers (ValueError naming the reward otherwise).

    Attributes: `layout`, `model` (the compiled MjModel), `frame_skip` (physics steps per env step),
    `dt` (seconds per env step), the three rewards, `start_distributions` (name -> distribution),
    `observation_space` and `action_space` (one env's).
    """

    def __init__(self, layout: Layout, *, goal_reward: float = 1.0, lava_reward: float = 0.0,
                 step_reward: float = 0.0):
        if not isinstance(layout, Layout):
            raise ValueError(f"layout must be a Layout, got {layout!r}")
        # a reward is returned as given, so a string or NaN here would reach the learner unseen
        self.goal_reward, self.lava_reward, self.step_reward = (
            check_number(name, value, -math.inf, math.inf) for name, value in
            (("goal_reward", goal_reward), ("lava_reward", lava_reward), ("step_reward", step_reward)))
        self.layout = layout
        self.model = load_model(layout)
        self.frame_skip = layout.frame_skip
        self.dt = layout.control_dt
        self._probe = mujoco.MjData(self.model)  # scratch data: check a state without touching the caller's

        geom_id = lambda name: mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, name)  # noqa: E731
        # geom id -> what touching it means, so classifying all contacts is one fancy-index
        self._touch_event = np.zeros(self.model.ngeom, dtype=np.int8)
        self._touch_event[[geom_id(n) for n in layout.lava_pits]] = LAVA
        self._touch_event[geom_id("goal")] = GOAL
        self.start_distributions = {name: start_distribution(layout, name) for name in START_NAMES}

        hx, hy = layout.half_extent
        # Each axis's speed stays below gear / damping: the force's terminal velocity.
        v = layout.top_speed
        high = np.array([hx, hy, v, v])
        self.observation_space = spaces.Box(-high, high, dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)

    # --- contacts ------------------------------------------------------------------------------
    def lava_contact(self, data: mujoco.MjData) -> bool:
        """True when the ball's footprint touches a lava pit, read from MuJoCo's contacts of `data`."""
        return LAVA in self._touch_events(data)

    def goal_contact(self, data: mujoco.MjData) -> bool:
        """True when the ball's centre is within goal_radius of the goal, read from MuJoCo's contacts."""
        return GOAL in self._touch_events(data)

    def _touch_events(self, data: mujoco.MjData) -> np.ndarray:
        return self._touch_event[data.contact.geom].ravel() if data.ncon else self._touch_event[:0]

    # --- states --------------------------------------------------------------------------------
    def check_state(self, qpos: Any, qvel: Any = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """(qpos, qvel) as float64 copies, after checking they are a state the ball may start from.

        Raises ValueError naming what is wrong for a misshapen or non-finite state, one outside the
        maze, overlapping a wall, faster than the top speed or touching lava.
        """
        qpos = as_vector("qpos", qpos)
        qvel = as_vector("qvel", qvel)
        hx, hy = self.layout.half_extent
        x, y = qpos
        # A ball may overlap a wall by less than its radius (soft contacts let a ball that hits a
        # wall sink in by millimetres, and every visited state must reset); its centre may not.
        if abs(x) > hx or abs(y) > hy:
            raise ValueError(f"state position ({x:g}, {y:g}) is inside a wall or outside the maze: the ball's "
                             f"centre must satisfy |x| <= {hx:g} and |y| <= {hy:g}")
        v = self.layout.top_speed
        if np.abs(qvel).max() > v:
            raise ValueError(f"state velocity {qvel} exceeds the top speed {v:g} m/s on an axis (gear / damping)")
        probe = self._probe
        mujoco.mj_resetData(self.model, probe)
        probe.qpos[:] = qpos
        mujoco.mj_fwdPosition(self.model, probe)  # kinematics and collision only
        if self.lava_contact(probe):
            raise ValueError(f"state position ({x:g}, {y:g}) touches lava")
        return qpos, qvel

    def set_state(self, data: mujoco.MjData, qpos: np.ndarray, qvel: np.ndarray) -> None:
        """Put `data` in the state (qpos, qvel), from `check_state` or a start distribution (not checked
        again): time, controls and solver state zeroed, contacts current for `step`."""
        mujoco.mj_resetData(self.model, data)  # zero time, controls and solver state: deterministic
        data.qpos[:] = qpos
        data.qvel[:] = qvel
        # step() expects position- and velocity-dependent quantities (contacts) to be current
        mujoco.mj_forward(self.model, data)

    def check_start_name(self, name: Any) -> str:
        """`name` when it names a start distribution; ValueError naming it and the known ones otherwise."""
        if not isinstance(name, str) or name not in self.start_distributions:
            raise ValueError(f"unknown start distribution {name!r}; expected one of {START_NAMES}")
        return name

    def sample_start(self, name: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """A (qpos, qvel) drawn with `rng` from the start distribution `name`: valid by construction
        (Layout checks its discs), so it goes to `set_state` unchecked."""
        state = self.start_distributions[name].sample(rng)
        return state[:2], state[2:]

    @staticmethod
    def observation(data: mujoco.MjData) -> np.ndarray:
        """The observation (x, y, vx, vy) of `data`: its whole physics state, a copy."""
        return np.concatenate([data.qpos, data.qvel])

    # --- dynamics ------------------------------------------------------------------------------
    @staticmethod
    def check_action(action: Any) -> np.ndarray:
        """`action` as an array of 2 finite real numbers (not copied when it already is one);
        ValueError naming what is wrong otherwise. Out-of-range values are MuJoCo's to clip."""
        array = np.asarray(action)
        # the hot path: a dtype-kind test and two scalar tests cost less than check_real_array's
        # np.isfinite, which only runs to word the error
        if (array.dtype.kind in REAL_KINDS and array.shape == (2,)
                and math.isfinite(array[0]) and math.isfinite(array[1])):
            return array
        return check_real_array("action", action, (2,))  # raises, naming what is wrong

    def step(self, data: mujoco.MjData, action: np.ndarray) -> tuple[float, bool, bool]:
        """Advance `data` one env step (frame_skip physics steps) under an action from `check_action`.

        Returns (reward, lava, success). It stops at the first physics step whose contacts touch lava
        (lava) or the goal (success); either ends the episode.
        """
        model = self.model
        data.ctrl[:] = action  # MuJoCo clips to the actuators' ctrlrange [-1, 1]
        lava = success = False
        # mj_step split in two so contacts are current for the state just reached: lava and the
        # goal are checked after every physics step, so a fast ball cannot cross a corner unseen.
        for _ in range(self.frame_skip):
            mujoco.mj_step2(model, data)
            mujoco.mj_step1(model, data)
            if data.ncon:  # most steps have no contact at all; walls are the common one
                events = self._touch_events(data)
                if events.any():
                    lava, success = LAVA in events, GOAL in events
                    break
        reward = self.goal_reward if success else self.lava_reward if lava else self.step_reward
        return reward, lava, success


def as_vector(name: str, value: Any, size: int = 2) -> np.ndarray:
    """`value` as a float64 copy of `size` finite real numbers (the caller's array may change later);
    ValueError naming `name` otherwise."""
    return check_real_array(name, value, (size,)).astype(np.float64)
