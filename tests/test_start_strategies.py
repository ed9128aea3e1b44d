"""Start-state strategies and StartStateWrapper: hand-computed updates, sampling, persistence, resets."""

import dataclasses
import json
import math
import re

import gymnasium
import numpy as np
import pytest

import lava_bridge_mj  # noqa: F401  (registers LavaBridge-v0)
from lava_bridge_mj.agents.auxss import AuxSS
from lava_bridge_mj.agents.goaldist_ss import GoalDistSS
from lava_bridge_mj.agents.methods import METHODS as METHOD_SPECS
from lava_bridge_mj.agents.omega_ss import OmegaSS, estimate_random_policy_safety
from lava_bridge_mj.agents.start_state_wrapper import StartSelector, StartStateWrapper
from lava_bridge_mj.agents.start_strategies import (
    NO_STATE,
    STRATEGY_NAMES,
    P0Start,
    UniformSS,
    StrategyContext,
    make_start_strategy,
)
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.task_states import TaskStates

# Three states for hand computation: S1 is 0.3 m from S0 in x, S2 differs from S0 only in vy (0.6 m/s).
# With sigma = 0.3 (2 sigma^2 = 0.18): lam(S0, S1) = exp(-0.09 / 0.18) = exp(-0.5),
# lam(S0, S2) = exp(-0.36 / 0.18) = exp(-2), lam(S1, S2) = exp(-(0.09 + 0.36) / 0.18) = exp(-2.5).
THREE_STATES = np.array([[0.0, 0.0, 0.0, 0.0],
                         [0.3, 0.0, 0.0, 0.0],
                         [0.0, 0.0, 0.0, 0.6]])


def chi_square(counts: np.ndarray, probabilities: np.ndarray) -> float:
    expected = counts.sum() * probabilities
    return float(((counts - expected) ** 2 / expected).sum())


# --- AuxSS ------------------------------------------------------------------------------------
def test_auxss_update_matches_hand_computation_with_delta_floor():
    aux = AuxSS(THREE_STATES, horizon=100, delta=0.05, sigma=0.3)
    np.testing.assert_array_equal(aux.weights, [1.0, 1.0, 1.0])

    # episode of 40 steps from S0: W[0] = (100 - 40) / 100 = 0.6, smoothed onto S1 and S2
    aux.update(0, 40)
    w0 = 0.6
    w1 = (1 - math.exp(-0.5)) * 1.0 + math.exp(-0.5) * 0.6
    w2 = (1 - math.exp(-2.0)) * 1.0 + math.exp(-2.0) * 0.6
    np.testing.assert_allclose(aux.weights, [w0, w1, w2], rtol=1e-12)
    np.testing.assert_allclose(aux.weights, [0.6, 0.7573877361, 0.9458658867], rtol=1e-9)

    # a timeout from S1: (100 - 100) / 100 = 0 is floored at delta = 0.05
    aux.update(1, 100)
    w0, w1, w2 = ((1 - math.exp(-0.5)) * w0 + math.exp(-0.5) * 0.05,
                  0.05,
                  (1 - math.exp(-2.5)) * w2 + math.exp(-2.5) * 0.05)
    np.testing.assert_allclose(aux.weights, [w0, w1, w2], rtol=1e-12)
    np.testing.assert_allclose(aux.probabilities, np.array([w0, w1, w2]) / (w0 + w1 + w2), rtol=1e-12)


def test_auxss_position_kernel_ignores_velocity():
    aux = AuxSS(THREE_STATES, horizon=100, delta=0.05, sigma=0.3, kernel_dims=[0, 1])  # LavaBridge's (x, y)
    aux.update(0, 40)
    # S2 sits at S0's position, so lam = 1 and it takes W[0] outright
    np.testing.assert_allclose(aux.weights, [0.6, 1 - 0.4 * math.exp(-0.5), 0.6], rtol=1e-12)


def test_auxss_state_scale_divides_components_before_distance():
    # vy scaled by 2: S2's 0.6 m/s counts as 0.3, so lam(S0, S2) = exp(-0.09 / 0.18) = exp(-0.5)
    aux = AuxSS(THREE_STATES, horizon=100, sigma=0.3, state_scale=(1, 1, 1, 2))
    aux.update(0, 40)
    assert aux.weights[2] == pytest.approx(1 - 0.4 * math.exp(-0.5), rel=1e-12)


def test_auxss_ema_moves_part_way():
    aux = AuxSS(THREE_STATES, horizon=100, delta=0.05, sigma=0.3, ema=0.5)
    aux.update(0, 40)
    w0 = 0.5 * 1.0 + 0.5 * 0.6  # 0.8, not the overwrite's 0.6
    w1 = (1 - math.exp(-0.5)) + math.exp(-0.5) * w0
    np.testing.assert_allclose(aux.weights[:2], [0.8, w1], rtol=1e-12)
    aux.update(0, 40)
    assert aux.weights[0] == pytest.approx(0.5 * 0.8 + 0.5 * 0.6, rel=1e-12)


