"""The trainer and demonstrations on Gymnasium MuJoCo envs that are not Lava Bridge tasks.

InvertedPendulum-v5 (a cart balancing a pole; no success reported, no goal declared) and a variant
registered here, `Reach`, that declares what the other strategies need: success when the cart reaches
x > 0.15 (which ends the episode), the distance to it as its goal, and an `ood` start.
"""

import json
import shutil

import gymnasium
import numpy as np
import pytest
import torch
from conftest import interrupted_copy, metrics_without_wall_time
from gymnasium.envs.mujoco.inverted_pendulum_v5 import InvertedPendulumEnv

import lava_bridge_mj
from lava_bridge_mj import RunConfig, ResetToState, load_demos, record_demos, save_demos, train
from lava_bridge_mj.agents.methods import METHODS
from lava_bridge_mj.eval.cli import main as cli_main
from lava_bridge_mj.eval.training.run_files import EPISODE_LOG, RunDirectoryError
from lava_bridge_mj.state_vector import ResetToStateVectorEnv
from lava_bridge_mj.task_states import TaskStates

PENDULUM = "InvertedPendulum-v5"
REACH = "lava_bridge_tests/InvertedPendulumReach-v0"
GOAL_X = 0.15
OOD_X = -0.3


class Reach(gymnasium.Wrapper):
    """InvertedPendulum whose episode succeeds (and ends) once the cart passes x = GOAL_X; its goal
    distance is read from the full state (time, then qpos: the cart's x is coordinate 1)."""

    task_states = TaskStates(goal_distance=lambda states: np.maximum(GOAL_X - states[:, 1], 0.0))
    start_names = ("p0", "ood")

    def __init__(self):
        super().__init__(InvertedPendulumEnv())

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed)
        if options and options.get("start") == "ood":  # the cart starts left of its p0 spot
            env = self.env.unwrapped
            env.set_state(env.data.qpos + np.array([OOD_X, 0.0]), env.data.qvel)
            obs = env._get_obs()
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        success = bool(obs[0] > GOAL_X)
        return obs, reward, terminated or success, truncated, {**info, "success": success}


gymnasium.register(REACH, entry_point=Reach, max_episode_steps=100)


def balancing_policy(drift=0.0, noise=0.3, seed=0):
    """A linear controller that mostly balances the pole (and pushes the cart right by `drift`), with
    seeded noise so that some episodes fail: obs -> action in [-3, 3]."""
    rng = np.random.default_rng(seed)

    def act(obs):
        force = 1.0 * obs[0] + 6.0 * obs[1] + 0.5 * obs[2] + 1.0 * obs[3] + drift + noise * rng.standard_normal()
        return np.clip([force], -3.0, 3.0)
    return act


@pytest.fixture(scope="module")
def demo_files(tmp_path_factory):
    """Demo files recorded here: InvertedPendulum's and Reach's."""
    root = tmp_path_factory.mktemp("demos")
    files = {}
    for env_id, policy in ((PENDULUM, balancing_policy(noise=1.5)), (REACH, balancing_policy(drift=-0.3))):
        files[env_id] = root / f"{env_id.split('/')[-1]}.npz"
        save_demos(record_demos(gymnasium.make(env_id), policy, 300, seed=0), files[env_id])
    return files


def tiny(env_id, demos, method="auxss", **overrides):
    values = dict(env_id=env_id, demos=str(demos), method=method, seed=3, steps=300, eval_every=100,
                  eval_episodes=2, demo_subset=20,
                  sac={"hidden_sizes": [16, 16], "batch_size": 32, "buffer_size": 500, "learning_starts": 100},
                  bc={"hidden_sizes": [16, 16], "batch_size": 32}, iql={"hidden_sizes": [16, 16], "batch_size": 32},
                  jsrl={"guide": "iql", "guide_steps": 50, "initial_horizon": 40})
    values.update(overrides)
    return RunConfig(**values)


# --- demonstrations ----------------------------------------------------------------------------
def test_record_demos_records_exactly_n_transitions_whose_states_restore_their_observations(demo_files):
    demos = load_demos(path=demo_files[PENDULUM])
    assert len(demos["observations"]) == 300 and demos["env_id"] == PENDULUM
    ids = demos["episode_ids"]
    assert ids[-1] >= 2, "the noisy policy should fail several episodes"
    ends = np.flatnonzero(np.diff(ids))  # last rows of the episodes before the last
    assert demos["terminations"][ends].all() and demos["truncations"][-1] and not demos["terminations"][-1]
    # each episode's next observation is the following row's observation
    within = np.flatnonzero(np.diff(ids) == 0)
    np.testing.assert_array_equal(demos["next_observations"][within], demos["observations"][within + 1])
    # the full state restores the recorded observation exactly, and replaying the action its next one
    env = ResetToState(gymnasium.make(PENDULUM))
    for row in (0, 57, 250):
        obs, info = env.reset(options={"state": demos["states"][row]})
        np.testing.assert_array_equal(obs, demos["observations"][row])
        np.testing.assert_array_equal(info["state"], demos["states"][row])
        np.testing.assert_array_equal(env.step(demos["actions"][row])[0], demos["next_observations"][row])
    assert "successes" not in demos  # InvertedPendulum reports none


