"""The external tasks (lava_bridge_mj.external) in the trainer by id: their shipped demo sets, training
from p0 and ood through the CLI, batched seeds, videos and the demos command."""

import json
import subprocess
import sys

import imageio.v2 as imageio
import numpy as np
import pytest
from conftest import metrics_without_wall_time

import lava_bridge_mj
from lava_bridge_mj import EXTERNAL_TASKS, RunConfig, load_demos, make_task_env
from lava_bridge_mj.agents.rfcl import FORWARD_SEEDS, p0_states
from lava_bridge_mj.demos import SHIPPED_SEEDS, SHIPPED_SIZES, content_hash, generate_task_demos
from lava_bridge_mj.agents.sac import SACConfig
from lava_bridge_mj.eval.cli import main as cli_main
from lava_bridge_mj.eval.training.evaluate import MAX_EVAL_BYTES, evaluate, members_at_once
from lava_bridge_mj.eval.training.runner import Run, make_agent
from lava_bridge_mj.eval.training.run_files import EPISODE_LOG
from lava_bridge_mj.state_vector import ResetToStateVectorEnv

pytest.importorskip("gymnasium_robotics")
pytest.importorskip("ogbench")

MEDIUM, LARGE, CUBE = "PointMaze_Medium-v3", "PointMaze_Large-v3", "cube-single-singletask-task1-v0"
METHODS = ("sac", "auxss", "omega_ss", "uniform_ss", "goaldist_ss", "reverse_ss", "rfcl_reverse", "rfcl", "hysac_auxss")
"""Every method that starts training episodes from p0 or from demo states (the registry has no rfcl;
reverse_ss is its reverse curriculum)."""
TINY = ["--set", "sac.hidden_sizes=[16,16]", "--set", "sac.batch_size=32", "--set", "sac.buffer_size=500",
        "--set", "sac.learning_starts=100", "--set", "demo_subset=20", "--no-progress"]


def train_cli(out, method, seeds="0-1", env_id=MEDIUM, steps=200, *extra):
    argv = ["train", "--env", env_id, "--method", method, "--seeds" if "-" in seeds else "--seed", seeds,
            "--steps", str(steps), "--eval-every", str(steps), "--eval-episodes", "1", "--out", str(out), *TINY, *extra]
    assert cli_main(argv) == 0


@pytest.fixture(scope="module")
def medium_runs(tmp_path_factory):
    """Every method, seeds 0 and 1 batched, 200 steps on PointMaze_Medium-v3 by id, no --demos."""
    root = tmp_path_factory.mktemp("medium")
    for method in METHODS:
        train_cli(root / method, method)
    return root


# --- shipped demo sets -------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", sorted(EXTERNAL_TASKS))
@pytest.mark.parametrize("size", SHIPPED_SIZES)
def test_a_shipped_set_replays_from_its_first_states(env_id, size):
    """Resetting to an episode's first state and taking its actions reproduces its states and
    observations exactly; the expert's episodes end in success (all but the set's cut last one)."""
    demos = load_demos(size, env_id=env_id)
    assert len(demos["actions"]) == size and demos["env_id"] == env_id
    ids = demos["episode_ids"]
    assert demos["terminations"][np.flatnonzero(np.diff(ids))].all() and demos["truncations"][-1]
    assert demos["successes"][demos["terminations"]].all()
    env = make_task_env(env_id)
    for episode in range(2):  # the first two episodes
        rows = np.flatnonzero(ids == episode)
        observation, info = env.reset(options={"state": demos["states"][rows[0]]})
        np.testing.assert_array_equal(info["state"], demos["states"][rows[0]])
        for row in rows:
            flat = lava_bridge_mj.demos.gymnasium.spaces.flatten(env.observation_space, observation)
            np.testing.assert_array_equal(flat, demos["observations"][row])
            observation, reward, terminated, _, info = env.step(demos["actions"][row])
            assert reward == demos["rewards"][row] and terminated == demos["terminations"][row]
            if row + 1 < size and ids[row + 1] == episode:
                np.testing.assert_array_equal(info["state"], demos["states"][row + 1])
    env.close()


