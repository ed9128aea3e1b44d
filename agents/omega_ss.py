"""Omega-SS, a static start strategy: sample demo states in inverse proportion to a random policy's safety.

Omega(s) is the probability that k uniformly random actions from state s do not end the episode in
failure; `estimate_random_policy_safety` estimates it by rollouts in any resettable env. State i is drawn
with probability proportional to 1 / max(Omega(s_i), clamp), the same for the whole run, so the states
where random actions soon fail are practised most.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from .checks import check_number, check_real_array
from .start_strategies import StartStrategy, StrategyContext, check_states


class OmegaSS(StartStrategy):
    """Omega-SS (static): sample inversely to the random policy's safety, `weights = 1 / max(omega, clamp)`.

    Args:
        states: (n, d) candidate start states, of any length d.
        omega: per state, the probability that k uniformly random actions do not end in failure
            (`estimate_random_policy_safety` computes it), each in [0, 1]. `from_env` estimates it
            instead; built by name, give `omega=` or `env=`.
        clamp: floor on omega in (0, 1], so every weight lies in [1, 1 / clamp]. Default 0.05: a state
            certain to fail is at most 20x more likely than a perfectly safe one, and the floor sits
            above the 1/32 resolution of the default 32 rollouts, so one lucky survival does not change
            a doomed state's weight.
    """

    name = "omega_ss"
    description = "random-policy Monte-Carlo safety"
    run_supplied = ("env",)
    unrecorded = ("env", "omega")

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
        """Estimate omega by random rollouts in `env` (`estimate_random_policy_safety`), then build.

        Args:
            states: (n, d) candidate start states.
            env: an env of the task whose `reset` accepts `options={"state": s}`, to estimate omega
                in; a run supplies its probe env.
            k: random actions per rollout. Default 4.
            rollouts: rollouts per state. Default 32.
            seed: seeds the rollouts' actions; a run supplies its seed.
            clamp: as for the class.
        """
        states = check_states(states)
        return cls(states, estimate_random_policy_safety(env, states, k=k, rollouts=rollouts, seed=seed), clamp)

    @classmethod
    def constructors(cls) -> tuple[Callable[..., "OmegaSS"], ...]:
        return (cls, cls.from_env)

    @classmethod
    def parameters(cls) -> tuple[str, ...]:
        return ("omega", "env", "k", "rollouts", "seed", "clamp")  # both constructors', omega's first

    @classmethod
    def builder(cls, params: dict[str, Any]) -> Callable[..., "OmegaSS"]:
        """`from_env` with `env=`, the class itself with `omega=`; ValueError unless exactly one is given."""
        if ("omega" in params) == ("env" in params):
            raise ValueError("start strategy 'omega_ss' needs exactly one of omega= (precomputed) "
                             "or env= (to estimate)")
        rollout_params = sorted(set(params) & {"k", "rollouts", "seed"})
        if "omega" in params and rollout_params:
            raise ValueError(f"parameters {rollout_params} of 'omega_ss' only apply with env=, not omega=")
        return cls.from_env if "env" in params else cls

    @classmethod
    def fill_params(cls, params: dict[str, Any], states: Any, context: StrategyContext) -> dict[str, Any]:
        """Without `omega`, the run's probe env to estimate it in, and the run's seed for the rollouts."""
        params = dict(params)
        if "omega" not in params and context.probe is not None:
            params.setdefault("seed", context.seed)
            params.setdefault("env", context.probe)
        return params


def estimate_random_policy_safety(env: Any, states: Any, k: int = 4, rollouts: int = 32,
                                  seed: int = 0) -> np.ndarray:
    """Omega(s) per state: the fraction of `rollouts` of k uniformly random actions that do not fail.

    Each rollout resets `env` with `options={"state": s}` and takes up to k actions drawn uniformly
    from the action box by a numpy Generator seeded with `seed` (not `action_space.sample`, so the
    result does not depend on the env's own seeding). A rollout fails when it terminates without
    `info["is_success"]` (lava, on LavaBridge-v0); reaching the goal or being truncated is not a
    failure, since Omega measures how easily random actions end the episode badly.
    Works with any gymnasium env with a Box action space whose reset accepts `options={"state": s}`
    with states of any length (`lava_bridge_mj.ResetToState` gives one to a MuJoCo env); an env that
    never sets `info["is_success"]` counts every termination as a failure.
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
