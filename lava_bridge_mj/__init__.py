"""LavaBridge-v0: a MuJoCo hard-exploration benchmark for RL from auxiliary start state distributions.

Importing the package registers `LavaBridge-v0` with gymnasium. Without importing it first,
`gymnasium.make("lava_bridge_mj:LavaBridge-v0")` imports and registers it in one go.
"""

import os

# Off-screen rendering by default on headless machines; must be set before mujoco is imported.
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

import gymnasium  # noqa: E402

from lava_bridge_mj.demos import load_demos  # noqa: E402
from lava_bridge_mj.expert import ScriptedExpert  # noqa: E402
from lava_bridge_mj.layout import Disc, Layout  # noqa: E402
from lava_bridge_mj.lava_bridge import MAX_EPISODE_STEPS, LavaBridgeEnv  # noqa: E402
from lava_bridge_mj.starts import START_NAMES, start_distribution  # noqa: E402
from lava_bridge_mj.vector import LavaBridgeVectorEnv  # noqa: E402

ENV_ID = "LavaBridge-v0"


def register_envs() -> None:
    """Register LavaBridge-v0 (idempotent), with its native vector env for `gymnasium.make_vec`."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(ENV_ID, entry_point="lava_bridge_mj.lava_bridge:LavaBridgeEnv",
                           vector_entry_point="lava_bridge_mj.vector:LavaBridgeVectorEnv",
                           max_episode_steps=MAX_EPISODE_STEPS)


register_envs()

__all__ = ["ENV_ID", "MAX_EPISODE_STEPS", "Disc", "Layout", "LavaBridgeEnv", "LavaBridgeVectorEnv", "START_NAMES",
           "ScriptedExpert", "load_demos", "register_envs", "start_distribution"]
