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
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from lava_bridge_mj.checks import REAL_KINDS, check_number, check_real_array
from lava_bridge_mj.layout import Layout
from lava_bridge_mj.mjcf import load_model
from lava_bridge_mj.starts import START_NAMES, start_distribution
from lava_bridge_mj.task_states import TaskStates

LAVA, GOAL = 1, 2
"""What a contact with a geom means (0: nothing, e.g. a wall)."""
FREE_MOTION_SKIPS = mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
"""MuJoCo stages an env step in free motion skips: collision detection and the (then empty) constraint solver."""
CLEARANCE_SLACK = 1e-3
"""Metres added to every distance of the free-motion test, far above its rounding errors."""
HAZARD_SPEED_MARGIN = 1.5
"""`clear_of_hazards` assumes the ball moves at up to this multiple of the top speed on each axis: a
wall's contact can turn the ball around and push a sunken ball back out, which free motion alone
never does (a push-out is millimetres per physics step, far below the top speed)."""


class LavaBridgeTask:
    """One Lava Bridge task (a `Layout` and its rewards) on the MjModel compiled from the layout.

    Args:
        layout: the geometry and physics.
        goal_reward: the reward on reaching the goal, a finite number.
        lava_reward: the reward on touching lava, a finite number.
        step_reward: the reward otherwise, a finite number (ValueError naming the reward otherwise).

    Attributes: `layout`, `model` (the compiled MjModel), `frame_skip` (physics steps per env step),
    `dt` (seconds per env step), the three rewards, `start_distributions` (name -> distribution),
    `observation_space` and `action_space` (one env's), `task_states` (what the start strategies
    need to know about its states, `TaskStates`: the position (x, y), the goal, and AuxSS's kernel on
    raw metres and m/s), `skip_free_contacts` (True: `step` runs an
    env step in which `free_motion` rules out every contact without collision detection, and one in
    which `clear_of_hazards` rules out lava and the goal without checking each physics step, the
    same numbers faster; False: every physics step is checked, the reference for tests and benchmarks).
    The free-motion bounds are read from the model when the task is made: after changing the model's
    physics (damping, gear, timestep, geoms), set `skip_free_contacts = False`. Forces applied from
    outside (`data.qfrc_applied`, `data.xfrc_applied`) are outside the bounds too.
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
        self._free_motion_bounds()
        self.skip_free_contacts = True

        hx, hy = layout.half_extent
        # Each axis's speed stays below gear / damping: the force's terminal velocity.
        v = layout.top_speed
        high = np.array([hx, hy, v, v])
        self.observation_space = spaces.Box(-high, high, dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self.task_states = TaskStates(position=(0, 1), goal=layout.goal, kernel_scale=(1.0, 1.0, 1.0, 1.0))

    # --- contacts ------------------------------------------------------------------------------
    def lava_contact(self, data: mujoco.MjData) -> bool:
        """True when the ball's footprint touches a lava pit, read from MuJoCo's contacts of `data`."""
        return LAVA in self._touch_events(data)

    def goal_contact(self, data: mujoco.MjData) -> bool:
        """True when the ball's centre is within goal_radius of the goal, read from MuJoCo's contacts."""
        return GOAL in self._touch_events(data)

    def _touch_events(self, data: mujoco.MjData) -> np.ndarray:
        return self._touch_event[data.contact.geom].ravel() if data.ncon else self._touch_event[:0]

    # --- free motion ---------------------------------------------------------------------------
    def _free_motion_bounds(self) -> None:
        """What `free_motion` needs, from the compiled model: each axis's reach in one env step as
        `reach_base + reach_per_speed * |v|`, and every geom the ball can touch as an axis-aligned
        rectangle grown by the ball's radius, the contact margin and gap. A model outside what the
        bound covers (another integrator, springs, friction loss, limits, equality constraints, joints
        other than slides along x and y, a geom that moves, fluid forces) gets one rectangle that covers
        every position: every step then takes the checked path."""
        model, probe = self.model, self._probe
        mujoco.mj_resetData(model, probe)
        mujoco.mj_fwdPosition(model, probe)
        ball = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "ball")
        touches = ((model.geom_contype[ball] & model.geom_conaffinity)
                   | (model.geom_contype & model.geom_conaffinity[ball])) != 0
        touches[ball] = False
        obstacles = np.flatnonzero(touches)
        # rectangles of the geoms' world bounding boxes: |R| half-sizes about the box's world centre
        lo, hi = [], []
        for g in obstacles:
            rotation = probe.geom_xmat[g].reshape(3, 3)
            centre = probe.geom_xpos[g] + rotation @ model.geom_aabb[g, :3]
            half = np.abs(rotation) @ model.geom_aabb[g, 3:]
            grow = model.geom_rbound[ball] + model.geom_margin[[g, ball]].max() + model.geom_gap[[g, ball]].max()
            lo.append(centre[:2] - half[:2] - grow - CLEARANCE_SLACK)
            hi.append(centre[:2] + half[:2] + grow + CLEARANCE_SLACK)
        self._obstacles = [(*map(float, low), *map(float, high)) for low, high in zip(lo, hi)]
        # one axis under implicit-damping Euler: v' = (m v + h f) / (m + h c), x' = x + h v', |f| <= gear;
        # so |v_k| <= a_k |v_0| + b_k, and the reach over n steps is h * sum(b_k) + h * sum(a_k) |v_0|
        h, n = model.opt.timestep, self.frame_skip
        mass = model.body_mass[model.geom_bodyid[ball]] + model.dof_armature
        force = np.abs(model.actuator_gear[:, 0]) * np.abs(model.actuator_ctrlrange).max(axis=1)
        a, b = np.ones(2), np.zeros(2)
        reach_base, reach_per_speed = np.zeros(2), np.zeros(2)
        for _ in range(n):
            a, b = mass * a / (mass + h * model.dof_damping), (mass * b + h * force) / (mass + h * model.dof_damping)
            reach_base += h * b
            reach_per_speed += h * a
        self._reach = ((reach_base + CLEARANCE_SLACK).tolist(), reach_per_speed.tolist())
        # lava and goal alone, for env steps that may touch a wall but nothing that ends the episode
        hazard_reach = reach_base + CLEARANCE_SLACK + reach_per_speed * HAZARD_SPEED_MARGIN * self.layout.top_speed
        self._hazard_reach = hazard_reach.tolist()
        self._hazards = [box for g, box in zip(obstacles, self._obstacles) if self._touch_event[g]]
        disabled = mujoco.mjtDisableBit
        covered = (model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
                   and not model.opt.disableflags & (disabled.mjDSBL_EULERDAMP | disabled.mjDSBL_CLAMPCTRL)
                   and model.nv == 2 and model.nu == 2 and list(model.actuator_trnid[:, 0]) == [0, 1]
                   and (model.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE).all()
                   and np.array_equal(model.jnt_axis, [[1, 0, 0], [0, 1, 0]])
                   and not model.jnt_stiffness.any() and not model.dof_frictionloss.any()
                   and not model.jnt_limited.any() and model.neq == 0
                   and model.opt.density == 0 and model.opt.viscosity == 0
                   and (model.geom_bodyid[obstacles] == 0).all() and model.actuator_ctrllimited.all())
        if not covered:
            self._obstacles = self._hazards = [(-math.inf, -math.inf, math.inf, math.inf)]

    def free_motion(self, data: mujoco.MjData) -> bool:
        """True when, whatever the action, no contact (wall, lava or goal) can exist at any physics step
        of `data`'s coming env step.

        The ball moves freely there (its force and linear damping), so its reach along each axis in
        frame_skip physics steps is bounded from its speed now; free_motion is True when that reach
        keeps its centre off every geom's rectangle grown by the ball's radius and the contact margin
        and gap. Plain Python floats: for one ball, several times cheaper than numpy's array calls.
        """
        x, y = data.qpos.tolist()
        vx, vy = data.qvel.tolist()
        (base_x, base_y), (per_x, per_y) = self._reach
        reach_x, reach_y = base_x + per_x * abs(vx), base_y + per_y * abs(vy)
        for low_x, low_y, high_x, high_y in self._obstacles:
            if x - reach_x < high_x and x + reach_x > low_x and y - reach_y < high_y and y + reach_y > low_y:
                return False
        return True

    def clear_of_hazards(self, data: mujoco.MjData) -> bool:
        """True when no lava or goal contact can occur at any physics step of `data`'s coming env step,
        whatever the action and whatever the walls do.

        Walls may be touched: that step runs with MuJoCo's collisions and constraints, only the checks
        for lava and the goal after each physics step are skipped. The ball's reach is bounded as in
        `free_motion` but from `HAZARD_SPEED_MARGIN` times the top speed, whatever its speed now, since
        a wall can turn it around.
        """
        x, y = data.qpos.tolist()
        reach_x, reach_y = self._hazard_reach
        for low_x, low_y, high_x, high_y in self._hazards:
            if x - reach_x < high_x and x + reach_x > low_x and y - reach_y < high_y and y + reach_y > low_y:
                return False
        return True

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

    @staticmethod
    def observations(datas: Sequence[mujoco.MjData]) -> np.ndarray:
        """The observations (K, 4) of K MjData, row i `observation(datas[i])`. Gathered as Python
        floats: half the time of stacking K small arrays, the same float64 values."""
        return np.array([data.qpos.tolist() + data.qvel.tolist() for data in datas])

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

        Where `free_motion` holds (and `skip_free_contacts`), the physics steps loop in C without
        collision detection and constraint solver, which would have found nothing; where only
        `clear_of_hazards` does (a wall within reach, lava and goal out of it), they loop in C with
        both, without the lava and goal checks, which would have found nothing. Either way the
        numbers are those of the checked loop bit for bit (tests/test_task_physics.py compares them).
        """
        model = self.model
        data.ctrl[:] = action  # MuJoCo clips to the actuators' ctrlrange [-1, 1]
        if self.skip_free_contacts and self.free_motion(data):
            # no contact can occur: then contacts are computed once, for the state reached, as the
            # checked loop leaves them
            flags = model.opt.disableflags
            model.opt.disableflags = flags | FREE_MOTION_SKIPS
            try:
                self._step_in_c(data)
            finally:
                model.opt.disableflags = flags
            mujoco.mj_step1(model, data)
            return self.step_reward, False, False
        if self.skip_free_contacts and self.clear_of_hazards(data):
            # walls only (a ball pushed on a wall): MuJoCo's own steps, with contacts, minus our checks
            self._step_in_c(data)
            mujoco.mj_step1(model, data)
            return self.step_reward, False, False
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

    def _step_in_c(self, data: mujoco.MjData) -> None:
        """frame_skip physics steps in C, as the checked loop's mj_step2 / mj_step1 pairs do them,
        leaving the last one's mj_step1 to the caller."""
        mujoco.mj_step2(self.model, data)
        if self.frame_skip > 1:
            mujoco.mj_step(self.model, data, nstep=self.frame_skip - 1)


def as_vector(name: str, value: Any, size: int = 2) -> np.ndarray:
    """`value` as a float64 copy of `size` finite real numbers (the caller's array may change later);
    ValueError naming `name` otherwise."""
    return check_real_array(name, value, (size,)).astype(np.float64)
