"""A fixed-size ring buffer of transitions in numpy arrays, sampled uniformly with a caller's Generator.

It stores `terminated`, not `done`: an episode cut by the time limit (truncated) still has a future,
so its last transition must bootstrap from next_obs; only a true terminal state (goal, lava) must not.
"""

from __future__ import annotations

import numpy as np
import torch

FIELDS = ("obs", "action", "reward", "next_obs", "terminated")


class ReplayBuffer:
    """Holds the last `capacity` transitions; once full, each `add` overwrites the oldest.

    `sample` returns a dict of float32 torch tensors keyed by `FIELDS`: obs (B, obs_dim),
    action (B, act_dim), reward (B,), next_obs (B, obs_dim), terminated (B,) as 0.0 / 1.0.
    """

    def __init__(self, capacity: int, obs_dim: int, act_dim: int):
        self.capacity = int(capacity)
        self.obs = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.action = np.zeros((capacity, act_dim), dtype=np.float32)
        self.reward = np.zeros(capacity, dtype=np.float32)
        self.next_obs = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.terminated = np.zeros(capacity, dtype=np.float32)
        self.pos = 0  # where the next transition goes
        self.size = 0  # how many slots hold data

    def add(self, obs, action, reward: float, next_obs, terminated: bool) -> None:
        """Store one transition (obs, action, reward, next_obs, terminated)."""
        i = self.pos
        self.obs[i] = obs
        self.action[i] = action
        self.reward[i] = reward
        self.next_obs[i] = next_obs
        self.terminated[i] = terminated
        self.pos = (i + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

    def sample(self, batch_size: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        """`batch_size` transitions drawn uniformly with replacement using `rng`."""
        if self.size == 0:
            raise ValueError("cannot sample from an empty ReplayBuffer")
        idx = rng.integers(0, self.size, size=batch_size)
        return {name: torch.from_numpy(getattr(self, name)[idx]) for name in FIELDS}

    def __len__(self) -> int:
        return self.size

    def state_dict(self) -> dict:
        """Copies of the filled part of the arrays plus the write position: enough for an exact resume."""
        state = {name: getattr(self, name)[: self.size].copy() for name in FIELDS}
        state.update(capacity=self.capacity, pos=self.pos, size=self.size)
        return state

    def load_state_dict(self, state: dict) -> None:
        if state["capacity"] != self.capacity:
            raise ValueError(f"state has capacity {state['capacity']}, this buffer {self.capacity}")
        size = int(state["size"])
        for name in FIELDS:
            getattr(self, name)[:size] = state[name]
        self.pos, self.size = int(state["pos"]), size
