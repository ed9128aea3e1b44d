"""One seed's part of a training batch: its start strategy, buffers, RNGs, records and run directory.

`Run` (eval/training/runner.py) steps the seeds of a batch in lockstep; a `SeedRun` holds everything that is
only its seed's, writes its seed's files and makes its seed's checkpoint, so that a seed's files
are the same as if it had trained alone.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

import lava_bridge_mj
from lava_bridge_mj.agents.methods import METHODS
from lava_bridge_mj.agents.replay_buffer import ReplayBuffer
from lava_bridge_mj.agents.reverse_curriculum import goal_reaching_demos
from lava_bridge_mj.agents.start_state_wrapper import StartSelector
from lava_bridge_mj.agents.start_strategies import StrategyContext
from lava_bridge_mj.agents.strategy_registry import make_start_strategy
from lava_bridge_mj.eval.training.config import ConfigurationError, RunConfig
from lava_bridge_mj.eval.training.run_files import CHECKPOINT_VERSION, POLICIES, save_checkpoint, save_torch, write_results
from lava_bridge_mj.vector import LavaBridgeVectorEnv


def candidate_states(config: RunConfig) -> tuple[np.ndarray, np.ndarray | None]:
    """The start strategy's candidate states and, for whole demo episodes, each one's episode id.

    Its method's `candidates` decide: "subset", a seeded subset of `demo_subset` of the demo set's
    observations (another env's: its full `states`) (episode ids None); "demo_episodes", every goal-reaching demo episode, whole and
    in time order (`demo_subset` is unused)."""
    demos = config.load_demos()
    field = "observations" if config.lava_bridge else "states"  # another env starts from its full states
    if METHODS[config.method].candidates == "demo_episodes":
        if not config.lava_bridge and "successes" not in demos:
            raise ValueError(f"{config.method} needs demo episodes that end in success, but {config.demos_source} "
                             f"records no success ({config.env_id} reports neither info['success'] nor "
                             f"info['is_success'])")
        states, episode_ids = goal_reaching_demos(demos, field)
        if len(states) == 0:
            raise ValueError(f"{config.method} needs demo episodes that end in success, but none of the "
                             f"{int(demos['episode_ids'][-1]) + 1} episodes of {config.demos_source} does")
        return states, episode_ids
    return lava_bridge_mj.candidate_states(demos[field], config.demo_subset, config.seed), None


class SeedRun:
    """Seed `config.seed` of a batch: sub-env `index` of the batch's `envs`, its start strategy
    (built once from the method's strategy name, the candidate states and the run's context: `probe`,
    an env of the task, what the task declares about its states, the env's step limit and the
    candidates' demo episode ids), replay buffer,
    RNGs, metrics and directory. A strategy's `time_limit` shortens the episodes it starts, as
    `StartStateWrapper` does."""

    def __init__(self, config: RunConfig, out_dir: str | Path, probe: lava_bridge_mj.LavaBridgeEnv,
                 envs: LavaBridgeVectorEnv, index: int, demos: ReplayBuffer | None = None):
        self.config, self.dir = config, Path(out_dir)
        self.method = METHODS[config.method]
        self.states, episode_ids = candidate_states(config)
        context = StrategyContext.from_env(probe, config.seed, envs.max_episode_steps, episode_ids,
                                           budget=config.steps)
        try:  # the strategy checks its parameters' values: the config's checks name only the parameters
            self.strategy = make_start_strategy(self.method.start, self.states, context, **config.strategy)
            self.selector = StartSelector(self.strategy, config.seed, max_episode_steps=envs.max_episode_steps)
        except ValueError as error:
            raise ConfigurationError(f"strategy: {error}") from None
        extra = self.strategy.states[len(self.states):]  # start states a strategy adds (rfcl's p0 states)
        if len(extra):  # start_weights.npz records them beside their probabilities
            self.states = np.vstack([self.states, extra])
        self.envs, self.index = envs, index
        self.buffer = ReplayBuffer(config.sac.buffer_size, envs.single_observation_space.shape[0],
                                   envs.single_action_space.shape[0])
        self.demos = demos  # the demo transitions, shared read-only by the batch (None: the method uses none)
        self.rng = np.random.default_rng(config.seed)  # warm-up actions and minibatch indices
        self.episodes = 0
        self.episode_return = 0.0
        self.rows: list[dict[str, float]] = []
        self.weight_history: list[np.ndarray] = []
        self.recent: list[tuple[float, bool]] = []  # (return, success) of training episodes since the last eval
        self.episode_log: list[tuple] = []  # one EPISODE_FIELDS row per finished training episode
        self.episode_start = (float("nan"), float("nan"))  # the running episode's start position (x, y)
        self.last_update: dict[str, float] = {}
        self.obs: np.ndarray | None = None  # set by Run's first reset

    @property
    def strategy_settings(self) -> dict[str, Any]:
        """The start strategy's settings, defaults filled in: what provenance.json records."""
        return self.strategy.settings

    def observe(self, step: int, action: np.ndarray, reward: float, next_obs: np.ndarray, terminated: bool,
                truncated: bool, success: bool) -> bool:
        """Store the transition of training step `step` (1-based); True when the episode ended (the
        Run then resets this seed's env to a start its strategy chooses)."""
        self.buffer.add(self.obs, action, reward, next_obs, terminated)
        self.episode_return += reward
        self.obs = next_obs
        # the strategy's own step limit for this episode (RFCL's), where shorter than the env's
        truncated = truncated or (not terminated and self.selector.reaches_time_limit())
        ended = terminated or truncated
        self.selector.step(ended, success)
        if ended:
            self.episodes += 1
            self.recent.append((self.episode_return, bool(success)))
            self.episode_log.append((self.episodes, step, int(self.selector.start_index), *self.episode_start,
                                     self.selector.episode_length, int(bool(success)), float(self.episode_return)))
            self.episode_return = 0.0
        return ended

    def sample(self) -> dict:
        """A minibatch for this seed's update, drawn as the method draws them."""
        size = getattr(self.config, self.method.learner).batch_size
        return self.method.minibatch(self.buffer, self.demos, size, self.rng, self.config.hybrid_fraction)

    def record(self, step: int, p0: dict[str, float], ood: dict[str, float], actor: dict, elapsed: float,
               guide_horizon: float) -> dict:
        """Append an evaluation row and write metrics, weights and the policy snapshot."""
        returns = [r for r, _ in self.recent]
        row = {
            "step": step, "episodes": self.episodes,
            "success_p0": p0["success"], "success_ood": ood["success"],
            "return_p0": p0["return"], "return_ood": ood["return"],
            "train_return": float(np.mean(returns)) if returns else float("nan"),
            "train_success": (float(np.mean([s for _, s in self.recent])) if returns and self.envs.reports_success
                              else float("nan")),
            "q_mean": self.last_update.get("q_mean", float("nan")),
            "alpha": self.last_update.get("alpha", self.config.sac.initial_alpha if self.method.online
                                          else float("nan")),
            "actor_loss": self.last_update.get("actor_loss", float("nan")),
            "guide_horizon": guide_horizon,
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
        steps = np.array([row["step"] for row in self.rows], dtype=np.int64)
        # (0, n) before the first evaluation: a run stopped then still writes (and resumes from) its files
        weights = np.array(self.weight_history, dtype=np.float64).reshape(len(steps), len(self.strategy.probabilities))
        write_results(self.dir, self.rows, steps, self.states, weights,
                      self.episode_log if self.method.online else None)  # offline methods run no episodes

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
            "curriculum": None,  # JSRL's (JSRLGuide.seed_state) replaces it
        }

    def save(self, state: dict, name: str = "checkpoint.pt") -> None:
        save_checkpoint(self.dir, state, name)

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
        physics = np.zeros((envs.num_envs, len(state["physics"])))
        physics[i] = state["physics"]
        envs.reset(options={"state": physics, "reset_mask": mask})  # this sub-env only, mid-episode
        envs.episode_steps[i] = state["elapsed_steps"]
        envs.rngs[i].bit_generator.state = state["env_rng"]
        self.selector.load_state_dict(state["wrapper"])
        self.rng.bit_generator.state = state["rng"]
        self.obs, self.episode_return = state["obs"], state["episode_return"]
        self.write_results()  # drop rows written after the checkpoint, so the files agree with it