def test_record_demos_takes_an_sb3_style_model_and_the_same_seed_gives_the_same_set():
    class Model:  # stable-baselines3's predict interface
        def predict(self, obs, deterministic=False):
            assert deterministic
            return np.clip([6.0 * obs[1] + obs[3]], -3, 3), None

    a = record_demos(gymnasium.make(PENDULUM), Model(), 40, seed=5)
    b = record_demos(ResetToState(gymnasium.make(PENDULUM)), Model(), 40, seed=5)
    c = record_demos(gymnasium.make(PENDULUM), Model(), 40, seed=6)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["observations"], c["observations"])
    np.testing.assert_array_equal(a["actions"][:, 0], np.clip(6.0 * a["observations"][:, 1] + a["observations"][:, 3],
                                                             -3, 3).astype(np.float32))


def test_a_dict_observation_env_is_recorded_flattened_in_gymnasium_order():
    class DictObservation(gymnasium.Wrapper):  # outside ResetToState, as observation wrappers must be
        def __init__(self, env):
            super().__init__(env)
            self.observation_space = gymnasium.spaces.Dict({"b": gymnasium.spaces.Box(-np.inf, np.inf, (2,), np.float64),
                                                            "a": gymnasium.spaces.Box(-np.inf, np.inf, (2,), np.float64)})

        def split(self, obs):
            return {"b": obs[:2], "a": obs[2:]}

        def reset(self, **kwargs):
            obs, info = self.env.reset(**kwargs)
            return self.split(obs), info

        def step(self, action):
            obs, *rest = self.env.step(action)
            return self.split(obs), *rest

    env = DictObservation(ResetToState(gymnasium.make(PENDULUM)))
    demos = record_demos(env, lambda obs: np.array([0.1]), 5, seed=0)
    plain = record_demos(gymnasium.make(PENDULUM), lambda obs: np.array([0.1]), 5, seed=0)
    # gymnasium's Dict sorts its keys: "a" (the velocities) first
    np.testing.assert_array_equal(demos["observations"], plain["observations"][:, [2, 3, 0, 1]])


def test_a_demo_file_names_what_is_wrong_in_one_line(demo_files, tmp_path):
    demos = load_demos(path=demo_files[PENDULUM])
    broken = {**demos, "states": demos["states"][:10]}
    save_demos(broken, tmp_path / "short.npz")
    with pytest.raises(ValueError, match=r"field 'states' has dtype float64 and shape \(10, \d+\); expected") as error:
        load_demos(path=tmp_path / "short.npz")
    assert "\n" not in str(error.value)
    save_demos({**demos, "extra": demos["rewards"]}, tmp_path / "extra.npz")
    with pytest.raises(ValueError, match=r"unknown fields \['extra'\]"):
        load_demos(path=tmp_path / "extra.npz")


def test_the_shipped_demo_sets_keep_their_recorded_hashes():
    from lava_bridge_mj.demos import content_hash

    manifest = json.loads((lava_bridge_mj.demos.resources.files("lava_bridge_mj.assets") / "demos.json").read_text())
    assert content_hash(load_demos(500)) == manifest["LavaBridge-v0"]["500"]["sha256"]


# --- the vector env --------------------------------------------------------------------------
def test_the_vector_env_steps_each_sub_env_as_the_single_env_with_rescaled_actions():
    envs = ResetToStateVectorEnv(PENDULUM, 2)
    single = ResetToState(gymnasium.make(PENDULUM))
    obs, _ = envs.reset(seed=[7, 8])
    np.testing.assert_array_equal(obs[0], single.reset(seed=7)[0])
    low, high = single.action_space.low, single.action_space.high  # [-3, 3]
    for unit in (0.5, -1.0, 0.25):
        obs, rewards, terminated, truncated, info = envs.step(np.array([[unit], [0.0]], dtype=np.float32))
        expected = single.step(np.float32(low + (unit + 1) / 2 * (high - low)))
        np.testing.assert_array_equal(obs[0], expected[0])
        assert rewards[0] == expected[1] and terminated[0] == expected[2]
    assert not envs.reports_success and envs.start_names == ("p0",)
    state = envs.get_state()
    envs.step(np.zeros((2, 1), dtype=np.float32))
    restored, _ = envs.reset(options={"state": state, "reset_mask": np.array([True, False])})
    np.testing.assert_array_equal(restored[0], single.reset(options={"state": state[0]})[0])
    with pytest.raises(ValueError, match="unknown start 'ood'; this env offers \\['p0'\\]"):
        envs.reset(options={"start": "ood"})


