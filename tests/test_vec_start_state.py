"""`VecStartStateWrapper`: one start strategy for all sub-envs of an SB3 VecEnv.

Two ways to get this wrong, and what catches each:
- a copy of the strategy per sub-env (as a `StartStateWrapper` inside each worker of a `SubprocVecEnv`
  has): the strategy the caller holds learns nothing, or only one sub-env's episodes. Caught by
  `test_one_strategy_learns_from_every_sub_env_as_one_wrapped_env_would`: its updates must be every
  episode that ended in any sub-env, and its weights bit for bit those of one `StartStateWrapper`-ed env
  fed the same episodes;
- one seed for every sub-env's draws: all sub-envs start from the same states. Caught by
  `test_sub_env_i_draws_with_seed_plus_i`: the first starts must be those of seeds seed + i, and differ.
"""

import functools
import re

import gymnasium
import numpy as np
import pytest

import lava_bridge_mj
from lava_bridge_mj.agents import AuxSS, StartStateWrapper, UniformSS
from lava_bridge_mj.agents.start_state_wrapper import StartSelector

pytest.importorskip("stable_baselines3", reason="stable-baselines3 is a test extra: pip install -e '.[test]'")
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize  # noqa: E402

from lava_bridge_mj.agents import VecStartStateWrapper  # noqa: E402

SEED, N_ENVS, STEPS = 3, 4, 400
ENV_ID = "lava_bridge_mj:LavaBridge-v0"  # the module path: SubprocVecEnv's workers import the package from it
STATES = lava_bridge_mj.candidate_states(lava_bridge_mj.load_demos(500)["observations"], seed=SEED)


class RecordingAuxSS(AuxSS):
    """AuxSS that keeps the list of its updates, in order."""

    def __init__(self, states):
        super().__init__(states)
        self.updates = []

    def update(self, index, episode_length, success=False):
        self.updates.append((index, episode_length, success))
        super().update(index, episode_length, success=success)


class ReplayedStarts(AuxSS):
    """AuxSS whose draws are given: the starts of recorded episodes, in order."""

    def __init__(self, states, starts):
        super().__init__(states)
        self.starts = iter(starts)

    def sample(self, rng):
        return next(self.starts)


class ReplayedEpisodes(gymnasium.Env):
    """Plays recorded episodes back: each reset must be to the recorded start state; the episode then
    ends after the recorded number of steps, with the recorded success."""

    observation_space = gymnasium.spaces.Box(-np.inf, np.inf, (4,))
    action_space = gymnasium.spaces.Box(-1.0, 1.0, (2,))

    def __init__(self, states, episodes):
        self.states, self.episodes = states, iter(episodes)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        index, self.length, self.success = next(self.episodes)
        assert np.array_equal(options["state"], self.states[index])
        self.t = 0
        return options["state"].astype(np.float32), {}

    def step(self, action):
        self.t += 1
        ended = self.t == self.length
        terminated = ended and (self.success or self.length < lava_bridge_mj.MAX_EPISODE_STEPS)
        info = {"is_success": ended and self.success}
        return np.zeros(4, np.float32), 0.0, terminated, ended and not terminated, info


def sub_env_states(venv):
    return np.array(venv.env_method("get_state"))


@functools.cache  # each kind runs once: the tests only read what it returns
def run_random_actions(vec_env_cls):
    """STEPS random steps of N_ENVS LavaBridge-v0 sub-envs through VecStartStateWrapper; every start is
    checked against the sub-env's real state. Returns the strategy and each sub-env's finished episodes."""
    # spawned workers: the default forkserver keeps a socket in the tests' temporary directory, which is
    # removed before the forkserver's own clean-up at exit
    kwargs = {"vec_env_kwargs": {"start_method": "spawn"}} if vec_env_cls is SubprocVecEnv else {}
    venv = make_vec_env(ENV_ID, n_envs=N_ENVS, vec_env_cls=vec_env_cls, **kwargs)
    strategy = RecordingAuxSS(STATES)
    wrapper = VecStartStateWrapper(venv, strategy, seed=SEED)
    rng = np.random.default_rng(0)
    finished = np.zeros(N_ENVS, dtype=int)
    try:
        obs = wrapper.reset()
        assert np.array_equal(sub_env_states(venv), STATES[wrapper.start_indices])
        assert np.array_equal(obs, STATES[wrapper.start_indices])
        for _ in range(STEPS):
            obs, _, dones, infos = wrapper.step(rng.uniform(-1, 1, (N_ENVS, 2)).astype(np.float32))
            if dones.any():
                # each sub-env whose episode ended was reset to the state the strategy chose for it
                new = np.flatnonzero(dones)
                assert np.array_equal(sub_env_states(venv)[new], STATES[wrapper.start_indices[new]])
                assert np.array_equal(obs[new], STATES[wrapper.start_indices[new]])
                assert [venv.reset_infos[i]["start_index"] for i in new] == list(wrapper.start_indices[new])
                # and its terminal observation is not the new start
                assert all(not np.array_equal(infos[i]["terminal_observation"], obs[i]) for i in new)
            finished += dones
    finally:
        wrapper.close()
    return strategy, finished


