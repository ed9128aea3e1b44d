"""The training runner and the lava-bridge-bench CLI: run directories, resume, bad arguments."""

import csv
import json
import shutil

import numpy as np
import pytest
import torch

from lava_bridge_mj.agents.sac import SACConfig
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.runner import METRIC_FIELDS, RunConfig, train

TINY_SAC = SACConfig(hidden_sizes=(16, 16), batch_size=32, buffer_size=500, learning_starts=100)


def tiny_config(method="auxss", **overrides):
    values = dict(method=method, seed=3, steps=700, eval_every=100, eval_episodes=2, demo_subset=20, sac=TINY_SAC)
    values.update(overrides)
    return RunConfig(**values)


def read_metrics(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def without_wall_time(rows):
    return [{k: v for k, v in row.items() if k != "wall_time"} for row in rows]


@pytest.mark.parametrize("method", ["sac", "auxss", "omega_ss", "uniform_ss", "goaldist_ss"])
def test_every_method_writes_a_complete_run_directory(tmp_path, method):
    config = tiny_config(method, steps=300)
    run = train(config, tmp_path, progress=False)
    rows = read_metrics(tmp_path / "metrics.csv")
    assert [int(r["step"]) for r in rows] == [100, 200, 300]
    assert list(rows[0]) == list(METRIC_FIELDS)
    for row in rows:
        assert 0.0 <= float(row["success_p0"]) <= 1.0 and 0.0 <= float(row["success_ood"]) <= 1.0
    assert json.loads((tmp_path / "config.json").read_text()) == config.to_dict()
    assert (tmp_path / "final.pt").exists()
    assert sorted(p.name for p in (tmp_path / "policies").iterdir()) == ["step_100.pt", "step_200.pt", "step_300.pt"]
    weights = np.load(tmp_path / "start_weights.npz")
    assert weights["steps"].tolist() == [100, 200, 300]
    expected_states = 0 if method == "sac" else 20
    assert weights["probabilities"].shape == (3, expected_states)
    assert weights["states"].shape == (20, 4)
    assert run.step == 300


def test_auxss_weights_move_during_training(tmp_path):
    train(tiny_config("auxss", steps=300), tmp_path, progress=False)
    probabilities = np.load(tmp_path / "start_weights.npz")["probabilities"]
    assert not np.allclose(probabilities[-1], probabilities[-1].mean()), "AuxSS never updated its weights"


def test_same_seed_same_metrics(tmp_path):
    config = tiny_config(steps=300)
    train(config, tmp_path / "a", progress=False)
    train(config, tmp_path / "b", progress=False)
    a, b = read_metrics(tmp_path / "a/metrics.csv"), read_metrics(tmp_path / "b/metrics.csv")
    assert without_wall_time(a) == without_wall_time(b)


def test_resume_from_checkpoint_equals_uninterrupted_run(tmp_path):
    config = tiny_config()
    full = train(config, tmp_path / "full", progress=False)
    checkpoint = torch.load(tmp_path / "full/checkpoint.pt", weights_only=False)
    assert 0 < checkpoint["step"] < config.steps, "the test needs a checkpoint from the middle of the run"

    # An interrupted run: only the files as they were at that checkpoint, plus a stale row past it.
    resumed_dir = tmp_path / "resumed"
    resumed_dir.mkdir()
    shutil.copy(tmp_path / "full/checkpoint.pt", resumed_dir / "checkpoint.pt")
    shutil.copy(tmp_path / "full/config.json", resumed_dir / "config.json")
    shutil.copy(tmp_path / "full/metrics.csv", resumed_dir / "metrics.csv")
    resumed = train(config, resumed_dir, resume=True, progress=False)

    assert without_wall_time(read_metrics(resumed_dir / "metrics.csv")) == \
        without_wall_time(read_metrics(tmp_path / "full/metrics.csv"))
    for name, tensor in full.agent.actor.state_dict().items():
        assert torch.equal(tensor, resumed.agent.actor.state_dict()[name]), name
    np.testing.assert_array_equal(full.strategy.weights, resumed.strategy.weights)


def test_resume_refuses_a_checkpoint_of_another_configuration(tmp_path):
    train(tiny_config(steps=300), tmp_path, progress=False)
    with pytest.raises(ValueError, match="another configuration"):
        train(tiny_config(steps=300, seed=4), tmp_path, resume=True, progress=False)


@pytest.mark.parametrize("argv, message", [
    (["--method", "ppo"], "invalid choice: 'ppo'"),
    (["--method", "auxss", "--steps", "0"], "expected a positive integer, got 0"),
    (["--method", "auxss", "--steps", "many"], "expected a positive integer, got 'many'"),
    (["--method", "auxss", "--seed", "-1"], "non-negative integer seed"),
    (["--method", "auxss", "--demos", "1000"], "invalid choice: 1000"),
    (["--method", "auxss", "--eval-every", "-3"], "expected a positive integer, got -3"),
    ([], "the following arguments are required: --method"),
])
def test_cli_rejects_bad_arguments(argv, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_info:
        cli.main([*argv, "--out", str(tmp_path / "run")])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "run").exists(), "a rejected command must write nothing"


def test_cli_rejects_an_output_path_that_is_a_file(capsys, tmp_path):
    target = tmp_path / "file"
    target.write_text("precious")
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--method", "auxss", "--out", str(target)])
    assert exit_info.value.code == 2
    assert "is not a directory" in capsys.readouterr().err
    assert target.read_text() == "precious"


def test_cli_refuses_to_overwrite_an_existing_run(capsys, tmp_path):
    (tmp_path / "config.json").write_text("{}")
    (tmp_path / "metrics.csv").write_text("step\n1\n")
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--method", "auxss", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "already holds a run" in capsys.readouterr().err
    assert (tmp_path / "metrics.csv").read_text() == "step\n1\n"


def test_cli_runs_a_tiny_training_job(tmp_path, capsys):
    code = cli.main(["--method", "uniform_ss", "--steps", "200", "--eval-every", "100", "--eval-episodes", "2",
                     "--out", str(tmp_path), "--no-progress"])
    assert code == 0
    assert [int(r["step"]) for r in read_metrics(tmp_path / "metrics.csv")] == [100, 200]
    assert "uniform_ss seed 0: 200 steps" in capsys.readouterr().out
