"""The CLI's commands: `train` named or implied, a mistyped command answered with the nearest ones,
and `--set` overrides of single RunConfig fields, checked like a config file."""

import json
import os

import pytest

from lava_bridge_mj.eval import cli


def config_of(argv):
    parser = cli.build_parser()
    return cli._config_from(parser.parse_args(argv), parser)


@pytest.mark.parametrize("typo, hint", [("reprot", "did you mean 'report' or 'export'?"),
                                        ("vidoe", "did you mean 'video'?"), ("sweeep", "did you mean 'sweep'?"),
                                        ("trian", "did you mean 'train'?"), ("exprot", "did you mean 'export'"),
                                        ("evaluate", "(commands: train, sweep, report, video, summary, export")])
def test_a_mistyped_command_names_the_nearest_and_writes_nothing(typo, hint, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert cli.main([typo, "runs/x"]) == 2
    err = capsys.readouterr().err
    assert f"unknown command {typo!r}" in err and hint in err
    assert "--method" not in err.splitlines()[0], "answered as a training command missing --method"
    assert list(tmp_path.iterdir()) == []


def test_train_named_or_implied_is_the_same_command(tmp_path, capsys):
    for argv in (["--method", "sac", "--set", "sac.lrr=1"], ["train", "--method", "sac", "--set", "sac.lrr=1"]):
        with pytest.raises(SystemExit) as stop:
            cli.main(argv)
        assert stop.value.code == 2
        assert "--set: 'sac': unknown fields ['lrr']" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["train", "--help"])
    assert capsys.readouterr().out.startswith("usage: lava-bridge-bench train")


def test_set_overrides_single_fields_over_the_config_file_and_options_over_both(tmp_path):
    path = tmp_path / "my.json"
    path.write_text(json.dumps({"sac": {"lr": 1e-3, "batch_size": 64}, "steps": 7000}))
    config = config_of(["--method", "auxss", "--config", str(path), "--set", "sac.lr=5e-4",
                        "--set", "strategy.sigma=0.2", "--set", "sac.hidden_sizes=[32, 32]",
                        "--set", "sac.critic_layer_norm=true", "--set", "steps=9000", "--steps", "11000"])
    assert config.sac.lr == 5e-4 and config.sac.batch_size == 64  # the file's other field kept
    assert config.sac.hidden_sizes == (32, 32) and config.sac.critic_layer_norm is True
    assert config.strategy == {"sigma": 0.2}
    assert config.steps == 11000  # a named option wins over --set and the file
    assert json.loads(path.read_text())["sac"] == {"lr": 1e-3, "batch_size": 64}  # the file is only read
    later = config_of(["--method", "goaldist_ss", "--set", "strategy.schedule=budget", "--set", "sac.lr=1e-3",
                       "--set", "sac.lr=2e-3"])
    assert later.strategy == {"schedule": "budget"} and later.sac.lr == 2e-3  # text values, the last one wins


@pytest.mark.parametrize("setting, message", [
    ("sac.lr=-1", "--set: sac.lr must be a finite number > 0, got -1"),
    ("strategy.sigmaa=0.2", "--set: unknown parameters ['sigmaa'] for start strategy 'auxss'"),
    ("sac", "argument --set: expected KEY=VALUE with a dotted RunConfig field"),
    ("sac..lr=1", "argument --set: expected KEY=VALUE"),
    ("steps=many", "--set: steps must be an integer in [1, 1000000000000], got 'many'"),
    # values only the start strategy checks: they reach it, and come back as a usage error of --set
    ("strategy.sigma=abc", "--set: strategy: sigma must be a finite number > 0, got 'abc'"),
    ("strategy.delta=2", "--set: strategy: delta must be a number in (0, 1], got 2"),
    ("env.timestep=10", "--set: env: Layout.timestep=10 lets the ball move 40 m in one physics step"),
    ("strategy.sigma=" + "[" * 5000 + "]" * 5000, "argument --set: the value of strategy.sigma: it nests arrays "
                                                     "and objects more than 32 levels deep"),
    ("strategy.sigma=" + "[" * 5000, "argument --set: the value of strategy.sigma: it nests"),
    (".".join(["sac"] * 5000) + "=1", "argument --set: expected a dotted RunConfig field of at most 32 names, "
                                      "got 5000"),
])
def test_a_bad_set_is_one_usage_line_and_writes_nothing(setting, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["--method", "auxss", "--set", setting, "--out", str(tmp_path / "run"), "--no-progress"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.startswith("usage: lava-bridge-bench") and len(err.split("error: ")) == 2 and "Traceback" not in err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("command", ["train", *cli.COMMANDS])
def test_every_command_calls_itself_by_its_cli_name(command, capsys):
    with pytest.raises(SystemExit):
        cli.main([command, "--help"])
    assert capsys.readouterr().out.startswith(f"usage: lava-bridge-bench {command} ")


def test_threads_are_capped_at_the_cpus_as_the_sweep_caps_them(tmp_path, capsys):
    """--threads 100000 once held about 13,500 threads, made other processes fail to start theirs and
    segfaulted at exit."""
    with pytest.raises(SystemExit) as stop:
        cli.main(["--method", "auxss", "--threads", "100000", "--out", str(tmp_path / "run")])
    assert stop.value.code == 2
    assert f"--threads 100000: this machine lets the run use {len(os.sched_getaffinity(0))} CPUs" in \
        capsys.readouterr().err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("argv, message", [
    (["--steps", str(10**30)], "steps must be an integer in [1, 1000000000000], got 10000000000000000000000000000"),
    (["--eval-every", str(10**13)], "eval_every must be an integer in [1, 1000000000000], got 10000000000000"),
    (["--out", "a" * 300], "cannot be used: File name too long"),
    (["--out", "a" * 300 + "/run"], "cannot be used: File name too long"),
])
def test_absurd_sizes_and_unusable_paths_are_one_usage_line(argv, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stop:
        cli.main(["--method", "auxss", "--no-progress", *argv])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_a_config_file_nested_thousands_deep_is_one_usage_line(tmp_path, capsys):
    path = tmp_path / "deep.json"
    path.write_text('{"strategy": {"sigma": ' + "[" * 5000 + "]" * 5000 + "}}")
    with pytest.raises(SystemExit) as stop:
        cli.main(["--method", "auxss", "--config", str(path), "--out", str(tmp_path / "run")])
    assert stop.value.code == 2
    assert f"--config {path}: it nests arrays and objects more than 32 levels deep" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_set_into_a_value_of_the_config_file_is_refused(tmp_path, capsys):
    path = tmp_path / "my.json"
    path.write_text(json.dumps({"steps": 7000}))
    with pytest.raises(SystemExit):
        config_of(["--method", "auxss", "--config", str(path), "--set", "steps.x=1"])
    assert "--set steps.x: steps is a value, not a section of fields" in capsys.readouterr().err


def test_a_run_trained_with_set_records_the_setting(tmp_path, capsys):
    out = tmp_path / "run"
    assert cli.main(["train", "--method", "sac", "--set", "sac.hidden_sizes=[8, 8]", "--set", "sac.learning_starts=50",
                     "--steps", "100", "--eval-every", "100", "--eval-episodes", "1", "--out", str(out),
                     "--no-progress"]) == 0
    saved = json.loads((out / "config.json").read_text())
    assert saved["sac"]["hidden_sizes"] == [8, 8] and saved["sac"]["learning_starts"] == 50
