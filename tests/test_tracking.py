"""Live tracking sinks (eval/tracking.py): TensorBoard and W&B receive what metrics.csv records, a
resume appends to the same record, --overwrite removes it with the run, and bad --log values are
refused before anything is written."""

import csv
import math
import subprocess
import sys

import numpy as np
import pytest

from lava_bridge_mj.eval import cli, tracking
from lava_bridge_mj.eval.config import RunConfig
from lava_bridge_mj.eval.run_files import RunDirectoryError, run_files

TINY = dict(steps=200, eval_every=100, eval_episodes=2, sac={"hidden_sizes": [8, 8], "learning_starts": 50,
                                                               "batch_size": 16})


def train(out, steps=200, env=None, **kwargs):
    from lava_bridge_mj.eval.runner import train as run_train

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


def test_tensorboard_gets_every_metrics_csv_value_and_the_start_weights(tmp_path):
    pytest.importorskip("tensorboard")
    run = train(tmp_path, log=("tensorboard",))
    events = tensorboard_events(tmp_path)
    rows = metrics(tmp_path)
    for column in rows[0]:
        if column == "step":
            continue
        expected = [(int(row["step"]), float(row[column])) for row in rows if math.isfinite(float(row[column]))]
        logged = [(e.step, e.value) for e in events.Scalars(f"eval/{column}")] if expected else []
        assert [step for step, _ in logged] == [step for step, _ in expected], column
        np.testing.assert_allclose([v for _, v in logged], [v for _, v in expected], rtol=1e-6, err_msg=column)
    assert "eval/guide_horizon" not in events.Tags()["scalars"]  # NaN in metrics.csv: nothing to show
    histograms = events.Histograms("start_strategy/probabilities")
    assert [h.step for h in histograms] == [100, 200]
    last = histograms[-1].histogram_value
    assert last.num == 150 and last.sum == pytest.approx(1.0, abs=1e-6)
    assert last.max == pytest.approx(run.strategy.probabilities.max(), rel=1e-6)


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


def test_wandb_offline_keeps_one_run_across_a_resume(tmp_path, monkeypatch):
    pytest.importorskip("wandb")
    monkeypatch.setenv("WANDB_MODE", "offline")
    monkeypatch.setenv("WANDB_SILENT", "true")
    train(tmp_path, steps=100, log=("wandb",))
    run_id = (tmp_path / "wandb" / tracking.WANDB_ID_FILE).read_text()
    train(tmp_path, steps=200, resume=True, log=("wandb",))
    assert (tmp_path / "wandb" / tracking.WANDB_ID_FILE).read_text() == run_id
    offline = sorted(p.name for p in (tmp_path / "wandb" / "wandb").glob("offline-run-*"))
    assert len(offline) == 2 and all(name.endswith(run_id) for name in offline)


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