@pytest.mark.parametrize("vec_env_cls", [DummyVecEnv, SubprocVecEnv])
def test_one_strategy_learns_from_every_sub_env_as_one_wrapped_env_would(vec_env_cls):
    strategy, finished = run_random_actions(vec_env_cls)
    # every episode that ended, in any sub-env, was reported to the one strategy the caller holds
    assert (finished > 0).all() and len(strategy.updates) == finished.sum() > N_ENVS
    assert not np.all(strategy.weights == 1.0)
    # one StartStateWrapper-ed env fed the same episodes (same starts, lengths and outcomes) ends with
    # the same weights, bit for bit: the same update rule, applied in the same order
    reference = ReplayedStarts(STATES, [index for index, _, _ in strategy.updates])
    env = StartStateWrapper(ReplayedEpisodes(STATES, strategy.updates), reference, seed=0)
    for _ in strategy.updates:
        env.reset()
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            done = terminated or truncated
    assert np.array_equal(reference.weights, strategy.weights)


def test_both_vec_env_kinds_give_the_same_starts_and_updates():
    dummy, _ = run_random_actions(DummyVecEnv)
    subproc, _ = run_random_actions(SubprocVecEnv)
    assert dummy.updates == subproc.updates
    assert np.array_equal(dummy.weights, subproc.weights)


def test_sub_env_i_draws_with_seed_plus_i():
    venv = make_vec_env(ENV_ID, n_envs=N_ENVS)
    wrapper = VecStartStateWrapper(venv, AuxSS(STATES), seed=SEED)
    for seed in (SEED, 11):
        if seed != SEED:
            assert wrapper.seed(seed) == [seed + i for i in range(N_ENVS)]  # SB3's seeds for the envs
        wrapper.reset()
        expected = [StartSelector(AuxSS(STATES), seed + i) for i in range(N_ENVS)]
        for selector in expected:
            selector.choose()
        assert list(wrapper.start_indices) == [selector.start_index for selector in expected]
        assert len(set(wrapper.start_indices)) == N_ENVS, "the sub-envs started from the same states"
    wrapper.close()


def test_a_strategys_own_step_limit_truncates_and_restarts_the_sub_env():
    class FiveSteps(UniformSS):
        def time_limit(self, index):
            return 5

    strategy = FiveSteps(STATES)
    venv = make_vec_env(ENV_ID, n_envs=2)
    wrapper = VecStartStateWrapper(venv, strategy, seed=0)
    wrapper.reset()
    # a zero action from a demo state: the ball rolls on for a while, and nothing else ends it
    for step in range(1, 6):
        starts = wrapper.start_indices.copy()
        before = sub_env_states(venv)
        obs, _, dones, infos = wrapper.step(np.zeros((2, 2), np.float32))
        if step < 5:
            assert not dones.any()
    assert dones.all() and all(info["TimeLimit.truncated"] for info in infos)
    assert all(info["terminal_observation"].shape == (4,) for info in infos)
    assert np.array_equal(sub_env_states(venv), STATES[wrapper.start_indices])
    assert np.array_equal(obs, STATES[wrapper.start_indices])
    assert not np.array_equal(before, STATES[starts])  # the sub-envs had moved from their starts
    wrapper.close()


def test_options_given_with_set_options_pass_through_unreported():
    venv = make_vec_env(ENV_ID, n_envs=2)
    strategy = RecordingAuxSS(STATES)
    wrapper = VecStartStateWrapper(venv, strategy, seed=0)
    wrapper.set_options([{"state": np.array([-1.0, 0.0, 0.4, 0.0])}, {}])
    obs = wrapper.reset()
    assert np.array_equal(obs[0], [-1.0, 0.0, 0.4, 0.0]) and wrapper.start_indices[0] == -1
    assert np.array_equal(obs[1], STATES[wrapper.start_indices[1]])
    wrapper.close()


def test_a_wrapped_vec_env_is_refused():
    with pytest.raises(ValueError, match="VecNormalize"):
        VecStartStateWrapper(VecNormalize(make_vec_env(ENV_ID, n_envs=1)), AuxSS(STATES))


def test_the_documented_sb3_example_trains_four_sub_envs_from_one_auxss(tmp_path):
    from test_readme_examples import run_example

    out = run_example("docs/start-strategies.md", "### Several envs at once: one strategy for all of SB3's sub-envs",
                      tmp_path)
    starts = [int(i) for i in re.search(r"^sub-envs run from start states \[(.*)\]$", out, re.M)[1].split(",")]
    assert len(starts) == N_ENVS and all(0 <= i < 150 for i in starts)
    most, least, uniform = map(float, re.search(
        r"most likely start ([0-9.]+), least likely ([0-9.]+) \(uniform: ([0-9.]+)\)", out).groups())
    assert uniform == pytest.approx(1 / 150, abs=1e-4)  # the benchmark's 150 candidate states
    assert most > uniform > least, "AuxSS's weights never moved: the sub-envs' episodes were not fed back"
