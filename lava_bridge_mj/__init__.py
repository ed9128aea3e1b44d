"""LavaBridge-v0: a MuJoCo hard-exploration benchmark for RL from auxiliary start state distributions.

Importing the package registers `LavaBridge-v0` and the other tasks of the suite (`TASKS`) with
gymnasium. Without importing it first, `gymnasium.make("lava_bridge_mj:LavaBridge-v0")` imports and
registers them in one go.

`ResetToState(env)` gives any MuJoCo-based Gymnasium env (Gymnasium's MuJoCo envs, Gymnasium-Robotics'
PointMaze, OGBench's cube envs) exact resets to the states it reports (reset_to_state.py);
`record_demos(env, policy, n, seed)` records demonstrations with their states on any such env, which
`train` then trains on (docs/any-env.md). `make_task_env(env_id)` makes one of `EXTERNAL_TASKS`, other
projects' tasks with named starts and an expert (external.py; their projects are optional extras,
imported on first use).

Training from Python: `lava_bridge_mj.train(lava_bridge_mj.RunConfig(method="auxss"), "runs/auxss")`
(eval/training/runner.py) returns the finished run; both load on first use, so importing the package for the
env alone loads no torch.
"""

import os

# Off-screen rendering by default on headless machines; must be set before mujoco is imported.
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

import gymnasium  # noqa: E402

from lava_bridge_mj.demos import candidate_states, load_demos, record_demos, save_demos  # noqa: E402
from lava_bridge_mj.expert import ScriptedExpert  # noqa: E402
from lava_bridge_mj.external import EXTERNAL_TASKS, make_task_env  # noqa: E402
from lava_bridge_mj.layout import Disc, Layout  # noqa: E402
from lava_bridge_mj.lava_bridge import MAX_EPISODE_STEPS, LavaBridgeEnv  # noqa: E402
from lava_bridge_mj.reset_to_state import ResetToState  # noqa: E402
from lava_bridge_mj.starts import START_NAMES, start_distribution  # noqa: E402
from lava_bridge_mj.task_physics import LavaBridgeTask  # noqa: E402
from lava_bridge_mj.tasks import DEFAULT_ENV_ID, SUITE, TASK_DOCS, TASKS, task_layout  # noqa: E402
from lava_bridge_mj.vector import LavaBridgeVectorEnv  # noqa: E402

ENV_ID = DEFAULT_ENV_ID


def register_envs() -> None:
    """Register every task of `TASKS` (idempotent), with its native vector env for `gymnasium.make_vec`.

    LavaBridge-v0 is the default `Layout()` and registers without keyword arguments, as it always
    has; every other task passes `layout=` its Layout (keyword arguments given to `gymnasium.make`
    still override single fields of it, e.g. `gymnasium.make("LavaBridgeNarrow-v0", damping=2.0)`).
    """
    for env_id, layout in TASKS.items():
        if env_id in gymnasium.registry:
            continue
        gymnasium.register(env_id, entry_point="lava_bridge_mj.lava_bridge:LavaBridgeEnv",
                           vector_entry_point="lava_bridge_mj.vector:LavaBridgeVectorEnv",
                           max_episode_steps=MAX_EPISODE_STEPS,
                           kwargs={} if env_id == ENV_ID else {"layout": layout})


register_envs()

__all__ = ["ENV_ID", "MAX_EPISODE_STEPS", "SUITE", "TASKS", "TASK_DOCS", "Disc", "Layout", "LavaBridgeEnv", "LavaBridgeTask",
           "LavaBridgeVectorEnv", "ResetToState", "RunConfig", "START_NAMES", "ScriptedExpert", "candidate_states",
           "load_demos", "EXTERNAL_TASKS", "make_task_env", "record_demos", "register_envs", "save_demos",
           "start_distribution", "task_layout", "train"]


def __getattr__(name: str):
    # the training API loads on first use: an env user's `import lava_bridge_mj` stays light (no torch)
    if name in ("RunConfig", "train"):
        from lava_bridge_mj import eval as training

        return getattr(training, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
