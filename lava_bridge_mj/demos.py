"""Expert demonstration sets: generate them from a seed, ship them, load them with integrity checks.

Every task of the suite (`lava_bridge_mj.TASKS`) ships two sets, 500 and 7,500 transitions: whole
scripted-expert episodes from p0, concatenated until the size is reached; the last episode is cut
there and marked truncated. LavaBridge-v0's are `assets/demos_500.npz` and `assets/demos_7500.npz`
(its 500 set is 3 trajectories, as in the paper), another task's `assets/demos_<env id>_<size>.npz`.
Each external task (`lava_bridge_mj.external.EXTERNAL_TASKS`) ships the same two sizes, its expert's
episodes from p0 recorded by `record_demos` on `make_task_env(env_id)` (`generate_task_demos`).
`assets/demos.json` records, per task and size, the file, seed, episode count and a SHA-256 of the
arrays; `python -m lava_bridge_mj demos --check` regenerates every set and compares them bit for bit
(`--env ID`: one task's).

`record_demos(env, policy, n_transitions, seed)` records a set the same way on any env that
`ResetToState` serves, with any policy, adding each transition's full state (`states`) and the env's
id (`env_id`): the demonstrations of a task that ships none. `save_demos` writes a set, `load_demos(path=...)`
reads it back.

`load_demos(..., format="d4rl")` gives a set under D4RL's names (terminals, timeouts), and
`to_minari(size, env_id)` (`python -m lava_bridge_mj demos --minari`) writes it as a local Minari
dataset, one Minari episode per expert episode with each step's state in its infos (needs the
`minari` extra); `load_minari_demos(dataset_id)` reads a local Minari dataset back as a demo set, which
`RunConfig(demos="minari:ID")` and `--demos minari:ID` train from.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
import warnings
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import gymnasium
import numpy as np

from lava_bridge_mj.expert import ScriptedExpert
from lava_bridge_mj.external import EXTERNAL_TASKS, make_task_env
from lava_bridge_mj.lava_bridge import MAX_EPISODE_STEPS, LavaBridgeEnv
from lava_bridge_mj.tasks import DEFAULT_ENV_ID, TASKS, task_layout

if TYPE_CHECKING:
    import minari

SHIPPED_SIZES = (500, 7500)
SHIPPED_SEEDS = {500: 0, 7500: 1}
MANIFEST = "demos.json"
FORMATS = ("gymnasium", "d4rl")
D4RL_NAMES = {"terminations": "terminals", "truncations": "timeouts"}
"""load_demos(format="d4rl") renames these fields, drops episode_ids and keeps the rest as they are."""
MINARI_NAMESPACE = "lava_bridge"
MINARI_PREFIX = "minari:"
"""`demos="minari:ID"` (RunConfig, `--demos`) names the local Minari dataset ID instead of a demo file."""


def demo_file(env_id: str, size: int) -> str:
    """The asset file name of a task's shipped set (LavaBridge-v0 keeps its original names)."""
    return f"demos_{size}.npz" if env_id == DEFAULT_ENV_ID else f"demos_{env_id}_{size}.npz"

