"""Rollout videos: decodable mp4 files with the expected frame count and size, written atomically."""

import subprocess
import sys

import gymnasium
import imageio.v2 as imageio
import numpy as np
import pytest

import lava_bridge_mj
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.video import record_rollouts


def _can_render() -> bool:
    # a missing GL backend aborts the process instead of raising, so probe in a child process
    probe = "import lava_bridge_mj, mujoco; mujoco.Renderer(lava_bridge_mj.LavaBridgeEnv().model, 16, 16).close()"
    return subprocess.run([sys.executable, "-c", probe], capture_output=True).returncode == 0


pytestmark = pytest.mark.skipif(not _can_render(), reason="no OpenGL for off-screen rendering "
                                "(install Debian's libegl1 libegl-mesa0 libgl1-mesa-dri, or set MUJOCO_GL=osmesa)")


def test_video_has_one_frame_per_step_plus_the_start_and_the_maze_size(tmp_path):
    env = gymnasium.make(lava_bridge_mj.ENV_ID, render_mode="rgb_array", max_episode_steps=12,
                         width=320, height=128)
    stay = lambda obs: np.zeros(2, dtype=np.float32)  # noqa: E731  (never terminates: 12 steps each)
    path = tmp_path / "rollouts.mp4"
    try:
        successes = record_rollouts(env, stay, path, starts=("p0", "ood"), episodes_per_start=1)
    finally:
        env.close()
    assert successes == {"p0": 0, "ood": 0}
    with imageio.get_reader(path) as reader:  # its len() is inf: count by decoding
        frames = [frame for frame in reader]
    assert len(frames) == 2 * (12 + 1)
    assert frames[0].shape == (128, 320, 3)
    assert not list(tmp_path.glob("*partial*")), "the temporary file must be renamed away"


def test_expert_video_records_successes(tmp_path):
    env = gymnasium.make(lava_bridge_mj.ENV_ID, render_mode="rgb_array", width=160, height=64)
    try:
        successes = record_rollouts(env, lava_bridge_mj.ScriptedExpert(env).act, tmp_path / "expert.mp4",
                                    starts=("ood",), episodes_per_start=1)
    finally:
        env.close()
    assert successes == {"ood": 1}


def test_cli_video_flag_records_the_trained_policy(tmp_path, monkeypatch):
    calls = []

    def fake_record(env, policy, path, **kwargs):
        calls.append(path)
        action = policy(np.zeros(4))
        assert action.shape == (2,) and np.all(np.abs(action) <= 1)
        return {"p0": 0, "ood": 0}

    monkeypatch.setattr("lava_bridge_mj.eval.video.record_rollouts", fake_record)
    code = cli.main(["--method", "sac", "--steps", "100", "--eval-every", "100", "--eval-episodes", "1",
                     "--out", str(tmp_path), "--no-progress", "--video"])
    assert code == 0
    assert calls == [tmp_path / "rollouts.mp4"]
