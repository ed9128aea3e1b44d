"""Start-state strategies: which demonstration state each training episode starts from.

Every strategy holds a fixed candidate set `states`, an (n, d) array of demo states of any length d
(LavaBridge's are (x, y, vx, vy)), and at each reset picks an index into it; some learn from how each
episode went. The shared API:

- `sample(rng) -> int`: an index into `states` (or `NO_STATE` for the MDP's own start distribution),
  drawn with probability `weights[i] / sum(weights)` from the caller's `np.random.Generator`.
- `update(index, episode_length, success=False)`: report one finished episode.
- `weights`: the *unnormalised* sampling weights, a read-only view; `probabilities`: normalised.
- `state_dict()` / `load_state_dict(d)`: the learned state as plain Python values (JSON and pickle
  both work), so a resumed run continues where it stopped.

This module holds the base class `StartStrategy`, which also declares how a strategy is built by
name (its CLI name, parameters and what a run supplies), `StrategyContext`, what a run supplies, and
the two fixed strategies, `P0Start` for the MDP's own start distribution and `UniformSS`. The paper's
methods (docs/design.md, section 1) each have their own module: `AuxSS` (Algorithm 2) in
agents/auxss.py, `OmegaSS` in agents/omega_ss.py and `GoalDistSS` in agents/goaldist_ss.py; RFCL's
reverse curriculum, `ReverseCurriculumSS`, is in agents/reverse_curriculum.py. The registry of them
all and `make_start_strategy(name, states, **params)`, which builds any by its CLI name, are in
agents/strategy_registry.py (and importable from here).
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from lava_bridge_mj.task_states import TaskStates, task_states_of

NO_STATE = -1
"""What `P0Start.sample` returns: start from the env's own reset, not from a candidate state.
`StartStateWrapper` checks for it explicitly (never use it to index `states`)."""


# --- shared helpers ---------------------------------------------------------------------------
def check_states(states: Any) -> np.ndarray:
    """`states` as a float64 (n, d) array with n >= 1, d >= 1 and finite entries; ValueError otherwise."""
    try:
        array = np.array(states, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"states must be an (n, d) array of numbers, one row per state, "
                         f"got {type(states).__name__}") from None
    if array.ndim != 2 or array.shape[1] == 0:
        raise ValueError(f"states must have shape (n, d), one row of coordinates per state, got shape {array.shape}")
    if len(array) == 0:
        raise ValueError(f"states must hold at least one state, got shape {array.shape}")
    bad_rows = np.flatnonzero(~np.isfinite(array).all(axis=1))
    if bad_rows.size:
        raise ValueError(f"states must be finite; rows {bad_rows[:5].tolist()} are not")
    return array


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


def _sample_index(weights: np.ndarray, rng: np.random.Generator) -> int:
    """Index i with probability weights[i] / sum(weights): one uniform draw, inverse CDF."""
    cumulative = np.cumsum(weights)
    # side="right" skips zero-weight entries, and rng.random() < 1 keeps the index below n
    return int(np.searchsorted(cumulative, rng.random() * cumulative[-1], side="right"))


CANDIDATE_SETS = ("subset", "demo_episodes")
"""The demo states a strategy chooses among in a run (`StartStrategy.candidates`)."""


class StartStrategy:
    """Base class: a fixed distribution `weights` over the candidate `states` that ignores feedback.

    Subclasses set `name` and `self._weights`; learning ones override `update` and the
    `_learned_state` / `_load_learned_state` pair that `state_dict` / `load_state_dict` call.

    A subclass is also its own declaration for building it by name (agents/strategy_registry.py):
    `name`, `description` and `candidates` below; its keyword parameters, with their defaults, are
    its constructor's (`parameters`), documented in its docstring's Args or, for one it shares with a
    base class, in the base's; `fill_params` takes from a run what the parameters leave unset.
    Registering the class makes it a strategy of `make_start_strategy`, of the CLI's `--method` and of
    a config's `strategy` section.
    """

    name = ""
    """Its name in `make_start_strategy`, the CLI's --method and a run's files."""
    description = ""
    """One line on what it does, for the CLI's help and the docs."""
    candidates = "subset"
    """The demo states it chooses among in a run: "subset", a seeded random subset of the demo states,
    the same for every strategy that uses it; "demo_episodes", every demo episode that reaches the goal,
    whole and in time order, with each state's episode id (eval/training/seed_run.py `candidate_states`)."""
    run_supplied: tuple[str, ...] = ()
    """Parameters that only code supplies (a run from its context, or a caller), never a config: an env
    to roll out in, a function, the candidates' own episode ids."""
    unrecorded: tuple[str, ...] = ()
    """Parameters left out of `settings`: objects and per-state data, not settings."""
    horizon: int | None = None
    """The env's step limit that `update` scores episode lengths against (AuxSS's H); None for a
    strategy that does not depend on it. `StartStateWrapper` checks it against the env's limit."""
    settings: dict[str, Any] | None = None
    """Every setting it was built with, defaults filled in (set by `make_start_strategy`)."""

    # --- how it is built by name --------------------------------------------------------------
    @classmethod
    def constructors(cls) -> tuple[Callable[..., "StartStrategy"], ...]:
        """What can build it from `states` and keyword parameters, each documenting its own under Args:
        the class itself and any alternative constructor (Omega-SS's `from_env`)."""
        return (cls,)

    @classmethod
    def parameters(cls) -> tuple[str, ...]:
        """The keyword parameters `make_start_strategy` accepts for it, in order: its constructor's."""
        return tuple(name for name in inspect.signature(cls).parameters if name != "states")

    @classmethod
    def builder(cls, params: dict[str, Any]) -> Callable[..., "StartStrategy"]:
        """Which of its `constructors` builds it from the keyword parameters `params`: the class
        itself, unless `params` call for another (Omega-SS estimates its omega given `env`)."""
        return cls

    @classmethod
    def fill_params(cls, params: dict[str, Any], states: Any, context: "StrategyContext") -> dict[str, Any]:
        """`params` completed with what the run's `context` supplies (its env, task, seed, step limit,
        budget) where they leave it unset; a new dict. A strategy that needs nothing from a run
        returns them as they are."""
        return dict(params)

    @classmethod
    def budget_tied(cls, params: dict[str, Any]) -> bool:
        """True when, built with `params` in a run, it depends on the run's training steps, so the
        run cannot be extended to more steps (GoalDist-SS's budget schedule)."""
        return False

    def __init__(self, states: Any):
        self._states = check_states(states)
        self._weights = np.ones(len(self._states))

    @property
    def states(self) -> np.ndarray:
        """The candidate start states, (n, d), read-only."""
        return _read_only(self._states)

    @property
    def weights(self) -> np.ndarray:
        """Unnormalised sampling weights, shape (n,), a read-only view that follows later updates."""
        return _read_only(self._weights)

    @property
    def probabilities(self) -> np.ndarray:
        """Sampling probabilities, weights / sum(weights): a fresh array."""
        return self._weights / self._weights.sum()

    def sample(self, rng: np.random.Generator) -> int:
        """An index into `states`, drawn with probability `probabilities[index]`."""
        return _sample_index(self._weights, rng)

    def update(self, index: int, episode_length: int, success: bool = False) -> None:
        """Report a finished episode that started from `states[index]`; static strategies ignore it."""
        self._check_episode(index, episode_length)

    def time_limit(self, index: int) -> int | None:
        """The step limit of an episode that starts from `states[index]`, or None for the env's own
        limit (every strategy but the reverse curriculum); `StartStateWrapper` truncates there."""
        return None

    def _check_episode(self, index: int, episode_length: int) -> None:
        if not 0 <= index < len(self._states):
            raise ValueError(f"index {index} is out of range for {len(self._states)} states")
        if episode_length < 0:
            raise ValueError(f"episode_length must be >= 0, got {episode_length}")

    def state_dict(self) -> dict[str, Any]:
        """The learned state as plain Python values (str, int, float, lists): JSON- and pickle-safe."""
        return {"name": self.name, "num_states": len(self._states), **self._learned_state()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore what `state_dict` returned; ValueError if it belongs to another strategy or state set."""
        if not isinstance(state, dict):
            raise ValueError(f"state_dict must be a dict, got {type(state).__name__}")
        if state.get("name") != self.name:
            raise ValueError(f"state_dict is for strategy {state.get('name')!r}, not {self.name!r}")
        if state.get("num_states") != len(self._states):
            raise ValueError(f"state_dict is for {state.get('num_states')} states, this strategy has {len(self._states)}")
        expected_keys = {"name", "num_states", *self._learned_state()}
        if set(state) != expected_keys:  # written by another version of the strategy: its state means other things
            missing, extra = sorted(expected_keys - set(state)), sorted(set(state) - expected_keys)
            raise ValueError(f"{self.name} state_dict lacks {missing or 'nothing'} and has unexpected "
                             f"{extra or 'nothing'} (expected keys {sorted(expected_keys)}): it was written by another "
                             f"version of {self.name}, whose state this one cannot continue")
        self._load_learned_state(state)

    def _learned_state(self) -> dict[str, Any]:
        return {}

    def _load_learned_state(self, state: dict[str, Any]) -> None:
        pass

    def __repr__(self) -> str:
        return f"{type(self).__name__}({len(self._states)} states)"


# --- the strategies ---------------------------------------------------------------------------
class P0Start(StartStrategy):
    """The MDP's own start distribution (plain SAC): `sample` always returns `NO_STATE`.

    Kept a strategy, rather than a special case of the runner, so every method goes through the same
    `StartStateWrapper`; the wrapper then calls the env's plain `reset()`. It has no candidate
    states: `states` is (0, 0) and `weights` is empty.

    Args:
        states: ignored (accepted so that every strategy is built alike).
    """

    name = "p0"
    description = "plain SAC from p0"

    def __init__(self, states: Any = None) -> None:
        self._states = np.zeros((0, 0))
        self._weights = np.zeros(0)

    @property
    def probabilities(self) -> np.ndarray:
        return np.zeros(0)

    def sample(self, rng: np.random.Generator) -> int:
        return NO_STATE

    def update(self, index: int, episode_length: int, success: bool = False) -> None:
        if index != NO_STATE:
            raise ValueError(f"P0Start only starts episodes with index NO_STATE={NO_STATE}, got {index}")


class UniformSS(StartStrategy):
    """U-SS: every demo state equally likely, forever (weights are all ones).

    Args:
        states: (n, d) candidate start states.
    """

    name = "uniform_ss"
    description = "uniform over demo states"


# --- what a run supplies ----------------------------------------------------------------------
@dataclass(frozen=True)
class StrategyContext:
    """What a run supplies to its start strategy, the same for every strategy: `probe`, an env of the
    run's task that resets to a state (Omega-SS's safety rollouts; left at an arbitrary state), `task`,
    what the task declares about its states (`TaskStates`: AuxSS's kernel scale and position, the
    goal or goal distance of GoalDist-SS; None: nothing, so each strategy keeps its own defaults), the
    run's `seed` (Omega-SS's rollouts) and `horizon`, the env's step limit (AuxSS's H), `episode_ids`,
    the demo episode of each candidate state where the candidates are whole demo episodes (the reverse
    curriculum's), and `budget`, the run's training steps (GoalDist-SS's schedule "budget"). A strategy
    takes from it only what its parameters leave unset (`StartStrategy.fill_params`)."""

    probe: Any = None
    task: TaskStates | None = None
    seed: int = 0
    horizon: int | None = None
    episode_ids: Any = None
    budget: int | None = None

    @classmethod
    def from_env(cls, probe: Any, seed: int, horizon: int | None, episode_ids: Any = None,
                 budget: int | None = None, task: TaskStates | None = None) -> "StrategyContext":
        """The context of a run of `probe`'s task: its `task` is the one given, else the `TaskStates`
        that `probe` declares (`task_states_of`: LavaBridgeEnv's, or a wrapper's), else
        `TaskStates()`, the generic defaults."""
        return cls(probe=probe, task=task_states_of(probe) if task is None else task, seed=seed, horizon=horizon,
                   episode_ids=episode_ids, budget=budget)


_REGISTRY_NAMES = ("STRATEGIES", "STRATEGY_NAMES", "check_strategy_params", "make_start_strategy")


def __getattr__(name: str) -> Any:
    # the registry imports every strategy's module, and each of those builds on this one
    if name in _REGISTRY_NAMES:
        from lava_bridge_mj.agents import strategy_registry

        return getattr(strategy_registry, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
