"""RFCL's reverse curriculum (ReverseCurriculumSS): hand-computed sequences, the shortened time limit
through StartStateWrapper, persistence, SB3, bad parameters."""

import json

import gymnasium
import numpy as np
import pytest

import lava_bridge_mj
from lava_bridge_mj.agents import ReverseCurriculumSS, StartStateWrapper, goal_reaching_demos, make_start_strategy
from lava_bridge_mj.agents.reverse_curriculum import forward_scores, rank_weights
from lava_bridge_mj.agents.start_state_wrapper import StartSelector
from lava_bridge_mj.agents.start_strategies import NO_STATE

# Two demonstrations: A with 4 states (indices 0-3), B with 3 (indices 4-6). Row i is (i, 0, 0, 0).
STATES = np.stack([np.arange(7.0), np.zeros(7), np.zeros(7), np.zeros(7)], axis=1)
EPISODE_IDS = np.array([0, 0, 0, 0, 1, 1, 1])
A_LAST, B_LAST = 3, 6
P0_STATES = np.array([[10.0, 0, 0, 0], [11.0, 0, 0, 0], [12.0, 0, 0, 0]])  # indices 7-9 with forward_states


def curriculum(**params):
    return ReverseCurriculumSS(STATES, EPISODE_IDS, **params)


def outcomes(strategy):
    return strategy.state_dict()["outcomes"]


# --- the curriculum ---------------------------------------------------------------------------
def test_each_demonstration_starts_at_its_last_state_and_demos_are_equally_likely():
    rc = curriculum()
    np.testing.assert_array_equal(rc.demo_lengths, [4, 3])
    np.testing.assert_array_equal(rc.start_steps, [3, 2])
    np.testing.assert_array_equal(rc.weights, [0, 0, 0, 1, 0, 0, 1])
    np.testing.assert_array_equal(rc.probabilities, [0, 0, 0, 0.5, 0, 0, 0.5])
    rng = np.random.default_rng(0)
    counts = np.bincount([rc.sample(rng) for _ in range(4000)], minlength=7)
    assert set(np.flatnonzero(counts)) == {A_LAST, B_LAST}
    assert abs(counts[A_LAST] / 4000 - 0.5) < 0.03  # 4 standard deviations


def test_the_index_moves_only_after_m_successes_in_a_row_and_the_buffer_is_cleared():
    rc = curriculum(per_demo_buffer_size=3)
    for success, t_a, buffer in [(True, 3, [True]), (True, 3, [True, True]), (False, 3, [True, True, False]),
                                 (True, 3, [True, False, True]), (True, 3, [False, True, True]),
                                 (True, 2, [])]:  # three successes in a row: t_A moves one state back
        rc.update(A_LAST, 5, success=success)
        assert rc.start_steps[0] == t_a and outcomes(rc)[0] == buffer
    np.testing.assert_array_equal(rc.weights, [0, 0, 1, 0, 0, 0, 1])  # A now starts from index 2
    assert rc.start_steps[1] == 2 and outcomes(rc)[1] == []  # B is untouched


def test_demonstrations_advance_independently_and_stale_starts_do_not_count():
    rc = curriculum(per_demo_buffer_size=2)
    rc.update(B_LAST, 4, success=True)
    rc.update(A_LAST, 4, success=True)
    rc.update(B_LAST, 4, success=True)  # B's second success: B moves, A keeps its one success
    np.testing.assert_array_equal(rc.start_steps, [3, 1])
    assert outcomes(rc) == [[True], []]
    rc.update(B_LAST, 4, success=True)  # an episode from B's old t_i, finished after it moved
    rc.update(4, 4, success=True)  # and one from a state B has not reached
    assert outcomes(rc) == [[True], []]
    rc.update(5, 4, success=False)  # from B's new t_i: counts
    assert outcomes(rc) == [[True], [False]]


