"""Start-state strategies: which demonstration state each training episode starts from.

Every strategy holds a fixed candidate set `states`, an (n, 4) array of demo states (x, y, vx, vy),
and at each reset picks an index into it; some learn from how each episode went. The shared API:

- `sample(rng) -> int`: an index into `states` (or `NO_STATE` for the MDP's own start distribution),
  drawn with probability `weights[i] / sum(weights)` from the caller's `np.random.Generator`.
- `update(index, episode_length, success=False)`: report one finished episode.
- `weights`: the *unnormalised* sampling weights, a read-only view; `probabilities`: normalised.
- `state_dict()` / `load_state_dict(d)`: the learned state as plain Python values (JSON and pickle
  both work), so a resumed run continues where it stopped.

The strategies are the paper's (docs/design.md, section 1): `AuxSS` (Algorithm 2), `OmegaSS`,
`UniformSS`, `GoalDistSS`, and `P0Start` for the MDP's own start distribution; RFCL's reverse
curriculum, `ReverseCurriculumSS`, lives in agents/reverse_curriculum.py.
`make_start_strategy(name, states, **params)` builds one by its CLI name.
"""

from __future__ import annotations

import inspect
import json
import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from lava_bridge_mj.lava_bridge import MAX_EPISODE_STEPS

from .checks import check_integer, check_number, check_real_array

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
        if set(state) != expected_keys:
            raise ValueError(f"{self.name} state_dict keys {sorted(state)} differ from {sorted(expected_keys)}")
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


class OmegaSS(StartStrategy):
    """Omega-SS (static): sample inversely to the random policy's safety, `weights = 1 / max(omega, clamp)`.

    Args:
        states: (n, 4) candidate start states.
        omega: per state, the probability that k uniformly random actions do not end in failure
            (`estimate_random_policy_safety` computes it), each in [0, 1].
        clamp: floor on omega in (0, 1], so every weight lies in [1, 1 / clamp]. Default 0.05: a state
            certain to fail is at most 20x more likely than a perfectly safe one, and the floor sits
            above the 1/32 resolution of the default 32 rollouts, so one lucky survival does not change
            a doomed state's weight.
    """

    name = "omega_ss"

    def __init__(self, states: Any, omega: Any, clamp: float = 0.05):
        super().__init__(states)
        omega = check_real_array("omega", omega, (len(self._states),)).astype(np.float64)  # one per state
        if not ((omega >= 0).all() and (omega <= 1).all()):
            raise ValueError("omega must hold probabilities in [0, 1]")
        self.clamp = check_number("clamp", clamp, 0, 1)
        self.omega = omega
        self._weights = 1.0 / np.maximum(omega, self.clamp)

    @classmethod
    def from_env(cls, states: Any, env: Any, k: int = 4, rollouts: int = 32, seed: int = 0,
                 clamp: float = 0.05) -> "OmegaSS":
        """Estimate omega by random rollouts in `env` (`estimate_random_policy_safety`), then build."""
        states = check_states(states)
        return cls(states, estimate_random_policy_safety(env, states, k=k, rollouts=rollouts, seed=seed), clamp)


def estimate_random_policy_safety(env: Any, states: Any, k: int = 4, rollouts: int = 32,
                                  seed: int = 0) -> np.ndarray:
    """Omega(s) per state: the fraction of `rollouts` of k uniformly random actions that do not fail.

    Each rollout resets `env` with `options={"state": s}` and takes up to k actions drawn uniformly
    from the action box by a numpy Generator seeded with `seed` (not `action_space.sample`, so the
    result does not depend on the env's own seeding). A rollout fails when it terminates without
    `info["is_success"]` (lava, on LavaBridge-v0); reaching the goal or being truncated is not a
    failure, since Omega measures how easily random actions end the episode badly.
    Works with any gymnasium env with a Box action space whose reset accepts `options={"state": s}`.
    """
    states = check_states(states)
    if not (isinstance(k, (int, np.integer)) and k >= 1):
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    if not (isinstance(rollouts, (int, np.integer)) and rollouts >= 1):
        raise ValueError(f"rollouts must be an integer >= 1, got {rollouts!r}")
    rng = np.random.default_rng(seed)
    low, high = env.action_space.low, env.action_space.high
    survived = np.zeros(len(states))
    for i, state in enumerate(states):
        for _ in range(rollouts):
            env.reset(options={"state": state})
            failed = False
            for _ in range(k):
                _, _, terminated, truncated, info = env.step(rng.uniform(low, high).astype(env.action_space.dtype))
                if terminated or truncated:
                    failed = terminated and not info.get("is_success", False)
                    break
            survived[i] += not failed
    return survived / rollouts


