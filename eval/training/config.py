"""A training run's configuration: `RunConfig`, its validation, and the names of the methods.

Torch-free, so that the CLI's help, a sweep's planning and a report read and check configurations
without loading the learners.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import gymnasium

import lava_bridge_mj
from lava_bridge_mj.agents.checks import check_fits_in_memory, check_integer, check_number
from lava_bridge_mj.agents.configs import BCConfig, IQLConfig, JSRLConfig, SACConfig
from lava_bridge_mj.agents.methods import METHODS as METHOD_SPECS
from lava_bridge_mj.agents.strategy_registry import check_strategy_params, strategy_class
from lava_bridge_mj.demos import MINARI_PREFIX, content_hash, load_minari_demos
from lava_bridge_mj.external import EXTERNAL_TASKS

METHODS = tuple(METHOD_SPECS)
"""Training methods, by their CLI names (agents/methods.py describes each)."""
AGENT_CONFIGS = {"sac": SACConfig, "bc": BCConfig, "iql": IQLConfig, "jsrl": JSRLConfig}
"""RunConfig's nested hyperparameter sections."""
MAX_SEED = 2**32 - 1
"""Seeds are 32-bit: what every RNG here (numpy's, torch's, MuJoCo's) takes without overflow."""
MAX_STEPS = 10**12
"""Most training steps (and steps between evaluations) a run may ask for: years of training at this
suite's few thousand steps per second, so a larger number is a typo, not a budget."""
MAX_EVAL_EPISODES = 1000
"""Evaluation keeps one env per episode; 1,000 already gives a success rate to within about 0.03."""


class ConfigurationError(ValueError):
    """A value of a RunConfig that only building the run can check (a start strategy's parameter out of
    its range): `train` raises it before anything is written; a usage error where the user gave it."""


