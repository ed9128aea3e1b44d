"""The scripted expert and the shipped expert demonstration sets (content, reproducibility, integrity)."""

from __future__ import annotations

import io
import json
import shutil
import struct
import types
import zipfile
from importlib import resources

import numpy as np
import pytest

from lava_bridge_mj import Layout, LavaBridgeEnv, ScriptedExpert, load_demos, start_distribution
from lava_bridge_mj.demos import FIELDS, MANIFEST, SHIPPED_SEEDS, content_hash, generate_demos, save_demos

ASSETS = resources.files("lava_bridge_mj.assets")


def run_expert(start: str, episodes: int, seed: int) -> tuple[int, list]:
    env = LavaBridgeEnv()
    expert = ScriptedExpert(env)
    env.reset(seed=seed)
    successes, failures = 0, []
    for _ in range(episodes):
        obs, _ = env.reset(options={"start": start})
        first = obs
        for _ in range(500):
            obs, _, terminated, _, info = env.step(expert.act(obs))
            if terminated:
                break
        successes += info["is_success"]
        if not info["is_success"]:
            failures.append((first, info))
    return successes, failures


# --- the expert ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("start, required", [("p0", 0.99), ("ood", 0.95)])
def test_expert_succeeds_from_the_start_distributions(start, required):
    successes, failures = run_expert(start, episodes=200, seed=2024)
    assert successes >= required * 200, failures[:5]


def test_expert_is_a_pure_function_of_the_observation():
    expert = ScriptedExpert()
    obs = np.array([-3.3, 0.4, 0.2, -0.1])
    first = expert.act(obs)
    assert first.dtype == np.float32 and first.shape == (2,) and np.all(np.abs(first) <= 1)
    for _ in range(3):
        assert np.array_equal(expert.act(obs.copy()), first)
    assert np.array_equal(expert(obs), first)


# --- shipped demo sets --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def demos500():
    return load_demos(500)


@pytest.fixture(scope="module")
def demos7500():
    return load_demos(7500)


def episodes_of(demos):
    ids = demos["episode_ids"]
    return [np.flatnonzero(ids == e) for e in np.unique(ids)]


def test_shipped_500_set_is_three_episodes(demos500):
    assert len(demos500["observations"]) == 500
    assert np.array_equal(np.unique(demos500["episode_ids"]), [0, 1, 2])


def test_shipped_7500_set_size_matches_its_manifest(demos7500):
    manifest = json.loads(ASSETS.joinpath(MANIFEST).read_text())["LavaBridge-v0"]
    assert len(demos7500["observations"]) == 7500
    assert len(np.unique(demos7500["episode_ids"])) == manifest["7500"]["episodes"]
    assert manifest["500"]["episodes"] == 3
    assert {size: entry["seed"] for size, entry in manifest.items()} == {str(k): v for k, v in SHIPPED_SEEDS.items()}


def test_lava_bridge_v0_sets_keep_their_original_files_and_hashes():
    """The suite added tasks beside LavaBridge-v0; its shipped sets are the ones runs were trained on."""
    manifest = json.loads(ASSETS.joinpath(MANIFEST).read_text())["LavaBridge-v0"]
    assert {size: (entry["file"], entry["sha256"]) for size, entry in manifest.items()} == {
        "500": ("demos_500.npz", "72dfebbf4ec01fbd86dd32d89fbdda02934d96b67bebf8041e46b45698ebae10"),
        "7500": ("demos_7500.npz", "4ff4c781432291186c929794ee54a15c7aa50f958fa64044d6e34398c82aec71"),
    }


@pytest.mark.parametrize("size", [500, 7500])
def test_shipped_sets_are_well_formed(size, demos500, demos7500):
    demos = {500: demos500, 7500: demos7500}[size]
    assert set(demos) == set(FIELDS)
    for name, (dtype, shape) in FIELDS.items():
        assert demos[name].dtype == dtype and demos[name].shape == (size, *shape), name
    for name in ("observations", "actions", "rewards", "next_observations"):
        assert np.isfinite(demos[name]).all()
    assert np.all(np.abs(demos["actions"]) <= 1)
    ids = demos["episode_ids"]
    assert ids[0] == 0 and np.all(np.diff(ids) >= 0) and np.all(np.diff(ids) <= 1)  # contiguous, in order

    ends = demos["terminations"] | demos["truncations"]
    assert not np.any(demos["terminations"] & demos["truncations"])
    for episode in episodes_of(demos):
        # next_observations[t] == observations[t + 1] within an episode
        assert np.array_equal(demos["next_observations"][episode[:-1]], demos["observations"][episode[1:]])
        # exactly one end, at the last transition
        assert np.flatnonzero(ends[episode]).tolist() == [len(episode) - 1]
    # whole episodes succeed (reward +1 on their terminal step, 0 elsewhere); the last is cut, truncated
    *whole, last = episodes_of(demos)
    for episode in whole:
        assert demos["terminations"][episode[-1]]
        assert demos["rewards"][episode[-1]] == 1.0 and np.all(demos["rewards"][episode[:-1]] == 0.0)
        assert len(episode) < 500
    assert demos["truncations"][last[-1]] and not demos["terminations"][last[-1]] and last[-1] == size - 1
    assert np.all(demos["rewards"][last] == 0.0)
    # every episode starts at rest in a p0 blob
    firsts = demos["observations"][[episode[0] for episode in episodes_of(demos)]]
    assert np.all(firsts[:, 2:] == 0.0)
    for x, y, _, _ in firsts:
        assert any(np.hypot(x - b.x, y - b.y) <= b.radius for b in Layout().p0_blobs)


