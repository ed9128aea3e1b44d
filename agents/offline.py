"""Offline baselines trained on the demonstration transitions only: behaviour cloning and IQL.

Both train K seeds at once like SAC (stacked networks, per-seed generators and checkpoints), and
the runner evaluates them exactly as it evaluates SAC: the deterministic policy tanh(mean) from p0
and ood. A "step" of an offline run is one gradient update on a minibatch of demo transitions.

BC: a tanh-squashed Gaussian policy fitted by maximum likelihood, -log pi(a_demo | s). Gaussian
rather than deterministic so that the same actor class, log-density and evaluation (its mean) serve
BC, IQL and JSRL's guide.

IQL (Kostrikov, Nair and Levine, 2022, "Offline Reinforcement Learning with Implicit Q-Learning"):
    value:  L_V = E[ |tau - 1(u < 0)| u^2 ],  u = min_i Q'_i(s, a) - V(s)        (expectile tau)
    critic: L_Q = E[ (Q_i(s, a) - r - gamma (1 - terminated) V(s'))^2 ]  for both Q's
    actor:  L_pi = -E[ min(exp(beta (min_i Q'_i(s, a) - V(s))), 100) log pi(a | s) ]
with Q' the Polyak-averaged target critics, updated in the order value, actor, critic, target.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np
import torch

from .configs import BCConfig, IQLConfig
from .networks import MLP, TanhGaussianActor, TwinQ, init_member, soft_update
from .seed_batch import SeedBatchedAgent, seed_adam


def expectile_loss(diff: torch.Tensor, expectile: float) -> torch.Tensor:
    """|expectile - 1(diff < 0)| diff^2, elementwise: squares weighted asymmetrically, so that V moves
    towards an upper expectile of Q (expectile 0.5 weighs both sides alike: half the squared error)."""
    weight = torch.where(diff < 0, 1.0 - expectile, expectile)
    return weight * diff**2


class BC(SeedBatchedAgent):
    """Behaviour cloning for K seeds: maximise log pi(a_demo | s)."""

    def __init__(self, obs_dim: int, act_dim: int, config: BCConfig | None = None, seeds: Sequence[int] = (0,),
                 device: torch.device | str = "cpu"):
        self.config = config = config or BCConfig()
        self.obs_dim, self.seeds, self.device = obs_dim, tuple(int(s) for s in seeds), torch.device(device)
        self.actor = TanhGaussianActor(len(self.seeds), obs_dim, act_dim, config.hidden_sizes)
        for i, seed in enumerate(self.seeds):  # on the CPU: the same initial weights on every device
            init_member(self.actor, i, torch.Generator().manual_seed(seed))
        self.actor.to(self.device)
        self.generators = [torch.Generator(self.device).manual_seed(seed) for seed in self.seeds]
        self.optimizer = seed_adam(self.actor.parameters(), config.lr)

    def update(self, batch: dict[str, torch.Tensor]) -> dict[str, np.ndarray]:
        batch = self.to_device(batch)
        loss = -self.actor.log_prob(batch["obs"], batch["action"]).mean(1)
        self.optimizer.zero_grad(set_to_none=True)
        loss.sum().backward()
        self.optimizer.step()
        return {"actor_loss": loss.detach().cpu().numpy()}

    def _parts(self) -> dict:
        return {"actor": self.actor, "optimizer": self.optimizer}


class IQL(SeedBatchedAgent):
    """Implicit Q-learning for K seeds (see the module docstring for the losses)."""

    def __init__(self, obs_dim: int, act_dim: int, config: IQLConfig | None = None, seeds: Sequence[int] = (0,),
                 device: torch.device | str = "cpu"):
        self.config = config = config or IQLConfig()
        self.obs_dim, self.seeds, self.device = obs_dim, tuple(int(s) for s in seeds), torch.device(device)
        k = len(self.seeds)
        self.actor = TanhGaussianActor(k, obs_dim, act_dim, config.hidden_sizes)
        self.critic = TwinQ(k, obs_dim, act_dim, config.hidden_sizes)
        self.value = MLP(k, obs_dim, 1, config.hidden_sizes)
        for i, seed in enumerate(self.seeds):
            init = torch.Generator().manual_seed(seed)
            for net in (self.actor, self.critic, self.value):
                init_member(net, i, init)
        for net in (self.actor, self.critic, self.value):
            net.to(self.device)
        self.target_critic = copy.deepcopy(self.critic).requires_grad_(False)
        self.generators = [torch.Generator(self.device).manual_seed(seed) for seed in self.seeds]
        self.actor_optimizer = seed_adam(self.actor.parameters(), config.lr)
        self.critic_optimizer = seed_adam(self.critic.parameters(), config.lr)
        self.value_optimizer = seed_adam(self.value.parameters(), config.lr)

    def update(self, batch: dict[str, torch.Tensor]) -> dict[str, np.ndarray]:
        config, batch = self.config, self.to_device(batch)
        obs, action = batch["obs"], batch["action"]
        with torch.no_grad():
            target_q = self.target_critic(obs, action)

        # Value: an upper expectile of the target Q over the data's actions.
        value = self.value(obs).squeeze(-1)
        value_loss = expectile_loss(target_q - value, config.expectile).mean(1)
        self.value_optimizer.zero_grad(set_to_none=True)
        value_loss.sum().backward()
        self.value_optimizer.step()

        # Actor: advantage-weighted regression onto the data's actions.
        with torch.no_grad():
            advantage = target_q - self.value(obs).squeeze(-1)
            weight = torch.exp(config.temperature * advantage).clamp(max=config.max_weight)
        actor_loss = -(weight * self.actor.log_prob(obs, action)).mean(1)
        self.actor_optimizer.zero_grad(set_to_none=True)
        actor_loss.sum().backward()
        self.actor_optimizer.step()

        # Critics: one-step targets through V(s'), never through an action outside the data.
        with torch.no_grad():
            next_value = self.value(batch["next_obs"]).squeeze(-1)
            target = batch["reward"] + config.gamma * (1.0 - batch["terminated"]) * next_value
        q1, q2 = self.critic.both(obs, action)
        critic_loss = ((q1 - target) ** 2).mean(1) + ((q2 - target) ** 2).mean(1)
        self.critic_optimizer.zero_grad(set_to_none=True)
        critic_loss.sum().backward()
        self.critic_optimizer.step()

        soft_update(self.target_critic.parameters(), self.critic.parameters(), config.tau)
        stats = torch.stack([critic_loss.detach(), value_loss.detach(), actor_loss.detach(),
                             0.5 * (q1.detach().mean(1) + q2.detach().mean(1))]).cpu().numpy()
        return dict(zip(("critic_loss", "value_loss", "actor_loss", "q_mean"), stats))

    def _parts(self) -> dict:
        return {
            "actor": self.actor, "critic": self.critic, "target_critic": self.target_critic, "value": self.value,
            "actor_optimizer": self.actor_optimizer, "critic_optimizer": self.critic_optimizer,
            "value_optimizer": self.value_optimizer,
        }


