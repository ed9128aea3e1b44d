"""The start strategies by name, each declared once: the registry that `make_start_strategy`, the CLI's
`--method` and `--set strategy.X=`, `RunConfig`'s checks, the docs and the tests all read.

A strategy is declared by its class alone (a `StartStrategy` subclass, agents/start_strategies.py):
its `name`, `description` and `candidates`; its keyword parameters with their defaults, the
constructor's signature (`parameters`), documented in the class docstring's Args (a parameter it does
not document there takes the entry of the nearest base class that does); and what a run supplies to
it (`fill_params`). `STRATEGIES` maps each name to its class, in the order the CLI lists them;
agents/methods.py makes each a training method, SAC from its starts.

Adding a strategy, e.g. "my_ss" (files touched: agents/my_ss.py, new, and this file):

1. agents/my_ss.py: `class MySS(StartStrategy)` with `name = "my_ss"`, a one-line `description`,
   its keyword parameters with defaults, each documented under Args in its docstring, `update`
   (and `_learned_state` / `_load_learned_state`) if it learns, and `fill_params` if it needs
   something from the run (`StrategyContext`: its env, task declaration, seed, step limit, budget);
2. here: `from .my_ss import MySS` and `MySS` in the tuple of `register` calls at the end.

Then `make_start_strategy("my_ss", states, **params)`, `lava-bridge-bench --method my_ss`,
`--set strategy.PARAM=VALUE`, a config's `{"strategy": {...}}` and tests/test_strategy_registry.py
(every strategy built from states of any length, run through `StartStateWrapper`, its parameters
documented, its state round-tripped) take it up. A strategy defined outside the package is added at
run time with `register(MySS)`, for `make_start_strategy` (the CLI's methods are fixed on import).
"""

from __future__ import annotations

import inspect
import json
import re
from dataclasses import dataclass
from typing import Any, Collection

import numpy as np

from .auxss import AuxSS
from .goaldist_ss import GoalDistSS
from .omega_ss import OmegaSS
from .reverse_curriculum import ReverseCurriculumSS
from .rfcl import RFCLReverseSS, RFCLSS
from .start_strategies import CANDIDATE_SETS, P0Start, StartStrategy, StrategyContext, UniformSS

STRATEGIES: dict[str, type[StartStrategy]] = {}
"""Every start strategy's class by its name, in registration order."""


def register(strategy_class: type[StartStrategy]) -> type[StartStrategy]:
    """Add `strategy_class` to `STRATEGIES` under its `name` and return it; ValueError unless it is a
    `StartStrategy` subclass with a new name (lower-case letters, digits, underscores), a
    description and a known `candidates`."""
    if not (isinstance(strategy_class, type) and issubclass(strategy_class, StartStrategy)):
        raise ValueError(f"a start strategy must be a StartStrategy subclass, got {strategy_class!r}")
    name = strategy_class.name
    if not (isinstance(name, str) and re.fullmatch(r"[a-z][a-z0-9_]*", name)):
        raise ValueError(f"{strategy_class.__name__}.name must be lower-case letters, digits and underscores, "
                         f"got {name!r}")
    if name in STRATEGIES:
        raise ValueError(f"start strategy {name!r} is already registered ({STRATEGIES[name].__name__})")
    if not strategy_class.description:
        raise ValueError(f"{strategy_class.__name__}.description must say in a line what it does")
    if strategy_class.candidates not in CANDIDATE_SETS:
        raise ValueError(f"{strategy_class.__name__}.candidates must be one of {CANDIDATE_SETS}, "
                         f"got {strategy_class.candidates!r}")
    STRATEGIES[name] = strategy_class
    return strategy_class


def strategy_class(name: Any) -> type[StartStrategy]:
    """The class of the strategy called `name`; ValueError naming the registered ones otherwise."""
    if not isinstance(name, str) or name not in STRATEGIES:
        raise ValueError(f"unknown start strategy {name!r}; expected one of {tuple(STRATEGIES)}")
    return STRATEGIES[name]


@dataclass(frozen=True)
class StrategyParameter:
    """One keyword parameter of a strategy, as its class declares it."""

    name: str
    default: Any
    """The constructor's default (`inspect.Parameter.empty`: required)."""
    doc: str
    """Its entry under Args in the class docstring, or in the nearest base class's that has one ("" when
    none has)."""
    from_config: bool
    """Whether a config (`RunConfig.strategy`, `--set strategy.NAME=`) may set it."""


def strategy_parameters(name: str) -> tuple[StrategyParameter, ...]:
    """The keyword parameters of strategy `name`, in order, with their defaults and docs."""
    cls = strategy_class(name)
    docs: dict[str, str] = {}
    defaults: dict[str, Any] = {}
    for constructor in cls.constructors():
        docs = {**_documented_args(constructor), **docs}  # the first one's docs win
        defaults = {**{p.name: p.default for p in inspect.signature(constructor).parameters.values()}, **defaults}
    return tuple(StrategyParameter(parameter, defaults.get(parameter, inspect.Parameter.empty),
                                   docs.get(parameter, ""), parameter not in cls.run_supplied)
                 for parameter in cls.parameters())


