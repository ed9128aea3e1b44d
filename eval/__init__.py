"""Training runner, benchmark CLI, metrics, plots and rollout videos.

`RunConfig` (eval/training/config.py, no torch) describes one run; `train(config, out_dir, seeds=...)`
(eval/training/runner.py, loads torch) trains it and returns the finished `Run`."""

import os

__all__ = ["RunConfig", "train"]


def __getattr__(name: str):
    if name == "RunConfig":
        from lava_bridge_mj.eval.training.config import RunConfig

        return RunConfig
    if name == "train":
        # as the CLI does: idle OpenMP threads sleep rather than spin (they collapse beside a busy
        # process); only takes effect if torch is not loaded yet, and a value already set is kept
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
        from lava_bridge_mj.eval.training.runner import train

        return train
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
