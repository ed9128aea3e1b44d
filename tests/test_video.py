"""Rollout videos: decodable mp4 files with the expected frame count and size, written atomically."""

import os
import shutil
import signal
import subprocess
import sys

import gymnasium
import imageio.v2 as imageio
import numpy as np
import pytest

import lava_bridge_mj
from conftest import flip_a_data_bit, read_only
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


def test_gymnasiums_record_video_wrapper_records_an_episode(tmp_path):
    # needs moviepy, which the record-video extra (and test) installs
    env = gymnasium.make(lava_bridge_mj.ENV_ID, render_mode="rgb_array", width=64, height=32, max_episode_steps=10)
    folder = tmp_path / "videos"
    env = gymnasium.wrappers.RecordVideo(env, str(folder), episode_trigger=lambda episode: True, name_prefix="lava")
    try:
        env.reset(seed=0)
        ended = False
        while not ended:
            _, _, terminated, truncated, _ = env.step(np.zeros(2, dtype=np.float32))
            ended = terminated or truncated
    finally:
        env.close()
    assert [p.name for p in folder.iterdir()] == ["lava-episode-0.mp4"]
    with imageio.get_reader(folder / "lava-episode-0.mp4") as reader:
        assert reader.count_frames() >= 10 and reader.get_data(0).shape == (32, 64, 3)


def test_the_native_vector_env_points_to_the_sync_vector_env_for_frames():
    with pytest.raises(ValueError, match=r"does not render; for frames use gymnasium\.make_vec\(\.\.\., "
                                         r"vectorization_mode='sync', render_mode='rgb_array'\)"):
        gymnasium.make_vec(lava_bridge_mj.ENV_ID, num_envs=2, render_mode="rgb_array")
    envs = gymnasium.make_vec(lava_bridge_mj.ENV_ID, num_envs=2, vectorization_mode="sync", render_mode="rgb_array",
                              width=64, height=32)
    try:
        envs.reset(seed=[0, 1])
        frames = envs.render()
    finally:
        envs.close()
    assert [frame.shape for frame in frames] == [(32, 64, 3)] * 2


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


# --- `lava-bridge-bench video RUN_DIR`: a trained run's policy -----------------------------------------
MAX_STEPS = 25


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A real SAC run of 300 steps (updates from step 100, snapshots at 150 and 300) and its Run,
    trained with the session's one torch thread (conftest.one_torch_thread)."""
    from lava_bridge_mj.agents.sac import SACConfig
    from lava_bridge_mj.eval.training.runner import RunConfig, train

    run_dir = tmp_path_factory.mktemp("tiny") / "sac" / "seed3"
    config = RunConfig(method="sac", seed=3, steps=300, eval_every=150, eval_episodes=1,
                       sac=SACConfig(hidden_sizes=(16, 16), batch_size=32, learning_starts=100))
    return run_dir, train(config, run_dir, progress=False)


def episode_lengths(policy, starts=("p0", "ood"), episodes=1, seed=0, max_steps=MAX_STEPS):
    """How many steps each episode of `policy` lasts under the video's time limit, counted independently."""
    env = gymnasium.make(lava_bridge_mj.ENV_ID, max_episode_steps=max_steps)
    lengths = []
    for start in starts:
        for episode in range(episodes):
            obs, _ = env.reset(seed=seed + episode, options={"start": start})
            steps, done = 0, False
            while not done:
                obs, _, terminated, truncated, _ = env.step(policy(obs))
                steps, done = steps + 1, terminated or truncated
            lengths.append(steps)
    env.close()
    return lengths


def test_video_of_a_run_decodes_with_one_frame_per_step_and_start(tiny_run, tmp_path, capsys):
    run_dir, run = tiny_run
    out = tmp_path / "clips" / "final.mp4"
    assert cli.main(["video", str(run_dir), "--episodes", "1", "--max-steps", str(MAX_STEPS), "--out", str(out)]) == 0
    assert "sac seed 3, final.pt (step 300)" in capsys.readouterr().out
    with imageio.get_reader(out) as reader:
        frames = [frame for frame in reader]
    lengths = episode_lengths(run.policy(0))  # the trainer's own policy, not the video's reloaded one
    assert len(frames) == sum(length + 1 for length in lengths)
    assert frames[0].shape == (400, 960, 3)  # the env's default render size
    assert not list(out.parent.glob("*partial*"))


