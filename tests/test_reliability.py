"""Nothing lost on interruption, bad input refused: real processes killed and resumed.

Every run here is a `python -m lava_bridge_mj.eval.cli` child process with a tiny configuration, so
killed, signalled and resumed runs are compared with an uninterrupted run made the same way.
"""

import csv
import json
import os
import signal
import subprocess
import sys
import time

import pytest
import torch

TINY = {"steps": 1500, "eval_every": 250, "eval_episodes": 2, "demo_subset": 20,
        "sac": {"hidden_sizes": [16, 16], "batch_size": 32, "buffer_size": 500, "learning_starts": 100}}
KILL_AFTER_CHECKPOINTS = (1, 3)
KILL_AFTER_SECONDS = (0.5, 4.0)  # before any checkpoint (likely), and at an arbitrary moment
"""Kill-and-resume trials: the README counts them (4 SIGKILL + 1 SIGTERM + 1 SIGINT, and 1 SIGKILL of a batch)."""


@pytest.fixture(scope="module")
def config_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("config") / "tiny.json"
    path.write_text(json.dumps(TINY))
    return path


def command(config_file, out, *extra):
    return [sys.executable, "-m", "lava_bridge_mj.eval.cli", "--method", "auxss", "--config", str(config_file),
            "--out", str(out), "--no-progress", *extra]


def metrics(out):
    with open(out / "metrics.csv") as f:
        return [{k: v for k, v in row.items() if k != "wall_time"} for row in csv.DictReader(f)]


@pytest.fixture(scope="module")
def reference(config_file, tmp_path_factory):
    out = tmp_path_factory.mktemp("reference") / "run"
    subprocess.run(command(config_file, out), check=True, capture_output=True)
    rows = metrics(out)
    assert [int(r["step"]) for r in rows] == list(range(250, 1501, 250))
    return rows


def checkpoint_mtime(out):
    try:
        return os.stat(out / "checkpoint.pt").st_mtime_ns
    except FileNotFoundError:
        return None


def wait_for_checkpoints(process, out, count, timeout=120):
    seen, last = 0, None
    deadline = time.monotonic() + timeout
    while seen < count:
        assert process.poll() is None, "the run ended before it was interrupted"
        assert time.monotonic() < deadline, "no checkpoint appeared"
        mtime = checkpoint_mtime(out)
        if mtime is not None and mtime != last:
            seen, last = seen + 1, mtime
        time.sleep(0.01)


