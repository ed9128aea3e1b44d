"""Train one method for one seed, or for K seeds at once, writing one run directory per seed.

A run directory holds:
    config.json         the full configuration (a resumed run must match it)
    provenance.json     per training session (the first, each resume): its steps, the code and library
                        versions that ran it and the start strategy's settings, defaults filled in
    metrics.csv         one row per evaluation: steps, success from p0 and ood, returns, SAC stats
    start_weights.npz   the start strategy's candidate states and its weights at every evaluation
    episodes.csv        one row per training episode (online methods): where it started, how it ended
    checkpoint.pt       the latest checkpoint: everything needed to continue exactly
    checkpoint.prev.pt  the one before it (see below)
    policies/step_N.pt  the actor's weights at every evaluation (for videos and later analysis)
    final.pt            the checkpoint at the end of training
Every file is replaced atomically, so an interrupted run never leaves a half-written one.

K seeds of one configuration train together in one process (`train(config, dirs, seeds=...)`): one
`SAC` with stacked networks updates all of them in one batched step, and one `LavaBridgeVectorEnv`
steps their episodes (sub-env i is seed i's, reset to the starts its strategy chooses), each seed with
its own start strategy, replay buffer, RNGs and directory. A seed's files are the same as if it had trained
alone (tests/test_runner.py checks it), and its checkpoint holds only its own state, so it can be
resumed alone or in another batch. The seeds of a batch checkpoint together after each evaluation,
mid-episode (the physics state (qpos, qvel) and the episode's step count are saved, and restoring
them replays the uninterrupted run exactly). A kill between two seeds' checkpoint writes leaves
some seeds one checkpoint ahead; each keeps the previous one too, and a resume picks the newest step
every seed of the batch has. A resume may raise `steps`: a finished run extended to a larger budget
equals one trained to it in one go (`RunConfig.continues`).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
import shutil
import signal
import sys
import threading
import time
from collections.abc import Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

import lava_bridge_mj
from lava_bridge_mj.agents.replay_buffer import ReplayBuffer
from lava_bridge_mj.agents.checks import check_fits_in_memory, check_integer, check_number
from lava_bridge_mj.agents.jsrl import JSRLConfig, JSRLCurriculum
from lava_bridge_mj.agents.offline import BC, IQL, BCConfig, IQLConfig
from lava_bridge_mj.agents.sac import SAC, SACConfig
from lava_bridge_mj.agents.seed_batch import stack_batches
from lava_bridge_mj.agents.start_state_wrapper import StartSelector
from lava_bridge_mj.agents.start_strategies import STRATEGY_PARAMS, make_start_strategy, strategy_settings
from lava_bridge_mj.eval.atomic import atomic_write, atomic_write_text
from lava_bridge_mj.eval.evaluate import evaluate
from lava_bridge_mj.eval.provenance import code_provenance
from lava_bridge_mj.eval.run_files import (CHECKPOINTS, POLICIES, RUN_FILES, DamagedFileError, RunDirectoryError,
                                           load_torch, locked, run_files, save_torch)
from lava_bridge_mj.vector import LavaBridgeVectorEnv

METHOD_STRATEGIES = {
    "sac": "p0",
    "auxss": "auxss",
    "omega_ss": "omega_ss",
    "uniform_ss": "uniform_ss",
    "goaldist_ss": "goaldist_ss",
    "hysac": "p0",
    "hysac_auxss": "auxss",
    "jsrl": "p0",
    "bc": "p0",
    "iql": "p0",
}
"""Training methods (CLI names) and the start strategy each trains with (offline ones never reset)."""
HYBRID_METHODS = ("hysac", "hysac_auxss")
"""Methods whose minibatches mix demo transitions into the online ones (HyQ with SAC)."""
OFFLINE_METHODS = ("bc", "iql")
"""Methods that learn from the demo transitions alone; a step is one gradient update."""
AGENT_CONFIGS = {"sac": SACConfig, "bc": BCConfig, "iql": IQLConfig, "jsrl": JSRLConfig}
"""RunConfig's nested hyperparameter sections."""
METHODS = tuple(METHOD_STRATEGIES)
MAX_SEED = 2**32 - 1
"""Seeds are 32-bit: what every RNG here (numpy's, torch's, MuJoCo's) takes without overflow."""
MAX_EVAL_EPISODES = 1000
"""Evaluation keeps one env per episode; 1,000 already gives a success rate to within about 0.03."""
METRIC_FIELDS = ("step", "episodes", "success_p0", "success_ood", "return_p0", "return_ood",
                 "train_return", "train_success", "q_mean", "alpha", "critic_loss", "actor_loss", "guide_horizon",
                 "wall_time")
EPISODE_FIELDS = ("episode", "step", "start_index", "start_x", "start_y", "length", "success", "return")
"""episodes.csv: the episode's number (1-based), the training step it ended at, the candidate state it
started from (-1: the env's own p0 start) and that start's position, its length, whether it reached
the goal, its return. What separates 'never tried from there' from 'tried and failed' per start."""
CHECKPOINT_VERSION = 3  # 3: optimisers in two parameter groups (seed_adam)


class RunInterrupted(Exception):
    """SIGINT or SIGTERM stopped training; a checkpoint was written first, so --resume continues."""

    def __init__(self, signum: int, step: int):
        super().__init__(f"stopped by {signal.Signals(signum).name} at step {step} after writing a checkpoint")
        self.signum, self.step = signum, step


