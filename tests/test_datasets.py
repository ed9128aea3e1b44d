"""The demo sets in the field's formats: D4RL names, Minari datasets, and Minari's DataCollector on the env."""

from __future__ import annotations

import sys

import gymnasium
import numpy as np
import pytest

import lava_bridge_mj  # noqa: F401  (registers the tasks)
from lava_bridge_mj import load_demos
from lava_bridge_mj.__main__ import main
from lava_bridge_mj.demos import minari_dataset_id, minari_dataset_path, to_minari

D4RL_KEYS = {"observations", "actions", "rewards", "next_observations", "terminals", "timeouts"}


# --- D4RL names ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("size", [500, 7500])
def test_d4rl_format_renames_the_end_flags_and_keeps_the_data(size):
    demos = load_demos(size)
    d4rl = load_demos(size, format="d4rl")
    assert set(d4rl) == D4RL_KEYS
    np.testing.assert_array_equal(d4rl["terminals"], demos["terminations"])
    np.testing.assert_array_equal(d4rl["timeouts"], demos["truncations"])
    for name in ("observations", "actions", "rewards", "next_observations"):
        np.testing.assert_array_equal(d4rl[name], demos[name])
    # every episode ends in exactly one of the two flags, the last one (cut at the set size) in a timeout
    ends = d4rl["terminals"] | d4rl["timeouts"]
    assert ends.sum() == demos["episode_ids"][-1] + 1 and ends[-1] and d4rl["timeouts"][-1]
    assert not (d4rl["terminals"] & d4rl["timeouts"]).any()


def test_d4rl_format_of_a_file_and_a_bad_format(tmp_path):
    path = tmp_path / "set.npz"
    lava_bridge_mj.demos.save_demos(load_demos(500), path)
    assert set(load_demos(path=path, format="d4rl")) == D4RL_KEYS
    with pytest.raises(ValueError, match=r"format='minari'; expected one of \('gymnasium', 'd4rl'\)"):
        load_demos(500, format="minari")


# --- Minari ------------------------------------------------------------------------------------------
@pytest.fixture
def minari_root(tmp_path, monkeypatch):
    """minari, with its datasets root in a fresh temporary directory."""
    minari = pytest.importorskip("minari")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    return minari


