"""Train one method for one seed and write a run directory.

A run directory holds:
    config.json         the full configuration (a resumed run must match it)
    metrics.csv         one row per evaluation: steps, success from p0 and ood, returns, SAC stats
    start_weights.npz   the start strategy's candidate states and its weights at every evaluation
    checkpoint.pt       the latest checkpoint: everything needed to continue exactly
    policies/step_N.pt  the actor's weights at every evaluation (for videos and later analysis)
    final.pt            the checkpoint at the end of training
Every file is replaced atomically, so an interrupted run never leaves a half-written one.

Checkpoints are taken at the first episode boundary after each evaluation: there the env needs
no physics state restored, only its random generators, so a resumed run replays the uninterrupted
one exactly.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
import shutil
import signal
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import torch
from tqdm.auto import tqdm

import lava_bridge_mj
from lava_bridge_mj.agents.replay_buffer import ReplayBuffer
from lava_bridge_mj.agents.sac import SAC, SACConfig
from lava_bridge_mj.agents.start_state_wrapper import StartStateWrapper
from lava_bridge_mj.agents.start_strategies import STRATEGY_PARAMS, make_start_strategy
from lava_bridge_mj.eval.atomic import atomic_write, atomic_write_text
from lava_bridge_mj.eval.evaluate import evaluate

METHOD_STRATEGIES = {
    "sac": "p0",
    "auxss": "auxss",
    "omega_ss": "omega_ss",
    "uniform_ss": "uniform_ss",
    "goaldist_ss": "goaldist_ss",
}
"""Training methods (CLI names) and the start strategy each trains SAC with."""
METHODS = tuple(METHOD_STRATEGIES)
METRIC_FIELDS = ("step", "episodes", "success_p0", "success_ood", "return_p0", "return_ood",
                 "train_return", "train_success", "q_mean", "alpha", "critic_loss", "wall_time")
CHECKPOINT_VERSION = 1
RUN_FILES = ("config.json", "metrics.csv", "start_weights.npz", "checkpoint.pt", "final.pt", "rollouts.mp4")
"""What a run directory holds besides policies/: what --overwrite removes."""


class RunInterrupted(Exception):
    """SIGINT or SIGTERM stopped training; a checkpoint was written first, so --resume continues."""

    def __init__(self, signum: int, step: int):
        super().__init__(f"stopped by {signal.Signals(signum).name} at step {step} after writing a checkpoint")
        self.signum, self.step = signum, step


class RunDirectoryError(ValueError):
    """The run directory cannot be used: another run's results, or another process writing it."""