class PolicyDiverged(ValueError):
    """A policy produced a non-finite action: its networks diverged."""


def _finite_policy(policy):
    """`policy`, raising PolicyDiverged instead of returning a non-finite action."""
    def act(obs: np.ndarray) -> np.ndarray:
        actions = policy(obs)
        if not np.isfinite(actions).all():
            raise PolicyDiverged(f"its evaluation policy's actions are not finite ({actions.reshape(-1, 2)[0]})")
        return actions
    return act


@dataclasses.dataclass
class RunConfig:
    """One training run. Defaults: a quick run that shows learning on a 2-core laptop in minutes;
    `steps=300_000` with `eval_every=10_000` is the paper's protocol."""

    method: str = "auxss"
    """Training method: sac (start from p0), SAC with a start strategy (auxss, omega_ss, uniform_ss,
    goaldist_ss), HySAC, whose minibatches mix in the demo transitions (hysac from p0, hysac_auxss), JSRL
    (a guide learned from the demos acts first in each episode), or an offline method trained on the demo
    transitions alone (bc, iql)."""
    env_id: str = lava_bridge_mj.ENV_ID
    """The task, an id of `lava_bridge_mj.TASKS`: its layout, its p0 and ood starts, and its shipped demos."""
    seed: int = 0
    """Seeds the networks, the env, the start strategy, the replay sampling and the demo subset."""
    steps: int = 50_000
    """Online environment steps (offline methods: gradient steps on the demo transitions)."""
    demos: int = 500
    """Which shipped demo set the candidate start states (and HySAC's offline transitions) come from (500 or 7500)."""
    demo_subset: int = 150
    """Candidate start states: a seeded random subset of this many demo states (the paper's 150),
    the same set for every start strategy so that they differ only in how they sample it."""
    hybrid_fraction: float = 0.5
    """HySAC only: the share of every minibatch drawn from the demo transitions, which stay in their own
    buffer for all of training (HyQ's half and half); the rest comes from the online replay buffer."""
    eval_every: int = 5_000
    """Evaluate (and checkpoint) every this many steps."""
    eval_episodes: int = 50
    """Evaluation episodes per start distribution (p0 and ood), with fixed seeds."""
    strategy: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Extra keyword parameters of the start strategy (e.g. {"sigma": 0.3} for auxss)."""
    sac: SACConfig = dataclasses.field(default_factory=SACConfig)
    """SAC hyperparameters (sac, the start-strategy methods, hysac, hysac_auxss)."""
    bc: BCConfig = dataclasses.field(default_factory=BCConfig)
    """Behaviour cloning hyperparameters (bc)."""
    iql: IQLConfig = dataclasses.field(default_factory=IQLConfig)
    """IQL hyperparameters (iql, and jsrl's guide when it is IQL)."""
    jsrl: JSRLConfig = dataclasses.field(default_factory=JSRLConfig)
    """JSRL's guide and curriculum (jsrl); its learner uses `sac`."""
    env: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Keyword arguments of the env, for training and evaluation alike (e.g. {"lava_reward": 0.0} or
    Layout fields such as {"bridge_width": 0.4}); the candidate states still come from the shipped demos."""

    def __post_init__(self) -> None:
        for name, section in AGENT_CONFIGS.items():
            if isinstance(getattr(self, name), dict):
                try:
                    setattr(self, name, section(**getattr(self, name)))
                except ValueError as error:  # name the section: "sac.lr must be ..."
                    raise ValueError(f"{name}.{error}") from None
        if self.method not in METHOD_STRATEGIES:
            raise ValueError(f"unknown method {self.method!r}; expected one of {METHODS}")
        for name, minimum in (("steps", 1), ("eval_every", 1), ("demo_subset", 1)):
            setattr(self, name, check_integer(name, getattr(self, name), minimum))
        self.seed = check_integer("seed", self.seed, 0, MAX_SEED)
        self.eval_episodes = check_integer("eval_episodes", self.eval_episodes, 1, MAX_EVAL_EPISODES)
        self.hybrid_fraction = check_number("hybrid_fraction", self.hybrid_fraction, 0, 1, low_inclusive=True)
        if self.demos not in (500, 7500):
            raise ValueError(f"demos must be 500 or 7500, got {self.demos!r}")
        if not isinstance(self.env_id, str) or self.env_id not in lava_bridge_mj.TASKS:
            raise ValueError(f"unknown env_id {self.env_id!r}; expected one of {list(lava_bridge_mj.TASKS)}")
        if not isinstance(self.env, dict):
            raise ValueError(f"env must be a dict of LavaBridgeEnv keyword arguments, got {self.env!r}")
        try:
            self.make_env().close()  # refuse bad env arguments before any work
        except (TypeError, ValueError) as error:
            raise ValueError(f"env: {error}") from None

    def env_kwargs(self) -> dict[str, Any]:
        """LavaBridgeEnv's (and LavaBridgeVectorEnv's) keyword arguments: the task's layout, then `env`."""
        return {"layout": lava_bridge_mj.task_layout(self.env_id), **self.env}

    def make_env(self, **kwargs: Any) -> lava_bridge_mj.LavaBridgeEnv:
        """The run's task as a single env (`kwargs` e.g. render_mode)."""
        return lava_bridge_mj.LavaBridgeEnv(**self.env_kwargs(), **kwargs)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON values (tuples become lists), as written to config.json."""
        return json.loads(json.dumps(dataclasses.asdict(self)))

    def continues(self, saved: Any) -> bool:
        """True when `saved` (a config.json's values) is this run up to its step budget: `steps` is
        the one field a resume may change, because nothing but the loop's end depends on it, so a
        finished run extended to more steps equals a run trained to them in one go."""
        # a config.json from before env_id existed was LavaBridge-v0's, the only task then
        return isinstance(saved, dict) and {"env_id": lava_bridge_mj.ENV_ID, **saved, "steps": self.steps} == self.to_dict()

    @classmethod
    def from_dict(cls, values: dict[str, Any], source: str = "config") -> "RunConfig":
        """A RunConfig from plain values (e.g. a JSON file); ValueError naming unknown or bad entries."""
        if not isinstance(values, dict):
            raise ValueError(f"{source} must be a JSON object of RunConfig fields, got {type(values).__name__}")
        _check_keys(values, cls, source)
        for name, section in AGENT_CONFIGS.items():
            fields = values.get(name, {})
            if not isinstance(fields, dict):
                raise ValueError(f"{source}: '{name}' must be an object of {section.__name__} fields, got {fields!r}")
            _check_keys(fields, section, f"{source}: '{name}'")
        strategy = values.get("strategy", {})
        name = METHOD_STRATEGIES.get(values.get("method", cls.method))
        if not isinstance(strategy, dict):
            raise ValueError(f"{source}: 'strategy' must be an object of start-strategy parameters")
        accepted = [p for p in STRATEGY_PARAMS.get(name, ()) if p != "env"]  # the runner supplies env
        unknown = sorted(set(strategy) - set(accepted))
        if unknown:
            raise ValueError(f"{source}: unknown parameters {unknown} for start strategy {name!r}; "
                             f"it accepts {accepted or 'none'}")
        try:
            return cls(**values)
        except (TypeError, ValueError) as error:  # e.g. a hyperparameter of the wrong type or range
            raise ValueError(f"{source}: {error}") from None


def _check_keys(values: dict[str, Any], dataclass: type, source: str) -> None:
    known = [field.name for field in dataclasses.fields(dataclass)]
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ValueError(f"{source}: unknown fields {unknown}; expected some of {known}")


def candidate_states(config: RunConfig) -> np.ndarray:
    """The start strategy's candidate states: a seeded subset of the demo set's observations."""
    states = lava_bridge_mj.load_demos(config.demos, env_id=config.env_id)["observations"]
    rng = np.random.default_rng([config.seed, 2024])  # its own stream: independent of training draws
    size = min(config.demo_subset, len(states))
    return states[np.sort(rng.choice(len(states), size=size, replace=False))]


def agent_config(config: RunConfig) -> SACConfig | BCConfig | IQLConfig:
    """The hyperparameter section the method trains with."""
    return getattr(config, config.method) if config.method in OFFLINE_METHODS else config.sac


def trained_configs(config: RunConfig) -> list[SACConfig | BCConfig | IQLConfig]:
    """The hyperparameter sections whose networks and buffers the method allocates (JSRL: its learner's
    and its guide's)."""
    guide = [getattr(config, config.jsrl.guide)] if config.method == "jsrl" else []
    return [agent_config(config), *guide]


def check_batch_fits(config: RunConfig, seeds: int) -> None:
    """ValueError unless `seeds` seeds of `config` fit in memory: checked before anything is built per
    seed, so an impossible batch fails at once instead of minutes later (or in MemoryError)."""
    check_fits_in_memory(*trained_configs(config), seeds=seeds, obs_dim=4, act_dim=2)


def make_agent(config: RunConfig, seeds: Sequence[int]) -> SAC | BC | IQL:
    """The method's learner for `seeds`, all stacked in one agent."""
    agent_class = {"bc": BC, "iql": IQL}.get(config.method, SAC)
    return agent_class(4, 2, agent_config(config), seeds=seeds)


def demo_buffer(config: RunConfig) -> ReplayBuffer:
    """HySAC's offline buffer: every transition of the demo set, exactly full, never written again.

    The shipped demos carry the default rewards (+1 at the goal, 0 otherwise; the expert never
    touches lava); they are relabelled with the run's env rewards so both buffers agree."""
    demos = lava_bridge_mj.load_demos(config.demos, env_id=config.env_id)
    env = config.make_env()
    rewards = np.where(demos["rewards"] == 1.0, env.goal_reward, env.step_reward)
    buffer = ReplayBuffer(len(rewards), 4, 2)
    for transition in zip(demos["observations"], demos["actions"], rewards, demos["next_observations"],
                          demos["terminations"]):
        buffer.add(*transition)
    return buffer


def strategy_params(config: RunConfig, probe: lava_bridge_mj.LavaBridgeEnv) -> dict[str, Any]:
    """The keyword parameters of the method's start strategy: the config's, plus what the run
    supplies: `probe`, an env of the run's task, gives Omega-SS its safety rollouts (seeded with
    the run's seed) and GoalDist-SS its goal (it is left at an arbitrary state)."""
    name = METHOD_STRATEGIES[config.method]
    params = dict(config.strategy)
    if name == "omega_ss" and "omega" not in params:
        params.setdefault("seed", config.seed)
        params["env"] = probe
    if name == "goaldist_ss":
        params.setdefault("goal", probe.layout.goal)
    return params


class SeedRun:
    """One seed's part of a training batch: its sub-env of the batch's vector env, its start
    strategy, replay buffer, RNGs, metrics and run directory. `Run` steps all of its seeds in lockstep."""

    def __init__(self, config: RunConfig, out_dir: str | Path, probe: lava_bridge_mj.LavaBridgeEnv,
                 envs: LavaBridgeVectorEnv, index: int, offline: ReplayBuffer | None = None):
        self.config, self.dir = config, Path(out_dir)
        seed = config.seed
        self.states = candidate_states(config)
        name, params = METHOD_STRATEGIES[config.method], strategy_params(config, probe)
        self.strategy = make_start_strategy(name, None if name == "p0" else self.states, **params)
        self.strategy_settings = strategy_settings(name, **params)  # what provenance.json records
        self.envs, self.index = envs, index  # this seed's env is sub-env `index` of the batch's `envs`
        self.selector = StartSelector(self.strategy, seed, max_episode_steps=envs.max_episode_steps)
        self.buffer = ReplayBuffer(config.sac.buffer_size, 4, 2)
        self.offline = offline  # the demo transitions (HySAC, JSRL's guide, BC, IQL), shared read-only by the batch
        self.curriculum = JSRLCurriculum(config.jsrl) if config.method == "jsrl" else None
        self.rng = np.random.default_rng(seed)  # warm-up actions and minibatch indices
        self.episodes = 0
        self.episode_return = 0.0
        self.rows: list[dict[str, float]] = []
        self.weight_history: list[np.ndarray] = []
        self.recent: list[tuple[float, bool]] = []  # (return, success) of training episodes since the last eval
        self.episode_log: list[tuple] = []  # one EPISODE_FIELDS row per finished training episode
        self.episode_start = (float("nan"), float("nan"))  # the running episode's start position (x, y)
        self.last_update: dict[str, float] = {}
        self.obs: np.ndarray | None = None  # set by Run's first reset

    def observe(self, step: int, action: np.ndarray, reward: float, next_obs: np.ndarray, terminated: bool,
                truncated: bool, success: bool) -> bool:
        """Store the transition of training step `step` (1-based); True when the episode ended (the
        Run then resets this seed's env to a start its strategy chooses)."""
        self.buffer.add(self.obs, action, reward, next_obs, terminated)
        self.episode_return += reward
        self.obs = next_obs
        ended = terminated or truncated
        self.selector.step(ended, success)
        if ended:
            self.episodes += 1
            self.recent.append((self.episode_return, bool(success)))
            self.episode_log.append((self.episodes, step, int(self.selector.start_index), *self.episode_start,
                                     self.selector.episode_length, int(bool(success)), float(self.episode_return)))
            if self.curriculum is not None:
                self.curriculum.record(success)
            self.episode_return = 0.0
        return ended

    def sample(self) -> dict[str, torch.Tensor]:
        """A minibatch for this seed's update: online transitions, plus demo ones for HySAC; demo
        transitions alone for the offline methods."""
        size = agent_config(self.config).batch_size
        if self.config.method in OFFLINE_METHODS:
            return self.offline.sample(size, self.rng)
        if self.config.method not in HYBRID_METHODS:
            return self.buffer.sample(size, self.rng)
        n_offline = round(self.config.hybrid_fraction * size)
        online = self.buffer.sample(size - n_offline, self.rng)
        offline = self.offline.sample(n_offline, self.rng)
        return {name: torch.cat([online[name], offline[name]]) for name in online}

    def record(self, step: int, p0: dict[str, float], ood: dict[str, float], actor: dict, elapsed: float) -> dict:
        """Append an evaluation row and write metrics, weights and the policy snapshot."""
        returns = [r for r, _ in self.recent]
        row = {
            "step": step, "episodes": self.episodes,
            "success_p0": p0["success"], "success_ood": ood["success"],
            "return_p0": p0["return"], "return_ood": ood["return"],
            "train_return": float(np.mean(returns)) if returns else float("nan"),
            "train_success": float(np.mean([s for _, s in self.recent])) if returns else float("nan"),
            "q_mean": self.last_update.get("q_mean", float("nan")),
            "alpha": self.last_update.get("alpha", self.config.sac.initial_alpha if self.config.method not in
                                          OFFLINE_METHODS else float("nan")),
            "actor_loss": self.last_update.get("actor_loss", float("nan")),
            "guide_horizon": self.curriculum.horizon if self.curriculum is not None else float("nan"),
            "critic_loss": self.last_update.get("critic_loss", float("nan")),
            "wall_time": round(elapsed, 2),
        }
        self.recent = []
        self.rows.append(row)
        self.weight_history.append(self.strategy.probabilities.copy())
        self.write_results()
        (self.dir / POLICIES).mkdir(exist_ok=True)
        save_torch(self.dir / POLICIES / f"step_{step}.pt", actor)
        return row

    def write_results(self) -> None:
        text = io.StringIO()
        writer = csv.DictWriter(text, fieldnames=METRIC_FIELDS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(self.rows)
        atomic_write_text(self.dir / "metrics.csv", text.getvalue())
        steps = np.array([row["step"] for row in self.rows], dtype=np.int64)
        # (0, n) before the first evaluation: a run stopped then still writes (and resumes from) its files
        weights = np.array(self.weight_history, dtype=np.float64).reshape(len(steps), len(self.strategy.probabilities))
        atomic_write(self.dir / "start_weights.npz",
                     lambda f: np.savez(f, steps=steps, states=self.states, probabilities=weights))
        if self.config.method not in OFFLINE_METHODS:  # offline methods run no episodes
            text = io.StringIO()
            writer = csv.writer(text, lineterminator="\n")
            writer.writerow(EPISODE_FIELDS)
            writer.writerows(self.episode_log)
            atomic_write_text(self.dir / "episodes.csv", text.getvalue())

    def state(self, step: int, elapsed: float, agent: dict) -> dict:
        """This seed's checkpoint at `step`, mid-episode: the physics state and the episode's step
        count make the env continue exactly where it was."""
        envs, i = self.envs, self.index
        return {
            "version": CHECKPOINT_VERSION,
            "config": self.config.to_dict(),
            "step": step, "episodes": self.episodes, "elapsed": elapsed,
            "rows": self.rows, "weight_history": self.weight_history,
            "recent": self.recent, "last_update": self.last_update,
            "episode_log": self.episode_log, "episode_start": self.episode_start,
            "agent": agent,
            "buffer": self.buffer.state_dict(),
            "wrapper": self.selector.state_dict(),
            "rng": self.rng.bit_generator.state,
            "env_rng": envs.rngs[i].bit_generator.state,
            "physics": envs.get_state()[i],
            "elapsed_steps": int(envs.episode_steps[i]),  # steps into the episode, for the time limit
            "obs": self.obs, "episode_return": self.episode_return,
            "curriculum": self.curriculum.state_dict() if self.curriculum is not None else None,
        }

    def save(self, state: dict, name: str = "checkpoint.pt") -> None:
        """Write `state` atomically; the checkpoint it replaces becomes checkpoint.prev.pt first."""
        path = self.dir / name
        if name == CHECKPOINTS[0] and path.exists():
            link = self.dir / f".{CHECKPOINTS[1]}.link{os.getpid()}"
            link.unlink(missing_ok=True)
            os.link(path, link)  # a second name for the same file, then an atomic rename over prev
            os.replace(link, self.dir / CHECKPOINTS[1])
        save_torch(path, state)

    def load(self, state: dict) -> None:
        self.episodes = state["episodes"]
        self.rows, self.weight_history = state["rows"], state["weight_history"]
        self.recent, self.last_update = state["recent"], state["last_update"]
        # checkpoints from before the episode log have none: the log then starts at the resume
        self.episode_log = state.get("episode_log", [])
        self.episode_start = state.get("episode_start", (float("nan"), float("nan")))
        self.buffer.load_state_dict(state["buffer"])
        envs, i = self.envs, self.index
        mask = np.arange(envs.num_envs) == i
        physics = np.zeros((envs.num_envs, 4))
        physics[i] = state["physics"]
        envs.reset(options={"state": physics, "reset_mask": mask})  # this sub-env only, mid-episode
        envs.episode_steps[i] = state["elapsed_steps"]
        envs.rngs[i].bit_generator.state = state["env_rng"]
        self.selector.load_state_dict(state["wrapper"])
        self.rng.bit_generator.state = state["rng"]
        self.obs, self.episode_return = state["obs"], state["episode_return"]
        if self.curriculum is not None:
            self.curriculum.load_state_dict(state["curriculum"])
        self.write_results()  # drop rows written after the checkpoint, so the files agree with it


class Run:
    """K seeds of one configuration training in lockstep, with the loop that advances them.

    `seed_runs[i]` holds seed i's env, strategy, buffers and files; `agent` is the method's learner
    (SAC, BC or IQL) over all seeds, `guide` JSRL's offline guide. `rows` and `strategy` are the first
    seed's (the single-seed case).
    """

    def __init__(self, configs: list[RunConfig], out_dirs: list[str | Path]):
        if not configs or len(configs) != len(out_dirs):
            raise ValueError(f"expected one run directory per configuration, got {len(configs)} and {len(out_dirs)}")
        shared = [{**c.to_dict(), "seed": None} for c in configs]
        if any(values != shared[0] for values in shared):
            raise ValueError("the seeds of one batch must share every setting but the seed")
        seeds = [c.seed for c in configs]
        if len(set(seeds)) != len(seeds):
            raise ValueError(f"seeds must be distinct, got {seeds}")
        self.config = configs[0]
        # evaluation resets every env with a fixed seed, so one of them can serve as the strategies' probe
        self.eval_envs = [self.config.make_env() for _ in range(self.config.eval_episodes)]
        # the seeds share the config's demo set; the buffer is never written, so one copy serves all
        uses_demos = self.config.method in (*HYBRID_METHODS, *OFFLINE_METHODS, "jsrl")
        demos = demo_buffer(self.config) if uses_demos else None
        # one vector env steps every seed's episode: sub-env i is seed i's, seeded with that seed
        self.envs = LavaBridgeVectorEnv(len(configs), **self.config.env_kwargs())
        self.seed_runs = [SeedRun(c, d, probe=self.eval_envs[0], envs=self.envs, index=i, offline=demos)
                          for i, (c, d) in enumerate(zip(configs, out_dirs))]
        self._start_episodes(np.ones(len(configs), dtype=bool), seeds=seeds)
        self.agent = make_agent(self.config, seeds)
        # JSRL's guide: an offline learner trained on the demos before the first online step
        self.guide = make_agent(dataclasses.replace(self.config, method=self.config.jsrl.guide), seeds) \
            if self.config.method == "jsrl" else None
        self.guide_trained = False
        self.step = 0
        self.elapsed = 0.0  # wall time of earlier sessions of this run
        self.stop_signal: int | None = None  # set by SIGINT/SIGTERM: checkpoint and stop after this step
        self.active = np.ones(len(configs), dtype=bool)  # False: the seed diverged and stopped
        self.diverged: dict[int, int] = {}  # seed -> the step it stopped at

    # single-seed conveniences
    @property
    def rows(self) -> list[dict[str, float]]:
        return self.seed_runs[0].rows

    @property
    def strategy(self):
        return self.seed_runs[0].strategy

    # --- the loop -------------------------------------------------------------------------------
    def train(self, progress: bool = True) -> None:
        """Advance to config.steps, then write final.pt; RunInterrupted after a checkpoint on a signal."""
        with self._stop_on_signals():
            self._train(progress)

    @contextmanager
    def _stop_on_signals(self):
        """SIGINT/SIGTERM ask the loop to checkpoint and stop after the current step; a second signal
        stops at once, losing only the work since the last checkpoint."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return

        def request_stop(signum, frame):
            if self.stop_signal is not None:
                raise KeyboardInterrupt
            self.stop_signal = signum

        previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)

    def _train(self, progress: bool) -> None:
        config, seed_runs = self.config, self.seed_runs
        online = config.method not in OFFLINE_METHODS
        learning_starts = config.sac.learning_starts if online else 0
        start_time = time.perf_counter() - self.elapsed
        if self.guide is not None and not self.guide_trained:
            self._train_guide()
            self.elapsed = time.perf_counter() - start_time
            self.save()  # the guide's training is not repeated by a resume
        seeds = ", ".join(str(s) for s in self.agent.seeds)
        bar = tqdm(total=config.steps, initial=self.step, disable=not progress, unit="step",
                   desc=f"{config.method} seed{'s' if len(seed_runs) > 1 else ''} {seeds}", dynamic_ncols=True)
        while self.step < config.steps:
            if online:  # offline methods only update
                if self.step < learning_starts:
                    actions = [s.rng.uniform(-1.0, 1.0, 2).astype(np.float32) for s in seed_runs]
                else:
                    actions = self.agent.act(np.stack([s.obs for s in seed_runs]))
                if self.guide is not None:  # JSRL: the guide acts for the first h steps of each episode
                    guided = [s.selector.episode_length < s.curriculum.horizon for s in seed_runs]
                    if any(guided):
                        guide_actions = self.guide.act(np.stack([s.obs for s in seed_runs]), deterministic=True)
                        actions = [g if use else a for use, g, a in zip(guided, guide_actions, actions)]
                actions = np.asarray(actions, dtype=np.float32)
                diverged = self.active & ~np.isfinite(actions).all(axis=1)
                if diverged.any():
                    self._stop_diverged(diverged, f"its policy's action {actions[diverged.argmax()]} is not finite")
                if not self.active.all():
                    actions[~self.active] = 0.0  # a stopped seed's sub-env idles; its transitions are dropped
                next_obs, rewards, terminated, truncated, info = self.envs.step(actions)
                ended = np.array([active and s.observe(self.step + 1, a, r, o, term, trunc, success)
                                  for s, active, a, r, o, term, trunc, success in zip(
                                      seed_runs, self.active, actions, rewards, next_obs, terminated, truncated,
                                      info["is_success"])])
                if ended.any():
                    self._start_episodes(ended)
            self.step += 1
            if self.step >= learning_starts:
                stats = self.agent.update(stack_batches([s.sample() for s in seed_runs]))
                for i in np.flatnonzero(self.active):
                    seed_runs[i].last_update = {name: float(values[i]) for name, values in stats.items()}
            evaluation_due = self.step % config.eval_every == 0 or self.step == config.steps
            if evaluation_due:
                self.elapsed = time.perf_counter() - start_time
                rows = self.evaluate()
                returns = [r["train_return"] for r in rows if np.isfinite(r["train_return"])]
                if rows:
                    bar.set_postfix(p0=f"{np.mean([r['success_p0'] for r in rows]):.2f}",
                                    ood=f"{np.mean([r['success_ood'] for r in rows]):.2f}",
                                    ret=f"{np.mean(returns):.2f}" if returns else "-")
            if not self.active.any():
                break  # every seed stopped: nothing left to train
            if evaluation_due or self.stop_signal is not None:
                self.elapsed = time.perf_counter() - start_time
                self.save()
                if self.stop_signal is not None:
                    bar.close()
                    raise RunInterrupted(self.stop_signal, self.step)
            bar.update(1)
        bar.close()
        self.elapsed = time.perf_counter() - start_time
        self.save("final.pt")

    def _stop_diverged(self, mask: np.ndarray, reason: str) -> None:
        """Stop the seeds in `mask` whose networks diverged: they write nothing more (their files keep
        their last checkpoint and evaluation) while the rest of the batch trains on unchanged, since
        every seed's slice of the batched networks is updated from its own loss alone."""
        for i in np.flatnonzero(mask):
            seed_run = self.seed_runs[i]
            self.active[i] = False
            self.diverged[seed_run.config.seed] = self.step
            last = seed_run.rows[-1]["step"] if seed_run.rows else None
            kept = f"its files keep step {last}" if last is not None else "it had not been evaluated yet"
            print(f"warning: seed {seed_run.config.seed} stopped at step {self.step}: {reason} (its networks "
                  f"diverged); {kept}; the other seeds go on", file=sys.stderr, flush=True)

    def _start_episodes(self, mask: np.ndarray, seeds: Sequence[int] | None = None) -> None:
        """Reset the sub-envs in `mask` to the starts their seeds' strategies choose (a candidate
        state, or the env's own p0 start); `seeds` (one per sub-env) reseeds their env RNGs first."""
        starts = [s.selector.choose() if m else None for s, m in zip(self.seed_runs, mask)]
        from_state = np.array([m and start is not None for m, start in zip(mask, starts)])
        seed_list = list(seeds) if seeds is not None else None
        obs = None
        if from_state.any():
            states = np.stack([start if start is not None else np.zeros(4) for start in starts])
            obs, _ = self.envs.reset(seed=seed_list, options={"state": states, "reset_mask": from_state})
        if (mask & ~from_state).any():
            obs, _ = self.envs.reset(seed=seed_list, options={"reset_mask": mask & ~from_state})
        for seed_run, m, o in zip(self.seed_runs, mask, obs):
            if m:
                seed_run.obs = o
                seed_run.episode_start = (float(o[0]), float(o[1]))

    def _train_guide(self) -> None:
        """JSRL: fit the guide (BC or IQL) to the demo transitions, each seed with its own sampling stream."""
        config = self.config
        size = getattr(config, config.jsrl.guide).batch_size
        rngs = [np.random.default_rng([s.config.seed, 17]) for s in self.seed_runs]
        for _ in range(config.jsrl.guide_steps):
            self.guide.update(stack_batches([s.offline.sample(size, rng) for s, rng in zip(self.seed_runs, rngs)]))
        self.guide_trained = True

    def evaluate(self) -> list[dict[str, float]]:
        """Each seed's deterministic policy on the fixed p0 and ood episodes; rows written to each run."""
        rows = []
        for i, seed_run in enumerate(self.seed_runs):
            if not self.active[i]:
                continue
            policy = _finite_policy(self.policy(i))
            try:
                p0 = evaluate(policy, self.eval_envs, "p0")
                ood = evaluate(policy, self.eval_envs, "ood")
            except PolicyDiverged as error:
                self._stop_diverged(np.arange(len(self.seed_runs)) == i, str(error))
                continue
            actor = {name: tensor[i:i + 1].clone() for name, tensor in self.agent.actor.state_dict().items()}
            rows.append(seed_run.record(self.step, p0, ood, actor, self.elapsed))
        return rows

    def policy(self, i: int = 0):
        """Seed i's deterministic policy: observations (n, 4) or (4,) -> actions (n, 2) or (2,)."""
        return self.agent.policy(i)

    # --- checkpoints ----------------------------------------------------------------------------
    def save(self, name: str = "checkpoint.pt") -> None:
        for i, seed_run in enumerate(self.seed_runs):
            if not self.active[i]:
                continue  # a diverged seed keeps its last good checkpoint
            state = seed_run.state(self.step, self.elapsed, self.agent.seed_state(i))
            if self.guide is not None:
                state.update(guide=self.guide.seed_state(i), guide_trained=self.guide_trained)
            seed_run.save(state, name)

    def resume(self) -> None:
        """Continue from the newest checkpoint step that every seed has (see the module docstring);
        from the start if some seed has none. A damaged checkpoint is moved aside (NAME.damaged) with a
        one-line warning and the seed continues from its other one; a seed whose checkpoints are all
        damaged stops the resume, before anything changes."""
        available, damaged = [], []
        for seed_run in self.seed_runs:
            found, bad = {}, []
            for name in CHECKPOINTS:
                path = seed_run.dir / name
                if path.exists():
                    try:
                        state = _read_checkpoint(path, seed_run.config)
                    except DamagedFileError as error:
                        bad.append((path, error))
                        continue
                    found[state["step"]] = state
            if bad and not found:
                raise DamagedFileError(f"every checkpoint of {seed_run.dir} is damaged ({'; '.join(map(str, (e for _, e in bad)))}); "
                                       "its run cannot continue: train it again with --overwrite, or into another directory")
            available.append(found)
            damaged.extend(bad)
        if all(available):
            common = set.intersection(*(set(found) for found in available))
            if not common:
                steps = {str(s.dir): sorted(found) for s, found in zip(self.seed_runs, available)}
                raise ValueError(f"the seeds' checkpoints are at different steps {steps}; resume them in separate batches")
            if max(common) > self.config.steps:
                raise ValueError(f"the checkpoints of {', '.join(str(s.dir) for s in self.seed_runs)} are at step "
                                 f"{max(common)}, past steps={self.config.steps}; a run continues to more steps, "
                                 "never fewer")
        for path, error in damaged:  # set aside, so the next checkpoint rotation cannot keep it as the fallback
            os.replace(path, path.with_name(path.name + ".damaged"))
            print(f"warning: {error}; moved it to {path.name}.damaged and continuing from the other checkpoint",
                  file=sys.stderr, flush=True)
        if not all(available):
            return
        self.step = max(common)
        states = [found[self.step] for found in available]
        self.elapsed = max(state["elapsed"] for state in states)
        self.agent.load_seed_states([state["agent"] for state in states])
        if self.guide is not None:
            self.guide.load_seed_states([state["guide"] for state in states])
            self.guide_trained = all(state["guide_trained"] for state in states)
        for seed_run, state in zip(self.seed_runs, states):
            seed_run.load(state)


def _read_checkpoint(path: Path, config: RunConfig) -> dict:
    """A checkpoint's state; DamagedFileError when the file is damaged or not a checkpoint (a resume
    then falls back to the other one), ValueError when it belongs to another configuration or format."""
    state = load_torch(path)
    if not isinstance(state, dict) or "version" not in state:
        raise DamagedFileError(f"{path} is not a lava-bridge-mj checkpoint")
    if state["version"] != CHECKPOINT_VERSION:
        raise ValueError(f"checkpoint {path} has format version {state['version']!r} and this lava-bridge-mj "
                         f"reads version {CHECKPOINT_VERSION}: continue it with the version that wrote it, "
                         "or start a new run directory")
    if not config.continues(state["config"]):
        raise ValueError(f"checkpoint {path} was written with another configuration; "
                         "resume with the same options (--steps may change) or start a new run directory")
    return state


def train(config: RunConfig, out_dir: str | Path | Sequence[str | Path], *, seeds: Sequence[int] | None = None,
          resume: bool = False, overwrite: bool = False, progress: bool = True) -> Run:
    """Train `config` into `out_dir` and return the finished Run.

    With `seeds`, train those seeds of `config` together in one batch, seed seeds[i] into out_dir[i]
    (a sequence of directories, one per seed); each directory is what a single-seed run would write.

    A directory holding another run's results is refused (RunDirectoryError) unless `resume` (continue
    from its checkpoints; the configuration must match) or `overwrite` (remove that run's files first).
    While training, every directory is locked against a second process.
    """
    check_batch_fits(config, 1 if seeds is None else len(seeds))
    if seeds is None:
        configs, dirs = [config], [Path(out_dir)]
    else:
        configs = [dataclasses.replace(config, seed=seed) for seed in seeds]
        dirs = [Path(d) for d in ([out_dir] if isinstance(out_dir, (str, Path)) else out_dir)]
        if len(dirs) != len(configs):
            raise ValueError(f"expected one run directory per seed ({len(configs)}), got {len(dirs)}")
    run = Run(configs, dirs)  # builds everything (and checks strategy parameters) before touching disk
    for directory in dirs:
        try:
            directory.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise RunDirectoryError(f"cannot create run directory {directory}: {error.strerror or error}") from None
    with ExitStack() as locks:
        for directory in dirs:
            locks.enter_context(locked(directory))
        for seed_config, directory in zip(configs, dirs):  # check every directory before changing any
            _check_run_directory(seed_config, directory, resume, overwrite)
        if overwrite:
            for directory in dirs:
                for name in RUN_FILES:
                    (directory / name).unlink(missing_ok=True)
                shutil.rmtree(directory / POLICIES, ignore_errors=True)
        if resume:
            run.resume()
        for seed_config, directory in zip(configs, dirs):
            atomic_write_text(directory / "config.json", json.dumps(seed_config.to_dict(), indent=2) + "\n")
        if run.step < config.steps:  # a finished run resumed at its budget trains nothing: no session
            code = code_provenance()
            started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
            for seed_run in run.seed_runs:
                session = {"from_step": run.step, "to_step": config.steps, "started": started, "code": code,
                           "strategy": seed_run.strategy_settings}
                sessions = _read_provenance(seed_run.dir) if resume else []
                atomic_write_text(seed_run.dir / "provenance.json", json.dumps([*sessions, session], indent=2) + "\n")
        run.train(progress=progress)
    return run


def _check_run_directory(config: RunConfig, directory: Path, resume: bool, overwrite: bool) -> None:
    """Refuse a directory holding any run file unless resuming the same configuration or overwriting."""
    found = run_files(directory)
    if not found or overwrite:
        return
    if not resume:
        raise RunDirectoryError(f"{directory} already holds a run ({', '.join(found)}); resume it or overwrite it")
    config_file = directory / "config.json"
    if not config_file.exists():
        raise RunDirectoryError(f"{directory} holds run files ({', '.join(found)}) but no config.json, so "
                                "nothing shows they belong to this configuration; not resuming into it "
                                "(overwrite it, or choose another directory)")
    try:
        existing = json.loads(config_file.read_text())
    except ValueError:
        raise RunDirectoryError(f"{config_file} is not valid JSON; not resuming into it") from None
    if not config.continues(existing):
        raise RunDirectoryError(f"{directory} holds a run with another configuration; resume it "
                                "with the same options (--steps may change), or choose another directory")
    _read_provenance(directory)  # refuse a damaged record before training changes anything


def _read_provenance(directory: Path) -> list[dict[str, Any]]:
    """The run's earlier sessions; none for a new run or one made before provenance was recorded."""
    path = directory / "provenance.json"
    if not path.exists():
        return []
    try:
        sessions = json.loads(path.read_text())
    except ValueError:
        sessions = None
    if not (isinstance(sessions, list) and all(isinstance(s, dict) for s in sessions)):
        raise RunDirectoryError(f"{path} is not a JSON list of training sessions; not resuming into it "
                                "(move it aside to continue without the earlier sessions' record)")
    return sessions