FIELDS = {  # name: (dtype, per-transition shape on Lava Bridge; other envs have their own dims)
    "observations": (np.float64, (4,)),
    "actions": (np.float32, (2,)),
    "rewards": (np.float64, ()),
    "next_observations": (np.float64, (4,)),
    "terminations": (np.bool_, ()),
    "truncations": (np.bool_, ()),
    "episode_ids": (np.int32, ()),
}
OPTIONAL_FIELDS = {  # name: dtype; what `record_demos` adds, absent from the shipped sets
    "states": np.float64,  # (n, state size): ResetToState's info["state"] before each transition
    "successes": np.bool_,  # (n,): the env's info["success"] or info["is_success"] after it, where it reports one
    "env_id": np.str_,  # (): the gymnasium id of the env recorded on
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


def record_demos(env: gymnasium.Env, policy, n_transitions: int, seed: int) -> dict[str, np.ndarray]:
    """Roll out `policy` in `env` until exactly `n_transitions` transitions are recorded, as
    `generate_demos` does: whole episodes, the first reset seeded with `seed`, the last episode cut at
    the set size and marked truncated.

    `env` is any env that `lava_bridge_mj.ResetToState` serves (it is wrapped if it is not already);
    `policy` maps the env's observation to an action: a callable, or a model with
    `.predict(obs, deterministic=True)` (stable-baselines3's); a callable that also has a method
    `reset(observation, info)` (an external task's expert, `lava_bridge_mj.external.Expert`) is told
    of every reset. Returns the demo format of `load_demos`
    (observations flattened in `gymnasium.spaces.flatten` order, float64; actions as the env took
    them, float32) plus `states`, the full state before each transition (ResetToState's
    `info["state"]`), `env_id`, the env's gymnasium id (its spec's; "" for an env made without one),
    and `successes`, the env's `info["success"]` or `info["is_success"]` after each step, only where
    the env reports one.
    """
    from lava_bridge_mj.reset_to_state import ResetToState

    if not (isinstance(n_transitions, (int, np.integer)) and not isinstance(n_transitions, bool) and n_transitions >= 1):
        raise ValueError(f"n_transitions must be a positive integer, got {n_transitions!r}")
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0):
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    policy_reset = None
    if hasattr(policy, "predict"):
        model = policy
        policy = lambda obs: model.predict(obs, deterministic=True)[0]  # noqa: E731
    elif callable(policy) and callable(getattr(policy, "reset", None)):
        policy_reset = policy.reset
    elif not callable(policy):
        raise ValueError(f"policy must be a callable obs -> action or have .predict(obs, deterministic=True), "
                         f"got {policy!r}")
    wrapped = env
    while isinstance(wrapped, gymnasium.Wrapper) and not isinstance(wrapped, ResetToState):
        wrapped = wrapped.env
    if not isinstance(wrapped, ResetToState):
        env = ResetToState(env)
    space = env.observation_space
    columns: dict[str, list] = {name: [] for name in (*FIELDS, "states", "successes")}
    episode, reports_success = 0, False
    obs, info = env.reset(seed=int(seed))
    while len(columns["observations"]) < n_transitions:
        if policy_reset is not None:
            policy_reset(obs, info)
        while True:
            action = np.asarray(policy(obs), dtype=env.action_space.dtype)
            next_obs, reward, terminated, truncated, next_info = env.step(action)
            full = len(columns["observations"]) + 1 == n_transitions
            truncated = not terminated and (bool(truncated) or full)
            success = next_info.get("success", next_info.get("is_success"))
            reports_success |= success is not None
            for name, value in zip(columns, (gymnasium.spaces.flatten(space, obs), action, reward,
                                             gymnasium.spaces.flatten(space, next_obs), terminated, truncated,
                                             episode, info["state"], bool(success))):
                columns[name].append(value)
            obs, info = next_obs, next_info
            if terminated or truncated:
                break
        episode += 1
        obs, info = env.reset()
    dtypes = {**{name: dtype for name, (dtype, _) in FIELDS.items()}, **OPTIONAL_FIELDS}
    demos = {name: np.asarray(values, dtype=dtypes[name]) for name, values in columns.items()}
    if not reports_success:
        del demos["successes"]
    spec = env.unwrapped.spec if env.spec is None else env.spec
    demos["env_id"] = np.array("" if spec is None else spec.id)
    return demos


def generate_task_demos(env_id: str, size: int, seed: int) -> dict[str, np.ndarray]:
    """An external task's demo set: `size` transitions of its expert (seeded with `seed`) from p0,
    recorded by `record_demos` on `make_task_env(env_id)` with `seed`."""
    env = make_task_env(env_id)
    try:
        return record_demos(env, EXTERNAL_TASKS[env_id].expert(env, seed=seed), size, seed)
    finally:
        env.close()


