"""Shared test set-up.

The package picks EGL for off-screen rendering on headless machines, but only if it is imported
before mujoco: mujoco reads MUJOCO_GL once, at import, and falls back to GLFW, which aborts the
whole process (not an exception) when there is no display. Test modules import mujoco in any
order, so the choice is made here, before any of them is collected.
"""

import os

if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

import csv  # noqa: E402
import shutil  # noqa: E402

import pytest  # noqa: E402


@pytest.fixture
def one_torch_thread():
    """One torch thread, as the CLI's default: a seed's numbers are then independent of its batch.
    The previous setting is restored so other tests are unaffected."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def metrics_without_wall_time(run_dir):
    """A run's metrics.csv rows as strings, without the one column that legitimately differs."""
    with open(run_dir / "metrics.csv") as f:
        return [{k: v for k, v in row.items() if k != "wall_time"} for row in csv.DictReader(f)]


def interrupted_copy(full_dir, resumed_dir):
    """What a run killed mid-way leaves: config, the metrics and episode log written so far (with rows
    past the checkpoint), and the checkpoint before the last one as its latest."""
    resumed_dir.mkdir()
    for name in ("config.json", "metrics.csv", "episodes.csv"):
        if (full_dir / name).exists():
            shutil.copy(full_dir / name, resumed_dir / name)
    shutil.copy(full_dir / "checkpoint.prev.pt", resumed_dir / "checkpoint.pt")