@dataclasses.dataclass
class RunConfig:
    """One training run. Defaults: a quick run that shows learning on a 2-core laptop in minutes;
    `steps=300_000` with `eval_every=10_000` is the paper's protocol."""

    method: str = "auxss"
    """Training method: sac (start from p0) or SAC with a start strategy (auxss, omega_ss, uniform_ss, goaldist_ss)."""
    seed: int = 0
    """Seeds the networks, the env, the start strategy, the replay sampling and the demo subset."""
    steps: int = 50_000
    """Online environment steps."""
    demos: int = 500
    """Which shipped demo set the candidate start states come from (500 or 7500)."""
    demo_subset: int = 150
    """Candidate start states: a seeded random subset of this many demo states (the paper's 150),
    the same set for every start strategy so that they differ only in how they sample it."""
    eval_every: int = 5_000
    """Evaluate (and checkpoint) every this many steps."""
    eval_episodes: int = 50
    """Evaluation episodes per start distribution (p0 and ood), with fixed seeds."""
    strategy: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Extra keyword parameters of the start strategy (e.g. {"sigma": 0.3} for auxss)."""
    sac: SACConfig = dataclasses.field(default_factory=SACConfig)
    """SAC hyperparameters."""
    env: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Keyword arguments of the env, for training and evaluation alike (e.g. {"lava_reward": 0.0} or
    Layout fields such as {"bridge_width": 0.4}); the candidate states still come from the shipped demos."""

    def __post_init__(self) -> None:
        if isinstance(self.sac, dict):
            self.sac = SACConfig(**self.sac)
        if self.method not in METHOD_STRATEGIES:
            raise ValueError(f"unknown method {self.method!r}; expected one of {METHODS}")
        for name, minimum in (("steps", 1), ("eval_every", 1), ("eval_episodes", 1), ("demo_subset", 1), ("seed", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, int) and value >= minimum):
                raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
        if self.demos not in (500, 7500):
            raise ValueError(f"demos must be 500 or 7500, got {self.demos!r}")
        if not isinstance(self.env, dict):
            raise ValueError(f"env must be a dict of LavaBridgeEnv keyword arguments, got {self.env!r}")
        try:
            lava_bridge_mj.LavaBridgeEnv(**self.env).close()  # refuse bad env arguments before any work
        except TypeError as error:
            raise ValueError(f"env: {error}") from None

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON values (tuples become lists), as written to config.json."""
        return json.loads(json.dumps(dataclasses.asdict(self)))

    @classmethod
    def from_dict(cls, values: dict[str, Any], source: str = "config") -> "RunConfig":
        """A RunConfig from plain values (e.g. a JSON file); ValueError naming unknown or bad entries."""
        if not isinstance(values, dict):
            raise ValueError(f"{source} must be a JSON object of RunConfig fields, got {type(values).__name__}")
        _check_keys(values, cls, source)
        sac = values.get("sac", {})
        if not isinstance(sac, dict):
            raise ValueError(f"{source}: 'sac' must be an object of SACConfig fields, got {sac!r}")
        _check_keys(sac, SACConfig, f"{source}: 'sac'")
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
        except TypeError as error:  # e.g. a SACConfig field of the wrong type
            raise ValueError(f"{source}: {error}") from None


def _check_keys(values: dict[str, Any], dataclass: type, source: str) -> None:
    known = [field.name for field in dataclasses.fields(dataclass)]
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ValueError(f"{source}: unknown fields {unknown}; expected some of {known}")


def candidate_states(config: RunConfig) -> np.ndarray:
    """The start strategy's candidate states: a seeded subset of the demo set's observations."""
    states = lava_bridge_mj.load_demos(config.demos)["observations"]
    rng = np.random.default_rng([config.seed, 2024])  # its own stream: independent of training draws
    size = min(config.demo_subset, len(states))
    return states[np.sort(rng.choice(len(states), size=size, replace=False))]


def make_strategy(config: RunConfig, states: np.ndarray, probe: lava_bridge_mj.LavaBridgeEnv):
    """The method's start strategy; `probe`, an env of the run's task, gives Omega-SS its safety
    rollouts and GoalDist-SS its goal (it is left at an arbitrary state)."""
    name = METHOD_STRATEGIES[config.method]
    params = dict(config.strategy)
    if name == "omega_ss" and "omega" not in params:
        params.setdefault("seed", config.seed)
        params["env"] = probe
    if name == "goaldist_ss":
        params.setdefault("goal", probe.layout.goal)
    return make_start_strategy(name, None if name == "p0" else states, **params)


class Run:
    """The state of one training run, with the loop that advances it and its on-disk form."""

    def __init__(self, config: RunConfig, out_dir: str | Path):
        self.config, self.dir = config, Path(out_dir)
        seed = config.seed
        self.states = candidate_states(config)
        # evaluation resets every env with a fixed seed, so one of them can serve as the strategy's probe
        self.eval_envs = [lava_bridge_mj.LavaBridgeEnv(**config.env) for _ in range(config.eval_episodes)]
        self.strategy = make_strategy(config, self.states, probe=self.eval_envs[0])
        self.env = StartStateWrapper(gymnasium.make(lava_bridge_mj.ENV_ID, **config.env), self.strategy, seed=seed)
        self.agent = SAC(4, 2, config.sac, seed=seed)
        self.buffer = ReplayBuffer(config.sac.buffer_size, 4, 2)
        self.rng = np.random.default_rng(seed)  # warm-up actions and minibatch indices
        self.step = 0
        self.episodes = 0
        self.rows: list[dict[str, float]] = []
        self.weight_history: list[np.ndarray] = []
        self.recent: list[tuple[float, bool]] = []  # (return, success) of training episodes since the last eval
        self.last_update: dict[str, float] = {}
        self.elapsed = 0.0  # wall time of earlier sessions of this run
        self.stop_signal: int | None = None  # set by SIGINT/SIGTERM: stop at the next episode boundary
        self.obs, _ = self.env.reset(seed=seed)

    # --- the loop -------------------------------------------------------------------------------
    def train(self, progress: bool = True) -> None:
        """Advance to config.steps, then write final.pt; RunInterrupted after a checkpoint on a signal."""
        with self._stop_on_signals():
            self._train(progress)

    @contextmanager
    def _stop_on_signals(self):
        """SIGINT/SIGTERM ask the loop to checkpoint and stop at the next episode boundary (at most one
        episode, a few seconds); a second signal stops at once, losing only the unsaved episode."""
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
        config, sac = self.config, self.config.sac
        start_time = time.perf_counter() - self.elapsed
        bar = tqdm(total=config.steps, initial=self.step, disable=not progress, unit="step",
                   desc=f"{config.method} seed {config.seed}", dynamic_ncols=True)
        episode_return = 0.0
        checkpoint_due = False
        while self.step < config.steps:
            if self.step < sac.learning_starts:
                action = self.rng.uniform(-1.0, 1.0, 2).astype(np.float32)
            else:
                action = self.agent.act(self.obs)
            next_obs, reward, terminated, truncated, info = self.env.step(action)
            self.buffer.add(self.obs, action, reward, next_obs, terminated)
            episode_return += reward
            self.obs = next_obs
            self.step += 1
            if self.step >= sac.learning_starts:
                self.last_update = self.agent.update(self.buffer.sample(sac.batch_size, self.rng))
            if self.step % config.eval_every == 0 or self.step == config.steps:
                self.elapsed = time.perf_counter() - start_time
                row = self.evaluate()
                bar.set_postfix(p0=f"{row['success_p0']:.2f}", ood=f"{row['success_ood']:.2f}",
                                ret=f"{row['train_return']:.2f}")
                checkpoint_due = True
            if terminated or truncated:
                self.episodes += 1
                self.recent.append((episode_return, bool(info["is_success"])))
                episode_return = 0.0
                self.obs, _ = self.env.reset()
                if checkpoint_due or self.stop_signal is not None:
                    self.elapsed = time.perf_counter() - start_time
                    self.save(self.dir / "checkpoint.pt")
                    checkpoint_due = False
                    if self.stop_signal is not None:
                        bar.close()
                        raise RunInterrupted(self.stop_signal, self.step)
            bar.update(1)
        bar.close()
        self.elapsed = time.perf_counter() - start_time
        self.save(self.dir / "final.pt")

    def evaluate(self) -> dict[str, float]:
        policy = lambda obs: self.agent.act(obs, deterministic=True)  # noqa: E731
        p0 = evaluate(policy, self.eval_envs, "p0")
        ood = evaluate(policy, self.eval_envs, "ood")
        returns = [r for r, _ in self.recent]
        row = {
            "step": self.step, "episodes": self.episodes,
            "success_p0": p0["success"], "success_ood": ood["success"],
            "return_p0": p0["return"], "return_ood": ood["return"],
            "train_return": float(np.mean(returns)) if returns else float("nan"),
            "train_success": float(np.mean([s for _, s in self.recent])) if returns else float("nan"),
            "q_mean": self.last_update.get("q_mean", float("nan")),
            "alpha": self.last_update.get("alpha", self.agent.alpha),
            "critic_loss": self.last_update.get("critic_loss", float("nan")),
            "wall_time": round(self.elapsed, 2),
        }
        self.recent = []
        self.rows.append(row)
        self.weight_history.append(self.strategy.probabilities.copy())
        self.write_results()
        (self.dir / "policies").mkdir(exist_ok=True)
        actor = self.agent.actor.state_dict()
        atomic_write(self.dir / "policies" / f"step_{self.step}.pt", lambda f: torch.save(actor, f))
        return row

    # --- files ----------------------------------------------------------------------------------
    def write_results(self) -> None:
        text = io.StringIO()
        writer = csv.DictWriter(text, fieldnames=METRIC_FIELDS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(self.rows)
        atomic_write_text(self.dir / "metrics.csv", text.getvalue())
        steps = np.array([row["step"] for row in self.rows], dtype=np.int64)
        weights = np.array(self.weight_history).reshape(len(steps), -1)
        atomic_write(self.dir / "start_weights.npz",
                     lambda f: np.savez(f, steps=steps, states=self.states, probabilities=weights))

    def save(self, path: Path) -> None:
        base = self.env.unwrapped
        state = {
            "version": CHECKPOINT_VERSION,
            "config": self.config.to_dict(),
            "step": self.step, "episodes": self.episodes, "elapsed": self.elapsed,
            "rows": self.rows, "weight_history": self.weight_history,
            "recent": self.recent, "last_update": self.last_update,
            "agent": self.agent.state_dict(),
            "buffer": self.buffer.state_dict(),
            "wrapper": self.env.state_dict(),
            "rng": self.rng.bit_generator.state,
            "env_rng": base.np_random.bit_generator.state,
            "obs": self.obs,
        }
        atomic_write(path, lambda f: torch.save(state, f))

    def load(self, path: Path) -> None:
        try:
            state = torch.load(path, weights_only=False)
        except Exception as error:  # a checkpoint from elsewhere can fail in many ways
            raise ValueError(f"checkpoint {path} cannot be read ({type(error).__name__}: {error})") from None
        if not isinstance(state, dict) or state.get("version") != CHECKPOINT_VERSION:
            raise ValueError(f"checkpoint {path} is not a version-{CHECKPOINT_VERSION} lava-bridge-mj checkpoint")
        if state["config"] != self.config.to_dict():
            raise ValueError(f"checkpoint {path} was written with another configuration; "
                             "resume with the same options or start a new run directory")
        self.step, self.episodes, self.elapsed = state["step"], state["episodes"], state["elapsed"]
        self.rows, self.weight_history = state["rows"], state["weight_history"]
        self.recent, self.last_update = state["recent"], state["last_update"]
        self.agent.load_state_dict(state["agent"])
        self.buffer.load_state_dict(state["buffer"])
        self.env.load_state_dict(state["wrapper"])
        self.rng.bit_generator.state = state["rng"]
        self.env.unwrapped.np_random.bit_generator.state = state["env_rng"]
        # Checkpoints are taken right after a reset, where the observation is the whole physics state.
        self.obs = state["obs"]
        self.env.unwrapped.set_state(self.obs[:2], self.obs[2:])
        self.write_results()  # drop rows written after the checkpoint, so the files agree with it


def train(config: RunConfig, out_dir: str | Path, *, resume: bool = False, overwrite: bool = False,
          progress: bool = True) -> Run:
    """Train `config` into `out_dir` and return the finished Run.

    A directory holding another run's results is refused (RunDirectoryError) unless `resume` (continue
    from its checkpoint; the configuration must match) or `overwrite` (remove that run's files first).
    While training, the directory is locked against a second process.
    """
    out_dir = Path(out_dir)
    run = Run(config, out_dir)  # builds everything (and checks strategy parameters) before touching disk
    out_dir.mkdir(parents=True, exist_ok=True)
    with _locked(out_dir):
        config_file = out_dir / "config.json"
        if config_file.exists() and overwrite:
            for name in RUN_FILES:
                (out_dir / name).unlink(missing_ok=True)
            shutil.rmtree(out_dir / "policies", ignore_errors=True)
        elif config_file.exists():
            if not resume:
                raise RunDirectoryError(f"{out_dir} already holds a run; resume it or overwrite it")
            try:
                existing = json.loads(config_file.read_text())
            except ValueError:
                raise RunDirectoryError(f"{config_file} is not valid JSON; not resuming into it") from None
            if existing != config.to_dict():
                raise RunDirectoryError(f"{out_dir} holds a run with another configuration; resume it "
                                        "with the same options, or choose another directory")
        checkpoint = out_dir / "checkpoint.pt"
        if resume and checkpoint.exists():
            run.load(checkpoint)
        atomic_write_text(config_file, json.dumps(config.to_dict(), indent=2) + "\n")
        run.train(progress=progress)
    return run


@contextmanager
def _locked(out_dir: Path):
    """Hold an exclusive lock on out_dir/.lock: two processes never write one run directory."""
    import fcntl

    with open(out_dir / ".lock", "a+") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.seek(0)
            raise RunDirectoryError(f"{out_dir} is being written by another process "
                                    f"(pid {lock.read().strip() or '?'}); not starting a second writer") from None
        lock.truncate(0)
        lock.write(str(os.getpid()))
        lock.flush()
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
