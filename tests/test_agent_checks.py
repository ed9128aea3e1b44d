"""Hyperparameter validation of every agent config, the shared number checks, and the memory estimate
that refuses configurations that cannot fit before any work."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re

import numpy as np
import pytest
import torch

from lava_bridge_mj.agents.checks import check_fits_in_memory, check_integer, check_number, physical_memory
from lava_bridge_mj.agents.jsrl import JSRLConfig
from lava_bridge_mj.agents.offline import BC, IQL, BCConfig, IQLConfig
from lava_bridge_mj.agents.replay_buffer import FIELDS, ReplayBuffer
from lava_bridge_mj.agents.sac import SAC, SACConfig
from lava_bridge_mj.eval.training.runner import RunConfig

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
    with pytest.raises(ValueError, match=r"^config: sac.lr must be a finite number > 0, got inf$"):
        RunConfig.from_dict(json.loads('{"method": "sac", "sac": {"lr": Infinity}}'))
    with pytest.raises(ValueError, match=r"^config: sac.target_entropy must be a finite number, got 'abc'$"):
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


# --- memory ---------------------------------------------------------------------------------------
def test_sac_memory_estimate_counts_its_buffer_minibatch_and_networks_with_gradients_and_adam_moments():
    # 64-64 networks on 4-d observations and 2-d actions: actor 4,740 parameters, twin critics 9,346;
    # a transition is 12 floats, the minibatch is held twice, and each twin critic keeps 64 + 64 activations
    config = SACConfig()
    assert config.memory_bytes(seeds=1, obs_dim=4, act_dim=2) == {
        "buffer_size": 10_000 * 12 * 4, "batch_size": 256 * (2 * 12 + 2 * 128) * 4,
        "hidden_sizes": (4 * (4_740 + 9_346) + 9_346) * 4}
    assert config.memory_bytes(seeds=5, obs_dim=4, act_dim=2)["hidden_sizes"] == 5 * 262_760
    assert config.memory_bytes(seeds=5, obs_dim=4, act_dim=2)["batch_size"] == 5 * 286_720


def test_memory_estimates_match_what_the_agents_allocate():
    obs_dim, act_dim, seeds = 4, 2, [0, 1]
    config = SACConfig(hidden_sizes=(16, 8), buffer_size=100, batch_size=4, critic_layer_norm=True)
    buffer = ReplayBuffer(config.buffer_size, obs_dim, act_dim)
    buffer_bytes = sum(getattr(buffer, name).nbytes for name in FIELDS)
    assert buffer_bytes == config.memory_bytes(1, obs_dim, act_dim)["buffer_size"]
    batch = {"obs": torch.rand(2, 4, obs_dim), "action": torch.rand(2, 4, act_dim) * 2 - 1,
             "next_obs": torch.rand(2, 4, obs_dim), "reward": torch.rand(2, 4), "terminated": torch.zeros(2, 4)}
    agents = [(SAC(obs_dim, act_dim, config, seeds), config),
              (BC(obs_dim, act_dim, BCConfig(hidden_sizes=(16, 8)), seeds), BCConfig(hidden_sizes=(16, 8))),
              (IQL(obs_dim, act_dim, IQLConfig(hidden_sizes=(16, 8)), seeds), IQLConfig(hidden_sizes=(16, 8)))]
    for agent, agent_config in agents:
        agent.update(batch)  # gradients and Adam moments exist from the first update on
        parts = agent._parts().values()
        networks = [p for p in parts if isinstance(p, torch.nn.Module)]
        optimizers = [p for p in parts if isinstance(p, torch.optim.Optimizer)]
        tensors = [t for net in networks for t in net.parameters()]
        tensors += [t.grad for net in networks for t in net.parameters() if t.grad is not None]
        tensors += [v for opt in optimizers for group in opt.param_groups for p in group["params"]
                    if p is not getattr(agent, "log_alpha", None)  # SAC's entropy coefficients: no network
                    for v in (opt.state[p]["exp_avg"], opt.state[p]["exp_avg_sq"])]
        allocated = sum(t.numel() * t.element_size() for t in tensors)
        assert allocated == agent_config.memory_bytes(len(seeds), obs_dim, act_dim)["hidden_sizes"], type(agent)


def test_a_configuration_that_cannot_fit_is_refused_naming_the_field_the_estimate_and_the_memory():
    config = SACConfig(buffer_size=10**12)
    with pytest.raises(ValueError) as error:
        check_fits_in_memory(config, seeds=5, obs_dim=4, act_dim=2, memory=8 * 2**30)
    assert str(error.value) == (
        "SACConfig.buffer_size=1000000000000 does not fit in memory: 5 seeds need at least 218.3 TiB "
        "(SACConfig.buffer_size: 218.3 TiB, SACConfig.batch_size: 1.4 MiB, SACConfig.hidden_sizes: 1.3 MiB), more "
        "than the 8.0 GiB of memory available here")
    with pytest.raises(ValueError, match=r"^SACConfig\.hidden_sizes=\(100000, 100000\) does not fit in memory: "
                                         r"1 seed needs at least 522\.0 GiB"):
        check_fits_in_memory(SACConfig(hidden_sizes=[100_000, 100_000]), seeds=1, obs_dim=4, act_dim=2,
                             memory=8 * 2**30)


def test_the_estimate_is_compared_with_the_memory_given_or_the_machines():
    sac, iql = SACConfig(), IQLConfig()
    need = sum(sum(c.memory_bytes(3, 4, 2).values()) for c in (sac, iql))
    check_fits_in_memory(sac, iql, seeds=3, obs_dim=4, act_dim=2, memory=need)  # exactly fits
    with pytest.raises(ValueError, match=r"^IQLConfig\.hidden_sizes=\(256, 256\) does not fit"):
        check_fits_in_memory(sac, iql, seeds=3, obs_dim=4, act_dim=2, memory=need - 1)  # the larger share named
    assert isinstance(physical_memory(), int) and physical_memory() > 2**20
    check_fits_in_memory(sac, seeds=5, obs_dim=4, act_dim=2)  # the defaults fit on any machine
    with pytest.raises(ValueError, match=r"more than the [0-9.]+ [GT]iB of memory available here$"):
        check_fits_in_memory(SACConfig(buffer_size=10**12), seeds=5, obs_dim=4, act_dim=2)


# One update at a large minibatch, in a fresh process: how far its peak resident memory rises above the
# memory in use before it (Linux: the peak, VmHWM, reset to the current use through /proc/self/clear_refs)
UPDATE_PEAK = """
import sys
import numpy as np, torch
from lava_bridge_mj.agents.methods import learner_class
from lava_bridge_mj.agents.offline import BCConfig, IQLConfig
from lava_bridge_mj.agents.replay_buffer import ReplayBuffer
from lava_bridge_mj.agents.sac import SACConfig
from lava_bridge_mj.agents.seed_batch import stack_batches
torch.set_num_threads(1)
learner, batch_size = sys.argv[1], int(sys.argv[2])
config = {"sac": SACConfig, "bc": BCConfig, "iql": IQLConfig}[learner](batch_size=batch_size, hidden_sizes=(64, 64))
agent = learner_class(learner)(4, 2, config, seeds=[0])
buffer, rng = ReplayBuffer(100, 4, 2), np.random.default_rng(0)
for _ in range(100):
    buffer.add(rng.random(4), rng.uniform(-1, 1, 2), 0.0, rng.random(4), False)
