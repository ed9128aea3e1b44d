"""Demonstrations in from Minari: the exported datasets carry each step's state, `load_minari_demos`
reads them back as a demo set, and training from `minari:ID` equals training from the set exported."""

from __future__ import annotations

import json

import gymnasium
import numpy as np
import pytest
from conftest import metrics_without_wall_time

import lava_bridge_mj
from lava_bridge_mj import RunConfig, ResetToState, load_demos, train
from lava_bridge_mj.demos import content_hash, load_minari_demos, minari_dataset_id, minari_dataset_path, to_minari
from lava_bridge_mj.eval.cli import main as cli_main
from lava_bridge_mj.eval.training.run_files import RunDirectoryError

minari = pytest.importorskip("minari")
h5py = pytest.importorskip("h5py")

DATASET = minari_dataset_id(500)  # lava_bridge/LavaBridge-v0/expert-500-v0
EXPORT = "python -m lava_bridge_mj demos --minari --size 500 --env LavaBridge-v0"


@pytest.fixture
def minari_root(tmp_path, monkeypatch):
    """Minari's datasets root in a fresh temporary directory, never the user's."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    return tmp_path / "datasets"


def tiny(**changes) -> RunConfig:
    return RunConfig(**{"method": "auxss", "steps": 300, "eval_every": 150, "eval_episodes": 2, **changes})


def edit_hdf5(dataset_id: str, edit) -> None:
    """Apply `edit(h5py.File)` to the stored episodes of a local HDF5 Minari dataset."""
    path = minari.storage.get_dataset_path(dataset_id) / "data" / "main_data.hdf5"
    with h5py.File(path, "a") as file:
        edit(file)


@pytest.mark.parametrize("env_id, size", [("LavaBridge-v0", 500), ("LavaBridgeTwoCrossings-v0", 7500)])
def test_export_then_load_gives_the_shipped_set_with_its_states(minari_root, env_id, size):
    shipped = load_demos(size, env_id=env_id)
    to_minari(size, env_id=env_id)
    # each episode's infos hold one state per observation: Lava Bridge's state is the observation
    for episode in minari.load_dataset(minari_dataset_id(size, env_id)).iterate_episodes():
        np.testing.assert_array_equal(episode.infos["state"], episode.observations)
    loaded = load_minari_demos(minari_dataset_id(size, env_id))
    assert set(loaded) == set(shipped) | {"states", "env_id"} and loaded["env_id"] == env_id
    for name, array in shipped.items():
        assert loaded[name].dtype == array.dtype, name
        np.testing.assert_array_equal(loaded[name], array, err_msg=name)
    # the states are the ones the trainer starts Lava Bridge from: the observations before each step
    np.testing.assert_array_equal(loaded["states"], shipped["observations"])
    env = lava_bridge_mj.LavaBridgeEnv(layout=lava_bridge_mj.task_layout(env_id))
    t = int(np.flatnonzero(loaded["episode_ids"] == 1)[5])
    env.reset(options={"state": loaded["states"][t]})
    np.testing.assert_array_equal(env.step(loaded["actions"][t])[0], loaded["next_observations"][t])
    env.close()


def test_a_run_from_minari_equals_the_run_from_the_shipped_set(minari_root, tmp_path, one_torch_thread):
    to_minari(500)
    shipped_dirs = [tmp_path / "shipped" / f"seed{s}" for s in (0, 1)]
    minari_dirs = [tmp_path / "minari" / f"seed{s}" for s in (0, 1)]
    train(tiny(demos=500), shipped_dirs, seeds=[0, 1], progress=False)
    run = train(tiny(demos=f"minari:{DATASET}"), minari_dirs, seeds=[0, 1], progress=False)
    for shipped, minari_dir in zip(shipped_dirs, minari_dirs):
        rows = metrics_without_wall_time(minari_dir)
        assert [row["step"] for row in rows] == ["150", "300"]
        assert rows == metrics_without_wall_time(shipped)
        with np.load(shipped / "start_weights.npz") as a, np.load(minari_dir / "start_weights.npz") as b:
            assert a.files == b.files
            for name in a.files:
                np.testing.assert_array_equal(a[name], b[name], err_msg=name)
        config = json.loads((minari_dir / "config.json").read_text())
        assert config["demos"] == f"minari:{DATASET}"
        assert config["demos_sha256"] == content_hash(load_minari_demos(DATASET)) == run.config.demos_sha256


def test_a_resume_refuses_a_minari_dataset_that_changed(minari_root, tmp_path):
    to_minari(500)
    config = tiny(demos=f"minari:{DATASET}", steps=150)
    train(config, tmp_path / "run", progress=False)

    def nudge_an_action(file):
        file["episode_1/actions"][3] = file["episode_1/actions"][3] * 0.5
    edit_hdf5(DATASET, nudge_an_action)
    with pytest.raises(RunDirectoryError, match=f"Minari dataset {DATASET} changed since the run in .* began") as error:
        train(tiny(demos=f"minari:{DATASET}", steps=300), tmp_path / "run", resume=True, progress=False)
    assert "\n" not in str(error.value)
    saved = RunConfig.from_dict(json.loads((tmp_path / "run" / "config.json").read_text()))
    with pytest.raises(ValueError, match=f"Minari dataset {DATASET} changed since this run began"):
        saved.load_demos()


def test_a_missing_dataset_is_named_with_the_command_that_writes_it(minari_root):
    with pytest.raises(ValueError) as error:
        load_minari_demos(DATASET)
    assert str(error.value) == f"Minari dataset {DATASET} is not in {minari_root}: write it with `{EXPORT}`"
    with pytest.raises(ValueError, match=r"^Minari dataset D4RL/door/human-v2 is not in .*: download it "
                                         r"\(`minari download D4RL/door/human-v2`\)"):
        tiny(demos="minari:D4RL/door/human-v2")
    assert not (minari_root / "D4RL").exists()  # nothing downloaded


def test_a_dataset_without_states_is_refused_in_one_line(minari_root):
    to_minari(500)
    edit_hdf5(DATASET, lambda file: file["episode_0"].__delitem__("infos"))
    with pytest.raises(ValueError) as error:
        tiny(demos=f"minari:{DATASET}")
    assert str(error.value) == (f"Minari dataset {DATASET} carries no states (infos['state'], one per observation) "
                                f"in episode 0, which the start strategies start from: delete it "
                                f"(minari.delete_dataset('{DATASET}')) and write it again with `{EXPORT}`")


def test_a_dataset_of_another_recorder_without_states_says_how_to_record_them(minari_root):
    from minari.data_collector import EpisodeBuffer

    demos = load_demos(500)
    rows = demos["episode_ids"] == 0
    observations = np.concatenate([demos["observations"][rows], demos["next_observations"][rows][-1:]])
    episode = EpisodeBuffer(observations=observations,
                            actions=demos["actions"][rows], rewards=demos["rewards"][rows],
                            terminations=demos["terminations"][rows], truncations=demos["truncations"][rows])
    with pytest.warns(UserWarning):  # no code URL, no e-mail
        minari.create_dataset_from_buffers("test/LavaBridge-v0/nostates-v0", [episode], env="LavaBridge-v0",
                                           algorithm_name="expert", author="test", data_format="hdf5")
    with pytest.raises(ValueError, match=r"^Minari dataset test/LavaBridge-v0/nostates-v0 carries no states .* "
                                         r"in episode 0, .*: record it with minari.DataCollector\(lava_bridge_mj."
                                         r"ResetToState\(env\), record_infos=True\)$"):
        load_minari_demos("test/LavaBridge-v0/nostates-v0")


def test_data_collector_states_train_another_env(minari_root, tmp_path):
    pytest.importorskip("jax")  # Minari's DataCollector records steps with jax (minari[create])

    class KeepState(minari.StepDataCallback):  # Gymnasium's MuJoCo envs report other info keys at reset
        def __call__(self, env, **kwargs):
            step = super().__call__(env, **kwargs)
            step["info"] = {"state": step["info"]["state"]}
            return step

    env = minari.DataCollector(ResetToState(gymnasium.make("InvertedPendulum-v5", max_episode_steps=40)),
                               step_data_callback=KeepState, record_infos=True)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    for _ in range(3):
        while not any(env.step(rng.uniform(-3, 3, 1).astype(np.float32))[2:4]):
            pass
        env.reset()
    env.create_dataset("test/InvertedPendulum-v5/random-v0", eval_env="InvertedPendulum-v5", algorithm_name="random",
                       author="test", author_email="test@example.org", code_permalink="none",
                       description="random actions")
    env.close()
    demos = load_minari_demos("test/InvertedPendulum-v5/random-v0")
    assert demos["env_id"] == "InvertedPendulum-v5" and demos["episode_ids"][-1] == 2
    # each state restores the moment of its observation: stepping its action gives the next observation
    replay = ResetToState(gymnasium.make("InvertedPendulum-v5"))
    for t in range(len(demos["actions"])):
        obs, _ = replay.reset(options={"state": demos["states"][t]})
        np.testing.assert_array_equal(obs, demos["observations"][t])
        np.testing.assert_array_equal(replay.step(demos["actions"][t])[0], demos["next_observations"][t])
    replay.close()
    config = RunConfig(env_id="InvertedPendulum-v5", demos="minari:test/InvertedPendulum-v5/random-v0",
                       method="auxss", steps=100, eval_every=100, eval_episodes=2)
    run = train(config, tmp_path / "run", progress=False)
    assert len(run.strategy.states) == len(demos["states"]) and run.strategy.states.shape[1] == replay.state_size


def test_cli_trains_from_minari_and_refuses_a_missing_dataset_with_exit_2(minari_root, tmp_path, capsys):
    args = ["train", "--method", "auxss", "--steps", "150", "--eval-every", "150", "--eval-episodes", "2",
            "--no-progress", "--demos", f"minari:{DATASET}", "--out", str(tmp_path / "run")]
    with pytest.raises(SystemExit) as exit_code:
        cli_main(args)
    assert exit_code.value.code == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == (f"lava-bridge-bench train: error: options: Minari dataset {DATASET} is not in "
                                    f"{minari_root}: write it with `{EXPORT}`")
    assert not (tmp_path / "run").exists()
    to_minari(500)
    assert cli_main(args) == 0
    assert json.loads((tmp_path / "run" / "config.json").read_text())["demos"] == f"minari:{DATASET}"


def test_sweep_runs_from_minari_go_to_the_dataset_name(minari_root, tmp_path):
    from lava_bridge_mj.eval.sweeps.sweep import main as sweep_main

    to_minari(500)
    assert sweep_main(["--methods", "sac", "--seeds", "0", "--steps", "100", "--eval-every", "100",
                       "--eval-episodes", "2", "--demos", f"minari:{DATASET}", "--workers", "1",
                       "--progress-every", "0", "--out", str(tmp_path / "sweep")]) == 0
    config = json.loads((tmp_path / "sweep" / "sac-dexpert-500-v0" / "seed0" / "config.json").read_text())
    assert config["demos"] == f"minari:{DATASET}" and config["demos_sha256"] == content_hash(load_minari_demos(DATASET))
    assert minari_dataset_path(500).exists()
