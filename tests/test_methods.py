"""The method table: every entry names a learner, a start strategy and a demo use that exist, and the
CLI offers exactly its methods."""

import dataclasses

import pytest

from lava_bridge_mj.agents.methods import LEARNERS, METHODS, Method
from lava_bridge_mj.agents.start_strategies import STRATEGY_NAMES
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.training.config import RunConfig


def test_every_method_names_what_exists():
    sections = {field.name for field in dataclasses.fields(RunConfig)}
    for name, method in METHODS.items():
        assert method.name == name
        assert method.start in STRATEGY_NAMES
        assert method.learner in sections and method.learner in LEARNERS
        assert method.description


def test_the_cli_offers_exactly_the_methods():
    action = next(a for a in cli.build_parser()._actions if a.dest == "method")
    assert tuple(action.choices) == tuple(METHODS)
    for name in METHODS:
        assert f"{name}: {METHODS[name].description}" in action.help


def test_a_method_with_an_unknown_learner_or_demo_use_is_refused():
    with pytest.raises(ValueError, match="learner must be one of"):
        Method("x", "ppo", "p0")
    with pytest.raises(ValueError, match="demos one of"):
        Method("x", "sac", "p0", "sometimes")


def test_only_offline_methods_run_no_episodes():
    assert {name for name, m in METHODS.items() if not m.online} == {"bc", "iql"}