def files_under(path):
    return {p: p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("env_id, size", [("LavaBridge-v0", 500), ("LavaBridgeTwoCrossings-v0", 500)])
def test_to_minari_writes_the_shipped_set_episode_by_episode(minari_root, env_id, size):
    demos = load_demos(size, env_id=env_id)
    to_minari(size, env_id=env_id)
    dataset = minari_root.load_dataset(f"lava_bridge/{env_id}/expert-{size}-v0")
    ids = demos["episode_ids"]
    assert dataset.total_episodes == ids[-1] + 1 and dataset.total_steps == size
    for episode in dataset.iterate_episodes():
        rows = ids == episode.id
        expected_obs = np.concatenate([demos["observations"][rows], demos["next_observations"][rows][-1:]])
        np.testing.assert_array_equal(episode.observations, expected_obs)
        np.testing.assert_array_equal(episode.actions, demos["actions"][rows])
        np.testing.assert_array_equal(episode.rewards, demos["rewards"][rows])
        np.testing.assert_array_equal(episode.terminations, demos["terminations"][rows])
        np.testing.assert_array_equal(episode.truncations, demos["truncations"][rows])
    last = int(ids[-1])
    assert episode.id == last and episode.truncations[-1] and not episode.terminations[-1]
    lengths = np.bincount(ids)
    assert (f"The last episode ({last}, {lengths[-1]} steps) is cut where the set reaches {size} transitions"
            in dataset.storage.metadata["description"])

    env = dataset.recover_environment()
    try:
        assert env.spec.max_episode_steps == 500
        assert env.unwrapped.layout == lava_bridge_mj.TASKS[env_id]
        obs, _ = env.reset(seed=0)
        # the recorded actions replay the first episode from its first observation
        env.reset(options={"state": demos["observations"][0]})
        for t in range(int(lengths[0])):
            obs, reward, terminated, truncated, _ = env.step(demos["actions"][t])
        np.testing.assert_array_equal(obs, demos["next_observations"][lengths[0] - 1])
        assert terminated and reward == 1.0
    finally:
        env.close()


def test_to_minari_refuses_an_existing_dataset_and_leaves_it_as_it_was(minari_root, tmp_path):
    to_minari(500)
    before = files_under(tmp_path / "datasets")
    with pytest.raises(ValueError, match="lava_bridge/LavaBridge-v0/expert-500-v0 already exists at"):
        to_minari(500)
    assert files_under(tmp_path / "datasets") == before


def test_to_minari_failing_midway_leaves_no_half_dataset(minari_root, monkeypatch):
    real = minari_root.create_dataset_from_buffers

    def fail_after_making_the_directory(dataset_id, *args, **kwargs):
        minari_dataset_path(500).joinpath("data").mkdir(parents=True)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(minari_root, "create_dataset_from_buffers", fail_after_making_the_directory)
    with pytest.raises(OSError, match="No space left"):
        to_minari(500)
    assert not minari_dataset_path(500).exists()
    monkeypatch.setattr(minari_root, "create_dataset_from_buffers", real)
    assert to_minari(500).total_episodes == 3  # the next try is not blocked


def test_cli_writes_minari_datasets(minari_root, tmp_path, capsys):
    assert main(["demos", "--minari", "--size", "500", "--env", "LavaBridgeNarrow-v0"]) == 0
    assert capsys.readouterr().out == ("wrote Minari dataset lava_bridge/LavaBridgeNarrow-v0/expert-500-v0: "
                                       "3 episodes, 500 steps\n")
    assert list(minari_root.list_local_datasets()) == [minari_dataset_id(500, "LavaBridgeNarrow-v0")]


@pytest.mark.parametrize("argv, message", [
    (["demos", "--minari"], "error: Minari datasets already exist at "),  # 500 exists: 7500 is not written either
    (["demos", "--minari", "--env", "LavaBridge-v9"], "error: no shipped demo sets for 'LavaBridge-v9'"),
])
def test_cli_bad_minari_export_writes_nothing(minari_root, tmp_path, capsys, argv, message):
    to_minari(500)
    before = files_under(tmp_path / "datasets")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(message) and err.count("\n") == 1
    assert files_under(tmp_path / "datasets") == before


@pytest.mark.parametrize("argv", [["model", "--minari"], ["demos", "--minari", "--check"], ["demos", "--size", "500"],
                                  ["demos", "--minari", "--size", "50"]])
def test_cli_misused_minari_flags_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    assert "error:" in capsys.readouterr().err


def test_cli_without_minari_says_how_to_install_it(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "minari", None)  # `import minari` raises ImportError
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    assert main(["demos", "--minari"]) == 2
    assert capsys.readouterr().err == ("error: Minari export needs the minari package with HDF5 support: "
                                       "pip install 'lava-bridge-mj[minari]'\n")
    assert not (tmp_path / "datasets").exists()


def test_minari_data_collector_collects_episodes(minari_root):
    pytest.importorskip("jax")  # Minari's DataCollector records steps with jax (minari[create])
    env = minari_root.DataCollector(gymnasium.make("LavaBridge-v0", max_episode_steps=20))
    rng = np.random.default_rng(0)
    lengths = []
    for options in (None, {"minari_autoseed": False}, {"minari_autoseed": True, "start": "ood"}):
        env.reset(seed=len(lengths), options=options)
        for t in range(1, 21):
            _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
            if terminated or truncated:
                break
        lengths.append(t)
    dataset = env.create_dataset("lava_bridge/LavaBridge-v0/collected-v0", eval_env="LavaBridge-v0",
                                 algorithm_name="random", author="test", author_email="test@example.org",
                                 code_permalink="none", description="random actions")
    env.close()
    assert dataset.total_episodes == 3
    assert [len(episode.actions) for episode in dataset.iterate_episodes()] == lengths
    assert [episode.observations.shape for episode in dataset.iterate_episodes()] == [(n + 1, 4) for n in lengths]
