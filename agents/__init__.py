"""Agents: SAC, start-state strategies and the wrapper that plugs them into any resettable env.

The start strategies take states of any length; what a task's coordinates mean comes from its
`TaskStates` (lava_bridge_mj/task_states.py). Each strategy is registered once by name
(agents/strategy_registry.py, which shows how to add one).

The learners (`SAC`, `ReplayBuffer`) load torch, so they are imported on first use: the
configurations and start strategies stay light. `VecStartStateWrapper` (one strategy for all
sub-envs of a Stable-Baselines3 VecEnv) loads stable-baselines3, on first use too."""

from lava_bridge_mj.agents.auxss import AuxSS
from lava_bridge_mj.agents.configs import SACConfig
from lava_bridge_mj.agents.goaldist_ss import GoalDistSS
from lava_bridge_mj.agents.omega_ss import OmegaSS, estimate_random_policy_safety
from lava_bridge_mj.agents.reverse_curriculum import ReverseCurriculumSS, goal_reaching_demos
from lava_bridge_mj.agents.rfcl import RFCLReverseSS, RFCLSS
from lava_bridge_mj.agents.start_state_wrapper import StartStateWrapper
from lava_bridge_mj.agents.start_strategies import NO_STATE, P0Start, StartStrategy, StrategyContext, UniformSS
from lava_bridge_mj.agents.strategy_registry import (
    STRATEGIES,
    STRATEGY_NAMES,
    check_strategy_params,
    make_start_strategy,
    register,
    strategy_parameters,
)
from lava_bridge_mj.task_states import TaskStates, coordinate_spread, task_states_of

__all__ = ["NO_STATE", "STRATEGIES", "STRATEGY_NAMES", "SAC", "AuxSS", "GoalDistSS", "OmegaSS", "P0Start",
           "RFCLReverseSS", "RFCLSS", "ReplayBuffer", "ReverseCurriculumSS", "SACConfig", "StartStateWrapper",
           "StartStrategy", "StrategyContext", "TaskStates", "UniformSS", "VecStartStateWrapper", "check_strategy_params",
           "coordinate_spread", "estimate_random_policy_safety", "goal_reaching_demos", "make_start_strategy", "register",
           "strategy_parameters", "task_states_of"]


def __getattr__(name: str):
    if name == "SAC":
        from lava_bridge_mj.agents.sac import SAC

        return SAC
    if name == "ReplayBuffer":
        from lava_bridge_mj.agents.replay_buffer import ReplayBuffer

        return ReplayBuffer
    if name == "VecStartStateWrapper":
        from lava_bridge_mj.agents.vec_start_state_wrapper import VecStartStateWrapper

        return VecStartStateWrapper
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