def test_auxss_count_successes_false_skips_goal_episodes():
    counting = AuxSS(THREE_STATES, horizon=100, sigma=0.3)
    skipping = AuxSS(THREE_STATES, horizon=100, sigma=0.3, count_successes=False)
    counting.update(0, 10, success=True)
    skipping.update(0, 10, success=True)
    assert counting.weights[0] == pytest.approx(0.9)  # the paper: a short success counts like a failure
    np.testing.assert_array_equal(skipping.weights, [1.0, 1.0, 1.0])
    skipping.update(0, 10, success=False)  # lava still counts
    assert skipping.weights[0] == pytest.approx(0.9)


def test_auxss_timeout_weight_scores_timeouts_only():
    paper = AuxSS(THREE_STATES, horizon=100, sigma=0.3)
    variant = AuxSS(THREE_STATES, horizon=100, sigma=0.3, timeout_weight=1.0)
    for aux in (paper, variant):
        aux.update(2, 30)  # lava at step 30: both score (100 - 30) / 100
        assert aux.weights[2] == pytest.approx(0.7)
    paper.update(0, 100)  # a timeout: the paper's formula gives the floor
    variant.update(0, 100)
    assert paper.weights[0] == pytest.approx(0.05)
    assert variant.weights[0] == 1.0
    # the kernel spreads the new W[0] as usual. S1 is sqrt(0.45) from S2 (lam = exp(-2.5)), so the
    # lava episode left W[1] = 1 - 0.3 exp(-2.5); S1 is 0.3 from S0 (lam = exp(-0.5))
    w1, lam = 1 - 0.3 * math.exp(-2.5), math.exp(-0.5)
    assert paper.weights[1] == pytest.approx((1 - lam) * w1 + lam * 0.05)
    assert variant.weights[1] == pytest.approx((1 - lam) * w1 + lam * 1.0)
    variant.update(0, 100, success=True)  # reaching the goal on the last step is no timeout
    assert variant.weights[0] == pytest.approx(0.05)
    half = AuxSS(THREE_STATES, horizon=100, sigma=0.3, timeout_weight=0.5)
    half.update(0, 100)
    assert half.weights[0] == pytest.approx(0.5)


def test_auxss_weights_view_is_read_only_and_live():
    aux = AuxSS(THREE_STATES)
    view = aux.weights
    with pytest.raises(ValueError):
        view[0] = 5.0
    aux.update(0, 250)
    assert view[0] == pytest.approx(0.5)  # (500 - 250) / 500, seen through the old view


def test_auxss_effective_neighbourhood_counts_states_within_half_kernel():
    # lam > 0.5 needs distance < sigma * sqrt(2 ln 2) ~ 0.353: S0-S1 (0.3) yes, S0-S2 (0.6) and S1-S2 no
    aux = AuxSS(THREE_STATES, sigma=0.3)
    np.testing.assert_array_equal(aux.effective_neighbourhood(), [2, 2, 1])
    np.testing.assert_array_equal(aux.effective_neighbourhood(threshold=0.1), [3, 2, 2])  # exp(-2) = 0.135


@pytest.mark.parametrize("params, match", [
    (dict(delta=0.0), "delta"), (dict(delta=1.5), "delta"), (dict(sigma=0.0), "sigma"),
    (dict(sigma=-1.0), "sigma"), (dict(sigma=float("nan")), "sigma"), (dict(horizon=0), "horizon"),
    (dict(ema=0.0), "ema"), (dict(kernel_dims="velocity"), "kernel_dims"),
    (dict(state_scale=(1, 1, 0, 1)), "state_scale"),
    (dict(timeout_weight=1.5), "timeout_weight"), (dict(timeout_weight=0.0), "timeout_weight"),
    (dict(timeout_weight=0.01, delta=0.05), r"timeout_weight must be in \[delta, 1\]"),
    (dict(sigma=float("inf")), "^sigma must be a finite number > 0, got inf$"),
    (dict(delta="0.05"), r"^delta must be a number in \(0, 1\], got '0.05'$"),
    (dict(ema=[0.1]), r"^ema must be a number in \(0, 1\], got \[0.1\]$"),
    (dict(horizon=500.0), r"^horizon must be an integer >= 1, got 500.0$"),
    (dict(state_scale=(1j, 1, 1, 1)), r"^state_scale must be finite real numbers of shape \(4,\)"),
])
def test_auxss_rejects_bad_parameters(params, match):
    with pytest.raises(ValueError, match=match):
        AuxSS(THREE_STATES, **params)


