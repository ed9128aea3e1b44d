"""Live tracking sinks (eval/training/tracking.py): TensorBoard and W&B receive training scalars under SB3's
names while training and what each evaluation measures, a resume appends to the same record (no step
twice), --overwrite removes it with the run, logging leaves training's results unchanged, W&B's
project, entity, group and name come from the options over the WANDB_* variables over the defaults,
and bad --log or W&B values are refused before anything is written."""

import csv
import json
import math
import struct
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import episode_rows
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.training import tracking
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.training.run_files import EPISODE_LOG, RunDirectoryError, run_files

TINY = dict(steps=200, eval_every=100, eval_episodes=2, sac={"hidden_sizes": [8, 8], "learning_starts": 50,
                                                               "batch_size": 16})


def train(out, steps=200, env=None, **kwargs):
    from lava_bridge_mj.eval.training.runner import train as run_train

    config = RunConfig(method="auxss", **{**TINY, "steps": steps, "env": env or {}})
    return run_train(config, out, progress=False, **kwargs)


def metrics(out):
    with open(out / "metrics.csv") as f:
        return list(csv.DictReader(f))


def tensorboard_events(out):
    event_accumulator = pytest.importorskip("tensorboard.backend.event_processing.event_accumulator")
    events = event_accumulator.EventAccumulator(str(out / "tensorboard"), size_guidance={"histograms": 0})
    events.Reload()
    return events


def episodes(out):
    return episode_rows(out)


def scalars(events, tag):
    return [(e.step, e.value) for e in events.Scalars(tag)]


SB3_TRAINING_TAGS = {"train/critic_loss", "train/actor_loss", "train/ent_coef", "train/q_mean", "train/entropy",
                     "rollout/ep_rew_mean", "rollout/ep_len_mean", "rollout/success_rate",
                     "time/fps", "time/episodes", "time/time_elapsed"}


def test_training_scalars_arrive_while_training_under_sb3_names_and_evaluations_under_eval(tmp_path):
    pytest.importorskip("tensorboard")
    train(tmp_path, log=("tensorboard",), log_every=25)  # learning starts at step 50, evaluations at 100, 200
    events = tensorboard_events(tmp_path)
    tags = set(events.Tags()["scalars"])
    assert tags == SB3_TRAINING_TAGS | {f"eval/{name}" for name in tracking.EVAL_COLUMNS}
    assert [step for step, _ in scalars(events, "train/critic_loss")] == list(range(50, 201, 25))
    assert [step for step, _ in scalars(events, "time/fps")] == list(range(25, 201, 25))
    first_evaluation = min(step for step, _ in scalars(events, "eval/success_p0"))
    assert first_evaluation == 100
    for tag in SB3_TRAINING_TAGS:  # every training scalar is written before the first evaluation
        assert min(step for step, _ in scalars(events, tag)) < first_evaluation, tag
    # at an evaluation step, the last update's statistics are the ones metrics.csv records
    rows = {int(row["step"]): row for row in metrics(tmp_path)}
    for tag, column in (("train/critic_loss", "critic_loss"), ("train/actor_loss", "actor_loss"),
                        ("train/ent_coef", "alpha"), ("train/q_mean", "q_mean"), ("time/episodes", "episodes")):
        logged = dict(scalars(events, tag))
        for step, row in rows.items():
            assert logged[step] == pytest.approx(float(row[column]), rel=1e-6), (tag, step)
    # rollout/: the episodes ended by each logged step, as the episode log lists them
    ended = episodes(tmp_path)
    for tag, field in (("rollout/ep_rew_mean", "return"), ("rollout/ep_len_mean", "length"),
                       ("rollout/success_rate", "success")):
        for step, value in scalars(events, tag):
            expected = np.mean([float(e[field]) for e in ended if int(e["step"]) <= step][-tracking.EPISODE_WINDOW:])
            assert value == pytest.approx(expected, rel=1e-6), (tag, step)
    for step, row in rows.items():
        for column in tracking.EVAL_COLUMNS:
            assert dict(scalars(events, f"eval/{column}"))[step] == pytest.approx(float(row[column]), rel=1e-6)


def test_rollout_scalars_average_the_last_100_episodes_and_skip_what_is_not_finite():
    # episode log rows: episode, step, start_index, start_x, start_y, length, success, return
    rows = [(n, 10 * n, -1, 0.0, 0.0, n % 7 + 1, n % 2, float(n)) for n in range(1, 151)]
    logged = tracking.training_scalars({"critic_loss": 0.5, "alpha": 0.2, "q_mean": float("nan")}, rows,
                                       {"fps": 600.0, "episodes": 150})
    assert logged == {"train/critic_loss": 0.5, "train/ent_coef": 0.2,
                      "rollout/ep_rew_mean": np.mean(range(51, 151)),
                      "rollout/ep_len_mean": np.mean([n % 7 + 1 for n in range(51, 151)]),
                      "rollout/success_rate": 0.5, "time/fps": 600.0, "time/episodes": 150}
    assert tracking.training_scalars({}, [], {"fps": 1.0}) == {"time/fps": 1.0}  # no episode ended yet