@dataclasses.dataclass
class RunConfig:
    """One training run. Defaults: a quick run that shows learning on a 2-core laptop in minutes;
    `steps=300_000` with `eval_every=10_000` is the paper's protocol."""

    method: str = "auxss"
    """Training method: sac (start from p0), SAC with a start strategy (auxss, omega_ss, uniform_ss,
    goaldist_ss, reverse_ss), HySAC, whose minibatches mix in the demo transitions (hysac from p0, hysac_auxss), JSRL
    (a guide learned from the demos acts first in each episode), or an offline method trained on the demo
    transitions alone (bc, iql)."""
    env_id: str = lava_bridge_mj.ENV_ID
    """The task: an id of `lava_bridge_mj.TASKS` (its layout, its p0 and ood starts, and its shipped
    demos), an external task of `lava_bridge_mj.external.EXTERNAL_TASKS` (`make_task_env`'s env, its p0
    and ood starts, its shipped demos; docs/external-tasks.md), or any other gymnasium id whose env
    `lava_bridge_mj.ResetToState` serves (Hopper-v5, ...), which trains from a demo file or Minari
    dataset recorded on it (docs/any-env.md)."""
    seed: int = 0
    """Seeds the networks, the env, the start strategy, the replay sampling and the demo subset."""
    steps: int = 50_000
    """Online environment steps (offline methods: gradient steps on the demo transitions)."""
    demos: int | str = 500
    """Which demo set the candidate start states (and HySAC's offline transitions) come from: a shipped
    set (500 or 7500; of a Lava Bridge task or an external task), the path of a demo file
    (`lava_bridge_mj.save_demos`), kept as an absolute path, or "minari:ID", the local Minari dataset ID
    (`lava_bridge_mj.demos.load_minari_demos`; never downloaded). An env that is not a Lava Bridge task
    starts from the set's full `states`."""
    demos_sha256: str | None = None
    """The content hash (`content_hash`) of the demo file or Minari dataset `demos` names (of its arrays
    as loaded), filled in from it; kept in config.json, so that a resume refuses a set that changed.
    None for a shipped set."""
    demo_subset: int = 150
    """Candidate start states: a seeded random subset of this many demo states (the paper's 150),
    the same set for every start strategy so that they differ only in how they sample it (reverse_ss
    starts from whole demo episodes instead)."""
    hybrid_fraction: float = 0.5
    """HySAC only: the share of every minibatch drawn from the demo transitions, which stay in their own
    buffer for all of training (HyQ's half and half); the rest comes from the online replay buffer."""
    eval_every: int = 5_000
    """Evaluate (and checkpoint) every this many steps."""
    eval_episodes: int = 50
    """Evaluation episodes per start distribution (p0 and ood), with fixed seeds."""
    strategy: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Extra keyword parameters of the start strategy (e.g. {"sigma": 0.3} for auxss)."""
    sac: SACConfig = dataclasses.field(default_factory=SACConfig)
    """SAC hyperparameters (sac, the start-strategy methods, hysac, hysac_auxss)."""
    bc: BCConfig = dataclasses.field(default_factory=BCConfig)
    """Behaviour cloning hyperparameters (bc)."""
    iql: IQLConfig = dataclasses.field(default_factory=IQLConfig)
    """IQL hyperparameters (iql, and jsrl's guide when it is IQL)."""
    jsrl: JSRLConfig = dataclasses.field(default_factory=JSRLConfig)
    """JSRL's guide and curriculum (jsrl); its learner uses `sac`."""
    env: dict[str, Any] = dataclasses.field(default_factory=dict)
    """Keyword arguments of the env, for training and evaluation alike (e.g. {"lava_reward": 0.0} or
    Layout fields such as {"bridge_width": 0.4}; `gymnasium.make`'s for another env); the candidate
    states still come from the demos."""

    def __post_init__(self) -> None:
        for name, section in AGENT_CONFIGS.items():
            if isinstance(getattr(self, name), dict):
                try:
                    setattr(self, name, section(**getattr(self, name)))
                except ValueError as error:  # name the section: "sac.lr must be ..."
                    raise ValueError(f"{name}.{error}") from None
        if not isinstance(self.method, str) or self.method not in METHOD_SPECS:
            raise ValueError(f"unknown method {self.method!r}; expected one of {METHODS}")
        for name, maximum in (("steps", MAX_STEPS), ("eval_every", MAX_STEPS), ("demo_subset", None)):
            setattr(self, name, check_integer(name, getattr(self, name), 1, maximum))
        self.seed = check_integer("seed", self.seed, 0, MAX_SEED)
        self.eval_episodes = check_integer("eval_episodes", self.eval_episodes, 1, MAX_EVAL_EPISODES)
        self.hybrid_fraction = check_number("hybrid_fraction", self.hybrid_fraction, 0, 1, low_inclusive=True)
        if isinstance(self.demos, Path):
            self.demos = str(self.demos)
        if isinstance(self.demos, str) and not self.demos.startswith(MINARI_PREFIX):
            self.demos = str(Path(self.demos).expanduser().resolve())
        elif not isinstance(self.demos, str) and (self.demos not in (500, 7500) or isinstance(self.demos, bool)):
            raise ValueError(f"demos must be 500 or 7500 (a shipped set), the path of a demo file or "
                             f"'{MINARI_PREFIX}DATASET_ID' (a local Minari dataset), got {self.demos!r}")
        if not isinstance(self.env_id, str) or not self.env_id:
            raise ValueError(f"env_id must be a gymnasium id, got {self.env_id!r}")
        if not self.lava_bridge:
            from lava_bridge_mj.state_vector import env_spec

            try:
                env_spec(self.env_id)
            except ValueError as error:
                raise ValueError(f"{error}; expected a Lava Bridge task ({list(lava_bridge_mj.TASKS)}) or a "
                                 f"registered gymnasium id (\"module:Id\" imports module first)") from None
            if not isinstance(self.demos, str) and not self.external:
                raise ValueError(f"env_id {self.env_id!r} ships no demos: give demos the path of a demo file "
                                 f"recorded on it (lava_bridge_mj.record_demos) or '{MINARI_PREFIX}DATASET_ID'; "
                                 f"the Lava Bridge tasks {list(lava_bridge_mj.TASKS)} and the external tasks "
                                 f"{list(EXTERNAL_TASKS)} ship theirs")
            if self.external and strategy_class(METHOD_SPECS[self.method].start).name == "auxss":
                # an external task's AuxSS kernel measures its declared position (TaskStates.position)
                self.strategy = {"kernel_dims": "position", **self.strategy}
        if not isinstance(self.env, dict):
            raise ValueError(f"env must be a dict of the env's keyword arguments, got {self.env!r}")
        try:
            env = self.make_env()  # refuse bad env arguments before any work
        except (TypeError, ValueError) as error:
            raise ValueError(f"env: {error}") from None
        try:
            if isinstance(self.demos, str) and self.demos_sha256 is None:  # a new run: read and check the set

                self.demos_sha256 = content_hash(self.load_demos(env))
            elif self.demos_sha256 is not None and not isinstance(self.demos, str):
                raise ValueError(f"demos_sha256 goes with a demo file or Minari dataset, not with the shipped set "
                                 f"{self.demos}")
        finally:
            env.close()

    @property
    def lava_bridge(self) -> bool:
        """True when `env_id` is a Lava Bridge task, False for any other gymnasium env."""
        return self.env_id in lava_bridge_mj.TASKS

    @property
    def demos_source(self) -> str:
        """What `demos` names, for messages: "demo file PATH", "Minari dataset ID" or "shipped set 500"."""
        if not isinstance(self.demos, str):
            return f"shipped set {self.demos}"
        if self.demos.startswith(MINARI_PREFIX):
            return f"Minari dataset {self.demos[len(MINARI_PREFIX):]}"
        return f"demo file {self.demos}"

    @property
    def external(self) -> bool:
        """True when `env_id` is an external task (`lava_bridge_mj.external.EXTERNAL_TASKS`): its env is
        `make_task_env`'s, with p0 and ood, and it ships demo sets as Lava Bridge's tasks do."""
        return self.env_id in EXTERNAL_TASKS

    def load_demos(self, env: Any = None) -> dict[str, Any]:
        """The run's demo set: the shipped set (`load_demos`), the file `demos` (`load_demos(path=...)`)
        or the Minari dataset "minari:ID" (`load_minari_demos`), checked against the run's env (`env`:
        one of it, made here when not given) and its recorded `demos_sha256`; ValueError naming what
        does not fit."""
        if not isinstance(self.demos, str):
            return lava_bridge_mj.load_demos(self.demos, env_id=self.env_id)
        if self.demos.startswith(MINARI_PREFIX):
            demos = load_minari_demos(self.demos[len(MINARI_PREFIX):])
        else:
            demos = lava_bridge_mj.load_demos(path=self.demos)
        source = self.demos_source
        recorded_on = demos.get("env_id")
        if not self.lava_bridge:  # "module:Id" and Id name one env, whose spec's id record_demos records
            from lava_bridge_mj.state_vector import env_spec

            same = recorded_on == env_spec(self.env_id).id
        else:
            same = recorded_on in (None, self.env_id)
        if not same:
            raise ValueError(f"{source} was recorded on {recorded_on or 'an env it does not name'}, not on "
                             f"{self.env_id}: record demos on {self.env_id} (lava_bridge_mj.record_demos)")
        if not self.lava_bridge and "states" not in demos:
            raise ValueError(f"{source} has no 'states' (the full state of each transition) to start "
                             f"{self.env_id}'s episodes from: record it with lava_bridge_mj.record_demos")
        if self.demos_sha256 is not None and content_hash(demos) != self.demos_sha256:
            raise ValueError(f"{source} changed since this run began: its content hash is {content_hash(demos)}, "
                             f"the run recorded {self.demos_sha256}; restore that file or train a new run")
        made = env is None
        env = self.make_env() if made else env
        try:
            obs_dim, act_dim = self.dims(env)
            sizes = [("observations", demos["observations"].shape[1], obs_dim),
                     ("actions", demos["actions"].shape[1], act_dim)]
            if not self.lava_bridge:
                sizes.append(("states", demos["states"].shape[1], env.state_size))
            for name, found, expected in sizes:
                if found != expected:
                    raise ValueError(f"{source}: its {name} have {found} numbers, {self.env_id}'s {expected}")
        finally:
            if made:
                env.close()
        return demos

    def dims(self, env: Any = None) -> tuple[int, int]:
        """(observation size, action size) of what the learners see: flattened observations, actions."""
        if self.lava_bridge:
            return 4, 2
        env = self.make_env() if env is None else env
        return int(gymnasium.spaces.flatdim(env.observation_space)), int(env.action_space.shape[0])

    def env_kwargs(self) -> dict[str, Any]:
        """LavaBridgeEnv's (and LavaBridgeVectorEnv's) keyword arguments: the task's layout, then `env`
        (another env's: `env`, gymnasium.make's)."""
        if not self.lava_bridge:
            return dict(self.env)
        return {"layout": lava_bridge_mj.task_layout(self.env_id), **self.env}

    def make_env(self, **kwargs: Any) -> Any:
        """The run's task as a single env (`kwargs` e.g. render_mode): a LavaBridgeEnv, or another env
        as `ResetToState(gymnasium.make(env_id, ...))`."""
        if not self.lava_bridge:
            from lava_bridge_mj.state_vector import make_state_env

            return make_state_env(self.env_id, **self.env_kwargs(), **kwargs)
        return lava_bridge_mj.LavaBridgeEnv(**self.env_kwargs(), **kwargs)

    def make_vector_env(self, num_envs: int) -> Any:
        """`num_envs` episodes of the run's task in one vector env: a LavaBridgeVectorEnv, or a
        ResetToStateVectorEnv for another env."""
        if not self.lava_bridge:
            from lava_bridge_mj.state_vector import ResetToStateVectorEnv

            return ResetToStateVectorEnv(self.env_id, num_envs, **self.env_kwargs())
        return lava_bridge_mj.LavaBridgeVectorEnv(num_envs, **self.env_kwargs())

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON values (tuples become lists), as written to config.json."""
        return json.loads(json.dumps(dataclasses.asdict(self)))

    def continues(self, saved: Any) -> bool:
        """True when `saved` (a config.json's values) is this run up to its step budget: `steps` is
        the one field a resume may change, because nothing but the loop's end depends on it, so a
        finished run extended to more steps equals a run trained to them in one go (except where
        `budget_tied`: then `steps` must match too)."""
        # a config.json from before env_id existed was LavaBridge-v0's, the only task then; one from
        # before demo files, a shipped set's
        if not isinstance(saved, dict):
            return False
        steps = saved.get("steps") if self.budget_tied else self.steps
        return {"env_id": lava_bridge_mj.ENV_ID, "demos_sha256": None, **saved, "steps": steps} == self.to_dict()

    @property
    def budget_tied(self) -> bool:
        """True when more than the loop's end depends on `steps`: GoalDist-SS's schedule "budget"
        spreads its temperature over the run's steps (unless the config sets its `budget`), so such a
        run cannot be extended to a larger budget."""
        return strategy_class(METHOD_SPECS[self.method].start).budget_tied(self.strategy)

    @classmethod
    def from_dict(cls, values: dict[str, Any], source: str = "config") -> "RunConfig":
        """A RunConfig from plain values (e.g. a JSON file); ValueError naming unknown or bad entries."""
        if not isinstance(values, dict):
            raise ValueError(f"{source} must be a JSON object of RunConfig fields, got {type(values).__name__}")
        _check_keys(values, cls, source)
        for name, section in AGENT_CONFIGS.items():
            fields = values.get(name, {})
            if not isinstance(fields, dict):
                raise ValueError(f"{source}: '{name}' must be an object of {section.__name__} fields, got {fields!r}")
            _check_keys(fields, section, f"{source}: '{name}'")
        strategy = values.get("strategy", {})
        if not isinstance(strategy, dict):
            raise ValueError(f"{source}: 'strategy' must be an object of start-strategy parameters")
        method = values.get("method", cls.method)
        spec = METHOD_SPECS.get(method) if isinstance(method, str) else None
        try:
            if spec is not None:  # an unknown method is named below
                check_strategy_params(spec.start, strategy, from_config=True)
            return cls(**values)
        except (TypeError, ValueError) as error:  # e.g. a hyperparameter of the wrong type or range
            raise ValueError(f"{source}: {error}") from None


def _check_keys(values: dict[str, Any], dataclass: type, source: str) -> None:
    known = [field.name for field in dataclasses.fields(dataclass)]
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ValueError(f"{source}: unknown fields {unknown}; expected some of {known}")


def trained_configs(config: RunConfig) -> list:
    """The hyperparameter sections whose networks and buffers the method allocates (JSRL: its learner's
    and its guide's)."""
    method = METHOD_SPECS[config.method]
    guide = [getattr(config, config.jsrl.guide)] if method.demos == "guide" else []
    return [getattr(config, method.learner), *guide]


def check_batch_fits(config: RunConfig, seeds: int) -> None:
    """ValueError unless `seeds` seeds of `config` fit in memory: checked before anything is built per
    seed, so an impossible batch fails at once instead of minutes later (or in MemoryError)."""
    obs_dim, act_dim = config.dims()
    check_fits_in_memory(*trained_configs(config), seeds=seeds, obs_dim=obs_dim, act_dim=act_dim)
