"""RFCL as its authors publish it: the reverse curriculum with RFCL's own constants (`rfcl_reverse`), and
the reverse curriculum followed by RFCL's forward curriculum over the task's own start states (`rfcl`)
(Tao, Shukla, Chan, Su, "Reverse Forward Curriculum Learning for Extreme Sample and Demonstration
Efficiency", ICLR 2024; code github.com/StoneT2000/rfcl).

Both build on `ReverseCurriculumSS` (agents/reverse_curriculum.py), whose per-demonstration pointer,
outcome buffer and step back are RFCL's, and change what `reverse_ss` keeps stricter:

- the constants of RFCL's ManiSkill2 configs (configs/ms2/base_sac_ms2_sample_efficient.yml): reverse
  step 4, buffer 3, time-limit ratio 3, and the time limit's constant 16 of its InitialStateWrapper
  (rfcl/envs/wrappers/curriculum.py);
- starts spread around the pointer t_i as RFCL's "geometric" start-step sampler spreads them: at
  min(t_i + k, T_i - 1), k = 0..4, with probabilities 1/2, 1/4, 1/8, 1/16, 1/16; only episodes from t_i
  itself move the pointer;
- demonstrations drawn with probability proportional to t_i / T_i (1e-6 at t_i = 0);
- the reverse stage hands over once more than 90% of the demonstrations are solved (train.py), not all.

docs/start-strategies.md names the source of each constant and what RFCL does that is not carried here.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .checks import check_integer, check_number
from .reverse_curriculum import ReverseCurriculumSS
from .start_strategies import NO_STATE, StrategyContext

START_STEP_SAMPLERS = ("geometric", "fixed_point")
GEOMETRIC_SPREAD = np.array([0.5, 0.25, 0.125, 0.0625, 0.0625])
"""RFCL's "geometric" start-step sampler: the probability of starting k = 0..4 states after t_i."""
FORWARD_SEEDS = 1000
"""RFCL's num_seeds: the forward curriculum's fixed p0 states are the env's resets with seeds 0..999."""