@pytest.mark.parametrize("states, match", [
    (np.zeros((0, 4)), "at least one"), (np.zeros((3, 0)), r"shape \(n, d\)"), (np.zeros(4), r"shape \(n, d\)"),
    (np.array([[0, 0, 0, np.nan]]), "finite"), ("abc", "numbers"),
])
def test_strategies_reject_bad_states(states, match):
    with pytest.raises(ValueError, match=match):
        UniformSS(states)


def test_update_rejects_out_of_range_index():
    with pytest.raises(ValueError, match="out of range"):
        AuxSS(THREE_STATES).update(3, 10)


# --- sampling ---------------------------------------------------------------------------------
def test_sampling_frequencies_follow_weights():
    # omega 0.5, 0.25 and 0 (clamped to 0.05) give weights 2, 4, 20
    omega_ss = OmegaSS(THREE_STATES, omega=[0.5, 0.25, 0.0], clamp=0.05)
    expected = np.array([2.0, 4.0, 20.0]) / 26.0
    np.testing.assert_allclose(omega_ss.probabilities, expected, rtol=1e-12)
    rng = np.random.default_rng(0)
    counts = np.bincount([omega_ss.sample(rng) for _ in range(20_000)], minlength=3)
    assert chi_square(counts, expected) < 16.0  # 2 degrees of freedom: p < 0.0004 to fail by chance


def test_auxss_sampling_follows_updated_weights():
    aux = AuxSS(THREE_STATES, horizon=100, delta=0.05, sigma=0.3)
    aux.update(1, 100)  # S1 drops to delta: rarely sampled afterwards
    rng = np.random.default_rng(1)
    counts = np.bincount([aux.sample(rng) for _ in range(20_000)], minlength=3)
    assert chi_square(counts, aux.probabilities) < 16.0
    assert counts[1] < counts[0] < counts[2]


def test_zero_weight_state_is_never_sampled():
    uniform = UniformSS(THREE_STATES)
    uniform._weights[1] = 0.0
    rng = np.random.default_rng(2)
    assert 1 not in {uniform.sample(rng) for _ in range(2_000)}


# --- OmegaSS ----------------------------------------------------------------------------------
def test_omega_ss_clamp_sets_the_largest_weight():
    # omega 0.5, 0.25, 0: the default floor 0.05 gives weights 2, 4, 20; a floor of 0.4 gives 2, 2.5, 2.5
    np.testing.assert_allclose(OmegaSS(THREE_STATES, omega=[0.5, 0.25, 0.0]).weights, [2.0, 4.0, 20.0], rtol=1e-12)
    np.testing.assert_allclose(OmegaSS(THREE_STATES, omega=[0.5, 0.25, 0.0], clamp=0.4).weights,
                               [2.0, 2.5, 2.5], rtol=1e-12)
    # and with the omega estimated by rollouts: CountdownEnv's first state always fails within k = 4
    states = np.array([[2.0, -1.0, 0, 0], [9.0, -1.0, 0, 0]])
    estimated = make_start_strategy("omega_ss", states, env=CountdownEnv(), rollouts=3, clamp=0.25)
    np.testing.assert_allclose(estimated.weights, [4.0, 1.0], rtol=1e-12)
    assert estimated.settings["clamp"] == 0.25


def test_omega_ss_ranks_a_state_over_lava_above_open_space():
    env = gymnasium.make("LavaBridge-v0")
    states = np.array([[0.0, 0.0, 0.0, 2.0],    # on the bridge, sliding sideways into lava at 2 m/s
                       [-4.5, 0.0, 0.0, 0.0]])  # at rest in the middle of the start room
    omega = estimate_random_policy_safety(env, states, k=4, rollouts=8, seed=0)
    np.testing.assert_array_equal(omega, [0.0, 1.0])
    omega_ss = make_start_strategy("omega_ss", states, env=env, rollouts=8)
    assert omega_ss.probabilities[0] > 0.9  # weights 1 / 0.05 = 20 against 1 / 1 = 1
    np.testing.assert_allclose(omega_ss.probabilities, [20 / 21, 1 / 21], rtol=1e-12)


class CountdownEnv(gymnasium.Env):
    """A fake env: the state's first component is how many steps until termination; success if y > 0.

    Records the options of every reset, so tests can see what the wrapper asked for.
    """

    observation_space = gymnasium.spaces.Box(-100, 100, (4,), dtype=np.float64)
    action_space = gymnasium.spaces.Box(-1, 1, (2,), dtype=np.float32)

    def __init__(self, default_steps: int = 7, truncate_at: int = 1_000):
        self.default_steps, self.truncate_at = default_steps, truncate_at
        self.reset_options = []

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.reset_options.append(options)
        state = (options or {}).get("state", (self.default_steps, 0.0, 0.0, 0.0))
        self.state = np.array(state, dtype=np.float64)
        self.steps = 0
        return self.state.copy(), {}

    def step(self, action):
        self.steps += 1
        terminated = self.steps >= self.state[0]
        success = bool(terminated and self.state[1] > 0)
        return self.state.copy(), float(success), terminated, self.steps >= self.truncate_at, {"is_success": success}