def test_shipped_500_set_replays_exactly_in_the_env(demos500):
    """Each episode, replayed from its first state with its actions, gives its exact transitions."""
    env = LavaBridgeEnv()
    for episode in episodes_of(demos500):
        env.reset(options={"state": demos500["observations"][episode[0]]})
        for t in episode:
            obs, reward, terminated, _, _ = env.step(demos500["actions"][t])
            assert np.array_equal(obs, demos500["next_observations"][t])
            assert reward == demos500["rewards"][t] and terminated == demos500["terminations"][t]


def test_shipped_500_set_is_the_expert_from_its_seed(demos500):
    env = LavaBridgeEnv()
    first, _ = env.reset(seed=SHIPPED_SEEDS[500])
    assert np.array_equal(demos500["observations"][0], first)
    assert np.array_equal(first, start_distribution(Layout(), "p0").sample(np.random.default_rng(SHIPPED_SEEDS[500])))
    expert = ScriptedExpert()
    actions = np.array([expert.act(o) for o in demos500["observations"]])
    assert np.array_equal(actions, demos500["actions"])


def test_regenerating_the_500_set_is_bit_identical(demos500):
    regenerated = generate_demos(500, SHIPPED_SEEDS[500])
    assert content_hash(regenerated) == content_hash(demos500)
    manifest = json.loads(ASSETS.joinpath(MANIFEST).read_text())
    assert content_hash(regenerated) == manifest["LavaBridge-v0"]["500"]["sha256"]
    for name in FIELDS:
        assert np.array_equal(regenerated[name], demos500[name]), name


def test_generate_demos_sizes_and_cut(demos500):
    small = generate_demos(50, seed=SHIPPED_SEEDS[500])
    assert len(small["observations"]) == 50 and small["truncations"][-1] and not small["terminations"].any()
    for name in FIELDS:  # a prefix of the same rollout
        assert np.array_equal(small[name][:49], demos500[name][:49]), name
    with pytest.raises(ValueError, match="positive integer"):
        generate_demos(0, seed=0)


def test_save_and_load_round_trip(tmp_path, demos500):
    path = tmp_path / "copy.npz"
    save_demos(demos500, path)
    loaded = load_demos(path=path)
    assert content_hash(loaded) == content_hash(demos500)
    assert not (tmp_path / "copy.npz.tmp").exists()


# --- the loader rejects bad files ---------------------------------------------------------------------
@pytest.fixture
def fake_assets(tmp_path, monkeypatch):
    """Point the loader's package-resource lookup at tmp_path, holding a copy of the real manifest."""
    shutil.copyfile(str(ASSETS.joinpath(MANIFEST)), tmp_path / MANIFEST)
    import lava_bridge_mj.demos as demos_module
    monkeypatch.setattr(demos_module, "resources", types.SimpleNamespace(files=lambda package: tmp_path))
    return tmp_path


def test_shipped_path_loads_an_untampered_copy(fake_assets, demos500):
    save_demos(demos500, fake_assets / "demos_500.npz")
    assert content_hash(load_demos(500)) == content_hash(demos500)


@pytest.mark.parametrize("field, index", [
    ("observations", (17, 1)),
    ("actions", (3, 0)),
    ("rewards", (499,)),
    ("terminations", (5,)),
    ("episode_ids", (499,)),
])
def test_shipped_set_with_a_flipped_value_is_rejected(fake_assets, demos500, field, index):
    tampered = {name: array.copy() for name, array in demos500.items()}
    value = tampered[field][index]
    tampered[field][index] = (not value) if field == "terminations" else value + 1
    save_demos(tampered, fake_assets / "demos_500.npz")
    with pytest.raises(ValueError, match=r"demos_500\.npz is corrupt.*content hash"):
        load_demos(500)
    # a custom path carries no recorded hash: the same file loads, well formed as it is
    assert load_demos(path=fake_assets / "demos_500.npz")[field][index] != value


