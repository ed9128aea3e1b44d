"""The hyperparameter sections of a run's configuration: SAC's, BC's, IQL's and JSRL's.

Plain dataclasses that validate their fields, free of torch, so that a configuration is read and
checked (by the CLI, a sweep's planner, a report) without loading the learners. `memory_bytes`
builds one seed's networks to count their parameters, so it imports torch when called.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .checks import FLOAT_BYTES, check_hidden_sizes, check_integer, check_number, minibatch_floats


@dataclass
class SACConfig:
    """SAC hyperparameters. Defaults follow the paper's protocol where it gives one."""

    hidden_sizes: tuple[int, ...] = (64, 64)
    """Hidden layer widths of the actor and of each critic. 64 units update about 5x as fast as 256 on
    2 CPU cores, and tuning runs at 64, 128 and 256 units did not separate the widths (docs/speed.md, "Network size")."""
    lr: float = 3e-4
    """Adam learning rate of actor, critics and entropy coefficient."""
    gamma: float = 0.99
    """Discount factor."""
    tau: float = 0.005
    """Polyak rate of the target critics: target <- (1 - tau) * target + tau * critic after each update."""
    batch_size: int = 256
    """Transitions per gradient update."""
    buffer_size: int = 10_000
    """Replay capacity, the paper's protocol; small, so old experience is forgotten within ~20 episodes."""
    learning_starts: int = 1_000
    """Env steps of uniform random actions before the first update (two full-length episodes'
    worth of data so the first minibatches are not a handful of transitions); then one update per step."""
    initial_alpha: float = 0.01
    """Entropy coefficient alpha before the first update; automatic tuning then adapts it. Not the
    usual 1.0: with a single +1 reward a large entropy bonus outweighs the goal (docs/calibration.md,
    section 6)."""
    target_entropy: float | None = None
    """Policy entropy (nats, summed over action dimensions) that the tuning of alpha holds: alpha rises
    while the policy's entropy is below it and falls while above. None means -act_dim, the SAC
    paper's heuristic (-2 on LavaBridge-v0); any finite number is accepted."""
    critic_layer_norm: bool = False
    """LayerNorm after each hidden layer of the critics (RLPD, Ball et al. 2023), which bounds how far Q
    can extrapolate to actions the data never shows. Off by default, as in plain SAC and the paper's
    HySAC; the setting to use when offline transitions cover states the online data never reaches,
    where HySAC's critic otherwise diverges (docs/calibration.md, section 2)."""

    def __post_init__(self) -> None:
        self.hidden_sizes = check_hidden_sizes(self.hidden_sizes)
        self.lr = check_number("lr", self.lr)
        self.gamma = check_number("gamma", self.gamma, 0, 1)
        self.tau = check_number("tau", self.tau, 0, 1)
        self.initial_alpha = check_number("initial_alpha", self.initial_alpha)
        if self.target_entropy is not None:
            self.target_entropy = check_number("target_entropy", self.target_entropy, -math.inf, math.inf)
        self.batch_size = check_integer("batch_size", self.batch_size, 1)
        self.buffer_size = check_integer("buffer_size", self.buffer_size, 1)
        self.learning_starts = check_integer("learning_starts", self.learning_starts, 0)
        if not isinstance(self.critic_layer_norm, bool):
            raise ValueError(f"critic_layer_norm must be true or false, got {self.critic_layer_norm!r}")

    def memory_bytes(self, seeds: int, obs_dim: int, act_dim: int) -> dict[str, int]:
        """Bytes of the arrays `seeds` seeds of SAC hold, by the field that sizes them: each seed's replay
        buffer (obs, action, reward, next_obs, terminated), its minibatch with the hidden activations the
        twin critics keep for the critic loss's backward pass (two passes), and the networks: every trained parameter with its gradient and two Adam moments, plus
        the target critics. For `check_fits_in_memory`."""
        from .networks import TanhGaussianActor, TwinQ, parameter_count  # imports torch

        actor = parameter_count(lambda: TanhGaussianActor(1, obs_dim, act_dim, self.hidden_sizes))
        critic = parameter_count(lambda: TwinQ(1, obs_dim, act_dim, self.hidden_sizes, self.critic_layer_norm))
        floats = {"buffer_size": self.buffer_size * (2 * obs_dim + act_dim + 2),
                  "batch_size": minibatch_floats(self.batch_size, obs_dim, act_dim, self.hidden_sizes, 2),
                  "hidden_sizes": 4 * (actor + critic) + critic}
        return {field: seeds * FLOAT_BYTES * count for field, count in floats.items()}