# --- training ----------------------------------------------------------------------------------
STRATEGY_METHODS = [name for name, method in METHODS.items() if method.start != "p0" or name == "sac"]


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """`trained(config, seeds)`: the directories of `config` trained from scratch (once per module)."""
    runs = {}

    def get(config, seeds=(3,)):
        key = json.dumps([config.to_dict(), list(seeds)], sort_keys=True)
        if key not in runs:
            root = tmp_path_factory.mktemp("runs")
            dirs = [root / f"seed{s}" for s in seeds]
            runs[key] = dirs, train(config, dirs, seeds=list(seeds), progress=False)
        return runs[key]
    return get


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_trains_two_seeds_on_a_foreign_env(demo_files, trained, method):
    dirs, run = trained(tiny(REACH, demo_files[REACH], method), seeds=(3, 4))
    for directory in dirs:
        rows = metrics_without_wall_time(directory)
        assert [row["step"] for row in rows] == ["100", "200", "300"]
        for row in rows:  # Reach reports success and declares ood: every rate is a number
            assert 0.0 <= float(row["success_p0"]) <= 1.0 and 0.0 <= float(row["success_ood"]) <= 1.0
        assert json.loads((directory / "config.json").read_text())["demos_sha256"] == run.config.demos_sha256
    if METHODS[method].online:
        assert rows != metrics_without_wall_time(dirs[0]), "two seeds gave the same results"


def test_training_from_a_reach_demo_starts_episodes_at_the_demo_states(demo_files, trained):
    dirs, run = trained(tiny(REACH, demo_files[REACH], "uniform_ss"), seeds=(3, 4))
    demos = load_demos(path=demo_files[REACH])
    assert run.strategy.states.shape[1] == demos["states"].shape[1]
    assert {tuple(s) for s in run.strategy.states} <= {tuple(s) for s in demos["states"]}


def test_an_env_without_success_scores_nan_and_ood_is_left_out(demo_files, trained):
    dirs, _ = trained(tiny(PENDULUM, demo_files[PENDULUM], "auxss"))
    for row in metrics_without_wall_time(dirs[0]):
        assert row["success_p0"] == "nan" and row["success_ood"] == "nan" and row["return_ood"] == "nan"
        assert float(row["return_p0"]) >= 1.0  # the pole stays up for at least its first step


def test_auxss_defaults_to_the_candidates_spread_as_its_kernel_scale(demo_files, trained):
    _, run = trained(tiny(PENDULUM, demo_files[PENDULUM], "auxss"))
    spread = np.std(run.strategy.states, axis=0)
    np.testing.assert_allclose(run.strategy.settings["state_scale"], np.where(spread > 0, spread, 1.0))


@pytest.mark.parametrize("method, missing", [("goaldist_ss", "goal_distance"),
                                             ("reverse_ss", "needs demo episodes that end in success")])
def test_a_method_that_needs_what_the_env_lacks_is_refused_in_one_line(demo_files, tmp_path, method, missing):
    with pytest.raises(ValueError, match=missing) as error:
        train(tiny(PENDULUM, demo_files[PENDULUM], method), tmp_path / "run", progress=False)
    assert "\n" not in str(error.value) and not (tmp_path / "run" / "config.json").exists()


@pytest.mark.parametrize("method", ["auxss", "hysac_auxss"])
def test_a_seed_trained_in_a_batch_equals_the_seed_trained_alone(demo_files, trained, method, one_torch_thread):
    config = tiny(REACH, demo_files[REACH], method)
    batch_dirs, _ = trained(config, seeds=(3, 4))
    alone_dirs, _ = trained(config)
    assert metrics_without_wall_time(batch_dirs[0]) == metrics_without_wall_time(alone_dirs[0])
    assert (batch_dirs[0] / EPISODE_LOG).read_bytes() == (alone_dirs[0] / EPISODE_LOG).read_bytes()
    for name in ("step_100.pt", "step_300.pt"):
        a, b = (torch.load(d[0] / "policies" / name) for d in (batch_dirs, alone_dirs))
        assert all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("method", ["auxss", "omega_ss"])