def shipped_task_ids() -> list[str]:
    """Every task that ships demo sets: the suite's, then the external tasks."""
    return [*TASKS, *EXTERNAL_TASKS]


def check_shipped_task(env_id: str) -> None:
    """ValueError naming `env_id` unless it is a task that ships demo sets."""
    if env_id not in EXTERNAL_TASKS:
        try:
            task_layout(env_id)
        except ValueError:
            raise ValueError(f"no shipped demo sets for {env_id!r}; expected one of {shipped_task_ids()}") from None


def content_hash(demos: dict[str, np.ndarray]) -> str:
    """SHA-256 over every field's name, dtype, shape and bytes, in a fixed order (the optional fields
    last, where present: a set without them hashes as it always has)."""
    digest = hashlib.sha256()
    for name in (*FIELDS, *(name for name in OPTIONAL_FIELDS if name in demos)):
        array = np.ascontiguousarray(demos[name])
        digest.update(f"{name}|{array.dtype.str}|{array.shape}|".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def save_demos(demos: dict[str, np.ndarray], path: str | Path) -> None:
    """Write a demo set (`generate_demos`'s or `record_demos`'s) to the .npz file `path`, atomically."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        np.savez_compressed(f, **demos)
    tmp.replace(path)  # never leave a half-written file under the real name


def check_demos(demos: dict[str, np.ndarray], source: str) -> None:
    """Raise ValueError naming `source` and the problem unless `demos` is a well-formed demo set.

    A set recorded on another env (its `env_id` not a Lava Bridge task) has that env's observation
    and action sizes; every other set has Lava Bridge's (4 and 2)."""
    missing = set(FIELDS) - set(demos)
    if missing:
        raise ValueError(f"demo file {source} lacks fields {sorted(missing)}")
    unknown = set(demos) - set(FIELDS) - set(OPTIONAL_FIELDS)
    if unknown:
        raise ValueError(f"demo file {source} has unknown fields {sorted(unknown)}; expected {list(FIELDS)} "
                         f"and optionally {list(OPTIONAL_FIELDS)}")
    env_id = demos.get("env_id")
    if env_id is not None and (env_id.dtype.kind != "U" or env_id.shape != ()):
        raise ValueError(f"demo file {source}: field 'env_id' must be one string, got {env_id!r}")
    foreign = env_id is not None and str(env_id) not in TASKS
    n = len(demos["observations"])
    shapes = {name: shape for name, (_, shape) in FIELDS.items()}
    if foreign:  # another env's sizes, the same in every transition
        shapes.update(observations=demos["observations"].shape[1:], next_observations=demos["observations"].shape[1:],
                      actions=demos["actions"].shape[1:])
        if len(shapes["observations"]) != 1 or len(shapes["actions"]) != 1:
            raise ValueError(f"demo file {source}: observations and actions must be (n, size) arrays, got shapes "
                             f"{demos['observations'].shape} and {demos['actions'].shape}")
    if "states" in demos:
        shapes["states"] = demos["states"].shape[1:] if demos["states"].ndim == 2 else (-1,)
    if "successes" in demos:
        shapes["successes"] = ()
    dtypes = {**{name: dtype for name, (dtype, _) in FIELDS.items()}, **OPTIONAL_FIELDS}
    for name, shape in shapes.items():
        array = demos[name]
        if array.dtype != dtypes[name] or array.shape != (n, *shape):
            raise ValueError(f"demo file {source}: field {name!r} has dtype {array.dtype} and shape "
                             f"{array.shape}; expected {np.dtype(dtypes[name])} and {(n, *shape)}")
    for name in ("observations", "actions", "rewards", "next_observations", "states"):
        if name in demos and not np.isfinite(demos[name]).all():
            raise ValueError(f"demo file {source}: field {name!r} has non-finite values")


def load_demos(size: int = 500, path: str | Path | None = None, env_id: str = DEFAULT_ENV_ID,
               format: str = "gymnasium") -> dict[str, np.ndarray]:
    """A task's shipped demo set by size (500 or 7500), or a file written by `save_demos` at `path`.

    `env_id` names the task (`lava_bridge_mj.TASKS` or an external task; LavaBridge-v0 by default); it is ignored with
    `path`. A file of `record_demos` also holds `states`, `env_id` and maybe `successes` (see there);
    it is checked for consistent fields, its `env_id` read as a str. Returns a dict of arrays, one row per transition: observations, actions, rewards,
    next_observations, terminations, truncations, episode_ids (Gymnasium's names). With
    `format="d4rl"`, D4RL's: observations, actions, rewards, next_observations, terminals, timeouts,
    as D4RL loaders (d3rlpy, CORL) read them; `timeouts` marks every episode end that is not a
    termination, the last episode's cut at the set size included. Shipped sets are checked against
    their recorded SHA-256.
    """
    if format not in FORMATS:
        raise ValueError(f"format={format!r}; expected one of {FORMATS}")
    if path is None:
        check_shipped_task(env_id)
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
    if "env_id" in demos:
        demos["env_id"] = str(demos["env_id"])
    if format == "d4rl":
        return {D4RL_NAMES.get(name, name): array for name, array in demos.items() if name != "episode_ids"}
    return demos


def candidate_states(states: np.ndarray, n: int = 150, seed: int = 0) -> np.ndarray:
    """The start strategies' candidate states of seed `seed`: a seeded random subset of `n` of `states`.

    The benchmark's protocol (the paper's): each seed's strategies start from `n` = 150 demo states
    drawn without replacement, in the demo set's order; all of them where there are fewer. Training
    (`lava-bridge-bench`, `lava_bridge_mj.train`) takes its candidates from here, `states` being the
    demo set's observations, so `candidate_states(load_demos(500)["observations"], seed=s)` are the
    states a run of seed `s` starts from. The draw has its own generator, seeded by `(seed, 2024)`,
    independent of any other draw of the run.
    """
    states = np.asarray(states)
    if states.ndim != 2 or len(states) == 0:
        raise ValueError(f"states: expected an (n, d) array of at least one state, got shape {states.shape}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n={n!r}: expected a positive whole number of states")
    rng = np.random.default_rng([seed, 2024])
    return states[np.sort(rng.choice(len(states), size=min(n, len(states)), replace=False))]


def regenerate_demos(check: bool = False, env_ids: list[str] | None = None) -> bool:
    """Regenerate the shipped sets of `env_ids` (default: every task's) from their seeds: write them
    (and their entries of the manifest), or with `check` only compare.

    Returns True when (checking) every shipped set is bit-identical to its regeneration.
    """
    env_ids = shipped_task_ids() if env_ids is None else env_ids
    for env_id in env_ids:
        check_shipped_task(env_id)
    assets = Path(str(resources.files("lava_bridge_mj.assets")))
    manifest, identical = json.loads((assets / MANIFEST).read_text()), True
    for env_id in env_ids:
        manifest[env_id] = {}
        for size in SHIPPED_SIZES:
            if env_id in EXTERNAL_TASKS:
                demos = generate_task_demos(env_id, size, SHIPPED_SEEDS[size])
            else:
                demos = generate_demos(size, SHIPPED_SEEDS[size], LavaBridgeEnv(layout=task_layout(env_id)))
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


# --- Minari ----------------------------------------------------------------------------------------
def minari_dataset_id(size: int, env_id: str = DEFAULT_ENV_ID) -> str:
    """The Minari id `to_minari` writes a task's shipped set under, e.g. lava_bridge/LavaBridge-v0/expert-500-v0."""
    return f"{MINARI_NAMESPACE}/{env_id}/expert-{size}-v0"


def minari_dataset_path(size: int, env_id: str = DEFAULT_ENV_ID) -> Path:
    """Where `to_minari` writes the dataset: under Minari's root, MINARI_DATASETS_PATH or ~/.minari/datasets."""
    import_minari()
    from minari.storage import get_dataset_path

    return Path(get_dataset_path(minari_dataset_id(size, env_id)))


def task_env(env_id: str, **kwargs) -> LavaBridgeEnv:
    """The suite's task `env_id` as a LavaBridgeEnv: the entry point recorded in a Minari dataset of a
    task other than LavaBridge-v0, whose registered keyword arguments (a Layout) are not JSON."""
    return LavaBridgeEnv(layout=task_layout(env_id), **kwargs)


def minari_env_spec(env_id: str) -> gymnasium.envs.registration.EnvSpec:
    """The task's registered EnvSpec, with JSON-serialisable keyword arguments, so that
    `MinariDataset.recover_environment()` can make the env again (an external task's with the task's
    arguments, e.g. PointMaze's sparse reward)."""
    if env_id in EXTERNAL_TASKS:
        task = EXTERNAL_TASKS[env_id]
        spec = task.spec()
        return dataclasses.replace(spec, kwargs={**spec.kwargs, **task.env_kwargs()})
    spec = gymnasium.spec(env_id)
    if not spec.kwargs:
        return spec
    return dataclasses.replace(spec, entry_point=f"{__name__}:task_env", kwargs={"env_id": env_id})


def import_minari(use: str = "export"):
    """The minari module; ImportError saying how to install it when it or h5py (its HDF5 storage) is missing."""
    try:
        import h5py  # noqa: F401
        import minari
    except ImportError:
        raise ImportError(f"Minari {use} needs the minari package with HDF5 support: "
                          "pip install 'lava-bridge-mj[minari]'") from None
    return minari


def to_minari(size: int, env_id: str = DEFAULT_ENV_ID) -> minari.MinariDataset:
    """Write a task's shipped `size` set as the local Minari dataset `minari_dataset_id(size, env_id)`.

    One Minari episode per expert episode (split by `episode_ids`), its observations the episode's
    observations followed by its last next_observation, and the same rows as its `infos["state"]`: a
    Lava Bridge state is its observation (x, y, vx, vy), what `reset(options={"state": s})` takes
    and the start strategies start from; an external task's are the set's full `states`, and the state
    after the episode's last action, replayed through `ResetToState`. The set's last episode is cut at the set
    size and recorded as truncated, as the dataset's description says. The dataset goes under
    Minari's root (MINARI_DATASETS_PATH, else ~/.minari/datasets); ValueError, writing nothing, when a
    dataset with that id exists there. Returns the dataset, as `minari.load_dataset(id)` would.
    """
    minari = import_minari()
    from minari.data_collector import EpisodeBuffer

    demos = load_demos(size, env_id=env_id)  # ValueError for an unknown task or size
    dataset_id = minari_dataset_id(size, env_id)
    path = minari_dataset_path(size, env_id)
    if path.exists():
        raise ValueError(f"Minari dataset {dataset_id} already exists at {path}; delete it "
                         f"(minari.delete_dataset({dataset_id!r})) to write it again")
    ids = demos["episode_ids"]
    replay = make_task_env(env_id) if env_id in EXTERNAL_TASKS else None  # for each episode's last state
    episodes = []
    for episode in range(int(ids[-1]) + 1):
        rows = ids == episode
        observations = np.concatenate([demos["observations"][rows], demos["next_observations"][rows][-1:]])
        states = observations if replay is None else np.concatenate(
            [demos["states"][rows], [state_after(replay, demos["states"][rows][-1], demos["actions"][rows][-1])]])
        episodes.append(EpisodeBuffer(
            id=episode,
            seed=SHIPPED_SEEDS[size] if episode == 0 else None,  # later episodes go on with its RNG
            observations=observations,
            actions=demos["actions"][rows],
            rewards=demos["rewards"][rows],
            terminations=demos["terminations"][rows],
            truncations=demos["truncations"][rows],
            # one state per observation, as minari.DataCollector(ResetToState(env), record_infos=True)
            # records info["state"] of the reset and of every step
            infos={"state": states}))
    spec = minari_env_spec(env_id)
    spaces = {}
    if replay is not None:  # its sets hold flattened observations: the dataset's space says so
        spaces = {"observation_space": gymnasium.spaces.flatten_space(replay.observation_space),
                  "action_space": replay.action_space}
        replay.close()
    expert = EXTERNAL_TASKS[env_id].expert_name if env_id in EXTERNAL_TASKS else "ScriptedExpert"
    try:
        with warnings.catch_warnings():  # Minari asks for a code URL and an e-mail; a local export has neither
            warnings.filterwarnings("ignore", message="`(code_permalink|author_email)` is set to None")
            return minari.create_dataset_from_buffers(
                dataset_id, episodes, env=spec, eval_env=spec, data_format="hdf5", algorithm_name=expert, **spaces,
                author="lava-bridge-mj", description=minari_description(demos, size, env_id),
                requirements=["lava-bridge-mj"])
    except BaseException:
        shutil.rmtree(path, ignore_errors=True)  # no half-written dataset blocks the next try
        raise


def state_after(env: gymnasium.Env, state: np.ndarray, action: np.ndarray) -> np.ndarray:
    """The state `env` (wrapped in ResetToState) reaches from `state` by `action`: a demo set keeps the
    state before each transition, and a Minari episode also needs the one after its last."""
    env.reset(options={"state": state})
    return np.asarray(env.step(action)[4]["state"])


def minari_description(demos: dict[str, np.ndarray], size: int, env_id: str) -> str:
    """What the Minari dataset holds, with how its last episode ends."""
    lengths = np.bincount(demos["episode_ids"])
    text = (f"Scripted-expert demonstrations on {env_id}: the {size}-transition set shipped with "
            f"lava-bridge-mj (lava_bridge_mj.load_demos({size}, env_id={env_id!r})), {len(lengths)} episodes "
            f"from p0 generated with seed {SHIPPED_SEEDS[size]}. ")
    if env_id in EXTERNAL_TASKS:
        task = EXTERNAL_TASKS[env_id]
        limit = task.max_episode_steps
        text += (f"The env is lava_bridge_mj.make_task_env({env_id!r}); observations are flattened "
                 f"(gymnasium.spaces.flatten). {task.description}")
    else:
        limit = MAX_EPISODE_STEPS
        text += "Reward +1 at the goal, where an episode terminates; 0 otherwise."
    text += (" Each episode's infos['state'] holds the env's state at each observation (on Lava Bridge the "
             "observation itself), which reset(options={'state': s}) restores.")
    if demos["truncations"][-1] and lengths[-1] < limit:
        text += (f" The last episode ({len(lengths) - 1}, {lengths[-1]} steps) is cut where the set reaches "
                 f"{size} transitions, not by the {limit}-step time limit, and is recorded as truncated.")
    return text


def minari_export_command(dataset_id: str) -> str | None:
    """The command that writes the local Minari dataset `dataset_id`, for one `to_minari` writes; else None."""
    for env_id in (*TASKS, *EXTERNAL_TASKS):
        for size in SHIPPED_SIZES:
            if dataset_id == minari_dataset_id(size, env_id):
                return f"python -m lava_bridge_mj demos --minari --size {size} --env {env_id}"
    return None


def _step_of(data, t: int):
    """Step `t` of an episode's batched observations (an array, or a dict / tuple of them)."""
    if isinstance(data, dict):
        return {key: _step_of(value, t) for key, value in data.items()}
    if isinstance(data, tuple):
        return tuple(_step_of(value, t) for value in data)
    return data[t]


def load_minari_demos(dataset_id: str) -> dict[str, np.ndarray]:
    """The local Minari dataset `dataset_id` as a demo set: the arrays `load_demos(path=...)` gives for
    a file of `record_demos`, checked the same way.

    Each Minari episode of T steps (T + 1 observations) gives T transitions, numbered by its place in
    the dataset (`episode_ids`): observations and next_observations flattened in
    `gymnasium.spaces.flatten` order (float64), actions (float32), rewards, terminations and
    truncations as stored. `states`, the state before each transition, come from the episode's
    `infos["state"]`, one row per observation: what `to_minari` writes and what
    `minari.DataCollector(ResetToState(env), record_infos=True)` records (with a StepDataCallback that
    keeps only info["state"] where the env's reset info has other keys than its step info, as
    Gymnasium's MuJoCo envs' do: docs/demonstrations.md). `successes` come from
    `infos["success"]` or `infos["is_success"]` after each step, where the episodes carry one; `env_id`
    is the id of the dataset's env spec ("" without one).

    Nothing is downloaded: ValueError naming the dataset and how to get it when it is not under
    Minari's root (MINARI_DATASETS_PATH, else ~/.minari/datasets), and naming the episode when its
    infos lack the states.
    """
    if not isinstance(dataset_id, str) or not dataset_id.strip():
        raise ValueError(f"Minari dataset id must be a non-empty string such as {minari_dataset_id(500)!r}, "
                         f"got {dataset_id!r}")
    try:
        minari = import_minari("datasets")
    except ImportError as error:
        raise ValueError(str(error)) from None
    from minari.storage import get_dataset_path

    source, command = f"Minari dataset {dataset_id}", minari_export_command(dataset_id)
    try:
        dataset = minari.load_dataset(dataset_id)  # download=False: a missing dataset raises
    except FileNotFoundError:
        how = (f"write it with `{command}`" if command else
               f"download it (`minari download {dataset_id}`) or record it (minari.DataCollector)")
        raise ValueError(f"{source} is not in {get_dataset_path()}: {how}") from None
    except Exception as error:  # an id Minari cannot parse, damaged metadata or storage
        raise ValueError(f"{source} cannot be read ({type(error).__name__}: {error})") from None
    obs_space = dataset.observation_space
    columns: dict[str, list] = {name: [] for name in (*FIELDS, "states", "successes")}
    success_keys = set()
    for index, episode in enumerate(dataset.iterate_episodes()):
        steps = len(episode.rewards)
        states = (episode.infos or {}).get("state")
        if not isinstance(states, np.ndarray) or states.ndim != 2 or len(states) != steps + 1:
            how = (f"delete it (minari.delete_dataset({dataset_id!r})) and write it again with `{command}`"
                   if command else "record it with minari.DataCollector(lava_bridge_mj.ResetToState(env), "
                                   "record_infos=True)")
            raise ValueError(f"{source} carries no states (infos['state'], one per observation) in episode "
                             f"{episode.id}, which the start strategies start from: {how}")
        flat = np.stack([gymnasium.spaces.flatten(obs_space, _step_of(episode.observations, t))
                         for t in range(steps + 1)]).astype(np.float64)
        key = next((key for key in ("success", "is_success") if key in (episode.infos or {})), None)
        success_keys.add(key)
        for name, values in (("observations", flat[:-1]), ("next_observations", flat[1:]),
                             ("actions", np.asarray(episode.actions).reshape(steps, -1)),
                             ("rewards", episode.rewards), ("terminations", episode.terminations),
                             ("truncations", episode.truncations), ("episode_ids", np.full(steps, index)),
                             ("states", states[:-1]),
                             ("successes", episode.infos[key][1:] if key else np.zeros(steps))):
            columns[name].append(np.asarray(values))
    if not columns["rewards"]:
        raise ValueError(f"{source} holds no episodes")
    dtypes = {**{name: dtype for name, (dtype, _) in FIELDS.items()}, **OPTIONAL_FIELDS}
    demos = {name: np.concatenate(parts).astype(dtypes[name]) for name, parts in columns.items()}
    if None in success_keys:  # successes only where every episode reports them
        del demos["successes"]
    demos["env_id"] = np.array("" if dataset.env_spec is None else dataset.env_spec.id)
    check_demos(demos, source)
    demos["env_id"] = str(demos["env_id"])
    return demos
