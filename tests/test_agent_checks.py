"""Hyperparameter validation of every agent config and the shared number checks."""

from __future__ import annotations

import dataclasses
import json
import math
import re

import numpy as np
import pytest

from lava_bridge_mj.agents.checks import check_integer, check_number
from lava_bridge_mj.agents.jsrl import JSRLConfig
from lava_bridge_mj.agents.offline import BCConfig, IQLConfig
from lava_bridge_mj.agents.sac import SACConfig
from lava_bridge_mj.eval.runner import RunConfig

INF, NAN = float("inf"), float("nan")

BAD_FIELDS = [
    (SACConfig, "lr", INF, "a finite number > 0"),
    (SACConfig, "lr", NAN, "a finite number > 0"),
    (SACConfig, "lr", "abc", "a finite number > 0"),
    (SACConfig, "lr", 0, "a finite number > 0"),
    (SACConfig, "lr", True, "a finite number > 0"),
    (SACConfig, "lr", 10**400, "a finite number > 0"),  # beyond float's range
    (SACConfig, "gamma", 1.5, r"a number in \(0, 1\]"),
    (SACConfig, "gamma", INF, r"a number in \(0, 1\]"),
    (SACConfig, "tau", 0.0, r"a number in \(0, 1\]"),
    (SACConfig, "initial_alpha", INF, "a finite number > 0"),
    (SACConfig, "initial_alpha", 0.0, "a finite number > 0"),
    (SACConfig, "target_entropy", "abc", "a finite number"),
    (SACConfig, "target_entropy", -INF, "a finite number"),
    (SACConfig, "target_entropy", NAN, "a finite number"),
    (SACConfig, "batch_size", 0, "an integer >= 1"),
    (SACConfig, "batch_size", 2.5, "an integer >= 1"),
    (SACConfig, "batch_size", "256", "an integer >= 1"),
    (SACConfig, "buffer_size", 1e12, "an integer >= 1"),
    (SACConfig, "learning_starts", -1, "an integer >= 0"),
    (SACConfig, "hidden_sizes", [], "a non-empty list of positive integers"),
    (SACConfig, "hidden_sizes", [64, 0], "a non-empty list of positive integers"),
    (SACConfig, "hidden_sizes", [64.0], "a non-empty list of positive integers"),
    (SACConfig, "hidden_sizes", "64", "a non-empty list of positive integers"),
    (SACConfig, "critic_layer_norm", "yes", "true or false"),
    (BCConfig, "lr", INF, "a finite number > 0"),
    (BCConfig, "batch_size", 0, "an integer >= 1"),
    (BCConfig, "hidden_sizes", [-1], "a non-empty list of positive integers"),
    (IQLConfig, "lr", "3e-4", "a finite number > 0"),
    (IQLConfig, "gamma", "x", r"a number in \(0, 1\]"),
    (IQLConfig, "tau", INF, r"a number in \(0, 1\]"),
    (IQLConfig, "expectile", 1.0, r"a number in \(0, 1\)"),
    (IQLConfig, "temperature", INF, "a finite number > 0"),
    (IQLConfig, "max_weight", NAN, "a finite number > 0"),
    (IQLConfig, "batch_size", None, "an integer >= 1"),
    (JSRLConfig, "guide", "ppo", "'iql' or 'bc'"),
    (JSRLConfig, "guide_steps", -1, "an integer >= 0"),
    (JSRLConfig, "initial_horizon", 1.5, "an integer >= 0"),
    (JSRLConfig, "stages", 0, "an integer >= 1"),
    (JSRLConfig, "window", INF, "an integer >= 1"),
    (JSRLConfig, "threshold", "abc", r"a number in \[0, 1\]"),
    (JSRLConfig, "threshold", NAN, r"a number in \[0, 1\]"),
]


@pytest.mark.parametrize("config, field, value, expected", BAD_FIELDS,
                         ids=[f"{c.__name__}.{f}={v!r}"[:60] for c, f, v, _ in BAD_FIELDS])
def test_bad_fields_raise_one_line_naming_the_field_and_the_value(config, field, value, expected):
    with pytest.raises(ValueError) as error:
        config(**{field: value})
    message = str(error.value)
    assert re.fullmatch(rf"{field} must be {expected}, got {re.escape(repr(value))}", message), message


def test_a_run_config_with_an_infinite_learning_rate_is_refused_before_any_work():
    """JSON's Infinity used to pass and the run died later with 'action must be finite'."""
    with pytest.raises(ValueError, match=r"^lr must be a finite number > 0, got inf$"):
        RunConfig.from_dict(json.loads('{"method": "sac", "sac": {"lr": Infinity}}'))
    with pytest.raises(ValueError, match=r"^target_entropy must be a finite number, got 'abc'$"):
        RunConfig.from_dict({"method": "sac", "sac": {"target_entropy": "abc"}})


def test_good_values_are_stored_as_plain_python_numbers():
    """numpy numbers are accepted and stored as float / int, so the config still writes to JSON."""
    config = SACConfig(lr=np.float32(1e-3), batch_size=np.int64(32), initial_alpha=1, target_entropy=np.int64(-3))
    assert (type(config.lr), type(config.batch_size), type(config.initial_alpha)) == (float, int, float)
    assert config.target_entropy == -3.0 and type(config.target_entropy) is float
    assert json.loads(json.dumps(dataclasses.asdict(config)))["batch_size"] == 32
    assert SACConfig(target_entropy=None).target_entropy is None
    assert JSRLConfig(threshold=0).threshold == 0.0


def test_check_number_and_check_integer():
    assert check_number("x", np.float64(0.5), 0, 1) == 0.5
    assert check_number("x", -2, -math.inf, math.inf) == -2.0
    assert check_number("x", 0, 0, 1, low_inclusive=True) == 0.0
    with pytest.raises(ValueError, match=r"^x must be a number in \[0, 1\), got 1$"):
        check_number("x", 1, 0, 1, low_inclusive=True, high_inclusive=False)
    with pytest.raises(ValueError, match=r"^x must be a finite number <= 2, got 3$"):
        check_number("x", 3, -math.inf, 2)
    with pytest.raises(ValueError, match=r"^x must be a finite number > 0, got \(1\+0j\)$"):
        check_number("x", 1 + 0j)  # the helper once raised TypeError on comparing such values
    assert check_integer("n", np.int32(3), 1) == 3 and type(check_integer("n", np.int32(3), 1)) is int
    with pytest.raises(ValueError, match=r"^n must be an integer in \[1, 4\], got 5$"):
        check_integer("n", 5, 1, 4)