def _documented_args(constructor: Any) -> dict[str, str]:
    """name -> doc of each parameter under Args in `constructor`'s docstring; for a class, in its own
    and every base class's docstring, the nearest class in the method resolution order winning, so a
    subclass documents only the parameters it adds or explains anew."""
    if not isinstance(constructor, type):
        return _args_docs(inspect.getdoc(constructor) or "")
    docs: dict[str, str] = {}
    for owner in reversed(constructor.__mro__):  # object first, the class itself last: its entries win
        docs.update(_args_docs(inspect.cleandoc(vars(owner).get("__doc__") or "")))
    return docs


def _args_docs(docstring: str) -> dict[str, str]:
    """name -> text of each entry under "Args:" in a Google-style docstring ("a, b: text" documents both)."""
    docs: dict[str, str] = {}
    lines = docstring.splitlines()
    if "Args:" not in (line.strip() for line in lines):
        return docs
    start = [line.strip() for line in lines].index("Args:") + 1
    current: list[str] = []
    for line in lines[start:]:
        if line.strip() and not line.startswith(" "):
            break  # the Args section ended
        entry = re.match(r"^ {4}([\w, ]+):\s*(.*)$", line)
        if entry:
            current = [part.strip() for part in entry.group(1).split(",")]
            for part in current:
                docs[part] = entry.group(2)
        elif current and line.strip():
            for part in current:
                docs[part] += " " + line.strip()
    return docs


def check_strategy_params(name: str, params: Collection[str], from_config: bool = False) -> None:
    """ValueError unless `name` is a registered strategy and every one of `params` is a parameter of it.
    With `from_config`, the parameters that only code supplies (`run_supplied`: an env, a function,
    episode ids) are refused too, and left out of the accepted ones that the message lists."""
    cls = strategy_class(name)
    accepted = [parameter for parameter in cls.parameters() if not (from_config and parameter in cls.run_supplied)]
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise ValueError(f"unknown parameters {unknown} for start strategy {name!r}; "
                         f"it accepts {accepted or 'none'}")


def make_start_strategy(name: str, states: Any = None, context: StrategyContext | None = None,
                        **params: Any) -> StartStrategy:
    """Build a start strategy by its CLI name: p0, auxss, omega_ss, uniform_ss, goaldist_ss,
    reverse_ss, rfcl_reverse, rfcl, or any other registered one (`STRATEGIES`).

    `states` is the (n, d) candidate set, of any length d (ignored, and may be None, for p0).
    Parameters are the class's keyword arguments (`strategy_parameters` lists them with their
    defaults and docs); `context` supplies what the run knows where they leave it unset: its probe
    env, what the task declares about its states (`TaskStates`), its seed, step limit, demo episode
    ids and training budget (each class's `fill_params`). omega_ss takes exactly one of `omega=`
    (precomputed, e.g. cached) or `env=` (estimated here by `estimate_random_policy_safety` with `k`,
    `rollouts`, `seed`); goaldist_ss needs `goal=` or `goal_distance=`, reverse_ss `episode_ids=`
    (agents/reverse_curriculum.py). Unknown names or parameters raise ValueError naming them and
    what is accepted (`check_strategy_params`).

    The strategy's `settings` are every setting it was built with, the code's defaults and what the
    context supplied filled in, as JSON values: what a run's config leaves to the defaults, written
    down (provenance.json) so that a later change of a default cannot silently relabel the runs made
    before it. Objects and per-state data (the env of Omega-SS's rollouts, a precomputed omega, a
    goal-distance function, episode ids) are not settings and are left out (`unrecorded`).
    """
    cls = strategy_class(name)
    check_strategy_params(name, params)
    params = cls.fill_params(params, states, StrategyContext() if context is None else context)
    builder = cls.builder(params)
    strategy = builder(states, **params)
    skipped = {"states", *cls.unrecorded}
    settings = {parameter.name: params.get(parameter.name, parameter.default)
                for parameter in inspect.signature(builder).parameters.values() if parameter.name not in skipped}
    strategy.settings = json.loads(json.dumps(settings, default=lambda value: np.asarray(value).tolist()))
    return strategy


for _built_in in (P0Start, AuxSS, OmegaSS, UniformSS, GoalDistSS, ReverseCurriculumSS, RFCLReverseSS, RFCLSS):
    register(_built_in)

STRATEGY_NAMES = tuple(STRATEGIES)
"""The names of the strategies registered on import, in the CLI's order (`STRATEGIES` also holds those
registered later)."""