def test_random_policy_safety_counts_lava_but_not_the_goal():
    states = np.array([[2.0, -1.0, 0, 0],   # fails within k = 4 steps
                       [2.0, 1.0, 0, 0],    # reaches the goal within 4 steps: safe
                       [9.0, -1.0, 0, 0]])  # survives 4 steps
    np.testing.assert_array_equal(estimate_random_policy_safety(CountdownEnv(), states, k=4, rollouts=3), [0, 1, 1])
    # with k = 1 the first state survives its only step
    np.testing.assert_array_equal(estimate_random_policy_safety(CountdownEnv(), states, k=1, rollouts=3), [1, 1, 1])


# --- GoalDistSS -------------------------------------------------------------------------------
def test_goaldist_moves_from_goal_heavy_to_near_uniform():
    goal = (4.5, 1.0)
    distances = np.array([0.0, 1.0, 2.0, 4.0])
    states = np.stack([goal[0] - distances, np.full(4, goal[1]), np.zeros(4), np.zeros(4)], axis=1)
    goaldist = GoalDistSS(states, goal=goal, temperature=0.5, temperature_growth=1.5, max_temperature=50.0)
    early = np.exp(-distances / 0.5)
    np.testing.assert_allclose(goaldist.probabilities, early / early.sum(), rtol=1e-12)
    assert goaldist.probabilities[0] > 0.85

    goaldist.update(0, 10)
    goaldist.update(3, 10)
    assert goaldist.temperature == pytest.approx(0.5 * 1.5 * 1.5)
    after_two = np.exp(-distances / 1.125)
    np.testing.assert_allclose(goaldist.probabilities, after_two / after_two.sum(), rtol=1e-12)

    for _ in range(30):  # 0.5 * 1.5**32 is far past the cap
        goaldist.update(1, 10)
    assert goaldist.temperature == 50.0
    late = np.exp(-distances / 50.0)
    np.testing.assert_allclose(goaldist.probabilities, late / late.sum(), rtol=1e-12)
    np.testing.assert_allclose(goaldist.probabilities, 0.25, atol=0.02)


def test_goaldist_temperature_starts_the_schedule_and_max_temperature_ends_it():
    # T = min(2 * 3 ** episodes, 10): 2, 6, then 10 for good; weights exp(-d / T) over d = 0, 1, 3
    distances = np.array([0.0, 1.0, 3.0])
    states = np.stack([-distances, np.zeros(3), np.zeros(3), np.zeros(3)], axis=1)
    goaldist = GoalDistSS(states, goal=(0.0, 0.0), temperature=2.0, temperature_growth=3.0, max_temperature=10.0)
    for temperature in (2.0, 6.0, 10.0, 10.0):
        assert goaldist.temperature == pytest.approx(temperature, rel=1e-12)
        np.testing.assert_allclose(goaldist.weights, np.exp(-distances / temperature), rtol=1e-12)
        goaldist.update(0, 10)
    with pytest.raises(ValueError, match=r"^max_temperature=1.0 must be >= temperature=2.0$"):
        GoalDistSS(states, goal=(0.0, 0.0), temperature=2.0, max_temperature=1.0)


def test_goaldist_budget_schedule_spreads_the_temperature_over_the_training_steps():
    # T = 0.5 * (50 / 0.5) ** min(steps / 1000, 1): 0.5 at 0 steps, 5 at 500, 50 from 1000 on
    distances = np.array([0.0, 1.0, 3.0])
    states = np.stack([-distances, np.zeros(3), np.zeros(3), np.zeros(3)], axis=1)
    goaldist = GoalDistSS(states, goal=(0.0, 0.0), schedule="budget", budget=1000)
    for length, temperature in ((200, 0.5), (300, 0.5 * 100 ** 0.2), (400, 5.0), (600, 0.5 * 100 ** 0.9),
                                (10, 50.0), (None, 50.0)):
        assert goaldist.temperature == pytest.approx(temperature, rel=1e-12)
        np.testing.assert_allclose(goaldist.weights, np.exp(-distances / temperature), rtol=1e-12)
        if length is not None:
            goaldist.update(1, length)
    assert (goaldist.episodes, goaldist.steps) == (5, 1510)
    # the episode count alone does not move it: one long episode is as far as many short ones
    one_long = GoalDistSS(states, goal=(0.0, 0.0), schedule="budget", budget=1000)
    one_long.update(0, 500)
    assert one_long.temperature == pytest.approx(5.0, rel=1e-12)


