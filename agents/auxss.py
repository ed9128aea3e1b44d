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
from lava_bridge_mj.task_states import check_coordinates

from .checks import check_integer, check_number, check_real_array
from .start_strategies import StartStrategy, StrategyContext, check_states


class AuxSS(StartStrategy):
    """AuxSS (the paper's Algorithms 1 and 2): sample states whose episodes end early more often.

    `W` starts at ones, so every state is tried before its weight drops. After an episode of length
    `L` from state `i`, `W[i]` becomes `max((H - L) / H, delta)` and the kernel `lam` spreads that
    value to nearby states: `W = (1 - lam) * W + lam * W[i]`. `weights` is `W` itself (unnormalised);
    every weight stays in [delta, 1]. Defaults are the paper's update with delta and sigma chosen on
    tuning seeds (docs/calibration.md, section 3); docs/design.md, section 2, explains the kernel.

    Args:
        states: (n, d) candidate start states, of any length d.
        horizon: H, in env steps: the step limit at which the env truncates an episode. It must equal
            the env's `max_episode_steps`; the default is `MAX_EPISODE_STEPS` (500), the limit of every
            registered task, and `StartStateWrapper` refuses an env whose limit differs. A run
            supplies its env's limit.
        delta: floor on `W[i]`, in (0, 1]. Default 0.05: a state whose episodes always time out stays
            sampled, 1/20 as often as one whose episodes fail at once.
        sigma: width of the Gaussian kernel `lam_j = exp(-||S_j - S_i||^2 / (2 sigma^2))`, in units of
            the scaled state (see `state_scale`); `lam_i = 1` and 0 < lam <= 1. Default 0.3: lam > 0.5
            within 1.18 sigma = 0.35 m (or m/s) on LavaBridge, so one episode informs a few consecutive
            steps of a demo trajectory; `effective_neighbourhood()` counts how many states that is.
        state_scale: per-coordinate divisors applied before distances, d positive numbers. None (the
            default) divides by 1: the paper's kernel on the raw coordinates. A run supplies its
            task's choice (`TaskStates.kernel_scale`): for a task that declares none, each
            coordinate's spread over the candidate states (`coordinate_spread`); LavaBridge declares
            (1, 1, 1, 1), metres and m/s, which weigh a velocity by the distance it carries a coasting
            ball when ball_mass / damping = 1 s (every task but LavaBridgeLowDamping-v0). For another
            ratio, (1, 1, damping / ball_mass, damping / ball_mass) keeps that meaning.
        count_successes: True (the paper) counts every termination, goal or lava, in `L`; False
            leaves `W` unchanged after an episode that reached the goal.
        ema: None (the paper) overwrites `W[i]` with the new value; a number in (0, 1] instead moves
            `W[i]` that fraction of the way towards it (an exponential moving average over episodes).
        kernel_dims: the coordinates the kernel measures distances on: "full" (the paper), all of
            them, or a list of coordinate indices. "position" stands for the task's position
            coordinates (`TaskStates.position`; LavaBridge's (x, y) are [0, 1]): a run replaces it by
            them, and records the list.
        timeout_weight: None (the paper) scores a timeout by the formula, `max((H - H) / H, delta) =
            delta`. A number in [delta, 1] is the new value after a timeout instead (1.0: like an
            immediate failure). A timeout is `L >= H` without success, so a lava touch on the very
            last step counts as one.
    """

    name = "auxss"
    description = "the paper's episode-length start-state safety"

    def __init__(
        self,
        states: Any,
        horizon: int = MAX_EPISODE_STEPS,
        delta: float = 0.05,
        sigma: float = 0.3,
        state_scale: Sequence[float] | None = None,
        count_successes: bool = True,
        ema: float | None = None,
        kernel_dims: str | Sequence[int] = "full",
        timeout_weight: float | None = None,
    ):
        super().__init__(states)
        dim = self._states.shape[1]
        full = isinstance(kernel_dims, str) and kernel_dims == "full"
        if isinstance(kernel_dims, str) and kernel_dims == "position":
            raise ValueError("kernel_dims='position' stands for the task's position coordinates, which only the "
                             "task knows: give them as a list (LavaBridge's: kernel_dims=[0, 1]), or build "
                             "through make_start_strategy with a context whose TaskStates declares position")
        if isinstance(kernel_dims, str) and not full:
            raise ValueError(f"kernel_dims must be 'full', 'position' or a list of coordinate indices, "
                             f"got {kernel_dims!r}")
        coordinates = None if full else check_coordinates("kernel_dims", kernel_dims, dim)
        scale = np.ones(dim) if state_scale is None else check_real_array("state_scale", state_scale, (dim,))
        scale = scale.astype(np.float64)
        if not (scale > 0).all():
            raise ValueError(f"state_scale must be {dim} positive finite numbers, one per state coordinate, "
                             f"got {state_scale!r}")
        self.horizon = check_integer("horizon", horizon, 1)
        self.delta = check_number("delta", delta, 0, 1)
        self.sigma = check_number("sigma", sigma)
        self.ema = None if ema is None else check_number("ema", ema, 0, 1)
        self.count_successes = bool(count_successes)
        self.kernel_dims = "full" if coordinates is None else list(coordinates)
        self.timeout_weight = None if timeout_weight is None else check_number("timeout_weight", timeout_weight, 0, 1)
        if self.timeout_weight is not None and self.timeout_weight < self.delta:
            raise ValueError(f"timeout_weight must be in [delta, 1] = [{self.delta}, 1], got {timeout_weight!r}")
        self.state_scale = scale
        scaled = self._states / scale
        # the points distances are measured between: computed once, the states never change
        self._kernel_points = scaled if coordinates is None else scaled[:, list(coordinates)]

    @classmethod
    def fill_params(cls, params: dict[str, Any], states: Any, context: StrategyContext) -> dict[str, Any]:
        """The run's step limit as H, and the task's kernel: its scale (`TaskStates.kernel_scale_for`,
        or 1 per coordinate without a task, so that `settings` record the numbers) and, for
        kernel_dims="position", its position coordinates."""
        params = dict(params)
        if context.horizon is not None:
            params.setdefault("horizon", context.horizon)
        task = context.task
        if isinstance(params.get("kernel_dims"), str) and params["kernel_dims"] == "position":
            if task is None or task.position is None:
                raise ValueError("kernel_dims='position' measures the task's position coordinates, and the task "
                                 "declares none (TaskStates.position): declare them, or give kernel_dims a list "
                                 "of coordinate indices")
            params["kernel_dims"] = list(task.position)
        if "state_scale" not in params:
            states = check_states(states)
            params["state_scale"] = (list(task.kernel_scale_for(states)) if task is not None
                                     else [1.0] * states.shape[1])
        return params

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
        """Per candidate state, how many candidate states (itself included) have lam > threshold.

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
