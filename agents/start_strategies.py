"""Start-state strategies: which demonstration state each training episode starts from.

Every strategy holds a fixed candidate set `states`, an (n, 4) array of demo states (x, y, vx, vy),
and at each reset picks an index into it; some learn from how each episode went. The shared API:

- `sample(rng) -> int`: an index into `states` (or `NO_STATE` for the MDP's own start distribution),
  drawn with probability `weights[i] / sum(weights)` from the caller's `np.random.Generator`.
- `update(index, episode_length, success=False)`: report one finished episode.
- `weights`: the *unnormalised* sampling weights, a read-only view; `probabilities`: normalised.
- `state_dict()` / `load_state_dict(d)`: the learned state as plain Python values (JSON and pickle
  both work), so a resumed run continues where it stopped.

This module holds the base class `StartStrategy`, the two fixed ones, `P0Start` for the MDP's own
start distribution and `UniformSS`, and the factory: `make_start_strategy(name, states, **params)`
builds any strategy by its CLI name. The paper's methods (docs/design.md, section 1) each have their
own module: `AuxSS` (Algorithm 2) in agents/auxss.py, `OmegaSS` in agents/omega_ss.py and
`GoalDistSS` in agents/goaldist_ss.py; RFCL's reverse curriculum, `ReverseCurriculumSS`, is in
agents/reverse_curriculum.py.
"""

from __future__ import annotations

import importlib
import inspect
import json
from dataclasses import dataclass
from typing import Any, Callable, Collection, Sequence

import numpy as np

NO_STATE = -1
"""What `P0Start.sample` returns: start from the env's own reset, not from a candidate state.
`StartStateWrapper` checks for it explicitly (never use it to index `states`)."""


# --- shared helpers ---------------------------------------------------------------------------
def check_states(states: Any) -> np.ndarray:
    """`states` as a float64 (n, 4) array with n >= 1 and finite entries; ValueError otherwise."""
    try:
        array = np.array(states, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"states must be an (n, 4) array of numbers, got {type(states).__name__}") from None
    if array.ndim != 2 or array.shape[1] != 4:
        raise ValueError(f"states must have shape (n, 4) = rows of (x, y, vx, vy), got shape {array.shape}")
    if len(array) == 0:
        raise ValueError("states must hold at least one state, got shape (0, 4)")
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