def test_goaldist_budget_schedule_round_trips_its_step_count():
    states = np.stack([-np.arange(3.0), np.zeros(3), np.zeros(3), np.zeros(3)], axis=1)
    goaldist = GoalDistSS(states, goal=(0.0, 0.0), schedule="budget", budget=100)
    goaldist.update(0, 30)
    goaldist.update(2, 20)
    restored = GoalDistSS(states, goal=(0.0, 0.0), schedule="budget", budget=100)
    restored.load_state_dict(json.loads(json.dumps(goaldist.state_dict())))
    assert (restored.episodes, restored.steps) == (2, 50)
    np.testing.assert_array_equal(restored.weights, goaldist.weights)


@pytest.mark.parametrize("params, message", [
    (dict(schedule="budget"), r"budget= goes with schedule='budget'.*got schedule='budget' and budget=None"),
    (dict(budget=1000), r"budget= goes with schedule='budget'.*got schedule='episodes' and budget=1000"),
    (dict(schedule="steps"), r"^schedule must be one of \('episodes', 'budget'\), got 'steps'$"),
    (dict(schedule="budget", budget=0), r"budget"),
])
def test_goaldist_schedule_and_budget_are_checked(params, message):
    with pytest.raises(ValueError, match=message):
        GoalDistSS(THREE_STATES, goal=(0.0, 0.0), **params)


def test_a_run_supplies_its_steps_as_the_budget_of_goaldist_budget_schedule():
    context = StrategyContext(task=TaskStates(goal=(1.5, 2.0)), budget=2000)
    budget = make_start_strategy("goaldist_ss", THREE_STATES, context, schedule="budget")
    assert budget.budget == 2000 and budget.settings["budget"] == 2000 and budget.settings["schedule"] == "budget"
    assert make_start_strategy("goaldist_ss", THREE_STATES, context, schedule="budget", budget=50).budget == 50
    episodes = make_start_strategy("goaldist_ss", THREE_STATES, context)  # the budget is not the episodes' business
    assert episodes.budget is None and episodes.settings["schedule"] == "episodes"


def test_a_budget_tied_run_cannot_be_extended_to_more_steps(tmp_path):
    from lava_bridge_mj.eval.training.run_files import RunDirectoryError, check_run_directory, write_config

    tied = RunConfig(method="goaldist_ss", steps=2000, strategy={"schedule": "budget"})
    write_config(tmp_path, tied.to_dict())
    assert tied.budget_tied and tied.continues(tied.to_dict())
    longer = dataclasses.replace(tied, steps=4000)
    assert not longer.continues(tied.to_dict())
    with pytest.raises(RunDirectoryError, match=r"the same --steps too: its GoalDist-SS temperature schedule"):
        check_run_directory(longer, tmp_path, resume=True, overwrite=False)
    # the episode schedule, or a budget the config fixes itself, leaves steps free as for every other run
    for strategy in ({}, {"schedule": "budget", "budget": 2000}):
        free = RunConfig(method="goaldist_ss", steps=2000, strategy=strategy)
        assert not free.budget_tied and dataclasses.replace(free, steps=4000).continues(free.to_dict())


# --- persistence ------------------------------------------------------------------------------
STRATEGY_PARAMS = {
    "p0": {},
    "auxss": dict(horizon=100, sigma=0.3),
    "omega_ss": dict(omega=[0.5, 0.25, 0.0]),
    "uniform_ss": {},
    "goaldist_ss": dict(goal=(0.0, 0.0), temperature=0.1, temperature_growth=2.0),
    "reverse_ss": dict(episode_ids=[0, 1, 1], per_demo_buffer_size=1),
    "rfcl_reverse": dict(episode_ids=[0, 1, 1], per_demo_buffer_size=1),
    "rfcl": dict(episode_ids=[0, 1, 1], per_demo_buffer_size=1),
}


@pytest.mark.parametrize("name", STRATEGY_NAMES)
def test_state_dict_round_trips_through_json(name):
    trained = make_start_strategy(name, THREE_STATES, **STRATEGY_PARAMS[name])
    episodes = [(0, 40, False), (1, 100, False), (2, 5, True)] if name != "p0" else [(NO_STATE, 40, False)]
    for index, length, success in episodes:
        trained.update(index, length, success=success)
    restored = make_start_strategy(name, THREE_STATES, **STRATEGY_PARAMS[name])
    restored.load_state_dict(json.loads(json.dumps(trained.state_dict())))

    np.testing.assert_array_equal(restored.weights, trained.weights)
    rng_a, rng_b = np.random.default_rng(3), np.random.default_rng(3)
    assert [restored.sample(rng_a) for _ in range(50)] == [trained.sample(rng_b) for _ in range(50)]
    if name in ("auxss", "goaldist_ss", "reverse_ss", "rfcl_reverse", "rfcl"):  # learning: a fresh one differs
        fresh = make_start_strategy(name, THREE_STATES, **STRATEGY_PARAMS[name])
        assert not np.allclose(fresh.probabilities, trained.probabilities)


