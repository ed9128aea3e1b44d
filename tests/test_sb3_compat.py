"""StartStateWrapper drives another library's agent: Stable-Baselines3's SAC trains through it."""

import gymnasium
import numpy as np
import pytest

import lava_bridge_mj
from lava_bridge_mj.agents import StartStateWrapper, make_start_strategy

sb3 = pytest.importorskip("stable_baselines3", reason="stable-baselines3 is a test extra: pip install -e '.[test]'")


class RecordingAuxSS:
    """Delegates to a real AuxSS and records every report, to check what SB3's loop fed back."""

    def __init__(self, strategy):
        self.inner, self.reports = strategy, []

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def update(self, index, episode_length, success=False):
        self.reports.append((index, episode_length))
        self.inner.update(index, episode_length, success=success)


def test_sb3_sac_trains_from_auxss_start_states():
    states = lava_bridge_mj.load_demos(500)["observations"][::10]
    strategy = RecordingAuxSS(make_start_strategy("auxss", states))
    env = StartStateWrapper(gymnasium.make(lava_bridge_mj.ENV_ID), strategy, seed=0)
    starts = []
    original_reset = env.reset

    def recording_reset(**kwargs):
        obs, info = original_reset(**kwargs)
        starts.append((obs.copy(), info["start_index"]))
        return obs, info

    env.reset = recording_reset
    model = sb3.SAC("MlpPolicy", env, policy_kwargs={"net_arch": [16, 16]}, learning_starts=100,
                    batch_size=32, buffer_size=1000, seed=0, device="cpu")
    model.learn(300)

    # every episode SB3 ran started from the candidate state the strategy chose ...
    for obs, index in starts:
        assert 0 <= index < len(states)
        np.testing.assert_array_equal(obs, states[index])
    # ... and every finished one was reported back once, with its length
    assert len(strategy.reports) >= 1
    assert sum(length for _, length in strategy.reports) <= 300
    assert [index for index, _ in strategy.reports] == [index for _, index in starts[: len(strategy.reports)]]
    assert not np.array_equal(strategy.weights, np.ones(len(states))), "AuxSS weights never moved"