def test_shipped_set_with_a_flipped_bit_is_rejected(fake_assets, demos500):
    tampered = {name: array.copy() for name, array in demos500.items()}
    tampered["observations"].view(np.uint64)[250, 0] ^= 1  # the smallest change: one mantissa bit
    save_demos(tampered, fake_assets / "demos_500.npz")
    with pytest.raises(ValueError, match="corrupt"):
        load_demos(500)


def test_unknown_shipped_size_is_rejected():
    for size in (123, 0, "500", None):
        with pytest.raises(ValueError, match=rf"no shipped demo set of size {size!r}"):
            load_demos(size)


def test_missing_file_is_rejected(tmp_path):
    with pytest.raises(ValueError, match="nope.npz does not exist"):
        load_demos(path=tmp_path / "nope.npz")


@pytest.mark.parametrize("contents", [
    pytest.param(lambda raw: raw[: len(raw) // 2], id="truncated"),
    pytest.param(lambda raw: raw[:100], id="header-only"),
    pytest.param(lambda raw: b"", id="empty"),
    pytest.param(lambda raw: bytes(range(256)) * 40, id="garbage"),
    pytest.param(lambda raw: b"observations,actions\n1,2\n" * 50, id="text"),
    pytest.param(lambda raw: raw[:2000] + bytes(1000) + raw[3000:], id="zeroed-block"),
])
def test_unreadable_files_are_rejected(tmp_path, contents):
    raw = ASSETS.joinpath("demos_500.npz").read_bytes()
    path = tmp_path / "bad.npz"
    path.write_bytes(contents(raw))
    with pytest.raises(ValueError, match=r"bad\.npz (is not a readable \.npz archive|lacks fields)"):
        load_demos(path=path)


def test_object_arrays_are_refused_not_unpickled(tmp_path, demos500):
    bad = dict(demos500, observations=np.array([None] * 500, dtype=object))
    np.savez(tmp_path / "pickled.npz", **bad)
    with pytest.raises(ValueError, match=r"pickled\.npz is not a readable"):
        load_demos(path=tmp_path / "pickled.npz")


def deflate_stream_offset(raw: bytes) -> int:
    """Byte offset of the first archive member's compressed data (after its local file header)."""
    with zipfile.ZipFile(io.BytesIO(raw)) as archive:
        info = archive.infolist()[0]
    assert info.compress_type == zipfile.ZIP_DEFLATED
    name_length, extra_length = struct.unpack("<HH", raw[info.header_offset + 26: info.header_offset + 30])
    return info.header_offset + 30 + name_length + extra_length


def test_corrupt_compressed_data_is_rejected_with_value_error(fake_assets):
    raw = bytearray(ASSETS.joinpath("demos_500.npz").read_bytes())
    raw[deflate_stream_offset(bytes(raw))] |= 0b110  # deflate block type 11: reserved, invalid
    (fake_assets / "demos_500.npz").write_bytes(bytes(raw))
    with pytest.raises(ValueError, match="demos_500.npz"):
        load_demos(500)


def test_npy_file_is_rejected_with_value_error(tmp_path):
    path = tmp_path / "array.npz"
    with open(path, "wb") as f:
        np.save(f, np.zeros((500, 4)))
    with pytest.raises(ValueError, match="array.npz"):
        load_demos(path=path)


@pytest.mark.parametrize("change, message", [
    (lambda d: d.pop("rewards"), r"lacks fields \['rewards'\]"),
    (lambda d: [d.pop("terminations"), d.pop("truncations")], r"lacks fields \['terminations', 'truncations'\]"),
    (lambda d: d.update(observations=d["observations"].astype(np.float32)), r"'observations' has dtype float32"),
    (lambda d: d.update(actions=d["actions"].astype(np.float64)), r"'actions' has dtype float64"),
    (lambda d: d.update(terminations=d["terminations"].astype(np.int8)), r"'terminations' has dtype int8"),
    (lambda d: d.update(episode_ids=d["episode_ids"].astype(np.int64)), r"'episode_ids' has dtype int64"),
    (lambda d: d.update(rewards=d["rewards"][:-1]), r"'rewards' .*shape \(499,\).*\(500,\)"),
    (lambda d: d.update(actions=d["actions"][:, :1]), r"'actions' .*shape \(500, 1\)"),
    (lambda d: d["next_observations"].__setitem__((7, 2), np.nan), r"'next_observations' has non-finite"),
    (lambda d: d["rewards"].__setitem__(0, np.inf), r"'rewards' has non-finite"),
])
def test_malformed_sets_are_rejected(tmp_path, demos500, change, message):
    demos = {name: array.copy() for name, array in demos500.items()}
    change(demos)
    path = tmp_path / "malformed.npz"
    save_demos(demos, path)
    with pytest.raises(ValueError, match=rf"malformed\.npz.*{message}"):
        load_demos(path=path)