def test_a_task_set_regenerates_bit_for_bit_and_the_command_checks_it():
    assert content_hash(generate_task_demos(MEDIUM, 500, SHIPPED_SEEDS[500])) == content_hash(load_demos(500, env_id=MEDIUM))
    done = subprocess.run([sys.executable, "-m", "lava_bridge_mj", "demos", "--check", "--env", MEDIUM],
                          capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout.count("identical") == 2, done.stdout + done.stderr
    done = subprocess.run([sys.executable, "-m", "lava_bridge_mj", "demos", "--check", "--env", "Maze-v0"],
                          capture_output=True, text=True)
    assert done.returncode == 2 and "no shipped demo sets for 'Maze-v0'" in done.stderr


def test_a_task_set_exports_to_minari(tmp_path, monkeypatch):
    pytest.importorskip("minari")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    dataset = lava_bridge_mj.demos.to_minari(500, MEDIUM)
    demos = load_demos(500, env_id=MEDIUM)
    assert dataset.total_steps == 500 and dataset.total_episodes == int(demos["episode_ids"][-1]) + 1
    first = next(dataset.iterate_episodes())
    rows = demos["episode_ids"] == 0
    np.testing.assert_array_equal(first.actions, demos["actions"][rows])
    np.testing.assert_array_equal(first.observations[:-1], demos["observations"][rows])
    assert first.terminations[-1] and dataset.recover_environment().spec.id == MEDIUM


# --- training by id ----------------------------------------------------------------------------
def test_the_tasks_train_with_their_horizon_their_starts_and_their_shipped_demos():
    config = RunConfig(env_id=MEDIUM, method="auxss")
    assert config.demos == 500 and config.external and config.strategy == {"kernel_dims": "position"}
    for env_id, horizon in ((LARGE, 800), (MEDIUM, 600), (CUBE, 200)):
        envs = ResetToStateVectorEnv(env_id, 1)
        assert envs.max_episode_steps == horizon == EXTERNAL_TASKS[env_id].max_episode_steps
        assert envs.start_names == ("p0", "ood")
        envs.close()
    with pytest.raises(ValueError, match=r"'PointMaze_UMaze-v3' ships no demos: .* the external tasks \['PointMaze_Large-v3'"):
        RunConfig(env_id="PointMaze_UMaze-v3")


@pytest.mark.parametrize("method", METHODS)
def test_every_method_trains_two_seeds_by_id_evaluated_from_p0_and_ood(medium_runs, method):
    demos = load_demos(500, env_id=MEDIUM)
    for seed in (0, 1):
        run = medium_runs / method / f"seed{seed}"
        config = json.loads((run / "config.json").read_text())
        assert config["env_id"] == MEDIUM and config["demos"] == 500 and config["seed"] == seed
        (row,) = metrics_without_wall_time(run)
        assert row["step"] == "200"
        for start in ("p0", "ood"):  # evaluated from both: numbers, not the NaN of an undeclared start
            assert 0.0 <= float(row[f"success_{start}"]) <= 1.0 and np.isfinite(float(row[f"return_{start}"]))
        if method != "sac":  # the candidate start states are states of the shipped set
            states = np.load(run / "start_weights.npz")["states"]
            from_demos = np.array([(demos["states"] == state).all(axis=1).any() for state in states])
            if method == "rfcl":  # then the forward stage's p0 states: the task's own reset states, seeds 0, 1, ...
                assert from_demos[:-FORWARD_SEEDS].all() and len(states) > FORWARD_SEEDS
                np.testing.assert_array_equal(states[-FORWARD_SEEDS:], p0_states(make_task_env(MEDIUM), FORWARD_SEEDS))
            else:
                assert from_demos.all()
    if method in ("auxss", "hysac_auxss"):
        assert config["strategy"] == {"kernel_dims": "position"}


def test_a_batched_seed_equals_the_seed_alone(medium_runs, tmp_path):
    train_cli(tmp_path / "alone", "auxss", "1")
    assert metrics_without_wall_time(tmp_path / "alone") == metrics_without_wall_time(medium_runs / "auxss" / "seed1")
    assert (tmp_path / "alone" / EPISODE_LOG).read_bytes() == (medium_runs / "auxss" / "seed1" / EPISODE_LOG).read_bytes()
    alone, batched = (np.load(d / "start_weights.npz") for d in (tmp_path / "alone", medium_runs / "auxss" / "seed1"))
    np.testing.assert_array_equal(alone["probabilities"], batched["probabilities"])


def test_an_evaluation_vector_env_holds_the_members_whose_models_fit(tmp_path):
    env = make_task_env(MEDIUM)
    model, data = env.unwrapped.model, env.unwrapped.data
    assert model.nbuffer > 6 * 800 * 800 * 3  # each maze env's own model: mostly its skybox, 6 RGB faces of 800 x 800
    assert members_at_once(10, 50, env) == 1  # 50 episodes' models are more than MAX_EVAL_BYTES
    assert members_at_once(40, 2, env) == MAX_EVAL_BYTES // (2 * (model.nbuffer + data.nbuffer)) < 40
    assert members_at_once(10, 50) == 10 and members_at_once(40, 50) == 25  # Lava Bridge: 1,250 sub-envs
    config = RunConfig(env_id=MEDIUM, method="auxss", eval_episodes=30)
    run = Run([config, RunConfig(env_id=MEDIUM, method="auxss", eval_episodes=30, seed=1)],
              [tmp_path / "seed0", tmp_path / "seed1"])
    assert run.eval_envs.num_envs == 30  # one seed's episodes at a time, not both seeds' 60


def test_members_evaluated_a_group_at_a_time_run_the_episodes_of_all_at_once():
    agent = make_agent(RunConfig(env_id=MEDIUM, method="auxss", sac=SACConfig(hidden_sizes=(16, 16))), seeds=[0, 1])
    one, both = ResetToStateVectorEnv(MEDIUM, 3), ResetToStateVectorEnv(MEDIUM, 6)
    for start in ("p0", "ood"):
        assert evaluate(agent, one, start, 3, horizon=40) == evaluate(agent, both, start, 3, horizon=40)
        # the last group's episodes ended in the same states, bit for bit
        np.testing.assert_array_equal(one.get_state(), both.get_state()[3:])


def test_a_short_run_on_the_cube(tmp_path):
    train_cli(tmp_path / "cube", "auxss", "0", CUBE, 100)
    (row,) = metrics_without_wall_time(tmp_path / "cube")
    # OGBench's reward: -1 a step until success, so 200 steps without it return -200 from both starts
    assert float(row["return_p0"]) >= -200 and float(row["return_ood"]) >= -200
    assert float(row["success_ood"]) in (0.0, 1.0)


def test_a_run_on_a_task_renders_its_video(medium_runs, tmp_path, capsys):
    out = tmp_path / "rollouts.mp4"
    assert cli_main(["video", str(medium_runs / "sac" / "seed0"), "--episodes", "1", "--max-steps", "3",
                     "--out", str(out)]) == 0
    assert "successes p0 0/1, ood 0/1" in capsys.readouterr().out
    frames = imageio.mimread(out)
    assert len(frames) == 2 * (1 + 3) and frames[0].shape == (480, 480, 3)
    with pytest.raises(SystemExit) as exit_:
        cli_main(["video", str(medium_runs / "sac" / "seed0"), "--max-steps", "601"])
    assert exit_.value.code == 2 and "--max-steps must be in 1-600" in capsys.readouterr().err


def test_a_sweep_takes_a_task_by_id(tmp_path, capsys):
    from lava_bridge_mj.eval.sweeps import sweep

    config = tmp_path / "tiny.json"
    config.write_text(json.dumps({"demo_subset": 20, "sac": {"hidden_sizes": [16, 16], "batch_size": 32,
                                                             "buffer_size": 500, "learning_starts": 100}}))
    out = tmp_path / "out"
    argv = ["--methods", "uniform_ss", "--seeds", "0", "--steps", "100", "--eval-every", "100", "--eval-episodes", "1",
            "--config", str(config), "--out", str(out), "--workers", "1"]
    assert sweep.main([*argv, "--envs", MEDIUM]) == 0
    run = out / MEDIUM / "uniform_ss-d500" / "seed0"
    assert json.loads((run / "config.json").read_text())["env_id"] == MEDIUM and (run / "final.pt").exists()
    with pytest.raises(SystemExit) as exit_:
        sweep.main([*argv, "--envs", "NoSuchMaze-v0"])
    assert exit_.value.code == 2 and "unknown task 'NoSuchMaze-v0'" in capsys.readouterr().err