class _RFCLStages(ReverseCurriculumSS):
    """What `RFCLReverseSS` and `RFCLSS` share: RFCL's start spread around t_i and its hand-over.

    Args:
        states: (n, d) demonstration states, of any length d: whole trajectories, each in time order, whose
            last state is one step before the goal (`goal_reaching_demos` gives them from a demo set).
        episode_ids: (n,) integers, the demonstration each state belongs to; each demonstration's
            states are contiguous. A run supplies its candidates' episode ids.
        per_demo_buffer_size: m, the outcomes a demonstration remembers from its t_i (3, RFCL's
            ManiSkill2, Adroit and MetaWorld configs).
        reverse_step_size: how many states t_i moves back each time (4, RFCL's ManiSkill2 configs;
            its Adroit and MetaWorld configs use 8).
        demo_sampler: "remaining" (RFCL's): demonstration i drawn with probability proportional to
            t_i / T_i, 1e-6 at t_i = 0; "uniform" draws each equally often.
        demo_horizon_to_max_steps_ratio: the time limit's divisor (3, RFCL's ManiSkill2 and Adroit
            configs; MetaWorld's use 1); None keeps the env's limit for every episode.
        max_steps_min: the time limit's constant (16, RFCL's InitialStateWrapper).
        start_step_sampler: "geometric" (RFCL's configs): start at t_i + k, k = 0..4 with probabilities
            1/2, 1/4, 1/8, 1/16, 1/16, never past the demonstration's last state; "fixed_point": at t_i.
        handover_solved_fraction: the reverse stage ends once the solved fraction of demonstrations is
            above it (0.9, RFCL's train.py); 0 ends it at the first solved one.
    """

    def __init__(self, states: Any, episode_ids: Any, per_demo_buffer_size: int, reverse_step_size: int,
                 demo_sampler: str, demo_horizon_to_max_steps_ratio: float | None, max_steps_min: int,
                 start_step_sampler: str, handover_solved_fraction: float, forward_states: Any):
        if start_step_sampler not in START_STEP_SAMPLERS:
            raise ValueError(f"start_step_sampler must be one of {START_STEP_SAMPLERS}, got {start_step_sampler!r}")
        self.start_step_sampler = start_step_sampler
        self.handover_solved_fraction = check_number("handover_solved_fraction", handover_solved_fraction, 0.0, 1.0,
                                                     low_inclusive=True, high_inclusive=False)
        super().__init__(states, episode_ids, per_demo_buffer_size=per_demo_buffer_size,
                         reverse_step_size=reverse_step_size, demo_sampler=demo_sampler,
                         demo_horizon_to_max_steps_ratio=demo_horizon_to_max_steps_ratio,
                         max_steps_min=max_steps_min, forward_states=forward_states)

    @property
    def solved_fraction(self) -> float:
        """The fraction of the demonstrations solved."""
        return float(self._solved.mean())

    @property
    def reverse_done(self) -> bool:
        """Whether the reverse stage handed over: once more than `handover_solved_fraction` are solved
        (solved demonstrations stay solved, so it never hands back)."""
        return self.solved_fraction > self.handover_solved_fraction

    def _refresh_weights(self) -> None:
        super()._refresh_weights()  # each demonstration's weight on its t_i, or the forward stage's
        if self.phase != "reverse" or self.start_step_sampler == "fixed_point":
            return
        demo_weights = self._weights[self._demo_first + self._start_steps].copy()
        self._weights[:] = 0.0
        last = self._demo_length - 1
        for offset, share in enumerate(GEOMETRIC_SPREAD):  # offsets past the last state pile up on it
            np.add.at(self._weights, self._demo_first + np.minimum(self._start_steps + offset, last),
                      share * demo_weights)

    def update(self, index: int, episode_length: int, success: bool = False) -> None:
        """As `ReverseCurriculumSS.update`; after the hand-over, an episode from a demonstration state
        (started before it) changes nothing: RFCL's stage 1 is over."""
        if index != NO_STATE and index < self._num_demo_states and self.phase != "reverse":
            self._check_episode(index, episode_length)
            return
        super().update(index, episode_length, success)

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self.num_demos} demonstrations, {self._num_demo_states} states, "
                f"{len(self._staleness)} forward states, phase {self.phase})")


class RFCLReverseSS(_RFCLStages):
    """RFCL's reverse curriculum with RFCL's own constants, then the env's own starts.

    Each demonstration i keeps a pointer t_i, at first its last state. An episode draws demonstration i
    with probability proportional to t_i / T_i (1e-6 at t_i = 0, `demo_sampler="remaining"`), then
    starts at min(t_i + k, T_i - 1) with k = 0..4 drawn with probabilities 1/2, 1/4, 1/8, 1/16, 1/16
    (`start_step_sampler="geometric"`); `weights` hold that joint distribution over the demonstration
    states. An episode that started exactly at t_i adds its outcome to the demonstration's buffer of
    the last m; when all m reached the goal the buffer is cleared and t_i moves `reverse_step_size`
    states back (never below 0), and m successes at t_i = 0 solve the demonstration. An episode from
    t steps before the goal may last `max_steps_min + t // demo_horizon_to_max_steps_ratio` steps,
    capped by the env's limit. Once more than `handover_solved_fraction` of the demonstrations are
    solved, the reverse stage is over for good (`phase` "p0"): episodes start from the env's own reset
    (`NO_STATE`) with the env's limit, RFCL's second stage without its forward curriculum (`rfcl` adds
    that).
    """

    name = "rfcl_reverse"
    description = ("RFCL's reverse curriculum with its own constants and start spread, then p0 once more than 0.9 "
                   "of the demos are solved")
    unrecorded = ("episode_ids",)

    def __init__(self, states: Any, episode_ids: Any, per_demo_buffer_size: int = 3, reverse_step_size: int = 4,
                 demo_sampler: str = "remaining", demo_horizon_to_max_steps_ratio: float | None = 3.0,
                 max_steps_min: int = 16, start_step_sampler: str = "geometric",
                 handover_solved_fraction: float = 0.9):
        super().__init__(states, episode_ids, per_demo_buffer_size, reverse_step_size, demo_sampler,
                         demo_horizon_to_max_steps_ratio, max_steps_min, start_step_sampler,
                         handover_solved_fraction, forward_states=None)