def test_the_index_never_goes_past_zero_and_zero_needs_m_more_successes_to_be_solved():
    rc = curriculum(per_demo_buffer_size=1, reverse_step_size=2)
    rc.update(A_LAST, 1, success=True)
    assert rc.start_steps[0] == 1
    rc.update(1, 1, success=True)
    assert rc.start_steps[0] == 0 and not rc.solved[0]  # max(1 - 2, 0)
    rc.update(0, 1, success=True)
    assert rc.start_steps[0] == 0 and rc.solved[0] and rc.phase == "reverse"
    rc.update(0, 1, success=False)  # a solved demonstration records nothing more
    assert outcomes(rc)[0] == []
    np.testing.assert_array_equal(rc.weights, [1, 0, 0, 0, 0, 0, 1])  # still drawn, from its first state


def test_once_every_demonstration_is_solved_episodes_start_from_p0():
    rc = curriculum(per_demo_buffer_size=1, reverse_step_size=5)
    for index in (A_LAST, 0, B_LAST, 4):
        assert rc.phase == "reverse"
        rc.update(index, 3, success=True)
    assert rc.phase == "p0" and rc.solved.all()
    np.testing.assert_array_equal(rc.weights, np.zeros(7))
    np.testing.assert_array_equal(rc.probabilities, np.zeros(7))
    assert rc.sample(np.random.default_rng(0)) == NO_STATE
    assert rc.time_limit(NO_STATE) is None
    rc.update(NO_STATE, 40, success=False)  # a p0 episode changes nothing
    rc.update(0, 5, success=True)  # nor one that started before the switch
    assert rc.phase == "p0"


def solve_every_demonstration(rc):
    for index in (A_LAST, 0, B_LAST, 4):  # with m = 1 and a step of 5: one success moves t_i to 0
        rc.update(index, 3, success=True)
    assert rc.solved.all()


def test_forward_curriculum_scores_and_ranks_p0_states_by_hand():
    assert forward_scores([[True], [], [True] * 4, [True, True, True, False], [False] * 5]).tolist() == [3, 2, 1, 3, 2]
    # ties share a rank; c values at or above a value give it rank c + 1 (RFCL's "rankmin")
    np.testing.assert_allclose(rank_weights(np.array([3.0, 2.0, 1.0]), 0.1),
                               np.array([2.0, 3.0, 4.0]) ** -10 / (2.0**-10 + 3.0**-10 + 4.0**-10), rtol=1e-12)
    np.testing.assert_allclose(rank_weights(np.array([0.0, 1.0, 1.0]), 0.1),
                               np.array([4.0, 3.0, 3.0]) ** -10 / (4.0**-10 + 2 * 3.0**-10), rtol=1e-12)

    rc = curriculum(per_demo_buffer_size=1, reverse_step_size=5, forward_states=P0_STATES)
    assert len(rc.states) == 10 and rc.demo_states.shape == (7, 4)
    np.testing.assert_array_equal(rc.weights[7:], 0)  # no p0 state before the demonstrations are solved
    solve_every_demonstration(rc)
    assert rc.phase == "forward"
    np.testing.assert_allclose(rc.weights, [0] * 7 + [1 / 3] * 3, rtol=1e-12)  # every score 2, staleness 0

    rng = np.random.default_rng(0)
    first = rc.sample(rng)
    assert first in (7, 8, 9) and rc.time_limit(first) is None  # p0 starts keep the env's limit
    staleness = np.where(np.arange(7, 10) == first, 0.0, 1.0)  # the drawn state 0, the others 1
    expected = 0.9 / 3 + 0.1 * rank_weights(staleness, 0.1)
    np.testing.assert_allclose(rc.weights[7:], expected, rtol=1e-12)

    # scores 3 (one success in 5: the frontier), 2 (none), 1 (4 of 5: mastered)
    rc.update(7, 20, success=True)
    for _ in range(4):
        rc.update(9, 20, success=True)
    assert rc.state_dict()["forward_outcomes"] == [[True], [], [True] * 4]
    scores = np.array([2.0, 3.0, 4.0]) ** -10 / (2.0**-10 + 3.0**-10 + 4.0**-10)
    np.testing.assert_allclose(rc.weights[7:], 0.9 * scores + 0.1 * rank_weights(staleness, 0.1), rtol=1e-12)
    for _ in range(6):  # only the last 5 outcomes count
        rc.update(8, 20, success=False)
    assert rc.state_dict()["forward_outcomes"][1] == [False] * 5