class GoalDistSS(StartStrategy):
    """GoalDist-SS (dynamic): weights `exp(-d(s, goal) / T)`, with the temperature T rising per episode.

    d is the Euclidean distance from a state's position (x, y) to `goal`. Early, near-goal states
    dominate; as T grows the distribution flattens towards uniform. The schedule is geometric,
    `T = min(temperature * temperature_growth ** episodes, max_temperature)`: how peaked the weights
    are depends on d / T, so equal multiplicative steps flatten it at an even pace. `weights` are
    shifted so the state nearest the goal has weight 1 (`exp(-(d - d.min()) / T)`), which changes no
    probability but keeps a small T from underflowing every weight to zero.

    Args:
        states: (n, 4) candidate start states.
        goal: the goal position (x, y); LavaBridge-v0's is `env.unwrapped.layout.goal`.
        temperature: T before the first episode (m), > 0. Default 0.5: a state 2 m further from the
            goal is e^4 ~ 55x less likely.
        temperature_growth: factor per finished episode, >= 1 (1 keeps T fixed). Default 1.005: T
            grows 100x, from 0.5 m to 50 m, in about 920 episodes, well inside a 300k-step run; chosen
            on tuning seeds (docs/calibration.md, section 5).
        max_temperature: the cap on T (m), >= temperature; T stays there once reached. Default 50:
            across LavaBridge-v0's ~10 m from the start room's far wall to the goal, weights then
            differ by at most e^0.2 ~ 1.2x.
    """

    name = "goaldist_ss"

    def __init__(self, states: Any, goal: Sequence[float], temperature: float = 0.5,
                 temperature_growth: float = 1.005, max_temperature: float = 50.0):
        super().__init__(states)
        self.goal = check_real_array("goal", goal, (2,)).astype(np.float64)
        self.initial_temperature = check_number("temperature", temperature)
        self.temperature_growth = check_number("temperature_growth", temperature_growth, 1, low_inclusive=True)
        self.max_temperature = check_number("max_temperature", max_temperature)
        if self.max_temperature < self.initial_temperature:
            raise ValueError(f"max_temperature={max_temperature!r} must be >= temperature={temperature!r}")
        distance = np.linalg.norm(self._states[:, :2] - self.goal, axis=1)
        self._excess_distance = distance - distance.min()
        self.episodes = 0
        self._refresh_weights()

    @property
    def temperature(self) -> float:
        """The current T."""
        # in log space, so many episodes cannot overflow growth ** episodes
        log_t = math.log(self.initial_temperature) + self.episodes * math.log(self.temperature_growth)
        return min(math.exp(min(log_t, 700.0)), self.max_temperature)

    def _refresh_weights(self) -> None:
        self._weights[:] = np.exp(-self._excess_distance / self.temperature)

    def update(self, index: int, episode_length: int, success: bool = False) -> None:
        """Count the episode; the temperature follows the episode count."""
        self._check_episode(index, episode_length)
        self.episodes += 1
        self._refresh_weights()

    def _learned_state(self) -> dict[str, Any]:
        return {"episodes": self.episodes}

    def _load_learned_state(self, state: dict[str, Any]) -> None:
        episodes = state["episodes"]
        if not (isinstance(episodes, (int, np.integer)) and episodes >= 0):
            raise ValueError(f"state_dict episodes must be an integer >= 0, got {episodes!r}")
        self.episodes = int(episodes)
        self._refresh_weights()