def resume_to_the_end(config_file, out):
    result = subprocess.run(command(config_file, out, "--resume"), capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("checkpoints", KILL_AFTER_CHECKPOINTS)
def test_sigkill_after_checkpoints_then_resume_matches_the_uninterrupted_run(config_file, reference, tmp_path, checkpoints):
    out = tmp_path / "run"
    process = subprocess.Popen(command(config_file, out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_for_checkpoints(process, out, checkpoints)
    process.kill()
    process.wait()
    rows_at_kill = metrics(out)  # whatever was written is complete and parseable
    assert all(len(row) == len(reference[0]) for row in rows_at_kill)
    assert rows_at_kill == reference[: len(rows_at_kill)], "rows written before the kill differ"
    resume_to_the_end(config_file, out)
    assert metrics(out) == reference
    assert not list(out.glob(".*.tmp*")), "a temporary file was left behind"


@pytest.mark.parametrize("seconds", KILL_AFTER_SECONDS)
def test_sigkill_at_an_arbitrary_moment_then_resume_matches(config_file, reference, tmp_path, seconds):
    out = tmp_path / "run"
    process = subprocess.Popen(command(config_file, out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(seconds)
    process.kill()
    process.wait()
    if (out / "metrics.csv").exists():
        assert metrics(out) == reference[: len(metrics(out))]
    resume_to_the_end(config_file, out)
    assert metrics(out) == reference


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_cleanly_with_a_checkpoint_and_resume_continues(config_file, reference, tmp_path, sig):
    out = tmp_path / "run"
    process = subprocess.Popen(command(config_file, out), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wait_for_checkpoints(process, out, 1)
    before = checkpoint_mtime(out)
    process.send_signal(sig)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + sig, stderr
    assert "after writing a checkpoint" in stderr and "--resume" in stderr
    assert checkpoint_mtime(out) != before, "the stop did not write a fresh checkpoint"
    resume_to_the_end(config_file, out)
    assert metrics(out) == reference


def test_a_second_process_cannot_write_a_run_directory_in_use(config_file, tmp_path):
    out = tmp_path / "run"
    first = subprocess.Popen(command(config_file, out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for_checkpoints(first, out, 1)
        second = subprocess.run(command(config_file, out, "--resume"), capture_output=True, text=True)
        assert second.returncode == 2
        assert "being written by another process" in second.stderr
        assert "Traceback" not in second.stderr
    finally:
        first.kill()
        first.wait()


@pytest.mark.parametrize("content, message", [
    ("{not json", "is not valid JSON"),
    ("[1, 2]", "must hold a JSON object"),
    ('{"stepz": 10}', "unknown fields ['stepz']"),
    ('{"sac": {"hidden": [8]}}', "unknown fields ['hidden']"),
    ('{"sac": {"hidden_sizes": [0]}}', "hidden_sizes must be a non-empty list of positive integers"),
    ('{"sac": {"gamma": 1.5}}', "gamma must be a number in (0, 1]"),
    ('{"strategy": {"sigmaa": 0.2}}', "unknown parameters ['sigmaa'] for start strategy 'auxss'"),
    ('{"demo_subset": 0}', "demo_subset must be an integer >= 1"),
    ('{"hybrid_fraction": 1.5}', "hybrid_fraction must be a number in [0, 1], got 1.5"),
])
def test_bad_config_files_are_refused_without_writing(tmp_path, content, message):
    config = tmp_path / "bad.json"
    config.write_text(content)
    out = tmp_path / "run"
    result = subprocess.run(command(config, out), capture_output=True, text=True)
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists()


def test_a_foreign_or_corrupt_checkpoint_is_refused_and_earlier_results_kept(config_file, reference, tmp_path):
    out = tmp_path / "run"
    subprocess.run(command(config_file, out), check=True, capture_output=True)
    (out / "checkpoint.pt").write_bytes(b"not a checkpoint")
    kept = (out / "metrics.csv").read_text()
    result = subprocess.run(command(config_file, out, "--resume"), capture_output=True, text=True)
    assert result.returncode == 2
    assert "cannot be read" in result.stderr and "Traceback" not in result.stderr
    assert (out / "metrics.csv").read_text() == kept


def test_a_checkpoint_of_an_older_format_is_refused_by_version(config_file, reference, tmp_path):
    out = tmp_path / "run"
    subprocess.run(command(config_file, out), check=True, capture_output=True)
    for name in ("checkpoint.pt", "checkpoint.prev.pt"):
        state = torch.load(out / name, weights_only=False)
        torch.save({**state, "version": 2}, out / name)
    kept = (out / "metrics.csv").read_text()
    result = subprocess.run(command(config_file, out, "--resume"), capture_output=True, text=True)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "format version 2" in result.stderr and "reads version 3" in result.stderr
    assert (out / "metrics.csv").read_text() == kept


def test_resume_with_another_configuration_is_refused(config_file, tmp_path):
    out = tmp_path / "run"
    subprocess.run(command(config_file, out), check=True, capture_output=True)
    kept = (out / "metrics.csv").read_text()
    result = subprocess.run([*command(config_file, out, "--resume"), "--seed", "7"], capture_output=True, text=True)
    assert result.returncode == 2
    assert "another configuration" in result.stderr
    assert (out / "metrics.csv").read_text() == kept


def test_overwrite_replaces_the_previous_run(config_file, reference, tmp_path):
    out = tmp_path / "run"
    subprocess.run(command(config_file, out, "--steps", "250"), check=True, capture_output=True)
    assert len(metrics(out)) == 1
    subprocess.run(command(config_file, out, "--overwrite"), check=True, capture_output=True)
    assert metrics(out) == reference


def test_a_killed_batch_resumes_and_each_seed_matches_its_single_seed_run(config_file, reference, tmp_path):
    """Seeds 0 and 1 trained together, killed after two checkpoints, resumed: seed 0's metrics equal the
    reference run of seed 0 alone (one torch thread, the CLI's default)."""
    out = tmp_path / "batch"
    batch = command(config_file, out, "--seeds", "0,1")
    process = subprocess.Popen(batch, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_for_checkpoints(process, out / "seed1", 2)
    process.kill()
    process.wait()
    result = subprocess.run([*batch, "--resume"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert metrics(out / "seed0") == reference
    assert metrics(out / "seed1") != reference
