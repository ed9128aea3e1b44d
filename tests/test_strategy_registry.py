"""Start strategies on states of any length, the task's declaration of its states (`TaskStates`), and
the registry that declares each strategy once."""

import inspect
import json
import math
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import lava_bridge_mj
from lava_bridge_mj.agents import strategy_registry
from lava_bridge_mj.agents.auxss import AuxSS
from lava_bridge_mj.agents.goaldist_ss import GoalDistSS
from lava_bridge_mj.agents.methods import METHODS
from lava_bridge_mj.agents.rfcl import RFCLReverseSS, RFCLSS, _RFCLStages
from lava_bridge_mj.agents.start_state_wrapper import StartStateWrapper
from lava_bridge_mj.agents.start_strategies import NO_STATE, StartStrategy, StrategyContext
from lava_bridge_mj.agents.strategy_registry import (
    STRATEGIES,
    check_strategy_params,
    make_start_strategy,
    register,
    strategy_parameters,
)
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.task_states import TaskStates, coordinate_spread, task_states_of

DIM = 12
HORIZON = 40


class CorridorEnv(gymnasium.Env):
    """A fake env with a 12-D state that resets to any state: coordinate 0 counts the steps left until
    the episode terminates (whatever the actions), coordinate 1 > 0 makes that end a success, the rest
    only ride along. Its `task_states` declares a goal distance (the steps left) and a position,
    coordinates 2 and 3, that is not the state's first."""

    observation_space = gymnasium.spaces.Box(-np.inf, np.inf, (DIM,), dtype=np.float64)
    action_space = gymnasium.spaces.Box(-1, 1, (3,), dtype=np.float32)
    task_states = TaskStates(position=(2, 3), goal_distance=lambda states: states[:, 0])

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        state = (options or {}).get("state")
        self.state = np.full(DIM, 5.0) if state is None else np.array(state, dtype=np.float64)
        if self.state.shape != (DIM,):
            raise ValueError(f"state must have {DIM} coordinates, got shape {self.state.shape}")
        return self.state.copy(), {}

    def step(self, action):
        self.state[0] -= 1
        self.state[4:7] += action  # the actions move some coordinates, and decide nothing
        terminated = bool(self.state[0] <= 0)
        success = terminated and bool(self.state[1] > 0)
        return self.state.copy(), float(success), terminated, False, {"is_success": success}