def test_load_state_dict_rejects_other_strategies_and_state_sets():
    aux = AuxSS(THREE_STATES)
    with pytest.raises(ValueError, match="goaldist_ss"):
        aux.load_state_dict({"name": "goaldist_ss", "num_states": 3, "weights": [1, 1, 1]})
    with pytest.raises(ValueError, match="5 states"):
        aux.load_state_dict({"name": "auxss", "num_states": 5, "weights": [1, 1, 1]})
    with pytest.raises(ValueError, match="shape"):
        aux.load_state_dict({"name": "auxss", "num_states": 3, "weights": [1, 1]})
    with pytest.raises(ValueError, match=r"auxss state_dict lacks \['weights'\] and has unexpected nothing"):
        aux.load_state_dict({"name": "auxss", "num_states": 3})
    with pytest.raises(ValueError, match="'auxss', not 'uniform_ss'"):
        UniformSS(THREE_STATES).load_state_dict(aux.state_dict())
    with pytest.raises(ValueError, match=r"lacks nothing and has unexpected \['episodes'\].*another version of auxss"):
        aux.load_state_dict({"name": "auxss", "num_states": 3, "weights": [1, 1, 1], "episodes": 2})


# --- make_start_strategy ----------------------------------------------------------------------
def test_make_start_strategy_builds_each_name():
    built = {name: make_start_strategy(name, THREE_STATES, **STRATEGY_PARAMS[name]) for name in STRATEGY_NAMES}
    assert isinstance(built["p0"], P0Start)
    assert isinstance(built["auxss"], AuxSS) and built["auxss"].horizon == 100
    assert isinstance(built["omega_ss"], OmegaSS)
    assert isinstance(built["uniform_ss"], UniformSS)
    assert isinstance(built["goaldist_ss"], GoalDistSS)
    assert built["p0"].sample(np.random.default_rng(0)) == NO_STATE


def test_auxss_defaults_are_documented_values():
    aux = make_start_strategy("auxss", THREE_STATES)
    assert (aux.horizon, aux.delta, aux.sigma, aux.ema, aux.count_successes, aux.kernel_dims, aux.timeout_weight) == \
        (500, 0.05, 0.3, None, True, "full", None)


def test_strategy_settings_fill_in_the_defaults_and_keep_what_was_given():
    settings = make_start_strategy("auxss", THREE_STATES, delta=0.01).settings
    aux = make_start_strategy("auxss", THREE_STATES)
    assert settings == {"horizon": aux.horizon, "delta": 0.01, "sigma": aux.sigma, "state_scale": [1.0, 1.0, 1.0, 1.0],
                        "count_successes": aux.count_successes, "ema": aux.ema, "kernel_dims": aux.kernel_dims,
                        "timeout_weight": aux.timeout_weight}
    goaldist = make_start_strategy("goaldist_ss", THREE_STATES, goal=np.array([1.5, 2.0])).settings
    assert goaldist["goal"] == [1.5, 2.0] and goaldist["temperature_growth"] == GoalDistSS(
        THREE_STATES, goal=(1.5, 2.0)).temperature_growth
    # the rollouts' env and a precomputed omega are objects, not settings
    assert make_start_strategy("omega_ss", THREE_STATES, env=CountdownEnv(), seed=3, rollouts=2).settings == {
        "k": 4, "rollouts": 2, "seed": 3, "clamp": 0.05}
    assert make_start_strategy("omega_ss", THREE_STATES, omega=[1.0, 0.5, 0.0]).settings == {"clamp": 0.05}
    assert make_start_strategy("uniform_ss", THREE_STATES).settings == make_start_strategy("p0").settings == {}
    assert json.loads(json.dumps(settings)) == settings


def test_the_context_fills_only_what_the_parameters_leave_unset():
    context = StrategyContext(probe=CountdownEnv(), task=TaskStates(goal=(1.5, 2.0)), seed=7, horizon=300)
    assert make_start_strategy("auxss", THREE_STATES, context).horizon == 300
    assert make_start_strategy("auxss", THREE_STATES, context, horizon=500).horizon == 500
    assert make_start_strategy("goaldist_ss", THREE_STATES, context).settings["goal"] == [1.5, 2.0]
    assert make_start_strategy("goaldist_ss", THREE_STATES, context, goal=(0, 0)).settings["goal"] == [0, 0]
    omega = make_start_strategy("omega_ss", THREE_STATES, context, rollouts=2)
    assert omega.settings["seed"] == 7 and omega.settings["rollouts"] == 2
    assert make_start_strategy("omega_ss", THREE_STATES, context, omega=[1.0, 0.5, 0.0]).settings == {"clamp": 0.05}
    assert make_start_strategy("uniform_ss", THREE_STATES, context).settings == {}