def test_reloaded_policies_match_the_trainer_and_the_snapshots(tiny_run):
    from lava_bridge_mj.eval.video import load_policy

    run_dir, run = tiny_run
    obs = np.random.default_rng(0).uniform(-2, 2, (20, 4))
    trained = np.stack([run.policy(0)(o) for o in obs])  # one at a time, as in a rollout (same kernels)
    final, config, _ = load_policy(run_dir, "final")
    assert config.seed == 3 and config.sac.hidden_sizes == (16, 16)
    np.testing.assert_array_equal(np.stack([final(o) for o in obs]), trained)
    last, _, _ = load_policy(run_dir, "step_300")
    np.testing.assert_array_equal(np.stack([last(o) for o in obs]), trained)
    earlier, _, _ = load_policy(run_dir, "step_150")
    assert not np.allclose(np.stack([earlier(o) for o in obs]), trained)  # 150 updates later it acts otherwise


def test_video_of_a_snapshot_defaults_to_a_file_in_the_run(tiny_run, tmp_path):
    import shutil

    from lava_bridge_mj.eval import video

    run_dir = tmp_path / "copy"
    shutil.copytree(tiny_run[0], run_dir)
    assert video.main([str(run_dir), "--policy", "step_150", "--episodes", "2", "--max-steps", "6", "--seed", "5"]) == 0
    with imageio.get_reader(run_dir / "rollouts_step_150.mp4") as reader:
        frames = len([frame for frame in reader])
    lengths = episode_lengths(video.load_policy(run_dir, "step_150")[0], episodes=2, seed=5, max_steps=6)
    assert frames == sum(length + 1 for length in lengths)


