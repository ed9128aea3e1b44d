"""HySAC: Hybrid Q-learning (Song et al., 2023, "Hybrid RL") with SAC as the learner.

The demo transitions stay in their own buffer for all of training, and every minibatch draws a
fixed share of its transitions from them (HyQ's half and half by default) and the rest from the
online replay buffer.
"""

from __future__ import annotations

import numpy as np
import torch

from .replay_buffer import ReplayBuffer


def hybrid_minibatch(online: ReplayBuffer, demos: ReplayBuffer, size: int, demo_fraction: float,
                     rng: np.random.Generator) -> dict[str, torch.Tensor]:
    """`size` transitions: round(demo_fraction * size) from `demos` after the rest from `online`,
    both drawn with `rng` (online first)."""
    n_demos = round(demo_fraction * size)
    from_online = online.sample(size - n_demos, rng)
    from_demos = demos.sample(n_demos, rng)
    return {name: torch.cat([from_online[name], from_demos[name]]) for name in from_online}