@pytest.mark.parametrize("name", ["auxss", "goaldist_ss"])
def test_recorded_settings_rebuild_the_same_strategy(name):
    # what provenance.json records is enough to build the strategy again, whatever the defaults become
    given = STRATEGY_PARAMS[name]
    original = make_start_strategy(name, THREE_STATES, **given)
    rebuilt = make_start_strategy(name, THREE_STATES, **original.settings)
    for _ in range(3):
        original.update(0, 40)
        rebuilt.update(0, 40)
    np.testing.assert_array_equal(original.weights, rebuilt.weights)
    assert original.state_dict() == rebuilt.state_dict()


@pytest.mark.parametrize("name, params, match", [
    ("aux_ss", {}, r"'aux_ss'.*'auxss'"),
    ("auxss", dict(sigmaa=0.1), r"sigmaa.*sigma"),
    ("uniform_ss", dict(delta=0.1), "delta"),
    ("omega_ss", {}, "exactly one"),
    ("omega_ss", dict(omega=[1, 1, 1], env="x"), "exactly one"),
    ("omega_ss", dict(omega=[1, 1, 1], rollouts=4), "rollouts"),
    ("omega_ss", dict(omega=[1, 1]), "shape"),
    ("goaldist_ss", {}, "goal"),
    ("goaldist_ss", dict(goal=(0, 0), temperature_growth=0.9), "^temperature_growth must be a finite number >= 1, got 0.9$"),
    ("goaldist_ss", dict(goal=(0, 0), temperature=float("inf")), "^temperature must be a finite number > 0, got inf$"),
    ("goaldist_ss", dict(goal=(1j, 0)), r"^goal must be finite real numbers of shape \(2,\)"),
    ("omega_ss", dict(omega=[object()] * 3), r"^omega must be finite real numbers of shape \(3,\)"),
    ("omega_ss", dict(omega=[1, 1, 1], clamp="0.1"), r"^clamp must be a number in \(0, 1\], got '0.1'$"),
])
def test_make_start_strategy_rejects_bad_names_and_params(name, params, match):
    with pytest.raises(ValueError, match=match):
        make_start_strategy(name, THREE_STATES, **params)


@pytest.mark.parametrize("method", ["auxss", "goaldist_ss", "uniform_ss", "sac"])
def test_a_config_and_the_api_refuse_an_unknown_parameter_with_one_message(method):
    start = METHOD_SPECS[method].start
    with pytest.raises(ValueError) as from_api:
        make_start_strategy(start, THREE_STATES, sigmaa=0.2)
    with pytest.raises(ValueError) as from_config:
        RunConfig.from_dict({"method": method, "strategy": {"sigmaa": 0.2}})
    assert str(from_api.value).startswith(f"unknown parameters ['sigmaa'] for start strategy {start!r}; it accepts")
    assert str(from_config.value) == f"config: {from_api.value}"


def test_a_config_cannot_set_what_the_runner_supplies():
    with pytest.raises(ValueError) as error:
        RunConfig.from_dict({"method": "omega_ss", "strategy": {"env": "LavaBridge-v0"}})
    assert str(error.value) == ("config: unknown parameters ['env'] for start strategy 'omega_ss'; "
                                "it accepts ['omega', 'k', 'rollouts', 'seed', 'clamp']")


def test_a_config_of_an_unknown_method_names_the_method_not_its_strategy_parameters():
    with pytest.raises(ValueError, match=r"^config: unknown method 'auxs'; expected one of"):
        RunConfig.from_dict({"method": "auxs", "strategy": {"sigma": 0.2}})


@pytest.mark.parametrize("method", [["auxss"], {"name": "auxss"}, 3])
def test_a_config_whose_method_is_not_a_name_is_refused_naming_it(method):
    with pytest.raises(ValueError, match=rf"^config: unknown method {re.escape(repr(method))}; expected one of"):
        RunConfig.from_dict({"method": method})


# --- StartStateWrapper ------------------------------------------------------------------------
class RecordingUniform(UniformSS):
    """UniformSS that remembers every update."""

    def __init__(self, states):
        super().__init__(states)
        self.updates = []

    def update(self, index, episode_length, success=False):
        super().update(index, episode_length, success)
        self.updates.append((index, episode_length, success))


