"""The native vector env: gymnasium.make_vec gives it, and it matches K single envs step by step."""

import gymnasium
import numpy as np
import pytest

import lava_bridge_mj
from lava_bridge_mj import ENV_ID, LavaBridgeVectorEnv


def sync_envs(k, env_id=ENV_ID, **kwargs):
    return gymnasium.vector.SyncVectorEnv([lambda: gymnasium.make(env_id, **kwargs) for _ in range(k)])


def assert_same_step(a, b):
    for x, y, name in zip(a, b, ("obs", "reward", "terminated", "truncated")):
        np.testing.assert_array_equal(x, y, err_msg=name)
    for key in ("is_success", "lava"):
        np.testing.assert_array_equal(a[4][key], b[4][key], err_msg=key)


def test_make_vec_returns_the_native_vector_env():
    envs = gymnasium.make_vec(ENV_ID, num_envs=3)
    assert isinstance(envs.unwrapped, LavaBridgeVectorEnv)
    assert envs.num_envs == 3 and envs.unwrapped.max_episode_steps == lava_bridge_mj.MAX_EPISODE_STEPS
    assert envs.observation_space.shape == (3, 4) and envs.action_space.shape == (3, 2)
    assert len({id(d) for d in envs.unwrapped.datas}) == 3  # one MjData per sub-env, one model
    assert envs.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP


@pytest.mark.parametrize("env_id, kwargs", [(ENV_ID, {}), (ENV_ID, {"lava_reward": 0.0, "bridge_width": 0.4}),
                                            *((env_id, {}) for env_id in list(lava_bridge_mj.TASKS)[1:])])
def test_matches_sync_vector_env_of_single_envs_through_terminations_truncations_and_autoresets(env_id, kwargs):
    k, steps = 6, 1_200  # > 2 horizons: every sub-env truncates at least twice or terminates
    native, reference = gymnasium.make_vec(env_id, num_envs=k, **kwargs), sync_envs(k, env_id, **kwargs)
    rng = np.random.default_rng(0)
    first = native.reset(seed=7), reference.reset(seed=7)
    np.testing.assert_array_equal(first[0][0], first[1][0])
    ended = {"terminated": 0, "truncated": 0}
    for _ in range(steps):
        actions = rng.uniform(-1, 1, (k, 2)).astype(np.float32)
        a, b = native.step(actions), reference.step(actions)
        assert_same_step(a, b)
        ended["terminated"] += a[2].sum()
        ended["truncated"] += a[3].sum()
    assert ended["terminated"] > 0 and ended["truncated"] > 0, ended  # both kinds of ending were compared


def test_resets_to_given_states_with_a_mask_match_single_envs():
    k = 4
    native, singles = LavaBridgeVectorEnv(num_envs=k), [gymnasium.make(ENV_ID) for _ in range(k)]
    native.reset(seed=1)
    for i, env in enumerate(singles):
        env.reset(seed=1 + i)
    states = np.array([[-4.0, 0.5, 0.2, -0.1], [-1.0, 0.0, 1.0, 0.0], [2.0, 1.0, 0.0, 0.3], [4.0, -1.0, 0.0, 0.0]])
    mask = np.array([True, False, True, True])
    obs, _ = native.reset(options={"state": states, "reset_mask": mask})
    for i in np.flatnonzero(mask):
        np.testing.assert_array_equal(obs[i], states[i])
        singles[i].reset(options={"state": states[i]})
    rng = np.random.default_rng(3)
    for _ in range(40):  # until the first episode ends (then the two sides differ in when they reset)
        actions = rng.uniform(-1, 1, (k, 2))
        obs, reward, terminated, truncated, _ = native.step(actions)
        singles_out = [env.step(a) for env, a in zip(singles, actions)]
        np.testing.assert_array_equal(obs, np.stack([out[0] for out in singles_out]))
        np.testing.assert_array_equal(reward, [out[1] for out in singles_out])
        np.testing.assert_array_equal(terminated, [out[2] for out in singles_out])
        if terminated.any():
            break


@pytest.mark.parametrize("options, message", [
    ({"state": np.zeros((3, 4))}, r"shape \(2, 4\)"),
    ({"state": np.zeros((2, 4)), "start": "p0"}, "conflict"),
    ({"start": "nowhere"}, "unknown start distribution 'nowhere'"),
    ({"reset_mask": [1, 0]}, "bool array of shape"),
    ({"reset_mask": [True]}, "bool array of shape"),
    ({"sate": 1}, r"unknown reset options \['sate'\]"),
    ({"state": [[10.0, 0, 0, 0], [0, 0, 0, 0]]}, "inside a wall or outside the maze"),
])
def test_bad_reset_options_are_refused_and_nothing_changes(options, message):
    envs = LavaBridgeVectorEnv(num_envs=2)
    before, _ = envs.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        envs.reset(options=options)
    np.testing.assert_array_equal(envs.get_state(), before)


def test_bad_actions_are_refused():
    envs = LavaBridgeVectorEnv(num_envs=2)
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2, 2\)"):
        envs.step(np.zeros(2))
    with pytest.raises(ValueError, match="finite"):
        envs.step(np.array([[0.0, 0.0], [np.nan, 0.0]]))


