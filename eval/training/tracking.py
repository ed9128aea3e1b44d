"""Live experiment tracking beside a run's own files: TensorBoard and Weights & Biases.

`metrics.csv` stays the source of truth. A sink receives, under Stable-Baselines3's names:

- while training, every `log_every` steps (`TRAIN_LOG_EVERY` by default): the last update's statistics
  `train/NAME` (critic and actor losses, `ent_coef`, the critics' mean Q, the policy's entropy; the
  learner's own for BC and IQL; JSRL's `guide_horizon`), `rollout/ep_rew_mean`, `ep_len_mean` and
  `success_rate` over the seed's last `EPISODE_WINDOW` training episodes, and `time/fps` (loop steps
  per second since this process started or resumed training), `time/episodes` and `time/time_elapsed` (the run's seconds);
- at every evaluation: `eval/NAME` for the evaluation's own columns of metrics.csv (`EVAL_COLUMNS`),
  the start strategy's sampling probabilities as a histogram, and, when the run records them, the
  mp4 of the policy's rollouts from p0 and ood.

Logging reads what training computed and draws no random numbers, so a run's results are the same
with and without sinks. Each seed of a batch has its own sink, written inside its run directory
(`tensorboard/`, `wandb/`) with the same tags, so `tensorboard --logdir` over the batch shows one run
per seed; `--overwrite` removes a sink with the run and a resume appends to it.

`ProgressReport` is the sweep's own sink: a small JSON file per job saying how far it is, which the
sweep reads to print one progress line per running job.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import secrets
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from lava_bridge_mj.eval.training.atomic import atomic_write_text

SINKS = ("tensorboard", "wandb")
"""The names `--log` accepts."""
EXTRAS = {"tensorboard": "pip install 'lava-bridge-mj[tensorboard]'", "wandb": "pip install 'lava-bridge-mj[wandb]'"}
TRAIN_LOG_EVERY = 1000
"""Steps between two writes of the training scalars: at this interval TensorBoard costs about 0.05% of
training time (bench/tracking_cost.py; docs/training.md gives the measurement)."""
EPISODE_WINDOW = 100
"""rollout/ scalars average the last this many training episodes (SB3's stats_window_size)."""
EVAL_COLUMNS = ("success_p0", "success_ood", "return_p0", "return_ood")
"""The metrics.csv columns an evaluation measures, logged as eval/NAME; the others are training's."""
TRAIN_NAMES = {"alpha": "ent_coef"}
"""Update statistics renamed to SB3's names under train/; the others keep the learner's names."""
WANDB_PROJECT = "lava-bridge-mj"
"""The W&B project when neither the `project` setting nor WANDB_PROJECT names one."""
WANDB_SETTINGS = {"project": "WANDB_PROJECT", "entity": "WANDB_ENTITY", "group": "WANDB_RUN_GROUP",
                  "name": "WANDB_NAME"}
"""wandb.init's keywords that a run sets (`--wandb-project` ...), each with the environment variable
that W&B reads for it."""
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


def wandb_settings(settings: Mapping[str, Any] | None = None) -> dict[str, str]:
    """The W&B runs' project, entity, group and name: each from `settings` (keys of WANDB_SETTINGS)
    where it names one, else from its WANDB_* environment variable, else the project is WANDB_PROJECT
    and the others are left out (WandbSink fills in the group and name). ValueError naming an unknown
    key, or a value that is not a non-empty string or that W&B refuses (a project with '/', ...)."""
    settings = dict(settings or {})
    unknown = sorted(set(settings) - set(WANDB_SETTINGS), key=str)
    if unknown:
        raise ValueError(f"unknown W&B settings {unknown}; expected some of {list(WANDB_SETTINGS)}")
    resolved = {}
    for key, variable in WANDB_SETTINGS.items():
        value, source = settings.get(key), f"wandb {key}"
        if value is None:
            value, source = os.environ.get(variable) or None, variable
        if value is None:
            continue
        if not isinstance(value, str) or not value.strip():
            raise ValueError(f"{source} must be a non-empty string, got {value!r}")
        resolved[key] = value
    resolved.setdefault("project", WANDB_PROJECT)
    import wandb

    try:  # W&B's own checks (a project name's length and characters), before any run directory is touched
        wandb.Settings(project=resolved["project"], entity=resolved.get("entity"),
                       run_group=resolved.get("group"), run_name=resolved.get("name"))
    except wandb.errors.UsageError as error:
        raise ValueError(str(error)) from None
    return resolved


def open_sink(name: str, directory: Path, config: dict[str, Any], label: str, resume_step: int = 0,
              wandb: Mapping[str, str] | None = None):
    """The sink `name` of the run in `directory`, whose configuration is `config` (config.json's
    values), continuing after `resume_step`; `wandb`: wandb_settings()'s values, for the W&B sink."""
    if name == "wandb":
        return WandbSink(directory, config, label, wandb_settings(wandb))
    return TensorBoardSink(directory, config, label, resume_step)


def training_scalars(train: Mapping[str, float], episodes: Sequence[Sequence[float]],
                     timing: Mapping[str, float]) -> dict[str, float]:
    """One seed's training scalars under SB3's names: `train` (the last update's statistics and JSRL's
    guide horizon) as train/NAME, alpha as train/ent_coef; the rollout/ means (ep_rew_mean, ep_len_mean,
    success_rate) of the last EPISODE_WINDOW of `episodes`, its episodes.csv rows (EPISODE_FIELDS;
    none before an episode ends); `timing` as time/NAME. Non-finite values are left out."""
    from lava_bridge_mj.eval.training.run_files import EPISODE_FIELDS

    scalars = {f"train/{TRAIN_NAMES.get(name, name)}": value for name, value in train.items()}
    recent = np.array(episodes[-EPISODE_WINDOW:], dtype=np.float64).reshape(-1, len(EPISODE_FIELDS))
    if len(recent):
        for tag, field in (("ep_rew_mean", "return"), ("ep_len_mean", "length"), ("success_rate", "success")):
            scalars[f"rollout/{tag}"] = recent[:, EPISODE_FIELDS.index(field)].mean()
    scalars.update({f"time/{name}": value for name, value in timing.items()})
    return _finite(scalars)


def evaluation_scalars(row: Mapping[str, float]) -> dict[str, float]:
    """An evaluation row of metrics.csv as eval/NAME scalars (EVAL_COLUMNS)."""
    return _finite({f"eval/{name}": row[name] for name in EVAL_COLUMNS})


def _finite(scalars: Mapping[str, float]) -> dict[str, float]:
    # NaN marks "nothing to report" (no update yet, JSRL's horizon for another method)
    return {name: float(value) for name, value in scalars.items() if math.isfinite(value)}


class TensorBoardSink:
    """The scalars, the histogram `start_strategy/probabilities` and the config as text, in
    DIRECTORY/tensorboard (torch's SummaryWriter; `tensorboard --logdir runs` shows every seed). A
    resume from `resume_step` hides what an interrupted session wrote after it (SummaryWriter's
    purge_step), so no step appears twice."""

    def __init__(self, directory: Path, config: dict[str, Any], label: str, resume_step: int = 0):
        from torch.utils.tensorboard import SummaryWriter

        self.writer = SummaryWriter(log_dir=str(Path(directory) / "tensorboard"),
                                    purge_step=resume_step + 1 if resume_step else None)
        self.writer.add_text("config", f"{label}\n\n```\n{json.dumps(config, indent=1)}\n```")

    def log_training(self, step: int, scalars: Mapping[str, float]) -> None:
        for name, value in scalars.items():
            self.writer.add_scalar(name, value, step)

    def log(self, row: dict[str, float], probabilities: np.ndarray, video: Path | None = None) -> None:
        step = int(row["step"])
        for name, value in evaluation_scalars(row).items():
            self.writer.add_scalar(name, value, step)
        if probabilities.size:
            self.writer.add_histogram("start_strategy/probabilities", probabilities, step)
        if video is not None:  # TensorBoard shows no mp4; the file's path, to find it from the dashboard
            self.writer.add_text("rollouts", str(video), step)
        self.writer.flush()

    def close(self) -> None:
        self.writer.close()


class WandbSink:
    """One W&B run per seed, in the project, entity and group of `settings` (wandb_settings(); group by
    default the configuration's label), named "NAME seed S" (NAME by default the label); its config is
    `config` with the settings under "wandb". Files and the run's id (wandb/run_id) in DIRECTORY/wandb
    whatever WANDB_DIR and WANDB_RUN_ID say, so a resume and --overwrite find them; `WANDB_MODE=offline`
    keeps them on disk for `wandb sync`. The same scalars as TensorBoard, the probabilities as a
    histogram and the rollouts as a video."""

    def __init__(self, directory: Path, config: dict[str, Any], label: str, settings: Mapping[str, str]):
        import wandb

        self.wandb = wandb
        files = Path(directory) / "wandb"
        files.mkdir(parents=True, exist_ok=True)
        id_file = files / WANDB_ID_FILE
        # each seed's own id (never WANDB_RUN_ID, which would give every seed of a batch the same run)
        run_id = id_file.read_text().strip() if id_file.exists() else secrets.token_hex(6)
        settings = {"group": label, **settings, "name": f"{settings.get('name', label)} seed {config['seed']}"}
        self.run = wandb.init(dir=str(files), config={**config, "wandb": settings}, reinit="create_new",
                              id=run_id, resume="allow", **settings)
        id_file.write_text(self.run.id)

    def log_training(self, step: int, scalars: Mapping[str, float]) -> None:
        self.run.log(dict(scalars), step=step)

    def log(self, row: dict[str, float], probabilities: np.ndarray, video: Path | None = None) -> None:
        values: dict[str, Any] = evaluation_scalars(row)
        if probabilities.size:
            values["start_strategy/probabilities"] = self.wandb.Histogram(probabilities)
        if video is not None:
            values["rollouts"] = self.wandb.Video(str(video), format="mp4")
        self.run.log(values, step=int(row["step"]))

    def close(self) -> None:
        self.run.finish()
