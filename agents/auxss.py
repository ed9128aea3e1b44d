"""AuxSS, the paper's start strategy (Mehra, Capone and Schneider, Algorithms 1 and 2): sample the demo
states whose episodes end early more often.

Each candidate state i has a weight W[i], starting at 1, and is drawn with probability W[i] / sum(W).
After an episode of length L from state i, out of the step limit H, W[i] becomes max((H - L) / H, delta)
and a Gaussian kernel spreads that value to the states near S_i; every weight stays in [delta, 1].
docs/design.md, section 2, explains the kernel and where it departs from the paper's text.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from lava_bridge_mj.lava_bridge import MAX_EPISODE_STEPS

from .checks import check_integer, check_number, check_real_array
from .start_strategies import StartStrategy


class AuxSS(StartStrategy):
    """AuxSS (the paper's Algorithms 1 and 2): sample states whose episodes end early more often.

    `W` starts at ones, so every state is tried before its weight drops. After an episode of length
    `L` from state `i`, `W[i]` becomes `max((H - L) / H, delta)` and the kernel `lam` spreads that
    value to nearby states: `W = (1 - lam) * W + lam * W[i]`. `weights` is `W` itself (unnormalised);
    every weight stays in [delta, 1]. Defaults are the paper's update with delta and sigma chosen on
    tuning seeds (docs/calibration.md, section 3); docs/design.md, section 2, explains the kernel.

    Args:
        states: (n, 4) candidate start states (x, y, vx, vy).
        horizon: H, in env steps: the step limit at which the env truncates an episode. It must equal
            the env's `max_episode_steps`; the default is `MAX_EPISODE_STEPS` (500), the limit of every
            registered task, and `StartStateWrapper` refuses an env whose limit differs.
        delta: floor on `W[i]`, in (0, 1]. Default 0.05: a state whose episodes always time out stays
            sampled, 1/20 as often as one whose episodes fail at once.
        sigma: width of the Gaussian kernel `lam_j = exp(-||S_j - S_i||^2 / (2 sigma^2))`, in units of
            the scaled state (see `state_scale`); `lam_i = 1` and 0 < lam <= 1. Default 0.3: lam > 0.5
            within 1.18 sigma = 0.35 m (or m/s), so one episode informs a few consecutive steps of a
            demo trajectory; `effective_neighbourhood()` counts how many states that is.
        state_scale: per-component divisors (x, y, vx, vy) applied before distances, all > 0. Default
            (1, 1, 1, 1): metres and m/s, which weigh a velocity by the distance it carries a coasting
            ball when ball_mass / damping = 1 s (every task but LavaBridgeLowDamping-v0). For another
            ratio, (1, 1, damping / ball_mass, damping / ball_mass) keeps that meaning.
        count_successes: True (the paper) counts every termination, goal or lava, in `L`; False
            leaves `W` unchanged after an episode that reached the goal.
        ema: None (the paper) overwrites `W[i]` with the new value; a number in (0, 1] instead moves
            `W[i]` that fraction of the way towards it (an exponential moving average over episodes).
        kernel_dims: "full" (the paper) measures distance on all four components; "position" on
            (x, y) only.
        timeout_weight: None (the paper) scores a timeout by the formula, `max((H - H) / H, delta) =
            delta`. A number in [delta, 1] is the new value after a timeout instead (1.0: like an
            immediate failure). A timeout is `L >= H` without success, so a lava touch on the very
            last step counts as one.
    """

    name = "auxss"

    def __init__(
        self,
        states: Any,
        horizon: int = MAX_EPISODE_STEPS,
        delta: float = 0.05,
        sigma: float = 0.3,
        state_scale: Sequence[float] = (1.0, 1.0, 1.0, 1.0),
        count_successes: bool = True,
        ema: float | None = None,
        kernel_dims: str = "full",
        timeout_weight: float | None = None,
    ):
        super().__init__(states)
        if kernel_dims not in ("full", "position"):
            raise ValueError(f"kernel_dims must be 'full' or 'position', got {kernel_dims!r}")
        scale = check_real_array("state_scale", state_scale, (4,)).astype(np.float64)
        if not (scale > 0).all():
            raise ValueError(f"state_scale must be 4 positive finite numbers (x, y, vx, vy), got {state_scale!r}")
        self.horizon = check_integer("horizon", horizon, 1)
        self.delta = check_number("delta", delta, 0, 1)
        self.sigma = check_number("sigma", sigma)
        self.ema = None if ema is None else check_number("ema", ema, 0, 1)
        self.count_successes = bool(count_successes)
        self.kernel_dims = kernel_dims
        self.timeout_weight = None if timeout_weight is None else check_number("timeout_weight", timeout_weight, 0, 1)
        if self.timeout_weight is not None and self.timeout_weight < self.delta:
            raise ValueError(f"timeout_weight must be in [delta, 1] = [{self.delta}, 1], got {timeout_weight!r}")
        self.state_scale = scale
        scaled = self._states / scale
        # the points distances are measured between: computed once, the states never change
        self._kernel_points = scaled if kernel_dims == "full" else scaled[:, :2]

    def kernel_row(self, index: int) -> np.ndarray:
        """lam_j = exp(-||S_j - S_index||^2 / (2 sigma^2)) for every demo state j; lam_index = 1."""
        squared_distance = ((self._kernel_points - self._kernel_points[index]) ** 2).sum(axis=1)
        return np.exp(-squared_distance / (2 * self.sigma**2))

    def update(self, index: int, episode_length: int, success: bool = False) -> None:
        """Algorithm 2: set W[i] from the episode length, then smooth it onto neighbouring states."""
        self._check_episode(index, episode_length)
        if success and not self.count_successes:
            return  # ablation: only lava and timeouts say anything about a state's safety
        W, H, L = self._weights, self.horizon, episode_length
        target = max((H - L) / H, self.delta)  # delta keeps every state sampleable
        if self.timeout_weight is not None and L >= H and not success:
            target = self.timeout_weight  # ablation: a timeout says the policy has not solved this start
        W[index] = target if self.ema is None else (1 - self.ema) * W[index] + self.ema * target
        lam = self.kernel_row(index)
        W[:] = (1 - lam) * W + lam * W[index]

    def effective_neighbourhood(self, threshold: float = 0.5) -> np.ndarray:
        """Per demo state, how many demo states (itself included) have lam > threshold.

        The kernel's reach in units of demo states: one episode moves about this many weights.
        """
        return np.array([(self.kernel_row(i) > threshold).sum() for i in range(len(self._states))])

    def _learned_state(self) -> dict[str, Any]:
        return {"weights": self._weights.tolist()}

    def _load_learned_state(self, state: dict[str, Any]) -> None:
        weights = np.asarray(state["weights"], dtype=np.float64)
        if weights.shape != self._weights.shape:
            raise ValueError(f"state_dict weights have shape {weights.shape}, expected {self._weights.shape}")
        if not (np.isfinite(weights).all() and (weights > 0).all()):
            raise ValueError("state_dict weights must be positive and finite")
        self._weights[:] = weights