def test_the_start_weights_go_to_tensorboard_at_every_evaluation(tmp_path):
    pytest.importorskip("tensorboard")
    run = train(tmp_path, log=("tensorboard",))
    events = tensorboard_events(tmp_path)
    assert not {tag for tag in events.Tags()["scalars"] if tag.startswith("eval/")} - {
        f"eval/{name}" for name in tracking.EVAL_COLUMNS}  # training statistics stay out of eval/
    histograms = events.Histograms("start_strategy/probabilities")
    assert [h.step for h in histograms] == [100, 200]
    last = histograms[-1].histogram_value
    assert last.num == 150 and last.sum == pytest.approx(1.0, abs=1e-6)
    assert last.max == pytest.approx(run.strategy.probabilities.max(), rel=1e-6)


def test_logging_leaves_the_results_bit_identical(tmp_path):
    pytest.importorskip("tensorboard")
    seeds = ("seed0", "seed1")
    train([tmp_path / "plain" / seed for seed in seeds], seeds=[0, 1])
    train([tmp_path / "logged" / seed for seed in seeds], seeds=[0, 1], log=("tensorboard",), log_every=1)
    for seed in seeds:
        plain, logged = tmp_path / "plain" / seed, tmp_path / "logged" / seed
        assert [{k: v for k, v in row.items() if k != "wall_time"} for row in metrics(plain)] == \
            [{k: v for k, v in row.items() if k != "wall_time"} for row in metrics(logged)]
        assert (plain / EPISODE_LOG).read_bytes() == (logged / EPISODE_LOG).read_bytes()
        with np.load(plain / "start_weights.npz") as a, np.load(logged / "start_weights.npz") as b:
            assert all(a[key].tobytes() == b[key].tobytes() for key in a.files)
        assert (logged / "tensorboard").is_dir() and not (plain / "tensorboard").exists()


def test_a_resume_appends_to_the_sink_and_overwrite_removes_it(tmp_path):
    pytest.importorskip("tensorboard")
    train(tmp_path, steps=100, log=("tensorboard",))
    assert "tensorboard/" in run_files(tmp_path)
    train(tmp_path, steps=200, resume=True, log=("tensorboard",))
    assert [e.step for e in tensorboard_events(tmp_path).Scalars("eval/success_p0")] == [100, 200]
    with pytest.raises(RunDirectoryError, match="already holds a run"):
        train(tmp_path, steps=200)
    train(tmp_path, steps=100, overwrite=True)  # no sink this time: the old record must not survive
    assert not (tmp_path / "tensorboard").exists() and "tensorboard/" not in run_files(tmp_path)


def test_a_resume_from_an_older_checkpoint_shows_each_step_once(tmp_path):
    pytest.importorskip("tensorboard")
    train(tmp_path, log=("tensorboard",), log_every=25)
    # what a kill after step 200's evaluation and before its checkpoint leaves: the sink is past the checkpoint
    (tmp_path / "checkpoint.pt").unlink()
    (tmp_path / "final.pt").unlink()
    train(tmp_path, resume=True, log=("tensorboard",), log_every=25)  # from checkpoint.prev.pt, step 100
    events = tensorboard_events(tmp_path)
    assert [step for step, _ in scalars(events, "train/critic_loss")] == list(range(50, 201, 25))
    assert [step for step, _ in scalars(events, "eval/success_p0")] == [100, 200]


def test_log_videos_writes_each_evaluations_rollouts(tmp_path):
    imageio = pytest.importorskip("imageio")
    try:
        train(tmp_path, steps=100, env={"width": 64, "height": 32}, log_videos=True)  # small frames: software GL
    except Exception as error:  # noqa: BLE001  (no off-screen GL on this machine)
        if "gl" in str(error).lower() or "egl" in str(error).lower():
            pytest.skip(f"no off-screen rendering: {error}")
        raise
    videos = sorted(p.name for p in (tmp_path / "videos").iterdir())
    assert videos == ["step_100.mp4"]
    with imageio.get_reader(tmp_path / "videos" / "step_100.mp4") as reader:
        assert reader.count_frames() > 2 and reader.get_data(0).shape == (32, 64, 3)


