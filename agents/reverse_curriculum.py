"""RFCL's per-demonstration reverse curriculum as a start strategy (Tao, Shukla, Chan, Su, "Reverse
Forward Curriculum Learning for Extreme Sample and Demonstration Efficiency", ICLR 2024).

Each demonstration i keeps a start index t_i, which begins at its last state (one step before the goal).
An episode picks a demonstration and starts from its state at t_i. Each demonstration remembers the
outcomes of its last m episodes that started at its current t_i; when all m reached the goal, the
memory is cleared and t_i moves `reverse_step_size` states towards the demonstration's start (never
past 0). A demonstration whose m last episodes from t_i = 0 all succeeded is solved. Once every
demonstration is solved, episodes start from the MDP's own start distribution: from a fixed set of
p0 states prioritised by RFCL's forward curriculum when `forward_states` are given, else from the
env's own reset (`NO_STATE`).

docs/design.md, section 4, maps each rule to RFCL's code and says what differs here and why.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .checks import check_integer, check_number, check_real_array
from .start_strategies import NO_STATE, StartStrategy, StrategyContext, _read_only, _sample_index

DEMO_SAMPLERS = ("uniform", "remaining")
FORWARD_WINDOW = 5
"""The forward curriculum scores a p0 state by its successes among its last 5 episodes (RFCL)."""
FORWARD_SCORE_TEMPERATURE = 0.1
FORWARD_STALENESS_TEMPERATURE = 0.1
FORWARD_STALENESS_COEF = 0.1
"""RFCL's forward-curriculum settings: rank weights `rank ** (-1 / 0.1)` for the score and for the
staleness, mixed 0.9 : 0.1."""
SOLVED_DEMO_WEIGHT = 1e-6
"""The "remaining" sampler's weight for a demonstration at t_i = 0 (RFCL's value): kept above zero so
that, once every demonstration reached 0, they are still drawn (equally) until each is solved."""


def goal_reaching_demos(demos: dict[str, np.ndarray], states: str = "observations") -> tuple[np.ndarray, np.ndarray]:
    """The states (the field `states` of the set) and episode ids of a demo set's episodes that end at
    the goal, in time order.

    A shipped set's last episode is cut at the set's size and never reaches the goal, so its last
    state is no place to start a reverse curriculum; RFCL likewise skips failed demonstrations. An
    episode ends at the goal when its last transition reports success (`successes`, in a set that
    `record_demos` recorded on an env that reports it); in a set without them, when its last
    transition terminated with a reward above the episode's others (the goal's +1 against 0: lava
    would end it on 0).
    """
    ids = np.asarray(demos["episode_ids"])
    keep = np.zeros(len(ids), dtype=bool)
    for episode in np.unique(ids):
        rows = np.flatnonzero(ids == episode)
        last = rows[-1]
        rewards = demos["rewards"][rows]
        if "successes" in demos:
            reached = bool(demos["successes"][last])
        else:
            reached = demos["terminations"][last] and rewards[-1] > rewards[:-1].max(initial=-np.inf)
        if reached:
            keep[rows] = True
    return demos[states][keep], ids[keep]


def forward_scores(outcomes: list[list[bool]]) -> np.ndarray:
    """RFCL's "success once" score of each p0 state from its last `FORWARD_WINDOW` outcomes: 2 for none
    successful (also a state never tried), 3 for some but under 75% (the frontier), 1 for the rest."""
    rates = np.array([sum(o) for o in outcomes], dtype=np.float64) / FORWARD_WINDOW
    return np.where(rates == 0, 2.0, np.where(rates < 0.75, 3.0, 1.0))


def rank_weights(values: np.ndarray, temperature: float) -> np.ndarray:
    """RFCL's "rankmin" prioritisation, normalised: ties share a rank, larger values rank first;
    a value with c values at or above it (itself included) has rank c + 1, weight rank ** (-1 / T)."""
    strictly_less = np.searchsorted(np.sort(values), values, side="left")
    ranks = len(values) - strictly_less + 1
    weights = ranks.astype(np.float64) ** (-1.0 / temperature)
    return weights / weights.sum()


def _check_forward_states(value: Any, dim: int) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):  # not numbers, or ragged
        array = np.zeros(0)
    if array.ndim != 2 or array.shape[1] != dim or len(array) == 0 or not np.isfinite(array).all():
        got = repr(value) if array.size <= 8 else f"shape {array.shape}"
        raise ValueError(f"forward_states must be a (k, {dim}) array of finite p0 states with k >= 1, or None, "
                         f"got {got}")
    return array


class ReverseCurriculumSS(StartStrategy):
    """RFCL's per-demonstration reverse curriculum over whole demonstrations.

    `weights` put the chosen demonstration's probability on its state at t_i and 0 on every other
    state. After every demonstration is solved, with `forward_states` the weights move onto those
    (`states` holds the demonstration states, then them) and follow RFCL's forward curriculum: a p0
    state is scored by `forward_scores` on its last 5 outcomes, and drawn with probability
    0.9 x `rank_weights(score)` + 0.1 x `rank_weights(staleness)`, staleness counting the draws since
    its last (each `sample` then updates it). Without `forward_states` the weights are all 0 and
    `sample` returns `NO_STATE`.

    Args:
        states: (n, d) demonstration states, of any length d: whole trajectories, each in time order, whose last
            state is one step before the goal (`goal_reaching_demos` gives them from a demo set).
        episode_ids: (n,) integers, the demonstration each state belongs to; each demonstration's
            states are contiguous. A run supplies its candidates' episode ids.
        per_demo_buffer_size: m, how many of a demonstration's latest episodes from its t_i are
            remembered; t_i moves once all m reached the goal (RFCL's default 3).
        reverse_step_size: how many states t_i moves towards the start each time (RFCL's delta;
            its ManiSkill port's default 1, one env step of the demonstration).
        demo_sampler: "uniform" picks each demonstration equally often; "remaining" picks
            demonstration i with probability proportional to t_i / T_i (T_i its length), and
            `SOLVED_DEMO_WEIGHT` at t_i = 0, as RFCL's code does: the ones furthest from their
            start are practised most.
        demo_horizon_to_max_steps_ratio: RFCL's shortened time limit: an episode starting t steps
            before the end of its demonstration may last `max_steps_min + t // ratio` steps
            (`time_limit`), which `StartStateWrapper` enforces, capped by the env's own limit. On
            by default with RFCL's 3; None keeps the env's limit for every episode.
        max_steps_min: the constant of that limit, so its smallest value (8, RFCL's ManiSkill port).
        forward_states: None, or (k, d) p0 start states for the forward curriculum (RFCL draws
            from 1,000 fixed env seeds: e.g. 1,000 seeded draws of the task's p0 distribution).
    """

    name = "reverse_ss"
    description = ("RFCL's per-demonstration reverse curriculum over the whole goal-reaching demo episodes, "
                   "with its shortened time limits")
    candidates = "demo_episodes"
    run_supplied = ("episode_ids",)
    unrecorded = ("episode_ids", "forward_states")

    def __init__(self, states: Any, episode_ids: Any, per_demo_buffer_size: int = 3, reverse_step_size: int = 1,
                 demo_sampler: str = "uniform", demo_horizon_to_max_steps_ratio: float | None = 3.0,
                 max_steps_min: int = 8, forward_states: Any = None):
        super().__init__(states)
        n = len(self._states)
        ids = check_real_array("episode_ids", episode_ids, (n,))
        if ids.dtype.kind not in "iu":
            raise ValueError(f"episode_ids must be integers, got dtype {ids.dtype}")
        boundaries = np.flatnonzero(np.diff(ids)) + 1
        if len(boundaries) + 1 != len(np.unique(ids)):
            raise ValueError("episode_ids must keep each demonstration's states together (contiguous, in time order); "
                             f"got ids {ids.tolist() if n <= 20 else str(ids[:20].tolist()) + '...'}")
        self.per_demo_buffer_size = check_integer("per_demo_buffer_size", per_demo_buffer_size, 1)
        self.reverse_step_size = check_integer("reverse_step_size", reverse_step_size, 1)
        if demo_sampler not in DEMO_SAMPLERS:
            raise ValueError(f"demo_sampler must be one of {DEMO_SAMPLERS}, got {demo_sampler!r}")
        self.demo_sampler = demo_sampler
        self.demo_horizon_to_max_steps_ratio = (None if demo_horizon_to_max_steps_ratio is None else
                                                check_number("demo_horizon_to_max_steps_ratio",
                                                             demo_horizon_to_max_steps_ratio))
        self.max_steps_min = check_integer("max_steps_min", max_steps_min, 1)

        self._demo_first = np.concatenate([[0], boundaries])  # index of each demonstration's first state
        self._demo_length = np.diff(np.append(self._demo_first, n))  # T_i
        self._demo_of_state = np.repeat(np.arange(len(self._demo_first)), self._demo_length)
        self._step_of_state = np.arange(n) - self._demo_first[self._demo_of_state]
        self._start_steps = self._demo_length - 1  # t_i: each demonstration's last state
        self._outcomes: list[list[bool]] = [[] for _ in self._demo_first]
        self._solved = np.zeros(len(self._demo_first), dtype=bool)

        self._num_demo_states = n
        dim = self._states.shape[1]
        forward = np.zeros((0, dim)) if forward_states is None else _check_forward_states(forward_states, dim)
        self._states = np.vstack([self._states, forward])
        self._weights = np.zeros(len(self._states))
        self._forward_outcomes: list[list[bool]] = [[] for _ in forward]
        self._staleness = np.zeros(len(forward), dtype=np.int64)
        self._refresh_weights()

    @classmethod
    def fill_params(cls, params: dict[str, Any], states: Any, context: StrategyContext) -> dict[str, Any]:
        """The run's candidates' episode ids, unless given."""
        params = dict(params)
        if context.episode_ids is not None:
            params.setdefault("episode_ids", context.episode_ids)
        return params

    # --- what the curriculum is at ----------------------------------------------------------
    @property
    def num_demos(self) -> int:
        return len(self._demo_first)

    @property
    def demo_states(self) -> np.ndarray:
        """The demonstration states, (n, d), read-only: `states` without the forward states."""
        return _read_only(self._states[:self._num_demo_states])

    @property
    def forward_states(self) -> np.ndarray:
        """The forward curriculum's p0 states, (k, d), read-only; (0, d) without them."""
        return _read_only(self._states[self._num_demo_states:])

    @property
    def demo_lengths(self) -> np.ndarray:
        """T_i: each demonstration's number of states."""
        return self._demo_length.copy()

    @property
    def start_steps(self) -> np.ndarray:
        """t_i: where in its demonstration each one's episodes start now."""
        return self._start_steps.copy()

    @property
    def solved(self) -> np.ndarray:
        return self._solved.copy()

    @property
    def phase(self) -> str:
        """"reverse" until the reverse stage is done (`reverse_done`: here, every demonstration solved), then
        "forward" (with forward states) or "p0"."""
        if not self.reverse_done:
            return "reverse"
        return "forward" if len(self._staleness) else "p0"

    @property
    def reverse_done(self) -> bool:
        """Whether the reverse stage handed over to p0: once every demonstration is solved."""
        return bool(self._solved.all())

    @property
    def probabilities(self) -> np.ndarray:
        total = self._weights.sum()
        return self._weights / total if total > 0 else np.zeros_like(self._weights)

    def steps_back(self, index: int) -> int:
        """How many steps the demonstration took from `states[index]` (a demonstration state) to the goal."""
        if not 0 <= index < self._num_demo_states:
            raise ValueError(f"index {index} is not one of the {self._num_demo_states} demonstration states")
        demo = self._demo_of_state[index]
        return int(self._demo_length[demo] - self._step_of_state[index])

    def time_limit(self, index: int) -> int | None:
        """RFCL's step limit for an episode from `states[index]`: `max_steps_min + steps_back // ratio`."""
        if not 0 <= index < self._num_demo_states or self.demo_horizon_to_max_steps_ratio is None:
            return None  # p0 starts keep the env's limit, as in RFCL's second stage
        return self.max_steps_min + int(self.steps_back(index) // self.demo_horizon_to_max_steps_ratio)

    # --- sampling and feedback --------------------------------------------------------------
    def _refresh_weights(self) -> None:
        self._weights[:] = 0.0  # in place: views from `weights` follow
        if self.reverse_done:
            if len(self._staleness):
                self._weights[self._num_demo_states:] = (
                    (1 - FORWARD_STALENESS_COEF) * rank_weights(forward_scores(self._forward_outcomes),
                                                                FORWARD_SCORE_TEMPERATURE)
                    + FORWARD_STALENESS_COEF * rank_weights(self._staleness, FORWARD_STALENESS_TEMPERATURE))
            return
        if self.demo_sampler == "uniform":
            demo_weights = np.ones(self.num_demos)
        else:
            demo_weights = self._start_steps / self._demo_length
            demo_weights[self._start_steps == 0] = SOLVED_DEMO_WEIGHT
        self._weights[self._demo_first + self._start_steps] = demo_weights

    def sample(self, rng: np.random.Generator) -> int:
        if self.phase == "p0":
            return NO_STATE
        index = _sample_index(self._weights, rng)
        if self.phase == "forward":  # RFCL's staleness: draws since each p0 state's last
            self._staleness += 1
            self._staleness[index - self._num_demo_states] = 0
            self._refresh_weights()
        return index

    def update(self, index: int, episode_length: int, success: bool = False) -> None:
        """Count an episode towards its demonstration's buffer if it started at that one's t_i.

        Episodes from p0 (`NO_STATE`), from a solved demonstration, or from a state that is no longer
        its demonstration's t_i (started before t_i moved) say nothing about the current t_i. An
        episode from a forward state counts towards that state's score.
        """
        if index == NO_STATE:
            if episode_length < 0:
                raise ValueError(f"episode_length must be >= 0, got {episode_length}")
            return
        self._check_episode(index, episode_length)
        if index >= self._num_demo_states:
            outcomes = self._forward_outcomes[index - self._num_demo_states]
            outcomes.append(bool(success))
            del outcomes[:-FORWARD_WINDOW]
            self._refresh_weights()
            return
        demo = self._demo_of_state[index]
        if self._solved[demo] or self._step_of_state[index] != self._start_steps[demo]:
            return
        outcomes = self._outcomes[demo]
        outcomes.append(bool(success))
        del outcomes[:-self.per_demo_buffer_size]
        if len(outcomes) == self.per_demo_buffer_size and all(outcomes):
            outcomes.clear()
            if self._start_steps[demo] > 0:
                self._start_steps[demo] = max(self._start_steps[demo] - self.reverse_step_size, 0)
            else:
                self._solved[demo] = True
            self._refresh_weights()

    # --- persistence -------------------------------------------------------------------------
    def _learned_state(self) -> dict[str, Any]:
        return {"start_steps": self._start_steps.tolist(), "outcomes": [list(o) for o in self._outcomes],
                "solved": self._solved.tolist(), "forward_outcomes": [list(o) for o in self._forward_outcomes],
                "staleness": self._staleness.tolist()}

    def _load_learned_state(self, state: dict[str, Any]) -> None:
        start_steps, outcomes, solved = state["start_steps"], state["outcomes"], state["solved"]
        k = self.num_demos
        if not (isinstance(start_steps, list) and len(start_steps) == k
                and all(isinstance(t, int) and 0 <= t < length for t, length in zip(start_steps, self._demo_length))):
            raise ValueError(f"state_dict start_steps must be {k} integers, each in [0, T_i), got {start_steps!r}")
        if not (isinstance(outcomes, list) and len(outcomes) == k
                and all(isinstance(o, list) and len(o) <= self.per_demo_buffer_size
                        and all(isinstance(x, bool) for x in o) for o in outcomes)):
            raise ValueError(f"state_dict outcomes must be {k} lists of at most {self.per_demo_buffer_size} "
                             f"booleans, got {outcomes!r}")
        if not (isinstance(solved, list) and len(solved) == k and all(isinstance(s, bool) for s in solved)
                and all(t == 0 for t, s in zip(start_steps, solved) if s)):
            raise ValueError(f"state_dict solved must be {k} booleans, true only where start_steps is 0, got {solved!r}")
        forward_outcomes, staleness, k_forward = state["forward_outcomes"], state["staleness"], len(self._staleness)
        if not (isinstance(forward_outcomes, list) and len(forward_outcomes) == k_forward
                and all(isinstance(o, list) and len(o) <= FORWARD_WINDOW
                        and all(isinstance(x, bool) for x in o) for o in forward_outcomes)):
            raise ValueError(f"state_dict forward_outcomes must be {k_forward} lists of at most {FORWARD_WINDOW} "
                             f"booleans, got {forward_outcomes!r}")
        if not (isinstance(staleness, list) and len(staleness) == k_forward
                and all(isinstance(x, int) and x >= 0 for x in staleness)):
            raise ValueError(f"state_dict staleness must be {k_forward} integers >= 0, got {staleness!r}")
        self._forward_outcomes = [list(o) for o in forward_outcomes]
        self._staleness = np.array(staleness, dtype=np.int64)
        self._start_steps = np.array(start_steps, dtype=np.int64)
        self._outcomes = [list(o) for o in outcomes]
        self._solved = np.array(solved, dtype=bool)
        self._refresh_weights()

    def __repr__(self) -> str:
        return (f"ReverseCurriculumSS({self.num_demos} demonstrations, {self._num_demo_states} states, "
                f"{len(self._staleness)} forward states, phase {self.phase})")