@dataclass
class BCConfig:
    """Behaviour cloning hyperparameters (the common D4RL-style defaults)."""

    hidden_sizes: tuple[int, ...] = (256, 256)
    """Hidden layer widths of the policy."""
    lr: float = 3e-4
    """Adam learning rate."""
    batch_size: int = 256
    """Demo transitions per gradient step."""

    def __post_init__(self) -> None:
        self.hidden_sizes = check_hidden_sizes(self.hidden_sizes)
        self.lr = check_number("lr", self.lr)
        self.batch_size = check_integer("batch_size", self.batch_size, 1)

    def memory_bytes(self, seeds: int, obs_dim: int, act_dim: int) -> dict[str, int]:
        """Bytes of `seeds` seeds' policies, each parameter with its gradient and two Adam moments, and
        their minibatches with the hidden activations the policy keeps for the backward pass (the demo
        transitions are a few thousand); for `check_fits_in_memory`."""
        from .networks import TanhGaussianActor, parameter_count  # imports torch

        actor = parameter_count(lambda: TanhGaussianActor(1, obs_dim, act_dim, self.hidden_sizes))
        return {"batch_size": seeds * FLOAT_BYTES * minibatch_floats(self.batch_size, obs_dim, act_dim,
                                                                      self.hidden_sizes, 1),
                "hidden_sizes": seeds * FLOAT_BYTES * 4 * actor}


@dataclass
class IQLConfig:
    """IQL hyperparameters: the paper's published defaults for its sparse-reward goal-reaching tasks
    (AntMaze: expectile 0.9, temperature 10); its locomotion settings are expectile 0.7, temperature 3.
    LavaBridge-v0 is a sparse-reward navigation task, so the AntMaze values are the default."""

    hidden_sizes: tuple[int, ...] = (256, 256)
    """Hidden layer widths of the policy, the value network and each critic."""
    lr: float = 3e-4
    """Adam learning rate of every network."""
    batch_size: int = 256
    """Demo transitions per gradient step."""
    gamma: float = 0.99
    """Discount factor."""
    tau: float = 0.005
    """Polyak rate of the target critics."""
    expectile: float = 0.9
    """tau of the expectile value loss: how close V(s) gets to the best in-data action's Q."""
    temperature: float = 10.0
    """beta of the advantage weights exp(beta A)."""
    max_weight: float = 100.0
    """Advantage weights are clipped at this value (the paper's 100)."""

    def __post_init__(self) -> None:
        self.hidden_sizes = check_hidden_sizes(self.hidden_sizes)
        self.lr = check_number("lr", self.lr)
        self.batch_size = check_integer("batch_size", self.batch_size, 1)
        self.gamma = check_number("gamma", self.gamma, 0, 1)
        self.tau = check_number("tau", self.tau, 0, 1)
        self.expectile = check_number("expectile", self.expectile, 0, 1, high_inclusive=False)
        self.temperature = check_number("temperature", self.temperature)
        self.max_weight = check_number("max_weight", self.max_weight)

    def memory_bytes(self, seeds: int, obs_dim: int, act_dim: int) -> dict[str, int]:
        """Bytes of `seeds` seeds' networks: policy, twin critics and value network, each parameter
        with its gradient and two Adam moments, plus the target critics; and their minibatches with the
        hidden activations the value network keeps for its loss's backward pass; for `check_fits_in_memory`."""
        from .networks import MLP, TanhGaussianActor, TwinQ, parameter_count  # imports torch

        actor = parameter_count(lambda: TanhGaussianActor(1, obs_dim, act_dim, self.hidden_sizes))
        critic = parameter_count(lambda: TwinQ(1, obs_dim, act_dim, self.hidden_sizes))
        value = parameter_count(lambda: MLP(1, obs_dim, 1, self.hidden_sizes))
        return {"batch_size": seeds * FLOAT_BYTES * minibatch_floats(self.batch_size, obs_dim, act_dim,
                                                                      self.hidden_sizes, 1),
                "hidden_sizes": seeds * FLOAT_BYTES * (4 * (actor + critic + value) + critic)}


@dataclass
class JSRLConfig:
    """JSRL's guide and curriculum."""

    guide: str = "iql"
    """The offline learner that becomes the guide: "iql" (the JSRL paper's choice) or "bc"; trained
    with the run's `iql` or `bc` hyperparameters on the run's demo set."""
    guide_steps: int = 20_000
    """Gradient steps of the guide on the demos, before the first online step."""
    initial_horizon: int = 170
    """h at stage 0: steps the guide acts at the start of each episode."""
    stages: int = 10
    """Number of shrinking steps from initial_horizon to 0."""
    window: int = 20
    """Training episodes at a stage whose success rate decides whether to advance."""
    threshold: float = 0.5
    """Success rate over the window that advances the curriculum."""

    def __post_init__(self) -> None:
        if self.guide not in ("iql", "bc"):
            raise ValueError(f"guide must be 'iql' or 'bc', got {self.guide!r}")
        self.guide_steps = check_integer("guide_steps", self.guide_steps, 0)
        self.initial_horizon = check_integer("initial_horizon", self.initial_horizon, 0)
        self.stages = check_integer("stages", self.stages, 1)
        self.window = check_integer("window", self.window, 1)
        self.threshold = check_number("threshold", self.threshold, 0, 1, low_inclusive=True)