def wandb_records(run_dir, wait=30.0):
    """The run record and the history ({step: {key: value}}) of each offline W&B run in RUN_DIR/wandb, read
    from the .wandb file W&B wrote. W&B's service process may still be flushing the file when the run has
    returned on a loaded machine, so the files are read again until every one holds its run record, for at
    most `wait` seconds."""
    from google.protobuf.message import DecodeError

    deadline = time.monotonic() + wait
    while True:
        try:
            found = _wandb_records(run_dir)
        except DecodeError:  # a record caught half-flushed: read the file again
            if time.monotonic() > deadline:
                raise
            found = [(None, {})]
        if all(run is not None for run, _ in found) or time.monotonic() > deadline:
            return found
        time.sleep(0.5)


def _wandb_records(run_dir):
    """One reading of `wandb_records`: records framed as in LevelDB's log (32 KiB blocks, 7-byte headers:
    checksum, length, type 1 full, 2 first, 3 middle, 4 last) after a 7-byte file header."""
    from wandb.proto import wandb_internal_pb2

    found = []
    for path in sorted((run_dir / "wandb" / "wandb").glob("offline-run-*/run-*.wandb")):
        data, position, pieces, run, history = path.read_bytes(), 7, [], None, {}
        while position + 7 <= len(data):
            if 32768 - position % 32768 < 7:  # a block's trailer
                position += 32768 - position % 32768
                continue
            _, length, kind = struct.unpack("<IHB", data[position:position + 7])
            if kind == 0 or position + 7 + length > len(data):  # padding, or a record still being written
                break
            pieces.append(data[position + 7:position + 7 + length])
            position += 7 + length
            if kind in (1, 4):
                record = wandb_internal_pb2.Record()
                record.ParseFromString(b"".join(pieces))
                pieces = []
                if record.HasField("run"):
                    run = record.run
                elif record.HasField("history"):
                    items = {item.key or "/".join(item.nested_key): json.loads(item.value_json)
                             for item in record.history.item}
                    history[items.pop("_step")] = items
        found.append((run, history))
    return found


@pytest.fixture
def offline_wandb(tmp_path, monkeypatch):
    """W&B offline, its own folders in tmp_path, no WANDB_* settings from the caller's environment."""
    pytest.importorskip("wandb")
    for variable in ("WANDB_PROJECT", "WANDB_ENTITY", "WANDB_RUN_GROUP", "WANDB_NAME", "WANDB_RUN_ID"):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv("WANDB_MODE", "offline")
    monkeypatch.setenv("WANDB_SILENT", "true")
    for variable in ("WANDB_DIR", "WANDB_CONFIG_DIR", "WANDB_CACHE_DIR", "WANDB_DATA_DIR"):
        (tmp_path / variable).mkdir()
        monkeypatch.setenv(variable, str(tmp_path / variable))


def test_wandb_offline_keeps_one_run_across_a_resume(tmp_path, offline_wandb):
    out = tmp_path / "run"
    train(out, steps=100, log=("wandb",), log_every=50)
    run_id = (out / "wandb" / tracking.WANDB_ID_FILE).read_text()
    train(out, steps=200, resume=True, log=("wandb",), log_every=50)
    assert (out / "wandb" / tracking.WANDB_ID_FILE).read_text() == run_id
    offline = sorted(p.name for p in (out / "wandb" / "wandb").glob("offline-run-*"))
    assert len(offline) == 2 and all(name.endswith(run_id) for name in offline)
    assert not any((tmp_path / "WANDB_DIR").iterdir())  # the files live in the run directory, not WANDB_DIR
    (first, history), _ = wandb_records(out)
    # without options or WANDB_* variables: the package's project, the configuration as group and name
    assert (first.project, first.entity, first.run_group) == ("lava-bridge-mj", "", "auxss on LavaBridge-v0")
    assert first.display_name == "auxss on LavaBridge-v0 seed 0"
    assert {"train/critic_loss", "train/ent_coef", "time/fps"} <= set(history[50])
    row = metrics(out)[0]  # step 100: the training scalars and the evaluation, as metrics.csv has them
    assert history[100]["train/critic_loss"] == pytest.approx(float(row["critic_loss"]), rel=1e-6)
    assert history[100]["eval/success_p0"] == float(row["success_p0"])


