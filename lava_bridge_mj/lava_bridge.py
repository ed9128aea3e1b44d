"""LavaBridge-v0: a point mass must cross a narrow bridge between lava pits to reach a goal."""

from __future__ import annotations

import atexit
import dataclasses
import weakref
from typing import Any, NamedTuple

import gymnasium
import mujoco
import numpy as np

from lava_bridge_mj.checks import check_integer
from lava_bridge_mj.layout import Layout
from lava_bridge_mj.task_physics import LavaBridgeTask, as_vector

MAX_EPISODE_STEPS = 500
"""The paper's horizon; `gymnasium.make` adds the TimeLimit."""
RESET_OPTION_KEYS = ("state", "qpos", "qvel", "start")
WRAPPER_RESET_OPTION_KEYS = ("minari_autoseed",)
"""Reset options that wrappers read and pass on (minari.DataCollector's seeding switch): accepted, ignored."""
RENDER_MODES = ("rgb_array",)


def _from_task(name: str, doc: str) -> property:
    """A read-only property of the env that is its task's attribute `name`."""
    return property(lambda self: getattr(self.task, name), doc=doc)


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
    its penalty (docs/calibration.md gives the reason for these defaults).

    ## Starting State
    `options={"start": "p0"}` (the default): a point in one of three small blobs at the left end of
    the start room, at rest. `options={"start": "ood"}`: spots elsewhere in the start room, some beside
    the lava edge, so the bridge must be approached along the pit. `options={"state": s}` or
    `options={"qpos": ..., "qvel": ...}` starts from any valid physics state. Any other option is
    refused, except `minari_autoseed`, which `minari.DataCollector` reads and passes on; it is ignored.

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

    ## Attributes
    `task`: the `LavaBridgeTask` (model, rewards, state checks, dynamics, start distributions) that
    this env drives its `data` (a `mujoco.MjData`) with; `model`, `layout`, `frame_skip`, `dt`, the
    rewards, `start_distributions` and `task_states` (its declaration for the start strategies) are
    the task's.

    ## Version History
    - v0: initial release.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 10}

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
        arguments = check_env_arguments(render_mode, layout=layout, goal_reward=goal_reward, lava_reward=lava_reward,
                                        step_reward=step_reward, width=width, height=height,
                                        render_quality=render_quality, **layout_fields)
        # the model, rewards, state checks, dynamics and start distributions, shared with the vector env
        self.task = arguments.task
        self.render_mode = arguments.render_mode
        self.render_quality = arguments.render_quality
        self.width, self.height = arguments.width, arguments.height
        self.data = mujoco.MjData(self.model)
        self.observation_space = self.task.observation_space
        self.action_space = self.task.action_space
        self._renderer = None

    # --- the task's parts, read from it (read-only: the task is shared with the vector env) ------
    layout = _from_task("layout", "The geometry and physics this env was built from (a Layout).")
    model = _from_task("model", "The compiled MjModel (the task's).")
    frame_skip = _from_task("frame_skip", "Physics steps per env step.")
    dt = _from_task("dt", "Seconds of simulated time per env step.")
    goal_reward = _from_task("goal_reward", "The reward on reaching the goal.")
    lava_reward = _from_task("lava_reward", "The reward on touching lava.")
    step_reward = _from_task("step_reward", "The reward on every other step.")
    start_distributions = _from_task("start_distributions", "Start distribution by name ('p0', 'ood').")
    task_states = _from_task("task_states", "What the start strategies need to know about its states (a "
                                            "TaskStates): position (x, y), the goal, AuxSS's kernel scale.")

    # --- named physics accessors ---------------------------------------------------------------
    def lava_contact(self, data: mujoco.MjData | None = None) -> bool:
        """True when the ball's footprint touches a lava pit, read from MuJoCo's contacts of `data`."""
        return self.task.lava_contact(self.data if data is None else data)

    def goal_contact(self, data: mujoco.MjData | None = None) -> bool:
        """True when the ball's centre is within goal_radius of the goal, read from MuJoCo's contacts."""
        return self.task.goal_contact(self.data if data is None else data)

    def get_state(self) -> np.ndarray:
        """The physics state (x, y, vx, vy): a copy, identical to the observation."""
        return self.task.observation(self.data)

    def set_state(self, qpos: Any, qvel: Any = (0.0, 0.0)) -> None:
        """Put the ball at `qpos` with velocity `qvel`, after checking the state is valid.

        Raises ValueError, leaving the current state untouched, for a misshapen or non-finite state,
        one outside the maze, overlapping a wall or touching lava.
        """
        self.task.set_state(self.data, *self.task.check_state(qpos, qvel))

    # --- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        start = self._parse_reset_options(options or {})  # raises before anything changes
        super().reset(seed=seed)
        if isinstance(start, str):
            start = self.task.sample_start(start, self.np_random)
        self.task.set_state(self.data, *start)
        return self.get_state(), {"is_success": False, "lava": False}

    def _parse_reset_options(self, options: dict[str, Any]) -> str | tuple[np.ndarray, np.ndarray]:
        """A start distribution's name, or a checked (qpos, qvel); ValueError for bad options."""
        if not isinstance(options, dict):
            raise ValueError(f"reset options must be a dict, got {type(options).__name__}")
        unknown = set(options) - set(RESET_OPTION_KEYS) - set(WRAPPER_RESET_OPTION_KEYS)
        if unknown:
            raise ValueError(f"unknown reset options {sorted(unknown)}; expected some of {RESET_OPTION_KEYS}")
        given = [k for k in ("state", "qpos", "start") if k in options]
        if len(given) > 1:
            raise ValueError(f"reset options {given} conflict: give one of 'state', 'qpos'(+'qvel'), 'start'")
        if "qvel" in options and "qpos" not in options:
            raise ValueError("reset option 'qvel' needs 'qpos' too")
        if "state" in options:
            state = as_vector("state", options["state"], size=4)
            return self.task.check_state(state[:2], state[2:])
        if "qpos" in options:
            return self.task.check_state(options["qpos"], options.get("qvel", (0.0, 0.0)))
        return self.task.check_start_name(options.get("start", "p0"))

    def step(self, action):
        task = self.task
        reward, lava, success = task.step(self.data, task.check_action(action))
        info = {"is_success": success, "lava": lava}
        return task.observation(self.data), reward, lava or success, False, info

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
        close_renderers_at_exit(self)
        if self.render_quality == "fast":
            for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION,
                         mujoco.mjtRndFlag.mjRND_SKYBOX):
                renderer.scene.flags[flag] = False
        return renderer

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


