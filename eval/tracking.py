"""Live experiment tracking beside a run's own files: TensorBoard and Weights & Biases.

`metrics.csv` stays the source of truth; a sink receives the same row at every evaluation (every
column but `step`, which is the x axis), the start strategy's sampling probabilities as a histogram,
and, when the run records them, the mp4 of the policy's rollouts from p0 and ood at that evaluation.
Each seed of a batch has its own sink, written inside its run directory (`tensorboard/`, `wandb/`),
so `--overwrite` removes it with the run and a resume appends to it.

`ProgressReport` is the sweep's own sink: a small JSON file per job saying how far it is, which the
sweep reads to print one progress line per running job.
"""

from __future__ import annotations

import importlib.util
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from lava_bridge_mj.eval.atomic import atomic_write_text

SINKS = ("tensorboard", "wandb")
"""The names `--log` accepts."""
EXTRAS = {"tensorboard": "pip install 'lava-bridge-mj[tensorboard]'", "wandb": "pip install 'lava-bridge-mj[wandb]'"}
WANDB_PROJECT = "lava-bridge-mj"
WANDB_ID_FILE = "run_id"
"""wandb/run_id: the W&B run's id, so a resumed run logs into the same W&B run."""


class ProgressReport:
    """A JSON file that says how far a training session is (step, steps, steps/s since the session
    began, mean success from p0 and ood at the last evaluation, and the step it began at: `started_at`,
    above 0 for a session that resumed a run), replaced atomically at most every `every` seconds and at
    each evaluation: what a sweep reads to print its jobs' progress."""

    def __init__(self, path: str | Path, step: int, steps: int, every: float = 5.0):
        self.path, self.steps, self.every = Path(path), steps, every
        self.first_step, self.started, self.last = step, time.perf_counter(), -math.inf
        self.success: tuple[float, float] | None = None

    def evaluated(self, p0: float, ood: float) -> None:
        self.success = (float(p0), float(ood))

    def write(self, step: int, force: bool = False) -> None:
        now = time.perf_counter()
        if not force and now - self.last < self.every:
            return
        self.last = now
        rate = (step - self.first_step) / max(now - self.started, 1e-9)
        record = {"step": step, "steps": self.steps, "rate": rate, "started_at": self.first_step,
                  "success_p0": self.success and self.success[0], "success_ood": self.success and self.success[1]}
        atomic_write_text(self.path, json.dumps(record))


class TrackingUnavailable(ValueError):
    """A sink's library is not installed."""


def check_sinks(names: Any) -> tuple[str, ...]:
    """`names` as a tuple of sink names; ValueError naming an unknown one, TrackingUnavailable naming
    the extra to install for one whose library is missing (checked before training starts)."""
    names = tuple(names)
    for name in names:
        if name not in SINKS:
            raise ValueError(f"unknown tracking sink {name!r}; expected some of {SINKS}")
        if importlib.util.find_spec(name) is None:  # the package is named like the sink
            raise TrackingUnavailable(f"--log {name} needs the {name} package: {EXTRAS[name]}")
    return names


def open_sink(name: str, directory: Path, config: dict[str, Any], label: str):
    """The sink `name` of the run in `directory`, whose configuration is `config` (config.json's values)."""
    return {"tensorboard": TensorBoardSink, "wandb": WandbSink}[name](directory, config, label)


def _scalars(row: dict[str, float]) -> dict[str, float]:
    # NaN marks "nothing to report" in metrics.csv (no training episode ended, an offline method)
    return {name: float(value) for name, value in row.items() if name != "step" and math.isfinite(value)}


class TensorBoardSink:
    """Scalars `eval/NAME`, the histogram `start_strategy/probabilities` and the config as text, in
    DIRECTORY/tensorboard (torch's SummaryWriter; `tensorboard --logdir runs` shows every seed)."""

    def __init__(self, directory: Path, config: dict[str, Any], label: str):
        import json

        from torch.utils.tensorboard import SummaryWriter

        self.writer = SummaryWriter(log_dir=str(Path(directory) / "tensorboard"))
        self.writer.add_text("config", f"{label}\n\n```\n{json.dumps(config, indent=1)}\n```")

    def log(self, row: dict[str, float], probabilities: np.ndarray, video: Path | None = None) -> None:
        step = int(row["step"])
        for name, value in _scalars(row).items():
            self.writer.add_scalar(f"eval/{name}", value, step)
        if probabilities.size:
            self.writer.add_histogram("start_strategy/probabilities", probabilities, step)
        if video is not None:  # TensorBoard shows no mp4; the file's path, to find it from the dashboard
            self.writer.add_text("rollouts", str(video), step)
        self.writer.flush()

    def close(self) -> None:
        self.writer.close()


class WandbSink:
    """One W&B run per seed in project `lava-bridge-mj` (group: the configuration's label), files in
    DIRECTORY/wandb; `WANDB_MODE=offline` keeps it on disk for `wandb sync`. The same scalars as
    TensorBoard, the probabilities as a histogram and the rollouts as a video."""

    def __init__(self, directory: Path, config: dict[str, Any], label: str):
        import wandb

        self.wandb = wandb
        files = Path(directory) / "wandb"
        files.mkdir(parents=True, exist_ok=True)
        id_file = files / WANDB_ID_FILE
        resumed = {"id": id_file.read_text().strip(), "resume": "allow"} if id_file.exists() else {}
        self.run = wandb.init(project=WANDB_PROJECT, dir=str(files), config=config, name=f"{label} seed {config['seed']}",
                              group=label, reinit="create_new", **resumed)
        id_file.write_text(self.run.id)

    def log(self, row: dict[str, float], probabilities: np.ndarray, video: Path | None = None) -> None:
        values: dict[str, Any] = {f"eval/{name}": value for name, value in _scalars(row).items()}
        if probabilities.size:
            values["start_strategy/probabilities"] = self.wandb.Histogram(probabilities)
        if video is not None:
            values["rollouts"] = self.wandb.Video(str(video), format="mp4")
        self.run.log(values, step=int(row["step"]))

    def close(self) -> None:
        self.run.finish()
