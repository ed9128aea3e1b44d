"""LavaBridge-v0: a point mass must cross a narrow bridge between lava pits to reach a goal."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import gymnasium
import mujoco
import numpy as np
from gymnasium import spaces

from lava_bridge_mj.checks import REAL_KINDS, check_integer, check_number, check_real_array
from lava_bridge_mj.layout import Layout
from lava_bridge_mj.mjcf import load_model
from lava_bridge_mj.starts import START_NAMES, start_distribution

MAX_EPISODE_STEPS = 500
"""The paper's horizon; `gymnasium.make` adds the TimeLimit."""
RESET_OPTION_KEYS = ("state", "qpos", "qvel", "start")
LAVA, GOAL = 1, 2
"""What a contact with a geom means (0: nothing, e.g. a wall)."""


class LavaBridgeEnv(gymnasium.Env):
    """A point mass in a two-room maze joined by a narrow bridge over lava.

    ## Description
    The ball starts in the left room and must reach the goal disc in the right room. The only way
    across is a bridge 0.3 m wide and 3 m long; everything else between the rooms is lava. A random or
    entropy-driven explorer almost never crosses; a controller that slows down and lines up does.
    The task reproduces "Lava Bridge" from Mehra, Capone and Schneider (2024), *Accelerated Online
    Reinforcement Learning using Auxiliary Start State Distributions*.
    The other tasks of the suite (`lava_bridge_mj.TASKS`: a longer, narrower or bent bridge, two
    crossings, a decoy, low damping, a far start) are this env with another `layout`.

    ## Action Space
    `Box(-1, 1, (2,), float32)`: the force on the ball along x and y, in units of `gear` newtons.
    Out-of-range actions are clipped (MuJoCo's control range); non-finite or misshapen ones raise.

    ## Observation Space
    `Box(4,) float64`: the ball's position (x, y) in metres and velocity (vx, vy) in m/s, which is
    the whole physics state, so `reset(options={"state": obs})` recreates any observed moment.

    ## Rewards
    Sparse: `goal_reward` (+1) on reaching the goal, `lava_reward` (0) on touching lava,
    `step_reward` (0) otherwise. Touching lava ends the episode, which forfeits the goal's +1: that is
    its penalty. A lava reward of -1 or -0.1 (the paper gives no value) made learning from p0 fail on
    most tuning seeds, the policies hiding in the start room (docs/calibration.md).

    ## Starting State
    `options={"start": "p0"}` (the default): a point in one of three small blobs at the left end of
    the start room, at rest. `options={"start": "ood"}`: spots elsewhere in the start room, some beside
    the lava edge, so the bridge must be approached along the pit. `options={"state": s}` or
    `options={"qpos": ..., "qvel": ...}` starts from any valid physics state.

    ## Episode End
    Terminates when the ball's centre comes within `goal_radius` of the goal (success,
    `info["is_success"]`) or its footprint touches a lava pit (`info["lava"]`), checked after every
    physics step, from MuJoCo's contacts. `gymnasium.make` truncates at 500 steps.

    ## Arguments
    `render_mode` (None or "rgb_array"), `width`/`height` of rendered frames (at most the model's
    1920 x 1080 off-screen framebuffer), `render_quality` ("fast": no shadows, reflections or
    anti-aliasing; "high": MuJoCo's defaults), the three rewards (finite numbers), and every field of
    `Layout` (room and bridge sizes, goal, p0 blobs, ood spots, ball, damping, gear, timestep, frame
    skip), e.g. `gymnasium.make("LavaBridge-v0", bridge_width=0.4)`; or a whole `layout=Layout(...)`.

    ## Version History
    - v0: initial release.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        layout: Layout | None = None,
        goal_reward: float = 1.0,
        lava_reward: float = 0.0,
        step_reward: float = 0.0,
        width: int = 960,
        height: int = 400,
        render_quality: str = "fast",
        **layout_fields: Any,
    ):
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode={render_mode!r}; expected None or 'rgb_array'")
        if not isinstance(render_quality, str) or render_quality not in ("fast", "high"):
            raise ValueError(f"render_quality={render_quality!r}; expected 'fast' or 'high'")
        unknown = set(layout_fields) - {f.name for f in dataclasses.fields(Layout)}
        if unknown:
            raise TypeError(f"unknown LavaBridgeEnv arguments {sorted(unknown)}; Layout fields and "
                            "render_mode, layout, goal_reward, lava_reward, step_reward, width, height, "
                            "render_quality are accepted")
        # a reward is returned as given, so a string or NaN here would reach the learner unseen
        self.goal_reward, self.lava_reward, self.step_reward = (
            check_number(name, value, -math.inf, math.inf) for name, value in
            (("goal_reward", goal_reward), ("lava_reward", lava_reward), ("step_reward", step_reward)))
        if layout is not None and not isinstance(layout, Layout):
            raise ValueError(f"layout must be a Layout, got {layout!r}")
        self.layout = dataclasses.replace(layout or Layout(), **layout_fields)
        self.render_mode = render_mode
        self.render_quality = render_quality

        self.model = load_model(self.layout)
        # MuJoCo's off-screen framebuffer bounds a frame (the model's <global offwidth/offheight>); checked
        # here, because the renderer is made at the first render and a size <= 0 aborts the process there
        framebuffer = self.model.vis.global_
        self.width = check_integer("width", width, 1, framebuffer.offwidth)
        self.height = check_integer("height", height, 1, framebuffer.offheight)
        self.data = mujoco.MjData(self.model)
        self._probe = mujoco.MjData(self.model)  # scratch data: validate a state without touching self.data
        self.frame_skip = self.layout.frame_skip
        self.dt = self.layout.control_dt

        geom_id = lambda name: mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, name)  # noqa: E731
        # geom id -> what touching it means, so classifying all contacts is one fancy-index
        self._touch_event = np.zeros(self.model.ngeom, dtype=np.int8)
        self._touch_event[[geom_id(n) for n in self.layout.lava_pits]] = LAVA
        self._touch_event[geom_id("goal")] = GOAL
        self.start_distributions = {name: start_distribution(self.layout, name) for name in START_NAMES}

        hx, hy = self.layout.half_extent
        # Each axis's speed stays below gear / damping: the force's terminal velocity.
        v = self.layout.top_speed
        high = np.array([hx, hy, v, v])
        self.observation_space = spaces.Box(-high, high, dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self._renderer = None

    # --- named physics accessors ---------------------------------------------------------------
    def lava_contact(self, data: mujoco.MjData | None = None) -> bool:
        """True when the ball's footprint touches a lava pit, read from MuJoCo's contacts of `data`."""
        return LAVA in self._touch_events(self.data if data is None else data)

    def goal_contact(self, data: mujoco.MjData | None = None) -> bool:
        """True when the ball's centre is within goal_radius of the goal, read from MuJoCo's contacts."""
        return GOAL in self._touch_events(self.data if data is None else data)

    def _touch_events(self, data: mujoco.MjData) -> np.ndarray:
        return self._touch_event[data.contact.geom].ravel() if data.ncon else self._touch_event[:0]

    def get_state(self) -> np.ndarray:
        """The physics state (x, y, vx, vy): a copy, identical to the observation."""
        return np.concatenate([self.data.qpos, self.data.qvel])

    def set_state(self, qpos: Any, qvel: Any = (0.0, 0.0)) -> None:
        """Put the ball at `qpos` with velocity `qvel`, after checking the state is valid.

        Raises ValueError, leaving the current state untouched, for a misshapen or non-finite state,
        one outside the maze, overlapping a wall or touching lava.
        """
        self._set_checked_state(*self._check_state(qpos, qvel))

    def _set_checked_state(self, qpos: np.ndarray, qvel: np.ndarray, data: mujoco.MjData | None = None) -> None:
        data = self.data if data is None else data
        mujoco.mj_resetData(self.model, data)  # zero time, controls and solver state: deterministic
        data.qpos[:] = qpos
        data.qvel[:] = qvel
        # step() expects position- and velocity-dependent quantities (contacts) to be current
        mujoco.mj_forward(self.model, data)

    def _check_state(self, qpos: Any, qvel: Any) -> tuple[np.ndarray, np.ndarray]:
        qpos = self._as_vector("qpos", qpos)
        qvel = self._as_vector("qvel", qvel)
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

    @staticmethod
    def _as_vector(name: str, value: Any, size: int = 2) -> np.ndarray:
        return check_real_array(name, value, (size,)).astype(np.float64)  # a copy: the caller's array may change

    # --- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        start = self._parse_reset_options(options or {})  # raises before anything changes
        super().reset(seed=seed)
        if isinstance(start, str):  # start distributions only hold valid states (Layout checks its discs)
            state = self.start_distributions[start].sample(self.np_random)
            start = (state[:2], state[2:])
        self._set_checked_state(*start)
        return self.get_state(), {"is_success": False, "lava": False}

    def _parse_reset_options(self, options: dict[str, Any]) -> str | tuple[np.ndarray, np.ndarray]:
        """A start distribution's name, or a checked (qpos, qvel); ValueError for bad options."""
        if not isinstance(options, dict):
            raise ValueError(f"reset options must be a dict, got {type(options).__name__}")
        unknown = set(options) - set(RESET_OPTION_KEYS)
        if unknown:
            raise ValueError(f"unknown reset options {sorted(unknown)}; expected some of {RESET_OPTION_KEYS}")
        given = [k for k in ("state", "qpos", "start") if k in options]
        if len(given) > 1:
            raise ValueError(f"reset options {given} conflict: give one of 'state', 'qpos'(+'qvel'), 'start'")
        if "qvel" in options and "qpos" not in options:
            raise ValueError("reset option 'qvel' needs 'qpos' too")
        if "state" in options:
            state = self._as_vector("state", options["state"], size=4)
            return self._check_state(state[:2], state[2:])
        if "qpos" in options:
            return self._check_state(options["qpos"], options.get("qvel", (0.0, 0.0)))
        name = options.get("start", "p0")
        if not isinstance(name, str) or name not in self.start_distributions:
            raise ValueError(f"unknown start distribution {name!r}; expected one of {START_NAMES}")
        return name

    def step(self, action):
        reward, lava, success = self._advance(self.data, self._checked_action(action))
        info = {"is_success": success, "lava": lava}
        return self.get_state(), reward, lava or success, False, info

    @staticmethod
    def _checked_action(action: Any) -> np.ndarray:
        array = np.asarray(action)
        # the hot path: a dtype-kind test and two scalar tests cost less than check_real_array's
        # np.isfinite, which only runs to word the error
        if (array.dtype.kind in REAL_KINDS and array.shape == (2,)
                and math.isfinite(array[0]) and math.isfinite(array[1])):
            return array
        return check_real_array("action", action, (2,))  # raises, naming what is wrong

    def _advance(self, data: mujoco.MjData, action: np.ndarray) -> tuple[float, bool, bool]:
        """One env step of `data` (frame_skip physics steps) under a checked action: (reward, lava, success).
        The vector env steps each of its MjData through this too, so both share the task's dynamics."""
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

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        self.renderer.update_scene(self.data, camera="top")
        return self.renderer.render()

    @property
    def renderer(self) -> mujoco.Renderer:
        """The off-screen mujoco.Renderer (made on first use), for drawing extras into its scene."""
        if self._renderer is None:
            self._renderer = self._make_renderer()
        return self._renderer

    def _make_renderer(self) -> mujoco.Renderer:
        if self.render_quality == "fast":
            self.model.vis.quality.offsamples = 0  # no multisample anti-aliasing: ~25x faster on Mesa
        renderer = mujoco.Renderer(self.model, height=self.height, width=self.width)
        if self.render_quality == "fast":
            for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION,
                         mujoco.mjtRndFlag.mjRND_SKYBOX):
                renderer.scene.flags[flag] = False
        return renderer

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
