"""The training methods, each described once: its learner, its start strategy and how it uses the demos.

The training loop (eval/training/runner.py) reads only these fields, so a new method is one `Method` entry in
`METHODS` plus its algorithm's file. Every registered start strategy (agents/strategy_registry.py) is
a method of its own, SAC from its starts, named as the strategy (p0's is plain SAC, "sac"), so a new
strategy needs no entry here. Importing this module loads no learner (and no torch):
`Method.learner_class` imports the learner's module when a run builds it.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from .strategy_registry import STRATEGIES

LEARNERS = {"sac": ("lava_bridge_mj.agents.sac", "SAC"), "bc": ("lava_bridge_mj.agents.offline", "BC"),
            "iql": ("lava_bridge_mj.agents.offline", "IQL")}
"""Learner name -> (module, class). The name is also the RunConfig section of its hyperparameters."""
DEMO_USES = ("none", "hybrid", "offline", "guide")


@dataclass(frozen=True)
class Method:
    """One training method of the CLI's --method."""

    name: str
    learner: str
    """The learner it trains (a key of `LEARNERS`), with the RunConfig section of the same name."""
    start: str
    """The start strategy its training episodes start from (`make_start_strategy`'s name)."""
    demos: str = "none"
    """How it uses the demo transitions: "none"; "hybrid": every minibatch mixes them into the online
    ones (HySAC, agents/hysac.py); "offline": they are all it learns from, a step is one gradient
    update and no episode runs; "guide": an offline learner fitted to them acts first in each
    episode (JSRL, agents/jsrl.py)."""
    description: str = ""

    def __post_init__(self) -> None:
        if self.learner not in LEARNERS or self.demos not in DEMO_USES:
            raise ValueError(f"method {self.name!r}: learner must be one of {list(LEARNERS)} and demos one of "
                             f"{DEMO_USES}, got {self.learner!r} and {self.demos!r}")
        if self.start not in STRATEGIES:
            raise ValueError(f"method {self.name!r}: start must be a registered start strategy, one of "
                             f"{list(STRATEGIES)}, got {self.start!r}")

    @property
    def candidates(self) -> str:
        """The demo states its start strategy chooses among: its strategy's `candidates` ("subset", a
        seeded random subset of `demo_subset` of them, the same for every method that uses it;
        "demo_episodes", every demo episode that reaches the goal, whole and in time order, with each
        state's episode id; eval/training/seed_run.py `candidate_states`)."""
        return STRATEGIES[self.start].candidates

    @property
    def online(self) -> bool:
        """True when it steps the env (every method but the offline ones)."""
        return self.demos != "offline"

    def learner_class(self) -> type:
        return learner_class(self.learner)

    def minibatch(self, online: Any, demos: Any, size: int, rng: Any, hybrid_fraction: float) -> dict:
        """One seed's minibatch of `size` for an update: from the online replay buffer, the demo
        transitions alone (offline) or both (hybrid, `hybrid_fraction` of it from the demos)."""
        if self.demos == "offline":
            return demos.sample(size, rng)
        if self.demos == "hybrid":
            from .hysac import hybrid_minibatch

            return hybrid_minibatch(online, demos, size, hybrid_fraction, rng)
        return online.sample(size, rng)


def learner_class(name: str) -> type:
    """The learner class called `name` in `LEARNERS` (SAC, BC or IQL), imported on use."""
    module, attribute = LEARNERS[name]
    return getattr(importlib.import_module(module), attribute)


METHODS = {method.name: method for method in (
    *(Method("sac" if strategy.name == "p0" else strategy.name, "sac", strategy.name,
             description=strategy.description) for strategy in STRATEGIES.values()),
    Method("hysac", "sac", "p0", "hybrid", description="SAC from p0 whose minibatches are half demo transitions (HyQ)"),
    Method("hysac_auxss", "sac", "auxss", "hybrid", description="both HySAC's replay and AuxSS's start states"),
    Method("jsrl", "sac", "p0", "guide", description="a guide learned from the demos (IQL by default) acts first "
                                                     "in each episode, for a horizon that shrinks as the learner succeeds"),
    Method("bc", "bc", "p0", "offline", description="behaviour cloning"),
    Method("iql", "iql", "p0", "offline", description="IQL"),
)}
"""Every training method by its CLI name: SAC from each registered start strategy's starts (p0's
is plain SAC, "sac"), then the methods that use the demos otherwise."""
