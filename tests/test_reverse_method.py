"""`--method reverse_ss`: RFCL's reverse curriculum trained by the batched loop, from whole demo
episodes, with its shortened time limits, recorded settings and an exact resume."""

import json

import numpy as np
import pytest

import lava_bridge_mj

from conftest import episode_rows
from test_runner import resume_from_mid_episode_checkpoint, tiny_config

from lava_bridge_mj.agents.reverse_curriculum import ReverseCurriculumSS, goal_reaching_demos
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.training.runner import train


@pytest.fixture(scope="module")
def reverse_run(tmp_path_factory):
    """A tiny reverse_ss run of 700 steps, trained once for the module; tests only read it."""
    config = tiny_config("reverse_ss")
    out = tmp_path_factory.mktemp("reverse") / "run"
    return config, out, train(config, out, progress=False)


def read_episodes(run_dir):
    return episode_rows(run_dir)


def test_it_starts_from_the_whole_goal_reaching_demo_episodes(reverse_run):
    config, out, run = reverse_run
    states, ids = goal_reaching_demos(lava_bridge_mj.load_demos(config.demos, env_id=config.env_id))
    strategy = run.strategy
    assert isinstance(strategy, ReverseCurriculumSS)
    np.testing.assert_array_equal(strategy.demo_states, states)
    assert strategy.num_demos == len(np.unique(ids)) and len(states) > config.demo_subset  # not the subset
    np.testing.assert_array_equal(np.load(out / "start_weights.npz")["states"], states)
    assert (strategy.start_steps < strategy.demo_lengths - 1).any(), "the curriculum never moved back"


def test_its_settings_are_recorded_in_provenance(reverse_run):
    _, out, _ = reverse_run
    session, = json.loads((out / "provenance.json").read_text())
    assert session["strategy"] == {"per_demo_buffer_size": 3, "reverse_step_size": 1, "demo_sampler": "uniform",
                                   "demo_horizon_to_max_steps_ratio": 3.0, "max_steps_min": 8}


def test_episodes_are_truncated_at_the_curriculum_time_limit(reverse_run):
    config, out, _ = reverse_run
    _, ids = goal_reaching_demos(lava_bridge_mj.load_demos(config.demos, env_id=config.env_id))
    last = {episode: np.flatnonzero(ids == episode)[-1] for episode in np.unique(ids)}
    log = read_episodes(out)
    index, length, success = (np.array([int(r[k]) for r in log]) for k in ("start_index", "length", "success"))
    assert (index >= 0).all(), "700 steps stay in the reverse phase: every episode starts from a demo state"
    steps_to_goal = np.array([last[ids[i]] - i + 1 for i in index])  # the demo's steps from there to the goal
    limit = 8 + steps_to_goal // 3
    assert (length <= limit).all(), np.flatnonzero(length > limit)
    cut = (length == limit) & (success == 0)
    assert cut.sum() >= 5, "no episode ran into its shortened limit: the test shows nothing"
    # one env, stepped once per training step: the log still accounts for every step
    np.testing.assert_array_equal(np.diff([int(r["step"]) for r in log], prepend=0), length)


def test_a_stopped_then_resumed_run_equals_the_uninterrupted_one(reverse_run, tmp_path):
    config, full_dir, full = reverse_run
    resumed = resume_from_mid_episode_checkpoint(config, full_dir, full, tmp_path / "resumed")
    assert resumed.strategy.state_dict() == full.strategy.state_dict()


def test_episode_ids_are_the_runners_not_a_config_parameter(tmp_path, capsys):
    with pytest.raises(ValueError, match=r"unknown parameters \['episode_ids'\] for start strategy 'reverse_ss'"):
        RunConfig.from_dict({"method": "reverse_ss", "strategy": {"episode_ids": [0, 1]}})
    config = tmp_path / "config.json"
    config.write_text(json.dumps({"strategy": {"episode_ids": [0]}}))
    out = tmp_path / "run"
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--method", "reverse_ss", "--config", str(config), "--out", str(out), "--no-progress"])
    assert exit_info.value.code == 2
    assert "unknown parameters ['episode_ids'] for start strategy 'reverse_ss'" in capsys.readouterr().err
    assert not out.exists()