_ENVS_WITH_RENDERERS: weakref.WeakSet[LavaBridgeEnv] = weakref.WeakSet()


def close_renderers_at_exit(env: LavaBridgeEnv) -> None:
    """Have `env`'s renderer closed at interpreter exit, while its GL display is still open.

    The first renderer of a process registers EGL's display shutdown with atexit; a renderer still
    open after it fails in its destructor and prints EGL tracebacks. Exit hooks run last-registered
    first, so the hook is moved to the end at every new renderer and runs before that shutdown.
    """
    _ENVS_WITH_RENDERERS.add(env)
    atexit.unregister(_close_renderers)
    atexit.register(_close_renderers)


def _close_renderers() -> None:
    for env in list(_ENVS_WITH_RENDERERS):
        env.close()


class EnvArguments(NamedTuple):
    """LavaBridgeEnv's arguments, checked: the task they define and the rendering settings."""

    task: LavaBridgeTask
    render_mode: str | None
    width: int
    height: int
    render_quality: str


def check_env_arguments(
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
) -> EnvArguments:
    """LavaBridgeEnv's arguments checked and the task built from them; ValueError (TypeError for an
    unknown argument) naming the first bad one. The vector env takes the same arguments through here."""
    if render_mode not in (None, *RENDER_MODES):
        raise ValueError(f"render_mode={render_mode!r}; expected None or 'rgb_array'")
    if not isinstance(render_quality, str) or render_quality not in ("fast", "high"):
        raise ValueError(f"render_quality={render_quality!r}; expected 'fast' or 'high'")
    unknown = set(layout_fields) - {f.name for f in dataclasses.fields(Layout)}
    if unknown:
        raise TypeError(f"unknown LavaBridgeEnv arguments {sorted(unknown)}; Layout fields and "
                        "render_mode, layout, goal_reward, lava_reward, step_reward, width, height, "
                        "render_quality are accepted")
    if layout is not None and not isinstance(layout, Layout):
        raise ValueError(f"layout must be a Layout, got {layout!r}")
    task = LavaBridgeTask(dataclasses.replace(layout or Layout(), **layout_fields), goal_reward=goal_reward,
                          lava_reward=lava_reward, step_reward=step_reward)
    # MuJoCo's off-screen framebuffer bounds a frame (the model's <global offwidth/offheight>); checked
    # here, because the renderer is made at the first render and a size <= 0 aborts the process there
    framebuffer = task.model.vis.global_
    return EnvArguments(task, render_mode, check_integer("width", width, 1, framebuffer.offwidth),
                        check_integer("height", height, 1, framebuffer.offheight), render_quality)