def test_wrapper_resets_real_env_to_state_and_reports_lava_episode_length():
    # on the bridge, drifting sideways at 0.5 m/s with no force: damping (1 s time constant) slows it,
    # y = 0.5 (1 - exp(-t)) reaches lava's edge (0.15 - 0.05 radius = 0.1) at t = 0.22 s, in env step 3
    state = np.array([0.0, 0.0, 0.0, 0.5])
    strategy = AuxSS(state[None], horizon=500)
    env = StartStateWrapper(gymnasium.make("LavaBridge-v0"), strategy, seed=0)
    obs, info = env.reset()
    np.testing.assert_array_equal(obs, state)
    assert info["start_index"] == 0
    steps, terminated = 0, False
    while not terminated:
        obs, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        steps += 1
    assert steps == 3 and info["lava"] and reward == env.unwrapped.lava_reward
    assert strategy.weights[0] == pytest.approx((500 - 3) / 500)


def test_auxss_default_horizon_is_the_step_limit_of_every_registered_task():
    horizon = AuxSS(THREE_STATES).horizon
    assert horizon == lava_bridge_mj.MAX_EPISODE_STEPS
    assert {gymnasium.spec(task).max_episode_steps for task in lava_bridge_mj.TASKS} == {horizon}


def test_wrapper_refuses_a_strategy_whose_horizon_differs_from_the_env_limit():
    short = gymnasium.make("LavaBridge-v0", max_episode_steps=200)
    with pytest.raises(ValueError, match=r"^AuxSS horizon=500 differs from the env's max_episode_steps=200; "
                                         r"build it with horizon=200$"):
        StartStateWrapper(short, AuxSS(THREE_STATES))
    with pytest.raises(ValueError, match="horizon=100 differs from the env's max_episode_steps=500"):
        StartSelector(AuxSS(THREE_STATES, horizon=100), max_episode_steps=500)
    StartStateWrapper(short, AuxSS(THREE_STATES, horizon=200))
    StartStateWrapper(short, UniformSS(THREE_STATES))  # no horizon: nothing to agree on
    StartStateWrapper(CountdownEnv(), AuxSS(THREE_STATES, horizon=100))  # no spec, no known limit
    StartSelector(AuxSS(THREE_STATES, horizon=100))


def test_wrapper_reports_each_chosen_episode_once_with_success():
    strategy = RecordingUniform([[3, 1.0, 0, 0], [5, -1.0, 0, 0]])
    fake = CountdownEnv()
    env = StartStateWrapper(fake, strategy, seed=0)
    for _ in range(6):
        obs, info = env.reset()
        np.testing.assert_array_equal(obs, strategy.states[info["start_index"]])
        np.testing.assert_array_equal(fake.reset_options[-1]["state"], obs)
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(np.zeros(2))
            done = terminated or truncated
        env.step(np.zeros(2))  # stepping past the end must not report again
        expected = (0, 3, True) if info["start_index"] == 0 else (1, 5, False)
        assert strategy.updates[-1] == expected
    assert len(strategy.updates) == 6
    assert {u[0] for u in strategy.updates} == {0, 1}


def test_wrapper_reports_truncated_episodes():
    strategy = RecordingUniform([[50, 0.0, 0, 0]])
    env = StartStateWrapper(CountdownEnv(truncate_at=4), strategy)
    env.reset()
    for _ in range(4):
        env.step(np.zeros(2))
    assert strategy.updates == [(0, 4, False)]


def test_wrapper_passes_explicit_options_through_unreported():
    strategy = RecordingUniform([[3, 0.0, 0, 0]])
    fake = CountdownEnv()
    env = StartStateWrapper(fake, strategy)
    options = {"state": np.array([2.0, 0.0, 0.0, 0.0])}
    obs, info = env.reset(options=options)
    assert fake.reset_options[-1] is options and info["start_index"] == NO_STATE
    env.step(np.zeros(2))
    _, _, terminated, _, _ = env.step(np.zeros(2))
    assert terminated and strategy.updates == []


def test_wrapper_p0_uses_the_env_plain_reset():
    fake = CountdownEnv(default_steps=2)
    env = StartStateWrapper(fake, P0Start())
    obs, info = env.reset(seed=1)
    assert fake.reset_options[-1] is None and info["start_index"] == NO_STATE
    assert obs[0] == 2.0


def test_wrapper_seeding_reproduces_start_sequence():
    states = np.arange(40, dtype=np.float64).reshape(10, 4) + 10.0

    def start_indices(seed):
        env = StartStateWrapper(CountdownEnv(), UniformSS(states))
        first = env.reset(seed=seed)[1]["start_index"]
        return [first] + [env.reset()[1]["start_index"] for _ in range(19)]

    assert start_indices(5) == start_indices(5)
    assert start_indices(5) != start_indices(6)


def test_wrapper_treats_empty_options_as_no_options():
    # some vector-env drivers pass options={} on every reset: the strategy still chooses the start
    strategy = RecordingUniform([[3, 0.0, 0, 0]])
    fake = CountdownEnv()
    env = StartStateWrapper(fake, strategy)
    obs, info = env.reset(options={})
    assert info["start_index"] == 0 and obs[0] == 3.0
