"""Soft Actor-Critic (Haarnoja et al., 2018) with clipped double Q and automatic entropy tuning.

One `SAC` object trains K independent seeds at once: every network, optimiser state and entropy
coefficient has a leading seed axis, so a gradient step for all K seeds is one batched kernel per layer
(on 2 CPU cores 25 seeds at 64 units update about 10x faster than 25 separate processes would; see
bench/sac_throughput.py). The seeds never mix: seed i's numbers are the same whatever other seeds share
its batch. A single-seed run is K = 1.

The training loop lives in the runner; per environment step it does
    actions = agent.act(obs)                  # obs (K, obs_dim); uniform random before learning_starts
    buffers[i].add(obs[i], actions[i], ...)   # one replay buffer per seed; terminated, not done
    if steps >= config.learning_starts:
        metrics = agent.update(stack_batches([b.sample(batch_size, rng_i) ...]))  # one update per step
Actions are in [-1, 1]^act_dim, LavaBridge-v0's action space.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import numpy as np
import torch

from .configs import SACConfig
from .networks import TanhGaussianActor, TwinQ, init_member, soft_update
from .seed_batch import SeedBatchedAgent, seed_adam


def bellman_target(reward: torch.Tensor, terminated: torch.Tensor, next_value: torch.Tensor,
                   gamma: float) -> torch.Tensor:
    """r + gamma * (1 - terminated) * V(s').

    Only a true terminal state (goal, lava) cuts the future; a time-limit truncation has
    terminated = 0 and bootstraps, since the state itself would have continued.
    """
    return reward + gamma * (1.0 - terminated) * next_value


def alpha_loss_gradient(log_prob: torch.Tensor, target_entropy: float) -> torch.Tensor:
    """d/d log_alpha of the entropy coefficient's loss -mean_b(log_alpha * (log_prob + target_entropy)),
    one per seed: -mean_b(log_prob + target_entropy), for log-probs (K, B).

    The loss is linear in log_alpha, so its gradient is written out rather than taken by autograd, whose
    backward pass over this one-op graph costs more than the alpha step's Adam. It is computed as autograd
    computes it: each term times -1/B, then summed, so the numbers are autograd's bit for bit
    (tests/test_sac.py compares them)."""
    return (log_prob + target_entropy).mul(-1.0 / log_prob.shape[1]).sum(1)


class SAC(SeedBatchedAgent):
    """K seeds of SAC: actor, twin critics with a target copy, log(alpha), and their Adam optimisers,
    each with a leading axis of length K = len(seeds).

    Tensors in and out carry the seed axis first: `act` maps observations (K, obs_dim) or
    (K, n, obs_dim) to actions of the same leading shape; `update` takes a batch of (K, B, ...) tensors.

    Reproducibility: seed i's initial weights are drawn on the CPU from
    `torch.Generator().manual_seed(seeds[i])`, so they are the same on every device, and every action
    it samples (in `act` and in `update`) draws its noise from its own generator on `device`, seeded
    the same way. torch's global RNG is never used, so given the same seed, config and data a seed
    is bit-identical whatever else runs and whichever seeds share its batch. `seed_state(i)` and
    `load_seed_states` save and restore seeds one by one, so a seed's checkpoint can be resumed alone
    or in another batch.
    """

    def __init__(self, obs_dim: int, act_dim: int, config: SACConfig | None = None,
                 seeds: Sequence[int] = (0,), device: torch.device | str = "cpu"):
        self.config = config = config or SACConfig()
        self.obs_dim, self.act_dim = obs_dim, act_dim
        self.seeds = tuple(int(s) for s in seeds)
        self.device = torch.device(device)
        k = len(self.seeds)
        if k == 0:
            raise ValueError("SAC needs at least one seed")
        self.actor = TanhGaussianActor(k, obs_dim, act_dim, config.hidden_sizes)
        self.critic = TwinQ(k, obs_dim, act_dim, config.hidden_sizes, config.critic_layer_norm)
        for i, seed in enumerate(self.seeds):
            init = torch.Generator().manual_seed(seed)
            init_member(self.actor, i, init)
            init_member(self.critic, i, init)
        self.actor.to(self.device)
        self.critic.to(self.device)
        self.target_critic = copy.deepcopy(self.critic).requires_grad_(False)
        # parameter lists walked once: module traversal at every update cost ~5% of a 64-unit update
        self.critic_params = list(self.critic.parameters())
        self.target_params = list(self.target_critic.parameters())
        self.generators = [torch.Generator(self.device).manual_seed(seed) for seed in self.seeds]
        self.log_alpha = torch.full((k,), math.log(config.initial_alpha), device=self.device, requires_grad=True)
        self.target_entropy = -float(act_dim) if config.target_entropy is None else config.target_entropy

        # seed_adam: a seed's updates are the same in any batch (see its docstring)
        self.actor_optimizer = seed_adam(self.actor.parameters(), config.lr)
        self.critic_optimizer = seed_adam(self.critic.parameters(), config.lr)
        self.alpha_optimizer = seed_adam([self.log_alpha], config.lr)

    @property
    def alpha(self) -> np.ndarray:
        """The current entropy coefficients exp(log_alpha), one per seed."""
        return self.log_alpha.detach().exp().cpu().numpy().copy()

    @torch.no_grad()
    def td_target(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """Soft Bellman target: r + gamma (1 - terminated) [min_i Q'_i(s', a') - alpha log pi(a'|s')]."""
        next_action, next_log_prob = self.actor(batch["next_obs"], generators=self.generators)
        alpha = self.log_alpha.exp().unsqueeze(1)
        next_value = self.target_critic(batch["next_obs"], next_action) - alpha * next_log_prob
        return bellman_target(batch["reward"], batch["terminated"], next_value, self.config.gamma)

    def update(self, batch: dict[str, torch.Tensor]) -> dict[str, np.ndarray]:
        """One gradient step on critics, actor and alpha for every seed, then a Polyak step on the
        target critics. Each loss is a sum over seeds of per-seed means, so seed i's gradient is exactly
        its own loss's. Returns per-seed statistics, arrays of shape (K,)."""
        batch = self.to_device(batch)
        obs, action = batch["obs"], batch["action"]

        # Critics: regress both Q's onto the shared target.
        target = self.td_target(batch)
        q1, q2 = self.critic.both(obs, action)
        critic_loss = ((q1 - target) ** 2).mean(1) + ((q2 - target) ** 2).mean(1)
        self.critic_optimizer.zero_grad(set_to_none=True)
        critic_loss.sum().backward()
        self.critic_optimizer.step()

        # Actor: maximise min Q - alpha log pi. Critics frozen: no weight gradients for them (~10% faster).
        alpha = self.log_alpha.exp().detach().unsqueeze(1)
        new_action, log_prob = self.actor(obs, generators=self.generators)
        for p in self.critic_params:
            p.requires_grad_(False)
        actor_loss = (alpha * log_prob - self.critic(obs, new_action)).mean(1)
        for p in self.critic_params:
            p.requires_grad_(True)
        self.actor_optimizer.zero_grad(set_to_none=True)
        actor_loss.sum().backward()
        self.actor_optimizer.step()

        # Alpha: raise it when entropy (-log pi) is below target, lower it when above.
        log_prob = log_prob.detach()
        self.log_alpha.grad = alpha_loss_gradient(log_prob, self.target_entropy)
        self.alpha_optimizer.step()

        soft_update(self.target_params, self.critic_params, self.config.tau)

        stats = torch.stack([critic_loss.detach(), actor_loss.detach(), alpha.squeeze(1),
                             0.5 * (q1.detach().mean(1) + q2.detach().mean(1)), -log_prob.mean(1)]).cpu().numpy()
        return dict(zip(("critic_loss", "actor_loss", "alpha", "q_mean", "entropy"), stats))

    def _parts(self) -> dict:
        return {
            "actor": self.actor, "critic": self.critic, "target_critic": self.target_critic,
            "log_alpha": self.log_alpha,
            "actor_optimizer": self.actor_optimizer, "critic_optimizer": self.critic_optimizer,
            "alpha_optimizer": self.alpha_optimizer,
        }