class StartStrategy:
    """Base class: a fixed distribution `weights` over the candidate `states` that ignores feedback.

    Subclasses set `name` (the CLI name) and `self._weights`; learning ones override `update` and
    the `_learned_state` / `_load_learned_state` pair that `state_dict` / `load_state_dict` call.
    """

    name = ""
    horizon: int | None = None
    """The env's step limit that `update` scores episode lengths against (AuxSS's H); None for a
    strategy that does not depend on it. `StartStateWrapper` checks it against the env's limit."""
    settings: dict[str, Any] | None = None
    """Every setting it was built with, defaults filled in (set by `make_start_strategy`)."""

    def __init__(self, states: Any):
        self._states = check_states(states)
        self._weights = np.ones(len(self._states))

    @property
    def states(self) -> np.ndarray:
        """The candidate start states, (n, 4), read-only."""
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
    states: `states` is (0, 4) and `weights` is empty.
    """

    name = "p0"

    def __init__(self) -> None:
        self._states = np.zeros((0, 4))
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
    """U-SS: every demo state equally likely, forever (weights are all ones)."""

    name = "uniform_ss"


# --- building by CLI name ---------------------------------------------------------------------
STRATEGY_PARAMS: dict[str, tuple[str, ...]] = {
    "p0": (),
    "auxss": ("horizon", "delta", "sigma", "state_scale", "count_successes", "ema", "kernel_dims",
              "timeout_weight"),
    "omega_ss": ("omega", "env", "k", "rollouts", "seed", "clamp"),
    "uniform_ss": (),
    "goaldist_ss": ("goal", "temperature", "temperature_growth", "max_temperature", "schedule", "budget"),
    "reverse_ss": ("episode_ids", "per_demo_buffer_size", "reverse_step_size", "demo_sampler",
                   "demo_horizon_to_max_steps_ratio", "max_steps_min", "forward_states"),
}
"""The keyword parameters each CLI name accepts in `make_start_strategy`."""
STRATEGY_NAMES = tuple(STRATEGY_PARAMS)


@dataclass(frozen=True)
class StrategyContext:
    """What a run supplies to its start strategy, the same for every strategy: `probe`, an env of the
    run's task that Omega-SS's safety rollouts use (left at an arbitrary state), the task's `goal`
    (x, y) that GoalDist-SS weighs by, the run's `seed` (Omega-SS's rollouts) and `horizon`, the env's
    step limit (AuxSS's H), `episode_ids`, the demo episode of each candidate state where the
    candidates are whole demo episodes (the reverse curriculum's), and `budget`, the run's training
    steps (GoalDist-SS's schedule "budget"). A strategy takes from it only what its parameters leave
    unset."""

    probe: Any = None
    goal: Sequence[float] | None = None
    seed: int = 0
    horizon: int | None = None
    episode_ids: Any = None
    budget: int | None = None

    @classmethod
    def from_env(cls, probe: Any, seed: int, horizon: int, episode_ids: Any = None,
                 budget: int | None = None) -> "StrategyContext":
        """The context of a run of `probe`'s task (a LavaBridgeEnv: its layout's goal)."""
        return cls(probe=probe, goal=tuple(probe.layout.goal), seed=seed, horizon=horizon, episode_ids=episode_ids,
                   budget=budget)

    def fill(self, name: str, params: dict[str, Any]) -> dict[str, Any]:
        """`params` of strategy `name` with what the run supplies added where they leave it unset."""
        params = dict(params)
        if name == "omega_ss" and "omega" not in params:
            params.setdefault("seed", self.seed)
            params.setdefault("env", self.probe)
        if name == "goaldist_ss" and self.goal is not None:
            params.setdefault("goal", self.goal)
        if name == "goaldist_ss" and params.get("schedule") == "budget" and self.budget is not None:
            params.setdefault("budget", self.budget)
        if name == "auxss" and self.horizon is not None:
            params.setdefault("horizon", self.horizon)
        if name == "reverse_ss" and self.episode_ids is not None:
            params.setdefault("episode_ids", self.episode_ids)
        return params


def make_start_strategy(name: str, states: Any = None, context: StrategyContext | None = None,
                        **params: Any) -> StartStrategy:
    """Build a start strategy by its CLI name: p0, auxss, omega_ss, uniform_ss, goaldist_ss or
    reverse_ss.

    `states` is the (n, 4) candidate set (ignored, and may be None, for p0). Parameters are the
    classes' keyword arguments (`STRATEGY_PARAMS` lists them); `context` supplies the run's probe
    env, goal, seed, horizon and demo episode ids where they are unset. omega_ss takes exactly one of `omega=`
    (precomputed, e.g. cached) or `env=` (estimated here by `estimate_random_policy_safety` with `k`,
    `rollouts`, `seed`). goaldist_ss needs `goal=(x, y)`, reverse_ss `episode_ids=`
    (agents/reverse_curriculum.py). Unknown names or parameters raise
    ValueError naming them and what is accepted (`check_strategy_params`).

    The strategy's `settings` are every setting it was built with, the code's defaults filled in,
    as JSON values: what a run's config leaves to the defaults, written down (provenance.json) so
    that a later change of a default cannot silently relabel the runs made before it. The env of
    Omega-SS's rollouts and a precomputed omega are objects, not settings, and are left out.
    """
    check_strategy_params(name, params)
    if context is not None:
        params = context.fill(name, params)
    strategy = _build(name, states, params)
    strategy.settings = _settings(name, params)
    return strategy


def check_strategy_params(name: str, params: Collection[str], supplied: Collection[str] = ()) -> None:
    """ValueError unless `name` is a strategy's CLI name and every one of `params` is a parameter of it
    (`STRATEGY_PARAMS`). `supplied` are parameters the caller always fills in itself: they are refused
    too, and left out of the accepted ones that the message lists."""
    if name not in STRATEGY_PARAMS:
        raise ValueError(f"unknown start strategy {name!r}; expected one of {STRATEGY_NAMES}")
    accepted = [parameter for parameter in STRATEGY_PARAMS[name] if parameter not in supplied]
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise ValueError(f"unknown parameters {unknown} for start strategy {name!r}; "
                         f"it accepts {accepted or 'none'}")


_CLASSES = {"p0": ("start_strategies", "P0Start"), "uniform_ss": ("start_strategies", "UniformSS"),
            "auxss": ("auxss", "AuxSS"), "omega_ss": ("omega_ss", "OmegaSS"),
            "goaldist_ss": ("goaldist_ss", "GoalDistSS"), "reverse_ss": ("reverse_curriculum", "ReverseCurriculumSS")}
"""CLI name -> (its module in agents/, its class)."""


def _builder(name: str, params: dict[str, Any]) -> Callable[..., StartStrategy]:
    """What builds strategy `name` from `params`: its class, or `OmegaSS.from_env` to estimate omega."""
    module, attribute = _CLASSES[name]
    # imported on use: each strategy's module builds on this one
    strategy_class = getattr(importlib.import_module(f".{module}", __package__), attribute)
    return strategy_class.from_env if name == "omega_ss" and "env" in params else strategy_class


def _build(name: str, states: Any, params: dict[str, Any]) -> StartStrategy:
    if name == "p0":
        return P0Start()
    if name == "goaldist_ss" and "goal" not in params:
        raise ValueError("start strategy 'goaldist_ss' needs goal=(x, y)")
    if name == "omega_ss":
        if ("omega" in params) == ("env" in params):
            raise ValueError("start strategy 'omega_ss' needs exactly one of omega= (precomputed) "
                             "or env= (to estimate)")
        rollout_params = sorted(set(params) & {"k", "rollouts", "seed"})
        if "omega" in params and rollout_params:
            raise ValueError(f"parameters {rollout_params} of 'omega_ss' only apply with env=, not omega=")
    return _builder(name, params)(states, **params)


def _settings(name: str, params: dict[str, Any]) -> dict[str, Any]:
    """The settings of a strategy built from valid `params` (see make_start_strategy)."""
    skipped = {"self", "states", "env", "omega", "episode_ids", "forward_states"}
    settings = {parameter.name: params.get(parameter.name, parameter.default)
                for parameter in inspect.signature(_builder(name, params)).parameters.values()
                if parameter.name not in skipped}
    return json.loads(json.dumps(settings, default=lambda value: np.asarray(value).tolist()))