class RFCLSS(_RFCLStages):
    """RFCL: its reverse curriculum (`RFCLReverseSS`), then its forward curriculum over p0 states.

    The reverse stage is `rfcl_reverse`'s. Once more than `handover_solved_fraction` of the
    demonstrations are solved, episodes start from a fixed set of k p0 states, the env's own resets with
    seeds 0..k-1 (RFCL's 1,000 seeds), prioritised as RFCL's forward curriculum (prioritised level
    replay) does: each state's score from its last 5 outcomes (`forward_scores`: 2 none successful or
    never tried, 3 some but under 75%, 1 otherwise), ranked with ties sharing a rank (`rank_weights`,
    weight rank^(-1/0.1)), mixed 0.9 : 0.1 with the same rank weights of each state's staleness, the
    draws since its last. Those episodes keep the env's step limit.

    Args:
        forward_states: None, or (k, d) p0 states for the forward stage. A run supplies them: its
            probe env's states after `reset(seed=s)` for s = 0..forward_seeds-1 (`p0_states`: the full
            state where the env reports one, else the observation). None with no probe: the forward stage is the env's own reset.
        forward_seeds: k, how many seeded p0 states the run draws (1,000, RFCL's num_seeds in its
            ManiSkill2, Adroit and MetaWorld configs); unused when `forward_states` are given.
    """

    name = "rfcl"
    description = ("its reverse curriculum (as rfcl_reverse), then its forward curriculum: prioritised "
                   "level replay over 1,000 seeded p0 states")
    run_supplied = ("episode_ids", "forward_states")
    unrecorded = ("episode_ids", "forward_states")

    def __init__(self, states: Any, episode_ids: Any, per_demo_buffer_size: int = 3, reverse_step_size: int = 4,
                 demo_sampler: str = "remaining", demo_horizon_to_max_steps_ratio: float | None = 3.0,
                 max_steps_min: int = 16, start_step_sampler: str = "geometric",
                 handover_solved_fraction: float = 0.9, forward_states: Any = None,
                 forward_seeds: int = FORWARD_SEEDS):
        self.forward_seeds = check_integer("forward_seeds", forward_seeds, 1)
        super().__init__(states, episode_ids, per_demo_buffer_size, reverse_step_size, demo_sampler,
                         demo_horizon_to_max_steps_ratio, max_steps_min, start_step_sampler,
                         handover_solved_fraction, forward_states)

    @classmethod
    def fill_params(cls, params: dict[str, Any], states: Any, context: StrategyContext) -> dict[str, Any]:
        """The run's candidates' episode ids and, from its probe env, the p0 states of seeds
        0..forward_seeds-1, unless given."""
        params = super().fill_params(params, states, context)
        if params.get("forward_states") is None and context.probe is not None:
            seeds = check_integer("forward_seeds", params.get("forward_seeds", FORWARD_SEEDS), 1)
            params["forward_states"] = p0_states(context.probe, seeds)
        return params


def p0_states(env: Any, count: int) -> np.ndarray:
    """The env's own start states for seeds 0..count-1 (RFCL's fixed seeds): after `reset(seed=s)`, the
    full state an env wrapped in `ResetToState` reports as `info["state"]`, else the observation (a Lava
    Bridge env's state is its observation)."""
    states = []
    for seed in range(count):
        obs, info = env.reset(seed=seed)
        states.append(np.asarray(info.get("state", obs), dtype=np.float64))
    return np.array(states)