def corridor_states(n=9, seed=0):
    """`n` 12-D states, each coordinate on its own scale; steps left 1..n, half of them successes,
    three demo episodes of n // 3 states each in time order (steps left falling)."""
    rng = np.random.default_rng(seed)
    states = rng.normal(size=(n, DIM)) * np.geomspace(0.01, 100.0, DIM)
    states[:, 0] = np.tile(np.arange(n // 3, 0, -1), 3)  # each episode counts down to the goal
    states[:, 1] = np.repeat([1.0, -1.0, 1.0], n // 3)
    return states, np.repeat(np.arange(3), n // 3)


def run_context(env, episode_ids=None):
    return StrategyContext.from_env(env, seed=3, horizon=HORIZON, episode_ids=episode_ids, budget=1_000)


# --- every strategy on states of another length -------------------------------------------------
@pytest.mark.parametrize("name", list(STRATEGIES))
def test_every_strategy_builds_from_12_d_states_and_runs_through_the_wrapper(name):
    states, ids = corridor_states()
    env = CorridorEnv()
    strategy = make_start_strategy(name, states, run_context(env, ids))
    assert strategy.settings == json.loads(json.dumps(strategy.settings))  # recordable as provenance
    wrapped = StartStateWrapper(gymnasium.wrappers.TimeLimit(env, HORIZON), strategy, seed=0)
    reported = []
    original_update = strategy.update
    strategy.update = lambda index, length, success=False: (reported.append((index, length, success)),
                                                             original_update(index, length, success))
    for _ in range(12):
        obs, info = wrapped.reset()
        index = info["start_index"]
        if index == NO_STATE:
            np.testing.assert_array_equal(obs, np.full(DIM, 5.0))  # the env's own reset
        else:
            np.testing.assert_array_equal(obs, states[index])
        done, length = False, 0
        while not done:
            _, _, terminated, truncated, info = wrapped.step(wrapped.action_space.sample())
            done, length = terminated or truncated, length + 1
        if name != "p0":
            steps_left = int(states[index, 0])
            limit = strategy.time_limit(index) or HORIZON
            assert reported[-1] == (index, min(steps_left, limit), steps_left <= limit and states[index, 1] > 0)
    restored = make_start_strategy(name, states, run_context(env, ids))
    restored.load_state_dict(json.loads(json.dumps(strategy.state_dict())))
    np.testing.assert_array_equal(restored.weights, strategy.weights)


def test_auxss_weights_move_on_17_d_states_by_the_generic_kernel():
    # a task that declares no kernel scale: each coordinate divided by its spread over the candidates.
    # Two states: each coordinate's spread is half their difference, so they are 2 scaled units apart
    # on every coordinate, whatever its scale: squared distance 17 * 4, lam = exp(-68 / (2 * 5^2))
    rng = np.random.default_rng(1)
    states = rng.normal(size=(2, 17)) * np.geomspace(0.01, 100.0, 17)
    aux = make_start_strategy("auxss", states, StrategyContext(task=TaskStates()), horizon=100, sigma=5.0)
    np.testing.assert_allclose(aux.settings["state_scale"], np.abs(states[0] - states[1]) / 2, rtol=1e-12)
    np.testing.assert_array_equal(aux.weights, [1.0, 1.0])
    aux.update(0, 30)
    lam = math.exp(-68 / 50)
    np.testing.assert_allclose(aux.weights, [0.7, (1 - lam) + lam * 0.7], rtol=1e-12)  # W[0] = (100 - 30) / 100
    # without a task, the paper's kernel on the raw coordinates: the far state barely moves
    raw = make_start_strategy("auxss", states, horizon=100, sigma=5.0)
    assert raw.settings["state_scale"] == [1.0] * 17
    raw.update(0, 30)
    far = math.exp(-((states[0] - states[1]) ** 2).sum() / 50)
    np.testing.assert_allclose(raw.weights, [0.7, (1 - far) + far * 0.7], rtol=1e-12)


def test_the_spread_of_a_constant_coordinate_is_one():
    np.testing.assert_array_equal(coordinate_spread([[1.0, 2.0, 5.0], [3.0, 2.0, 5.0]]), [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(coordinate_spread([[1.0, 2.0], [5.0, 2.0]]), [2.0, 1.0])


def test_auxss_position_kernel_measures_the_task_position_coordinates():
    states, _ = corridor_states()
    env = CorridorEnv()
    aux = make_start_strategy("auxss", states, run_context(env), kernel_dims="position", state_scale=[1.0] * DIM)
    assert aux.settings["kernel_dims"] == [2, 3]  # what the run used, recorded
    aux.update(0, 10)
    distance = ((states[:, 2:4] - states[0, 2:4]) ** 2).sum(axis=1)
    lam = np.exp(-distance / (2 * 0.3**2))
    np.testing.assert_allclose(aux.weights, (1 - lam) + lam * 0.75, rtol=1e-12)  # W[0] = (40 - 10) / 40
    with pytest.raises(ValueError, match=r"kernel_dims='position'.*declares none \(TaskStates.position\)"):
        make_start_strategy("auxss", states, StrategyContext(task=TaskStates()), kernel_dims="position")
    with pytest.raises(ValueError, match=r"^kernel_dims must be a non-empty list of distinct coordinate indices "
                                         r">= 0 below the state's 12 coordinates, got \[2, 12\]$"):
        AuxSS(states, kernel_dims=[2, 12])


def test_goaldist_weights_follow_a_supplied_distance_function():
    states, _ = corridor_states()
    goaldist = make_start_strategy("goaldist_ss", states, run_context(CorridorEnv()), temperature=2.0,
                                   temperature_growth=1.5)
    # the distance is the steps left: 3, 2, 1 in each episode, the nearest at 1
    excess = states[:, 0] - 1.0
    np.testing.assert_allclose(goaldist.weights, np.exp(-excess / 2.0), rtol=1e-12)
    np.testing.assert_allclose(goaldist.weights[:3], [math.exp(-1.0), math.exp(-0.5), 1.0], rtol=1e-12)
    goaldist.update(0, 3)
    np.testing.assert_allclose(goaldist.weights, np.exp(-excess / 3.0), rtol=1e-12)
    assert "goal_distance" not in goaldist.settings and goaldist.settings["goal"] is None


def test_goaldist_on_a_task_without_a_goal_names_what_is_missing():
    states, _ = corridor_states()
    with pytest.raises(ValueError, match=r"the task declares none: give its TaskStates a goal_distance .* or a goal"):
        make_start_strategy("goaldist_ss", states, StrategyContext.from_env(gymnasium.make("CartPole-v1"), 0, 500))
    with pytest.raises(ValueError, match=r"^goal_distance must return one finite distance per state, shape \(9,\)"):
        GoalDistSS(states, goal_distance=lambda s: s[:, :2])
    with pytest.raises(ValueError, match="exactly one of goal= .* or goal_distance=.*got both"):
        GoalDistSS(states, goal=(0.0,), goal_distance=lambda s: s[:, 0])


def test_omega_ss_rolls_out_in_the_run_env_on_12_d_states():
    states, _ = corridor_states()
    # k = 2 random actions: states with 1 or 2 steps left terminate; a failure unless coordinate 1 > 0
    omega = make_start_strategy("omega_ss", states, run_context(CorridorEnv()), k=2, rollouts=3)
    fails = (states[:, 0] <= 2) & (states[:, 1] < 0)
    np.testing.assert_array_equal(omega.omega, np.where(fails, 0.0, 1.0))
    np.testing.assert_allclose(omega.weights, np.where(fails, 20.0, 1.0), rtol=1e-12)


def test_reverse_curriculum_checks_forward_states_against_the_state_length():
    states, ids = corridor_states()
    make_start_strategy("reverse_ss", states, episode_ids=ids, forward_states=np.zeros((2, DIM)))
    with pytest.raises(ValueError, match=r"^forward_states must be a \(k, 12\) array .* got shape \(3, 4\)$"):
        make_start_strategy("reverse_ss", states, episode_ids=ids, forward_states=np.zeros((3, 4)))


# --- what the task declares --------------------------------------------------------------------
def test_lava_bridge_declares_the_choices_its_runs_always_made():
    env = gymnasium.make("LavaBridgeFarStart-v0")
    goal = tuple(env.unwrapped.layout.goal)
    declared = task_states_of(env)  # found through gymnasium.make's wrappers
    assert declared == TaskStates(position=(0, 1), goal=goal, kernel_scale=(1.0, 1.0, 1.0, 1.0))
    states = lava_bridge_mj.load_demos(500)["observations"][:50]
    context = StrategyContext.from_env(env, seed=0, horizon=500)
    aux = make_start_strategy("auxss", states, context, kernel_dims="position")
    assert aux.settings["state_scale"] == [1.0, 1.0, 1.0, 1.0] and aux.settings["kernel_dims"] == [0, 1]
    goaldist = make_start_strategy("goaldist_ss", states, context)
    assert goaldist.settings["goal"] == list(goal)
    np.testing.assert_array_equal(goaldist.weights, GoalDistSS(states, goal=goal).weights)
    distance = np.hypot(states[:, 0] - goal[0], states[:, 1] - goal[1])  # from (x, y), the leading coordinates
    np.testing.assert_allclose(goaldist.weights, np.exp(-(distance - distance.min()) / 0.5), rtol=1e-12)


@pytest.mark.parametrize("fields, match", [
    (dict(goal=(1.0, 2.0), position=(2, 3)), r"first 2 coordinates \(0, 1\), but position is \(2, 3\)"),
    (dict(goal=(1.0,), goal_distance=abs), "not both"),
    (dict(goal_distance=3.0), "goal_distance must be a function"),
    (dict(position=(0, 0)), "distinct coordinate indices"),
    (dict(kernel_scale=(1.0, 0.0)), "kernel_scale must be positive"),
    (dict(goal=()), "at least one coordinate"),
])
def test_a_bad_declaration_is_refused_naming_the_field(fields, match):
    with pytest.raises(ValueError, match=match):
        TaskStates(**fields)


def test_a_declared_kernel_scale_must_fit_the_states():
    states, _ = corridor_states()
    with pytest.raises(ValueError, match="the task's kernel_scale has 4 numbers, but its states have 12 coordinates"):
        make_start_strategy("auxss", states, StrategyContext(task=TaskStates(kernel_scale=(1, 1, 1, 1))))


# --- the registry ------------------------------------------------------------------------------
def test_the_registry_lists_exactly_the_strategies_the_cli_accepts():
    choices = next(a for a in cli.build_parser()._actions if a.dest == "method").choices
    sac_from = {method.start: name for name, method in METHODS.items()
                if method.learner == "sac" and method.demos == "none"}
    assert set(sac_from) == set(STRATEGIES) == {method.start for method in METHODS.values()}
    assert all(sac_from[name] in choices for name in STRATEGIES)
    assert strategy_registry.STRATEGY_NAMES == tuple(STRATEGIES)  # nothing registered but on import


@pytest.mark.parametrize("name", list(STRATEGIES))
def test_every_parameter_is_declared_once_with_its_doc(name):
    parameters = strategy_parameters(name)
    assert [p.name for p in parameters] == list(STRATEGIES[name].parameters())
    for parameter in parameters:
        assert parameter.doc, f"{name}'s parameter {parameter.name} is not documented under Args"
    # a config may set exactly the parameters that are not only the code's to give
    settable = [p.name for p in parameters if p.from_config]
    check_strategy_params(name, settable, from_config=True)
    for parameter in parameters:
        if not parameter.from_config:
            with pytest.raises(ValueError, match=rf"unknown parameters \['{parameter.name}'\]"):
                RunConfig.from_dict({"method": "sac" if name == "p0" else name,
                                     "strategy": {parameter.name: None}})


class ToySS(StartStrategy):
    """A toy strategy: the first state `first_weight` times as likely as each other one.

    Args:
        states: (n, d) candidate start states.
        first_weight: the first state's weight, > 0; every other state's is 1.
    """

    name = "toy_ss"
    description = "the first state weighted"

    def __init__(self, states, first_weight=2.0):
        super().__init__(states)
        self.first_weight = first_weight
        self._weights[0] = first_weight


def test_a_new_strategy_is_one_class_and_one_registration(monkeypatch):
    monkeypatch.setattr(strategy_registry, "STRATEGIES", dict(STRATEGIES))  # the registration ends with the test
    assert register(ToySS) is ToySS
    states, _ = corridor_states()
    toy = make_start_strategy("toy_ss", states, run_context(CorridorEnv()), first_weight=4.0)
    assert isinstance(toy, ToySS) and toy.settings == {"first_weight": 4.0}
    np.testing.assert_allclose(toy.probabilities, np.r_[4.0, np.ones(8)] / 12.0, rtol=1e-12)
    assert make_start_strategy("toy_ss", states).settings == {"first_weight": 2.0}
    assert [(p.name, p.default) for p in strategy_parameters("toy_ss")] == [("first_weight", 2.0)]
    with pytest.raises(ValueError, match=r"unknown parameters \['first'\] for start strategy 'toy_ss'; "
                                         r"it accepts \['first_weight'\]"):
        make_start_strategy("toy_ss", states, first=4.0)
    with pytest.raises(ValueError, match="'toy_ss' is already registered"):
        register(ToySS)


class ToyChildSS(ToySS):
    """The toy strategy with a second weighted state: it documents only the parameters it adds or
    explains anew.

    Args:
        second_weight: the second state's weight, > 0.
        states: (n, d) candidate start states, at least two.
    """

    name = "toy_child_ss"

    def __init__(self, states, first_weight=3.0, second_weight=2.0):
        super().__init__(states, first_weight)
        self._weights[1] = second_weight


def test_a_subclass_documents_only_what_it_adds_and_inherits_the_rest(monkeypatch):
    monkeypatch.setattr(strategy_registry, "STRATEGIES", dict(STRATEGIES))
    register(ToyChildSS)
    docs = {p.name: (p.default, p.doc) for p in strategy_parameters("toy_child_ss")}
    # first_weight: the parent's entry with the child's default; second_weight: the child's own
    assert docs == {"first_weight": (3.0, "the first state's weight, > 0; every other state's is 1."),
                    "second_weight": (2.0, "the second state's weight, > 0.")}
    assert strategy_registry._documented_args(ToyChildSS)["states"] == "(n, d) candidate start states, at least two."
    assert strategy_registry._documented_args(ToySS)["states"] == "(n, d) candidate start states."


def test_the_rfcl_strategies_share_one_documentation_of_their_common_parameters():
    reverse, full = ({p.name: p.doc for p in strategy_parameters(name)} for name in ("rfcl_reverse", "rfcl"))
    assert set(reverse) < set(full) and all(full[name] == doc for name, doc in reverse.items())
    assert reverse["per_demo_buffer_size"].startswith("m, the outcomes a demonstration remembers from its t_i (3")
    # written once, on the class both inherit from, and not on either of them
    assert "per_demo_buffer_size:" in _RFCLStages.__doc__
    assert "per_demo_buffer_size:" not in RFCLReverseSS.__doc__ and "per_demo_buffer_size:" not in RFCLSS.__doc__
    assert "forward_seeds:" in RFCLSS.__doc__


@pytest.mark.parametrize("attributes, match", [
    (dict(name="Toy SS"), "name must be lower-case"),
    (dict(name="auxss"), "'auxss' is already registered"),
    (dict(description=""), "description must say"),
    (dict(candidates="all"), "candidates must be one of"),
])
def test_a_registration_is_checked(monkeypatch, attributes, match):
    monkeypatch.setattr(strategy_registry, "STRATEGIES", dict(STRATEGIES))
    with pytest.raises(ValueError, match=match):
        register(type("Bad", (ToySS,), attributes))
    with pytest.raises(ValueError, match="must be a StartStrategy subclass"):
        register(object)


def test_the_design_doc_shows_adding_a_strategy_with_the_files_it_touches():
    registry_doc = inspect.getdoc(strategy_registry)
    assert "files touched: agents/my_ss.py, new, and this file" in registry_doc
    text = (Path(__file__).resolve().parent.parent / "docs" / "design.md").read_text()
    assert "agents/strategy_registry.py" in text and "Adding a start strategy" in text