def test_wandb_settings_come_from_options_over_environment_variables_over_defaults(tmp_path, offline_wandb,
                                                                                    monkeypatch):
    monkeypatch.setenv("WANDB_PROJECT", "project-from-env")
    monkeypatch.setenv("WANDB_ENTITY", "entity-from-env")
    monkeypatch.setenv("WANDB_RUN_GROUP", "group-from-env")
    monkeypatch.setenv("WANDB_RUN_ID", "same-for-all")  # not used: each seed's run needs its own id
    train([tmp_path / "api" / f"seed{seed}" for seed in (3, 4)], steps=100, seeds=[3, 4], log=("wandb",),
          wandb={"project": "project-option", "name": "trial"})
    expected = {"project": "project-option", "entity": "entity-from-env", "group": "group-from-env"}
    ids = set()
    for seed in (3, 4):
        [(run, _)] = wandb_records(tmp_path / "api" / f"seed{seed}")
        ids.add(run.run_id)
        assert run.run_id == (tmp_path / "api" / f"seed{seed}" / "wandb" / tracking.WANDB_ID_FILE).read_text()
        assert (run.project, run.entity, run.run_group, run.display_name) == (*expected.values(), f"trial seed {seed}")
        config = {item.key: json.loads(item.value_json) for item in run.config.update}
        assert config["seed"] == seed and config["wandb"] == {**expected, "name": f"trial seed {seed}"}
    assert len(ids) == 2 and "same-for-all" not in ids
    # the CLI's options, each over its variable
    monkeypatch.setenv("WANDB_NAME", "name-from-env")
    assert cli.main(["--method", "auxss", "--steps", "100", "--eval-every", "100", "--eval-episodes", "2",
                     "--set", "sac.hidden_sizes=[8,8]", "--set", "sac.learning_starts=50", "--set", "sac.batch_size=16",
                     "--log", "wandb", "--wandb-project", "cli-project", "--wandb-group", "cli-group",
                     "--out", str(tmp_path / "cli"), "--no-progress"]) == 0
    [(run, _)] = wandb_records(tmp_path / "cli")
    assert (run.project, run.entity, run.run_group, run.display_name) == (
        "cli-project", "entity-from-env", "cli-group", "name-from-env seed 0")


@pytest.mark.parametrize("argv, variables, message", [
    (["--wandb-group", "g"], {}, "--wandb-group needs --log wandb"),
    (["--log", "wandb", "--wandb-project", "a/b"], {}, "--log wandb: Invalid project name 'a/b': cannot contain"),
    (["--log", "wandb", "--wandb-entity", ""], {}, "--log wandb: wandb entity must be a non-empty string, got ''"),
    (["--log", "wandb"], {"WANDB_PROJECT": "x" * 129}, "exceeded 128 characters"),
])
def test_bad_wandb_settings_are_one_usage_line_before_anything_is_written(tmp_path, offline_wandb, monkeypatch, capsys,
                                                                          argv, variables, message):
    for name, value in variables.items():
        monkeypatch.setenv(name, value)
    with pytest.raises(SystemExit) as stop:
        cli.main(["--method", "sac", *argv, "--out", str(tmp_path / "run")])
    assert stop.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert error.startswith("lava-bridge-bench: error: ") and message in error
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("kwargs, message", [
    ({"log": ("wandb",), "wandb": {"projct": "p"}}, r"unknown W&B settings \['projct'\]; expected some of "
                                                     r"\['project', 'entity', 'group', 'name'\]"),
    ({"log": ("wandb",), "wandb": {"group": 3}}, "wandb group must be a non-empty string, got 3"),
    ({"log": ("tensorboard",), "wandb": {"project": "p"}}, r"need the wandb sink: log=\('wandb',\)"),
    ({"log": ("tensorboard",), "log_every": 0}, "log_every must be an integer >= 1, got 0"),
])
def test_the_python_api_refuses_bad_tracking_settings_before_anything_is_written(tmp_path, offline_wandb, kwargs,
                                                                                  message):
    pytest.importorskip("tensorboard")
    with pytest.raises(ValueError, match=message):
        train(tmp_path / "run", **kwargs)
    assert not (tmp_path / "run").exists()


def test_an_unknown_or_missing_sink_is_refused_before_anything_is_written(tmp_path, monkeypatch, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(["--method", "sac", "--log", "tensorboard,mlflow", "--out", str(tmp_path / "run")])
    assert stop.value.code == 2
    assert "--log: unknown tracking sink 'mlflow'; expected some of ('tensorboard', 'wandb')" in capsys.readouterr().err
    monkeypatch.setattr(tracking.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(tracking.TrackingUnavailable, match=r"--log wandb needs the wandb package: pip install "
                                                           r"'lava-bridge-mj\[wandb\]'"):
        train(tmp_path / "run", log=("wandb",))
    assert not (tmp_path / "run").exists()


def test_the_cli_without_log_imports_no_tracking_library():
    probe = ("import sys\nfrom lava_bridge_mj.eval import cli\ntry:\n    cli.main(['--help'])\nexcept SystemExit:\n"
             "    pass\nprint(sorted(m for m in ('wandb', 'tensorboard') if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip().splitlines()[-1] == "[]", result.stdout + result.stderr