@pytest.mark.parametrize("actions, message", [
    ([[0.5 + 1j, 0.0], [0.0, 0.0]], r"actions must be finite real numbers of shape \(2, 2\)"),
    (object(), r"actions must be finite real numbers of shape \(2, 2\), got <object object"),
    ([[0.5, 0.0], [0.0]], "actions must be finite real numbers"),  # ragged
    ([[0.5, 0.5], [np.nan, 0.0]], "actions must be finite"),
    ([[0.5, 0.5], [0.0, np.inf]], "actions must be finite"),
])
def test_bad_actions_leave_every_sub_env_where_it_was(actions, message):
    """The whole batch is checked before any sub-env steps: a bad row does not move the good ones."""
    envs = LavaBridgeVectorEnv(num_envs=2)
    before, _ = envs.reset(seed=0)
    steps = envs.episode_steps.copy()
    with pytest.raises(ValueError, match=message):
        envs.step(actions)
    np.testing.assert_array_equal(envs.get_state(), before)
    np.testing.assert_array_equal(envs.episode_steps, steps)


@pytest.mark.parametrize("kwargs, message", [
    ({"num_envs": 0}, "num_envs must be an integer >= 1, got 0"),
    ({"num_envs": 2.0}, r"num_envs must be an integer >= 1, got 2\.0"),
    ({"max_episode_steps": 0}, "max_episode_steps must be an integer >= 1, got 0"),
    ({"max_episode_steps": "500"}, "max_episode_steps must be an integer >= 1, got '500'"),
    ({"lava_reward": "x"}, "lava_reward must be a finite number, got 'x'"),
    ({"goal_reward": float("nan")}, "goal_reward must be a finite number, got nan"),
    ({"step_reward": float("inf")}, "step_reward must be a finite number, got inf"),
    ({"width": -5}, r"width must be an integer in \[1, 1920\], got -5"),
])
def test_bad_vector_env_arguments_raise_naming_the_argument(kwargs, message):
    with pytest.raises(ValueError, match=message):
        LavaBridgeVectorEnv(**{"num_envs": 2, **kwargs})


@pytest.mark.parametrize("seed, options, message", [
    (-1, None, "seed must be an integer >= 0, got -1"),
    ("ab", None, "seed must be an integer >= 0, got 'ab'"),
    ([0, 1.5], None, r"seed must be an integer >= 0, got 1\.5"),
    (None, {"state": [[-4.5 + 1j, 0, 0, 0], [-4.5, 0, 0, 0]]}, "reset option 'state' must be finite real numbers"),
    (None, {"state": object()}, "reset option 'state' must be finite real numbers"),
])
def test_bad_reset_arguments_raise_and_nothing_changes(seed, options, message):
    envs = LavaBridgeVectorEnv(num_envs=2)
    before, _ = envs.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        envs.reset(seed=seed, options=options)
    np.testing.assert_array_equal(envs.get_state(), before)


def test_rows_of_sub_envs_not_reset_are_ignored():
    envs = LavaBridgeVectorEnv(num_envs=2)
    before, _ = envs.reset(seed=0)
    obs, _ = envs.reset(options={"state": [[-4.5, 0.0, 0.0, 0.0], [np.nan] * 4], "reset_mask": np.array([True, False])})
    np.testing.assert_array_equal(obs, [[-4.5, 0.0, 0.0, 0.0], before[1]])


@pytest.mark.parametrize("env_id", [ENV_ID, "LavaBridgeNarrow-v0"])
def test_same_step_autoreset_matches_sync_vector_env(env_id):
    """SAME_STEP, through make_vec's keyword: observations, rewards, ends, infos and the ended episodes'
    final observations and infos equal gymnasium's SyncVectorEnv in the same mode, step by step."""
    k, steps, mode = 5, 1_200, gymnasium.vector.AutoresetMode.SAME_STEP
    native = gymnasium.make_vec(env_id, num_envs=k, autoreset_mode=mode)
    reference = gymnasium.make_vec(env_id, num_envs=k, vectorization_mode="sync",
                                   vector_kwargs={"autoreset_mode": mode})
    assert isinstance(native.unwrapped, LavaBridgeVectorEnv) and native.metadata["autoreset_mode"] == mode
    rng = np.random.default_rng(0)
    np.testing.assert_array_equal(native.reset(seed=11)[0], reference.reset(seed=11)[0])
    ended = {"terminated": 0, "truncated": 0}
    for _ in range(steps):
        actions = rng.uniform(-1, 1, (k, 2)).astype(np.float32)
        a, b = native.step(actions), reference.step(actions)
        assert_same_step(a, b)
        assert ("final_obs" in a[4]) == ("final_obs" in b[4])
        if "final_obs" in b[4]:
            np.testing.assert_array_equal(a[4]["_final_obs"], b[4]["_final_obs"])
            np.testing.assert_array_equal(a[4]["_final_info"], b[4]["_final_info"])
            for i in np.flatnonzero(b[4]["_final_obs"]):
                np.testing.assert_array_equal(a[4]["final_obs"][i], b[4]["final_obs"][i])
                for key in ("is_success", "lava"):
                    assert a[4]["final_info"][key][i] == b[4]["final_info"][key][i]
                    assert a[4]["final_info"]["_" + key][i] == b[4]["final_info"]["_" + key][i]
        ended["terminated"] += a[2].sum()
        ended["truncated"] += a[3].sum()
    assert ended["terminated"] > 0 and ended["truncated"] > 0, ended


@pytest.mark.parametrize("mode", ["Disabled", "sameStep", 3])
def test_unsupported_autoreset_modes_are_refused_naming_them(mode):
    with pytest.raises(ValueError, match=rf"autoreset_mode must be one of \['NextStep', 'SameStep'\].*got {mode!r}"):
        LavaBridgeVectorEnv(2, autoreset_mode=mode)
