"""Expert demonstration sets: generate them from a seed, ship them, load them with integrity checks.

Every task of the suite (`lava_bridge_mj.TASKS`) ships two sets, 500 and 7,500 transitions: whole
scripted-expert episodes from p0, concatenated until the size is reached; the last episode is cut
there and marked truncated. LavaBridge-v0's are `assets/demos_500.npz` and `assets/demos_7500.npz`
(its 500 set is 3 trajectories, as in the paper), another task's `assets/demos_<env id>_<size>.npz`.
`assets/demos.json` records, per task and size, the file, seed, episode count and a SHA-256 of the
arrays; `python -m lava_bridge_mj demos --check` regenerates every set and compares them bit for bit.
"""

from __future__ import annotations

import hashlib
import json
from importlib import resources
from pathlib import Path

import numpy as np

from lava_bridge_mj.expert import ScriptedExpert
from lava_bridge_mj.lava_bridge import MAX_EPISODE_STEPS, LavaBridgeEnv
from lava_bridge_mj.tasks import DEFAULT_ENV_ID, TASKS, task_layout

SHIPPED_SIZES = (500, 7500)
SHIPPED_SEEDS = {500: 0, 7500: 1}
MANIFEST = "demos.json"


def demo_file(env_id: str, size: int) -> str:
    """The asset file name of a task's shipped set (LavaBridge-v0 keeps its original names)."""
    return f"demos_{size}.npz" if env_id == DEFAULT_ENV_ID else f"demos_{env_id}_{size}.npz"

FIELDS = {  # name: (dtype, per-transition shape)
    "observations": (np.float64, (4,)),
    "actions": (np.float32, (2,)),
    "rewards": (np.float64, ()),
    "next_observations": (np.float64, (4,)),
    "terminations": (np.bool_, ()),
    "truncations": (np.bool_, ()),
    "episode_ids": (np.int32, ()),
}


def generate_demos(size: int, seed: int, env: LavaBridgeEnv | None = None) -> dict[str, np.ndarray]:
    """Roll out the scripted expert from p0 until `size` transitions are collected."""
    if not (isinstance(size, (int, np.integer)) and size >= 1):
        raise ValueError(f"demo size must be a positive integer, got {size!r}")
    env = env or LavaBridgeEnv()
    expert = ScriptedExpert(env)
    columns: dict[str, list] = {name: [] for name in FIELDS}
    episode = 0
    obs, _ = env.reset(seed=seed)
    while len(columns["observations"]) < size:
        for t in range(MAX_EPISODE_STEPS):
            action = expert.act(obs)
            next_obs, reward, terminated, _, _ = env.step(action)
            full = len(columns["observations"]) + 1 == size
            truncated = not terminated and (t + 1 == MAX_EPISODE_STEPS or full)
            for name, value in zip(FIELDS, (obs, action, reward, next_obs, terminated, truncated, episode)):
                columns[name].append(value)
            obs = next_obs
            if terminated or truncated:
                break
        episode += 1
        obs, _ = env.reset()
    return {name: np.asarray(values, dtype=FIELDS[name][0]) for name, values in columns.items()}


