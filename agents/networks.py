"""Network pieces shared by SAC and the baselines: a stacked MLP, a twin critic, a squashed Gaussian
actor, and Polyak averaging of target networks.

Every network holds `members` independent copies of itself, stacked along a leading axis and run with
batched matrix multiplies: input (members, batch, features) -> output (members, batch, ...). One
member is one training seed, so K seeds train in one process with one kernel call per layer instead of
K (`SAC` trains them together). Members never mix: member i's output and gradients depend only on
member i's weights and inputs, bit for bit (tests/test_sac.py checks that a member's numbers do not
change with the number of members beside it).

Everything is generic in `obs_dim`, `act_dim` and `hidden_sizes`. Actions live in [-1, 1]^act_dim
(LavaBridge-v0's action space); wrap other envs with `gymnasium.wrappers.RescaleAction` first.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import torch
from torch import nn
from torch.nn import functional as F

# log_std is clamped to this range: below it the Gaussian is a spike whose log-prob explodes,
# above it tanh saturates and the policy is effectively uniform noise.
LOG_STD_MIN = -5.0
LOG_STD_MAX = 2.0


class StackedLinear(nn.Module):
    """`members` independent linear layers y_i = x_i W_i + b_i, applied in one `torch.baddbmm`.

    weight: (members, in_features, out_features); bias: (members, 1, out_features).
    """

    def __init__(self, members: int, in_features: int, out_features: int):
        super().__init__()
        self.weight = nn.Parameter(torch.empty(members, in_features, out_features))
        self.bias = nn.Parameter(torch.empty(members, 1, out_features))

    @torch.no_grad()
    def init_member(self, i: int, generator: torch.Generator) -> None:
        """nn.Linear's default initialisation for member i: weights and bias ~ U(-1/sqrt(in), 1/sqrt(in))."""
        bound = 1.0 / math.sqrt(self.weight.shape[1])
        self.weight[i].uniform_(-bound, bound, generator=generator)
        self.bias[i].uniform_(-bound, bound, generator=generator)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.weight.shape[2] == 1:
            # One output (a Q-value): baddbmm becomes a matrix-vector product whose CPU kernel, and so
            # its rounding, changes with the number of members; a product and a sum over the last
            # axis round the same way for any number (measured: bit-identical for 1 and 8 members).
            return (x * self.weight.transpose(1, 2)).sum(-1, keepdim=True) + self.bias
        return torch.baddbmm(self.bias, x, self.weight)


class StackedLayerNorm(nn.Module):
    """`members` independent LayerNorms over the last axis: y_i = normalise(x_i) * weight_i + bias_i,
    the affine parameters starting at 1 and 0 as nn.LayerNorm's."""

    def __init__(self, members: int, features: int, eps: float = 1e-5):
        super().__init__()
        self.weight = nn.Parameter(torch.ones(members, 1, features))
        self.bias = nn.Parameter(torch.zeros(members, 1, features))
        self.eps = eps

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.layer_norm(x, x.shape[-1:], eps=self.eps) * self.weight + self.bias


class MLP(nn.Sequential):
    """StackedLinear -> ReLU, once per hidden size, then a StackedLinear output layer; with
    `layer_norm`, StackedLinear -> StackedLayerNorm -> ReLU (RLPD's critic, Ball et al. 2023)."""

    def __init__(self, members: int, in_dim: int, out_dim: int, hidden_sizes: Sequence[int] = (256, 256),
                 layer_norm: bool = False):
        layers: list[nn.Module] = []
        for size in hidden_sizes:
            layers.append(StackedLinear(members, in_dim, size))
            if layer_norm:
                layers.append(StackedLayerNorm(members, size))
            # in place: the layer before it does not keep its output for backward, and a (K, 256, 64)
            # batch is larger than a core's L2 cache, so every fresh tensor costs memory bandwidth
            # (measured: an SAC update at K = 13-25 seeds 1.1-1.25x faster, bit-identical)
            layers.append(nn.ReLU(inplace=True))
            in_dim = size
        layers.append(StackedLinear(members, in_dim, out_dim))
        super().__init__(*layers)


def init_member(module: nn.Module, i: int, generator: torch.Generator) -> None:
    """Initialise member i of every StackedLinear in `module`, in order, from `generator`: member i's
    weights depend only on its generator, never on how many members share the module."""
    for layer in module.modules():
        if isinstance(layer, StackedLinear):
            layer.init_member(i, generator)