def test_a_run_interrupted_mid_episode_and_resumed_equals_the_uninterrupted_run(demo_files, trained, tmp_path, method):
    config = tiny(PENDULUM, demo_files[PENDULUM], method)
    (full_dir,), full = trained(config)
    checkpoint = torch.load(full_dir / "checkpoint.prev.pt", weights_only=False)
    assert checkpoint["step"] == 200 and checkpoint["wrapper"]["episode_length"] > 0, "not mid-episode"
    interrupted_copy(full_dir, tmp_path / "resumed")
    resumed = train(config, tmp_path / "resumed", resume=True, progress=False)
    assert metrics_without_wall_time(tmp_path / "resumed") == metrics_without_wall_time(full_dir)
    assert (tmp_path / "resumed" / EPISODE_LOG).read_bytes() == (full_dir / EPISODE_LOG).read_bytes()
    for name, tensor in full.agent.actor.state_dict().items():
        assert torch.equal(tensor, resumed.agent.actor.state_dict()[name]), name


def test_a_resume_refuses_a_demo_file_that_changed(demo_files, trained, tmp_path):
    demos_path = tmp_path / "demos.npz"
    shutil.copy(demo_files[PENDULUM], demos_path)
    config = tiny(PENDULUM, demos_path, steps=100)
    train(config, tmp_path / "run", progress=False)
    demos = load_demos(path=demos_path)
    save_demos({**demos, "rewards": demos["rewards"] * 2}, demos_path)
    with pytest.raises(RunDirectoryError, match=r"demo file .*demos.npz changed since the run in .* began") as error:
        train(tiny(PENDULUM, demos_path, steps=200), tmp_path / "run", resume=True, progress=False)
    assert "\n" not in str(error.value)
    # the recorded hash also guards a run built from its config.json
    saved = RunConfig.from_dict(json.loads((tmp_path / "run" / "config.json").read_text()))
    with pytest.raises(ValueError, match="changed since this run began"):
        saved.load_demos()


def test_bad_input_is_named(demo_files, tmp_path):
    with pytest.raises(ValueError, match="unknown env_id 'NoSuchEnv-v0'"):
        tiny("NoSuchEnv-v0", demo_files[PENDULUM])
    with pytest.raises(ValueError, match="unknown env_id 'no_such_module:NoSuchEnv-v0': No module named"):
        tiny("no_such_module:NoSuchEnv-v0", demo_files[PENDULUM])
    with pytest.raises(ValueError, match=f"recorded on {PENDULUM}, not on InvertedDoublePendulum-v5"):
        tiny("InvertedDoublePendulum-v5", demo_files[PENDULUM])
    with pytest.raises(ValueError, match="ships no demos: give demos the path of a demo file"):
        RunConfig(env_id=PENDULUM, demos=500)
    demos = load_demos(path=demo_files[PENDULUM])
    del demos["states"]
    save_demos(demos, tmp_path / "stateless.npz")
    with pytest.raises(ValueError, match="has no 'states'"):
        tiny(PENDULUM, tmp_path / "stateless.npz")
    with pytest.raises(ValueError, match="does not exist"):
        tiny(PENDULUM, tmp_path / "missing.npz")


def test_the_cli_trains_a_gymnasium_id_from_a_demo_file(demo_files, tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["train", "--method", "uniform_ss", "--env", PENDULUM, "--demos", str(demo_files[PENDULUM]),
            "--steps", "150", "--eval-every", "150", "--eval-episodes", "2", "--set", "sac.learning_starts=100",
            "--set", "sac.hidden_sizes=[16,16]", "--out", str(out), "--no-progress"]
    assert cli_main(argv) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["env_id"] == PENDULUM and config["demos"] == str(demo_files[PENDULUM].resolve())
    assert len(config["demos_sha256"]) == 64
    assert cli_main(["report", str(tmp_path), "--out", str(tmp_path / "report")]) == 0
    with pytest.raises(SystemExit) as exit_:
        cli_main(["train", "--method", "auxss", "--env", PENDULUM, "--demos", str(tmp_path / "none.npz")])
    assert exit_.value.code == 2 and "is none of these" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        cli_main([*argv[:-3], "--out", str(tmp_path / "video"), "--video"])
    assert exit_.value.code == 2 and f"{PENDULUM} is another env" in capsys.readouterr().err


def test_the_reverse_curriculum_is_refused_demos_none_of_whose_episodes_succeed(tmp_path):
    demos = record_demos(gymnasium.make(REACH), lambda obs: np.array([-3.0]), 60, seed=0)  # pushed left: falls
    assert "successes" in demos and not demos["successes"].any()
    save_demos(demos, tmp_path / "failures.npz")
    with pytest.raises(ValueError, match=r"reverse_ss needs demo episodes that end in success, but none of the "
                                         r"\d+ episodes of demo file .*failures.npz does"):
        train(tiny(REACH, tmp_path / "failures.npz", "reverse_ss"), tmp_path / "run", progress=False)