agent.update(stack_batches([buffer.sample(8, rng)]))  # optimiser state and torch's own start-up first

def kib(name):
    with open("/proc/self/status") as status:
        return int(next(line for line in status if line.startswith(name + ":")).split()[1])

with open("/proc/self/clear_refs", "w") as clear:
    clear.write("5")  # the peak resident set starts again from the current one
before = kib("VmRSS")
agent.update(stack_batches([buffer.sample(batch_size, rng)]))
print((kib("VmHWM") - before) * 1024, config.memory_bytes(1, 4, 2)["batch_size"])
"""


@pytest.mark.skipif(not os.path.exists("/proc/self/clear_refs"), reason="measures peak memory through /proc")
@pytest.mark.parametrize("learner", ["sac", "bc", "iql"])
def test_the_minibatch_estimate_is_a_lower_bound_of_what_one_update_allocates(learner):
    """The minibatch size allocates (the transitions and every network's activations over them): a
    batch_size of 10^9 passed the check and was killed by the kernel at 22 GB. Its estimate must stay
    below what an update really takes, so that nothing that could run is refused."""
    import subprocess
    import sys

    batch_size = 2**16
    done = subprocess.run([sys.executable, "-c", UPDATE_PEAK, learner, str(batch_size)], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    grown, estimate = map(int, done.stdout.split())
    assert estimate >= batch_size * (2 * 12) * 4  # at least the two copies of the transitions
    assert estimate <= grown, f"estimate {estimate / 2**20:.0f} MiB above the {grown / 2**20:.0f} MiB measured"


def test_a_minibatch_that_cannot_fit_is_refused_naming_batch_size():
    for config in (SACConfig(batch_size=10**9), BCConfig(batch_size=10**9), IQLConfig(batch_size=10**9)):
        with pytest.raises(ValueError, match=rf"^{type(config).__name__}\.batch_size=1000000000 does not fit in "
                                             r"memory: 1 seed needs at least 1\.\d TiB"):
            check_fits_in_memory(config, seeds=1, obs_dim=4, act_dim=2, memory=16 * 2**30)


def test_the_check_reads_the_memory_available_now(monkeypatch):
    import lava_bridge_mj.agents.checks as checks

    available = checks.available_memory()
    assert isinstance(available, int) and 2**20 < available <= physical_memory()
    need = sum(SACConfig().memory_bytes(1, 4, 2).values())
    monkeypatch.setattr(checks, "available_memory", lambda: need - 1)  # the machine's memory is mostly in use
    with pytest.raises(ValueError, match=r"more than the [0-9.]+ KiB of memory available here$"):
        check_fits_in_memory(SACConfig(), seeds=1, obs_dim=4, act_dim=2)
