"""Named start-state distributions of the maze: `p0` (the MDP's own) and `ood` (robustness benchmark)."""

from __future__ import annotations

import numpy as np

from lava_bridge_mj.layout import Disc, Layout

START_NAMES = ("p0", "ood")


class DiscStartDistribution:
    """Pick a disc uniformly, then a ball position uniformly inside it, at rest.

    `sample(rng)` returns the 4-vector state (x, y, vx, vy) that `env.reset(options={"state": s})` takes.
    """

    def __init__(self, name: str, discs: tuple[Disc, ...]):
        self.name = name
        self.discs = np.asarray(discs, dtype=np.float64).reshape(-1, 3)

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        x, y, radius = self.discs[rng.integers(len(self.discs))]
        # sqrt of a uniform radius fraction gives a uniform density over the disc's area
        r = radius * np.sqrt(rng.random())
        angle = 2 * np.pi * rng.random()
        return np.array([x + r * np.cos(angle), y + r * np.sin(angle), 0.0, 0.0])

    def __repr__(self) -> str:
        return f"DiscStartDistribution({self.name!r}, {len(self.discs)} discs)"


def start_distribution(layout: Layout, name: str) -> DiscStartDistribution:
    """The named start distribution of `layout`: 'p0' or 'ood'."""
    if name == "p0":
        return DiscStartDistribution("p0", layout.p0_blobs)
    if name == "ood":
        return DiscStartDistribution("ood", layout.ood_spots)
    raise ValueError(f"unknown start distribution {name!r}; expected one of {START_NAMES}")