# --- building by CLI name ---------------------------------------------------------------------
STRATEGY_PARAMS: dict[str, tuple[str, ...]] = {
    "p0": (),
    "auxss": ("horizon", "delta", "sigma", "state_scale", "count_successes", "ema", "kernel_dims",
              "timeout_weight"),
    "omega_ss": ("omega", "env", "k", "rollouts", "seed", "clamp"),
    "uniform_ss": (),
    "goaldist_ss": ("goal", "temperature", "temperature_growth", "max_temperature"),
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
    step limit (AuxSS's H), and `episode_ids`, the demo episode of each candidate state where the
    candidates are whole demo episodes (the reverse curriculum's). A strategy takes from it only what
    its parameters leave unset."""

    probe: Any = None
    goal: Sequence[float] | None = None
    seed: int = 0
    horizon: int | None = None
    episode_ids: Any = None

    @classmethod
    def from_env(cls, probe: Any, seed: int, horizon: int, episode_ids: Any = None) -> "StrategyContext":
        """The context of a run of `probe`'s task (a LavaBridgeEnv: its layout's goal)."""
        return cls(probe=probe, goal=tuple(probe.layout.goal), seed=seed, horizon=horizon, episode_ids=episode_ids)

    def fill(self, name: str, params: dict[str, Any]) -> dict[str, Any]:
        """`params` of strategy `name` with what the run supplies added where they leave it unset."""
        params = dict(params)
        if name == "omega_ss" and "omega" not in params:
            params.setdefault("seed", self.seed)
            params.setdefault("env", self.probe)
        if name == "goaldist_ss" and self.goal is not None:
            params.setdefault("goal", self.goal)
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
    ValueError naming them and what is accepted.

    The strategy's `settings` are every setting it was built with, the code's defaults filled in,
    as JSON values: what a run's config leaves to the defaults, written down (provenance.json) so
    that a later change of a default cannot silently relabel the runs made before it. The env of
    Omega-SS's rollouts and a precomputed omega are objects, not settings, and are left out.
    """
    _check_params(name, params)
    if context is not None:
        params = context.fill(name, params)
    strategy = _build(name, states, params)
    strategy.settings = _settings(name, params)
    return strategy


def _build(name: str, states: Any, params: dict[str, Any]) -> StartStrategy:
    if name == "p0":
        return P0Start()
    if name == "uniform_ss":
        return UniformSS(states)
    if name == "reverse_ss":
        return _reverse_curriculum_class()(states, **params)
    if name == "auxss":
        return AuxSS(states, **params)
    if name == "goaldist_ss":
        if "goal" not in params:
            raise ValueError("start strategy 'goaldist_ss' needs goal=(x, y)")
        return GoalDistSS(states, **params)
    # omega_ss
    if ("omega" in params) == ("env" in params):
        raise ValueError("start strategy 'omega_ss' needs exactly one of omega= (precomputed) or env= (to estimate)")
    if "omega" in params:
        rollout_params = sorted(set(params) & {"k", "rollouts", "seed"})
        if rollout_params:
            raise ValueError(f"parameters {rollout_params} of 'omega_ss' only apply with env=, not omega=")
        return OmegaSS(states, **params)
    return OmegaSS.from_env(states, **params)


def _settings(name: str, params: dict[str, Any]) -> dict[str, Any]:
    """The settings of a strategy built from valid `params` (see make_start_strategy)."""
    builder = {"p0": P0Start, "uniform_ss": UniformSS, "auxss": AuxSS, "goaldist_ss": GoalDistSS,
               "reverse_ss": _reverse_curriculum_class(),
               "omega_ss": OmegaSS.from_env if "env" in params else OmegaSS}[name]
    skipped = {"self", "states", "env", "omega", "episode_ids", "forward_states"}
    settings = {parameter.name: params.get(parameter.name, parameter.default)
                for parameter in inspect.signature(builder).parameters.values() if parameter.name not in skipped}
    return json.loads(json.dumps(settings, default=lambda value: np.asarray(value).tolist()))


def _reverse_curriculum_class() -> type[StartStrategy]:
    # imported on use: agents/reverse_curriculum.py builds on this module
    from .reverse_curriculum import ReverseCurriculumSS

    return ReverseCurriculumSS


def _check_params(name: str, params: dict[str, Any]) -> None:
    if name not in STRATEGY_PARAMS:
        raise ValueError(f"unknown start strategy {name!r}; expected one of {STRATEGY_NAMES}")
    accepted = STRATEGY_PARAMS[name]
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise ValueError(f"unknown parameters {unknown} for start strategy {name!r}; "
                         f"it accepts {list(accepted) or 'none'}")