def test_remaining_sampler_weighs_demos_by_how_far_they_are_from_their_start():
    rc = curriculum(demo_sampler="remaining", per_demo_buffer_size=1, reverse_step_size=2)
    np.testing.assert_allclose(rc.weights, [0, 0, 0, 3 / 4, 0, 0, 2 / 3], rtol=1e-12)
    rc.update(B_LAST, 2, success=True)  # B: t = 0, drawn with RFCL's 1e-6
    np.testing.assert_allclose(rc.weights, [0, 0, 0, 3 / 4, 1e-6, 0, 0], rtol=1e-12)


# --- the time limit ---------------------------------------------------------------------------
def test_time_limit_is_rfcls_min_plus_steps_back_over_ratio():
    states = np.zeros((40, 4))
    rc = ReverseCurriculumSS(states, np.zeros(40, dtype=int))
    # index i is 40 - i demonstration steps from the goal: 8 + (40 - i) // 3
    assert [rc.steps_back(i) for i in (39, 37, 36, 0)] == [1, 3, 4, 40]
    assert [rc.time_limit(i) for i in (39, 37, 36, 0)] == [8, 9, 9, 21]
    other = ReverseCurriculumSS(states, np.zeros(40, dtype=int), demo_horizon_to_max_steps_ratio=2.5, max_steps_min=4)
    assert [other.time_limit(i) for i in (39, 35, 0)] == [4, 6, 20]  # 4 + 1 // 2.5, 4 + 5 // 2.5, 4 + 40 // 2.5
    off = ReverseCurriculumSS(states, np.zeros(40, dtype=int), demo_horizon_to_max_steps_ratio=None)
    assert off.time_limit(0) is None