class TwinQ(nn.Module):
    """Two independent Q(s, a) networks in one module, so one optimiser and one target copy serve both.

    `both(obs, action)` gives (q1, q2), each of shape (members, batch); calling the module gives their
    minimum, the pessimistic estimate SAC's actor and IQL's value target use (clipped double Q).
    """

    def __init__(self, members: int, obs_dim: int, act_dim: int, hidden_sizes: Sequence[int] = (256, 256),
                 layer_norm: bool = False):
        super().__init__()
        self.q1 = MLP(members, obs_dim + act_dim, 1, hidden_sizes, layer_norm)
        self.q2 = MLP(members, obs_dim + act_dim, 1, hidden_sizes, layer_norm)

    def both(self, obs: torch.Tensor, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.cat([obs, action], dim=-1)
        return self.q1(x).squeeze(-1), self.q2(x).squeeze(-1)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return torch.minimum(*self.both(obs, action))


class TanhGaussianActor(nn.Module):
    """pi(a|s) = tanh(u), u ~ Normal(mean(s), std(s)): a Gaussian squashed into [-1, 1].

    The log-density of a = tanh(u) is the Gaussian's minus the log-Jacobian of tanh,
    sum_i log(1 - tanh(u_i)^2), written as 2 * (log 2 - u - softplus(-2u)), which stays finite
    where tanh saturates. The deterministic (evaluation) action is tanh(mean).
    """

    def __init__(self, members: int, obs_dim: int, act_dim: int, hidden_sizes: Sequence[int] = (256, 256)):
        super().__init__()
        self.net = MLP(members, obs_dim, 2 * act_dim, hidden_sizes)

    def distribution(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The pre-tanh Gaussian: (mean, log_std), each (members, batch, act_dim)."""
        mean, log_std = self.net(obs).chunk(2, dim=-1)
        return mean, log_std.clamp(LOG_STD_MIN, LOG_STD_MAX)

    def forward(self, obs: torch.Tensor, deterministic: bool = False,
                generators: Sequence[torch.Generator] | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Sample (reparameterised, so gradients flow) an action and its log-prob, shape (members, batch).

        `generators`, one per member and on the actor's device, draw each member's noise, so a
        member's samples do not depend on the others; None draws from torch's global generator.
        In deterministic mode the action is tanh(mean) and the log-prob is that of the mean.
        """
        mean, log_std = self.distribution(obs)
        if deterministic:
            u = mean
        else:
            shape, dtype, device = mean.shape[1:], mean.dtype, mean.device
            if generators is None:
                noise = torch.randn(mean.shape, dtype=dtype, device=device)
            elif len(generators) == 1:  # the same draws as the stack below, without its copy
                noise = torch.randn(mean.shape, generator=generators[0], dtype=dtype, device=device)
            else:
                noise = torch.stack([torch.randn(shape, generator=g, dtype=dtype, device=device) for g in generators])
            u = mean + log_std.exp() * noise
        return torch.tanh(u), _squashed_log_prob(u, mean, log_std)

    def log_prob(self, obs: torch.Tensor, action: torch.Tensor, eps: float = 1e-6) -> torch.Tensor:
        """log pi(action | obs) for given actions in [-1, 1] (BC and IQL's weighted regression).

        Actions are clipped to [-1 + eps, 1 - eps] before atanh so demo actions on the bound stay finite.
        """
        mean, log_std = self.distribution(obs)
        u = torch.atanh(action.clamp(-1.0 + eps, 1.0 - eps))
        return _squashed_log_prob(u, mean, log_std)


def _squashed_log_prob(u: torch.Tensor, mean: torch.Tensor, log_std: torch.Tensor) -> torch.Tensor:
    """log N(u; mean, std) - log|d tanh(u)/du|, summed over action dimensions."""
    gaussian = -0.5 * ((u - mean) / log_std.exp()) ** 2 - log_std - 0.5 * math.log(2 * math.pi)
    log_jacobian = 2.0 * (math.log(2.0) - u - F.softplus(-2.0 * u))
    return (gaussian - log_jacobian).sum(-1)


@torch.no_grad()
def soft_update(target: Sequence[torch.Tensor], source: Sequence[torch.Tensor], tau: float) -> None:
    """Polyak averaging, in place, of matching parameter lists: target <- (1 - tau) * target + tau * source.
    Lists rather than modules, so callers walk their modules once, not at every update."""
    torch._foreach_lerp_(list(target), list(source), tau)


def parameter_count(build: Callable[[], nn.Module]) -> int:
    """The number of parameters of the module `build()` makes, built on torch's meta device: shapes
    only, no memory, so sizes far beyond the machine's can be counted."""
    with torch.device("meta"):
        return sum(p.numel() for p in build().parameters())