@pytest.mark.parametrize("case, message", [
    ("missing", "is not a directory"),
    ("no config", "holds no config.json"),
    ("bad config", "is not a usable run configuration"),
    ("no policy", "holds neither final.pt nor checkpoint.pt"),
    ("no snapshot", "has no policy snapshot step_999.pt; available steps: 150, 300"),
    ("damaged snapshot", "step_150.pt is damaged"),
    ("damaged final", "final.pt is damaged"),
    ("bad spec", "--policy must be final or step_N"),
])
def test_video_refuses_bad_runs_with_one_line_and_exit_2(tiny_run, tmp_path, capsys, case, message):
    import shutil

    from lava_bridge_mj.eval import video

    run_dir = tmp_path / "run"
    policy = {"no snapshot": "step_999", "bad spec": "best", "damaged snapshot": "step_150"}.get(case, "final")
    if case != "missing":
        shutil.copytree(tiny_run[0], run_dir)
    if case == "no config":
        (run_dir / "config.json").unlink()
    if case == "bad config":
        (run_dir / "config.json").write_text('{"method": "sac", "learning_rate": 1}')
    if case == "no policy":
        for name in ("final.pt", "checkpoint.pt"):
            (run_dir / name).unlink()
    if case.startswith("damaged"):  # a flipped bit that torch.load alone would not notice
        flip_a_data_bit(run_dir / ("policies/step_150.pt" if case == "damaged snapshot" else "final.pt"))
    before = sorted(p.name for p in tmp_path.rglob("*"))
    out = tmp_path / "out.mp4"
    assert video.main([str(run_dir), "--policy", policy, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("lava-bridge-bench video: error:")
    assert message in err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # nothing written


def test_expert_video_through_the_command(tmp_path):
    from lava_bridge_mj.eval import video

    firsts = {}
    for task in ("LavaBridge-v0", "LavaBridgeBend-v0"):
        out = tmp_path / f"{task}.mp4"
        assert video.main(["--expert", "--env", task, "--episodes", "1", "--max-steps", "4", "--out", str(out)]) == 0
        with imageio.get_reader(out) as reader:
            frames = [frame for frame in reader]
        assert len(frames) == 2 * (4 + 1)  # the expert needs far more than 4 steps
        firsts[task] = frames[0].astype(int)
    assert np.abs(firsts["LavaBridge-v0"] - firsts["LavaBridgeBend-v0"]).mean() > 1  # another maze is drawn


# --- outputs that cannot be written, bad options ------------------------------------------------------
@pytest.fixture
def no_rendering(monkeypatch):
    """record_rollouts replaced by a stub that records its calls: a refusal must come before rendering."""
    calls = []
    monkeypatch.setattr("lava_bridge_mj.eval.video.record_rollouts", lambda *args, **kwargs: calls.append(args))
    return calls


@pytest.mark.parametrize("option, value, message", [
    ("--out", "config.json/clip.mp4", "config.json is a file, not a directory"),
    ("--out", "deeper/config.json/clip.mp4", "config.json is a file, not a directory"),
    ("--out", "clip.txt", "expected a file name ending in .mp4"),
    ("--out", "clip", "expected a file name ending in .mp4"),
    ("--out", "policies", "expected a file name ending in .mp4"),
    ("--out", "policies.mp4", "is a directory"),
    ("--still", "frame.txt", "expected a file name ending in .png, .jpg or .jpeg"),
    ("--still", "config.json/frame.png", "config.json is a file, not a directory"),
])
def test_video_refuses_an_output_it_cannot_write_before_rendering(tiny_run, tmp_path, capsys, no_rendering, option,
                                                                   value, message):
    from lava_bridge_mj.eval import video

    run_dir = tmp_path / "run"
    shutil.copytree(tiny_run[0], run_dir)
    (run_dir / "policies.mp4").mkdir()
    (run_dir / "deeper").mkdir()
    (run_dir / "deeper" / "config.json").write_text("{}")
    before = sorted(p.name for p in tmp_path.rglob("*"))
    argv = [str(run_dir), "--out", str(run_dir / "clip.mp4"), option, str(run_dir / value)]
    assert video.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"lava-bridge-bench video: error: {option} {run_dir / value}") and message in err
    assert len(err.strip().splitlines()) == 1
    assert no_rendering == [] and sorted(p.name for p in tmp_path.rglob("*")) == before


@pytest.mark.parametrize("argv, message", [
    (["--seed", "-1"], "expected an integer seed in [0, 4294967295], got -1"),
    (["--episodes", "0"], "--episodes must be in 1-100, got 0"),
    (["--episodes", "1000000000"], "--episodes must be in 1-100, got 1000000000"),
    (["--max-steps", "501"], "--max-steps must be in 1-500, got 501"),
])
def test_video_refuses_bad_options(tmp_path, capsys, no_rendering, argv, message):
    from lava_bridge_mj.eval import video

    with pytest.raises(SystemExit) as exit_:
        video.main(["--expert", "--out", str(tmp_path / "x.mp4"), *argv])
    assert exit_.value.code == 2 and message in capsys.readouterr().err
    assert no_rendering == [] and not list(tmp_path.iterdir())


def test_a_still_in_a_new_directory_is_written_with_the_video(tmp_path, capsys):
    from lava_bridge_mj.eval import video

    still = tmp_path / "nodir" / "last.png"
    assert video.main(["--expert", "--episodes", "1", "--max-steps", "3", "--out", str(tmp_path / "e.mp4"),
                       "--still", str(still)]) == 0
    assert imageio.imread(still).shape == (400, 960, 3) and (tmp_path / "e.mp4").stat().st_size > 0


def test_ffmpeg_failing_to_write_is_one_line_and_leaves_nothing(tmp_path, capsys):
    """A real ffmpeg that cannot write its output (here: a directory holds the temporary name): one
    line naming the video with ffmpeg's reason, exit 2, no video, no still, ffmpeg's messages not shown."""

    from lava_bridge_mj.eval import video

    out, still = tmp_path / "e.mp4", tmp_path / "e.png"
    (tmp_path / f".e.partial{os.getpid()}.mp4").mkdir()
    assert video.main(["--expert", "--episodes", "1", "--max-steps", "3", "--out", str(out), "--still", str(still)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and err.startswith(f"lava-bridge-bench video: error: cannot write {out}: ")
    assert "directory" in err.lower() and err.strip().endswith("nothing written")
    assert not out.exists() and not still.exists()


def test_an_interrupted_video_leaves_nothing(tmp_path, capsys, monkeypatch):
    from lava_bridge_mj.eval import video

    steps = []

    def interrupted_after_five_steps(obs):
        steps.append(obs)
        if len(steps) == 5:
            raise KeyboardInterrupt
        return np.zeros(2, dtype=np.float32)

    monkeypatch.setattr("lava_bridge_mj.ScriptedExpert", lambda env: type("Stub", (), {"act": staticmethod(
        interrupted_after_five_steps)})())
    assert video.main(["--expert", "--episodes", "1", "--max-steps", "20", "--out", str(tmp_path / "e.mp4")]) == 130
    assert "interrupted; nothing written" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_video_into_a_read_only_run_directory_is_one_line(tiny_run, tmp_path, capsys, no_rendering):
    from lava_bridge_mj.eval import video

    run_dir = tmp_path / "run"
    shutil.copytree(tiny_run[0], run_dir)
    with read_only(run_dir):
        assert video.main([str(run_dir)]) == 2
    assert capsys.readouterr().err == (f"lava-bridge-bench video: error: --out {run_dir / 'rollouts.mp4'}: {run_dir} "
                                       "is not a writable directory\n")
    assert no_rendering == []


def test_a_full_disk_under_ffmpeg_names_the_disk_full_reason(tmp_path, capsys):
    """ffmpeg writing into /dev/full (the temporary name points there) fails as on a full disk: the one line
    gives that reason (ENOSPC), not ffmpeg's last words ("Nothing was written into output file ...")."""
    from lava_bridge_mj.eval import video

    out = tmp_path / "e.mp4"
    (tmp_path / f".e.partial{os.getpid()}.mp4").symlink_to("/dev/full")
    assert video.main(["--expert", "--episodes", "1", "--max-steps", "3", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == f"lava-bridge-bench video: error: cannot write {out}: No space left on device; nothing written\n"
    assert list(tmp_path.iterdir()) == []


# --- a video cut short by the file size limit ---------------------------------------------------------
def test_whole_mp4_tells_a_whole_video_from_any_cut_of_it(tmp_path):
    from lava_bridge_mj.eval import video

    out = tmp_path / "whole.mp4"
    assert video.main(["--expert", "--episodes", "1", "--max-steps", "10", "--out", str(out)]) == 0
    data = out.read_bytes()
    assert video.whole_mp4(out)
    cut = tmp_path / "cut.mp4"
    for size in [*range(0, len(data), max(1, len(data) // 200)), len(data) - 1]:
        cut.write_bytes(data[:size])
        assert not video.whole_mp4(cut), f"a video cut to {size} of {len(data)} bytes passed as whole"


@pytest.mark.parametrize("short_by", [1, "most"])
def test_a_video_cut_short_by_the_file_size_limit_is_one_line_and_no_file(tmp_path, short_by):
    """`ulimit -f` with SIGXFSZ ignored: ffmpeg's writes past the limit fail, and ffmpeg used to end without
    a word, so the command printed "wrote" over a truncated file with exit 0. The limit one byte short of
    the whole video cuts its index (written last); far short, its frames."""
    import resource

    from lava_bridge_mj.eval import video

    whole = tmp_path / "whole.mp4"
    argv = ["--expert", "--episodes", "1", "--max-steps", "10"]
    assert video.main([*argv, "--out", str(whole)]) == 0
    limit = whole.stat().st_size - 1 if short_by == 1 else whole.stat().st_size // 4

    def limit_file_size():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    out = tmp_path / "clips" / "cut.mp4"
    result = subprocess.run([sys.executable, "-m", "lava_bridge_mj.eval.cli", "video", *argv, "--out", str(out)],
                            capture_output=True, text=True, preexec_fn=limit_file_size, timeout=300)
    assert result.returncode != 0 and result.stdout == "", result.stdout + result.stderr
    assert result.stderr == (f"lava-bridge-bench video: error: cannot write {out}: File too large (the file size "
                             f"limit, {limit} bytes, cut it short); nothing written\n")
    assert list(out.parent.iterdir()) == []  # neither the video nor its temporary file