def test_the_env_limit_caps_the_time_limit():
    rc = ReverseCurriculumSS(np.zeros((40, 4)), np.zeros(40, dtype=int))
    rc.load_state_dict({**rc.state_dict(), "start_steps": [0]})  # a start 40 steps back: 21 steps
    for cap, expected in [(None, 21), (500, 21), (15, 15)]:
        selector = StartSelector(rc, seed=0, max_episode_steps=cap)
        selector.choose()
        assert selector.time_limit == expected
    # through the wrapper on the real env: 8 + 170 // 3 = 64 from LavaBridge-v0's first demo start,
    # capped at the env's 10 steps
    states, ids = goal_reaching_demos(lava_bridge_mj.load_demos(500))
    real = ReverseCurriculumSS(states, ids)
    real.load_state_dict({**real.state_dict(), "start_steps": [0, 0]})
    assert [real.time_limit(0), real.time_limit(real.demo_lengths[0])] == [8 + 169 // 3, 8 + 170 // 3]
    env = StartStateWrapper(gymnasium.make("LavaBridge-v0", max_episode_steps=10), real, seed=0)
    env.reset()
    assert env.time_limit == 10


class StepsEnv(gymnasium.Env):
    """A fake env: the episode terminates after state[0] steps, with success when state[1] > 0."""

    observation_space = gymnasium.spaces.Box(-1000, 1000, (4,), dtype=np.float64)
    action_space = gymnasium.spaces.Box(-1, 1, (2,), dtype=np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.state, self.steps = np.array(options["state"], dtype=np.float64), 0
        return self.state.copy(), {}

    def step(self, action):
        self.steps += 1
        terminated = self.steps >= self.state[0]
        success = bool(terminated and self.state[1] > 0)
        return self.state.copy(), float(success), terminated, False, {"is_success": success}


def run_episode(env):
    obs, info = env.reset()
    steps, terminated, truncated = 0, False, False
    while not (terminated or truncated):
        _, _, terminated, truncated, _ = env.step(np.zeros(2))
        steps += 1
    return info["start_index"], steps, terminated, truncated


def test_wrapper_truncates_at_the_time_limit_and_reports_a_failure():
    # one demonstration of 30 states; the last one (steps back 1: limit 8) never terminates by itself
    states = np.tile([1000.0, 1.0, 0.0, 0.0], (30, 1))
    rc = ReverseCurriculumSS(states, np.zeros(30, dtype=int), per_demo_buffer_size=1)
    env = StartStateWrapper(StepsEnv(), rc, seed=0)
    assert run_episode(env) == (29, 8, False, True)
    assert outcomes(rc) == [[False]] and rc.start_steps[0] == 29
    env.step(np.zeros(2))  # stepping past the end changes nothing
    assert outcomes(rc) == [[False]]

    # a start that terminates with success on the limit's own step: terminated, not truncated
    states[29, 0] = 8.0
    rc = ReverseCurriculumSS(states, np.zeros(30, dtype=int), per_demo_buffer_size=1)
    env = StartStateWrapper(StepsEnv(), rc, seed=0)
    assert run_episode(env) == (29, 8, True, False)
    assert rc.start_steps[0] == 28  # one success with m = 1 moves t back

    # with the limit off, the same never-ending start runs on past 8 steps
    states[:, 0] = 12.0
    rc = ReverseCurriculumSS(states, np.zeros(30, dtype=int), demo_horizon_to_max_steps_ratio=None)
    assert run_episode(StartStateWrapper(StepsEnv(), rc, seed=0)) == (29, 12, True, False)


# --- persistence ------------------------------------------------------------------------------
def play(strategy, rng, episodes):
    """Sample and report `episodes` episodes; every fourth one fails."""
    starts = []
    for episode in range(episodes):
        index = strategy.sample(rng)
        starts.append(index)
        strategy.update(index, 5, success=episode % 4 != 3)
    return starts


def test_state_dict_round_trip_mid_curriculum_gives_identical_futures():
    rng = np.random.default_rng(7)
    trained = curriculum(per_demo_buffer_size=2, forward_states=P0_STATES)
    play(trained, rng, 9)
    state = json.loads(json.dumps(trained.state_dict()))
    assert trained.phase == "reverse" and state["start_steps"] != [3, 2]  # mid-curriculum
    restored = curriculum(per_demo_buffer_size=2, forward_states=P0_STATES)
    restored.load_state_dict(state)
    assert restored.state_dict() == trained.state_dict()
    rng_state = rng.bit_generator.state
    future = play(trained, rng, 60)
    rng.bit_generator.state = rng_state
    assert play(restored, rng, 60) == future
    # the switch to the forward curriculum happened in both, and its staleness and scores agree
    assert restored.state_dict() == trained.state_dict() and trained.phase == "forward"
    assert {7, 8, 9} <= set(future) and any(trained.state_dict()["forward_outcomes"])


def test_selector_round_trip_restores_the_running_episodes_time_limit():
    selector = StartSelector(curriculum(), seed=3, max_episode_steps=500)
    selector.choose()
    selector.step(False, False)
    state = json.loads(json.dumps(selector.state_dict()))
    resumed = StartSelector(curriculum(), seed=99, max_episode_steps=500)
    resumed.load_state_dict(state)
    assert resumed.time_limit == selector.time_limit == 8 and resumed.episode_length == 1
    assert [resumed.choose().tolist() for _ in range(5)] == [selector.choose().tolist() for _ in range(5)]


@pytest.mark.parametrize("change, match", [
    (dict(start_steps=[4, 2]), "start_steps"), (dict(start_steps=[3]), "start_steps"),
    (dict(outcomes=[[True] * 4, []]), "outcomes"), (dict(outcomes=[[1], []]), "outcomes"),
    (dict(solved=[True, False]), "solved"), (dict(staleness=[0]), "staleness"),
    (dict(forward_outcomes=[[True]]), "forward_outcomes"),
])
def test_load_state_dict_rejects_inconsistent_states(change, match):
    rc = curriculum()
    with pytest.raises(ValueError, match=match):
        rc.load_state_dict({**rc.state_dict(), **change})


# --- building and checking --------------------------------------------------------------------
def test_goal_reaching_demos_drop_the_cut_last_episode():
    demos = lava_bridge_mj.load_demos(500)
    states, ids = goal_reaching_demos(demos)
    assert np.unique(demos["episode_ids"]).tolist() == [0, 1, 2] and np.unique(ids).tolist() == [0, 1]
    np.testing.assert_array_equal(states, demos["observations"][demos["episode_ids"] < 2])
    assert len(np.unique(goal_reaching_demos(lava_bridge_mj.load_demos(7500))[1])) == 44


def test_make_start_strategy_builds_it_and_settings_record_its_defaults():
    rc = make_start_strategy("reverse_ss", STATES, episode_ids=EPISODE_IDS, per_demo_buffer_size=2)
    assert isinstance(rc, ReverseCurriculumSS) and rc.per_demo_buffer_size == 2
    assert make_start_strategy("reverse_ss", STATES, episode_ids=EPISODE_IDS, reverse_step_size=4).settings == {
        "per_demo_buffer_size": 3, "reverse_step_size": 4, "demo_sampler": "uniform",
        "demo_horizon_to_max_steps_ratio": 3.0, "max_steps_min": 8}


@pytest.mark.parametrize("params, match", [
    (dict(per_demo_buffer_size=0), r"^per_demo_buffer_size must be an integer >= 1, got 0$"),
    (dict(reverse_step_size=1.5), r"^reverse_step_size must be an integer >= 1, got 1.5$"),
    (dict(demo_sampler="geometric"), r"^demo_sampler must be one of \('uniform', 'remaining'\), got 'geometric'$"),
    (dict(demo_horizon_to_max_steps_ratio=0), r"^demo_horizon_to_max_steps_ratio must be a finite number > 0, got 0$"),
    (dict(max_steps_min=-1), r"^max_steps_min must be an integer >= 1, got -1$"),
    (dict(episode_ids=[0, 0, 1, 1, 0, 2, 2]), r"^episode_ids must keep each demonstration's states together"),
    (dict(episode_ids=[0.0] * 7), r"^episode_ids must be integers, got dtype float64$"),
    (dict(episode_ids=[0, 1]), r"^episode_ids must have shape \(7,\)"),
    (dict(forward_states=np.zeros((5, 3))), r"^forward_states must be a \(k, 4\) array .* got shape \(5, 3\)$"),
    (dict(forward_states=[]), r"^forward_states must be a \(k, 4\) array of finite p0 states with k >= 1, or None, got \[\]$"),
])
def test_bad_parameters_are_rejected_naming_the_value(params, match):
    params = {"episode_ids": EPISODE_IDS, **params}
    with pytest.raises(ValueError, match=match):
        make_start_strategy("reverse_ss", STATES, **params)


# --- with another library's agent -------------------------------------------------------------
def test_sb3_sac_trains_through_the_wrapper_on_the_reverse_curriculum():
    sb3 = pytest.importorskip("stable_baselines3", reason="stable-baselines3 is a test extra: pip install -e '.[test]'")
    states, ids = goal_reaching_demos(lava_bridge_mj.load_demos(500))
    rc = ReverseCurriculumSS(states, ids, per_demo_buffer_size=1)
    env = StartStateWrapper(gymnasium.make(lava_bridge_mj.ENV_ID), rc, seed=0)
    starts, lengths = [], []
    original_reset, original_step = env.reset, env.step

    def recording_reset(**kwargs):
        obs, info = original_reset(**kwargs)
        index = info["start_index"]
        demo = int(np.searchsorted(np.cumsum(rc.demo_lengths), index, side="right"))
        starts.append((index, demo, int(rc.start_steps[demo]), env.time_limit))
        np.testing.assert_array_equal(obs, states[index])
        lengths.append(0)
        return obs, info

    def counting_step(action):
        lengths[-1] += 1
        return original_step(action)

    env.reset, env.step = recording_reset, counting_step
    model = sb3.SAC("MlpPolicy", env, policy_kwargs={"net_arch": [16, 16]}, learning_starts=100,
                    batch_size=32, buffer_size=1000, seed=0, device="cpu")
    model.learn(300)

    first = np.cumsum(np.append(0, rc.demo_lengths))[:-1]
    for (index, demo, t, limit), length in zip(starts, lengths):
        assert index == first[demo] + t  # every episode started at its demonstration's current t_i
        assert length <= limit == rc.time_limit(index)  # and ended by the shortened limit
    assert (rc.start_steps < rc.demo_lengths - 1).any(), "no demonstration's start moved back in 300 steps"