def content_hash(demos: dict[str, np.ndarray]) -> str:
    """SHA-256 over every field's name, dtype, shape and bytes, in a fixed order."""
    digest = hashlib.sha256()
    for name in FIELDS:
        array = np.ascontiguousarray(demos[name])
        digest.update(f"{name}|{array.dtype.str}|{array.shape}|".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def save_demos(demos: dict[str, np.ndarray], path: str | Path) -> None:
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        np.savez_compressed(f, **demos)
    tmp.replace(path)  # never leave a half-written file under the real name


def check_demos(demos: dict[str, np.ndarray], source: str) -> None:
    """Raise ValueError naming `source` and the problem unless `demos` is a well-formed demo set."""
    missing = set(FIELDS) - set(demos)
    if missing:
        raise ValueError(f"demo file {source} lacks fields {sorted(missing)}")
    n = len(demos["observations"])
    for name, (dtype, shape) in FIELDS.items():
        array = demos[name]
        if array.dtype != dtype or array.shape != (n, *shape):
            raise ValueError(f"demo file {source}: field {name!r} has dtype {array.dtype} and shape "
                             f"{array.shape}; expected {np.dtype(dtype)} and {(n, *shape)}")
    for name in ("observations", "actions", "rewards", "next_observations"):
        if not np.isfinite(demos[name]).all():
            raise ValueError(f"demo file {source}: field {name!r} has non-finite values")


def load_demos(size: int = 500, path: str | Path | None = None, env_id: str = DEFAULT_ENV_ID) -> dict[str, np.ndarray]:
    """A task's shipped demo set by size (500 or 7500), or a file written by `save_demos` at `path`.

    `env_id` names the task (`lava_bridge_mj.TASKS`; LavaBridge-v0 by default); it is ignored with
    `path`. Returns a dict of arrays: observations, actions, rewards, next_observations,
    terminations, truncations, episode_ids. Shipped sets are checked against their recorded SHA-256.
    """
    if path is None:
        task_layout(env_id)  # ValueError naming an unknown task
        if size not in SHIPPED_SIZES:
            raise ValueError(f"no shipped demo set of size {size!r}; expected one of {SHIPPED_SIZES}")
        assets = resources.files("lava_bridge_mj.assets")
        source = assets.joinpath(demo_file(env_id, size))
        recorded = json.loads(assets.joinpath(MANIFEST).read_text()).get(env_id, {}).get(str(size))
        if recorded is None:
            raise ValueError(f"{MANIFEST} records no {size}-transition demo set for {env_id}; "
                             "regenerate the sets with `python -m lava_bridge_mj demos`")
        expected = recorded["sha256"]
    else:
        source, expected = Path(path), None
    try:
        with source.open("rb") as f:
            archive = np.load(f, allow_pickle=False)
            if not isinstance(archive, np.lib.npyio.NpzFile):
                raise ValueError("it holds a single array, not an .npz archive of named arrays")
            with archive:
                demos = {name: archive[name] for name in archive.files}
    except FileNotFoundError:
        raise ValueError(f"demo file {source} does not exist") from None
    except Exception as error:  # a damaged archive fails in zlib, zipfile, the .npy header parser, ...
        raise ValueError(f"demo file {source} is not a readable .npz archive "
                         f"({type(error).__name__}: {error})") from None
    check_demos(demos, str(source))
    if expected is not None and content_hash(demos) != expected:
        raise ValueError(f"demo file {source} is corrupt: its content hash differs from the one "
                         f"recorded in {MANIFEST}; reinstall the package or regenerate it")
    return demos


def regenerate_demos(check: bool = False) -> bool:
    """Regenerate every task's shipped sets from their seeds: write them, or with `check` only compare.

    Returns True when (checking) every shipped set is bit-identical to its regeneration.
    """
    assets = Path(str(resources.files("lava_bridge_mj.assets")))
    manifest, identical = {}, True
    for env_id, layout in TASKS.items():
        manifest[env_id] = {}
        for size in SHIPPED_SIZES:
            demos = generate_demos(size, SHIPPED_SEEDS[size], LavaBridgeEnv(layout=layout))
            digest = content_hash(demos)
            episodes = int(demos["episode_ids"][-1]) + 1
            name = demo_file(env_id, size)
            manifest[env_id][str(size)] = {"file": name, "seed": SHIPPED_SEEDS[size], "episodes": episodes,
                                           "sha256": digest}
            if check:
                try:
                    same = content_hash(load_demos(size, env_id=env_id)) == digest
                except ValueError as error:  # missing, unreadable or not matching its recorded hash
                    print(f"{name}: {error}")
                    same = False
                identical &= same
                print(f"{name}: {'identical' if same else 'DIFFERENT'} ({episodes} episodes)")
            else:
                save_demos(demos, assets / name)
                print(f"wrote {name}: {episodes} episodes, sha256 {digest[:12]}")
    if not check:
        (assets / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return identical
