"""Nothing lost on interruption, bad input refused: real processes killed and resumed.

Every run that is killed or signalled is a `python -m lava_bridge_mj.eval.cli` child process with a
tiny configuration, compared with an uninterrupted run made the same way; that run is made once
(`reference_run`) and tests that damage a finished run work on a copy of it. Where a trial interrupts a
run several times, each resume that is interrupted in turn is a real process too, and the run goes on
from where the one before stopped. Everything else (the last resume to the end, runs that are not
interrupted, commands refused before training starts) takes the child's code path through `cli.main`
in this process, without a child's torch start-up.
"""

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import torch

from lava_bridge_mj.eval import cli

TINY = {"steps": 1500, "eval_every": 250, "eval_episodes": 2, "demo_subset": 20,
        "sac": {"hidden_sizes": [16, 16], "batch_size": 32, "buffer_size": 500, "learning_starts": 100}}
KILL_AFTER_CHECKPOINTS = (1, 3)
KILL_AFTER_SECONDS = (0.5, 4.0)  # before any checkpoint (likely), and at an arbitrary moment
"""Kill-and-resume trials: the README counts them (4 SIGKILL + 1 SIGTERM + 1 SIGINT, and 1 SIGKILL of a batch).
Each tuple is one run, interrupted at each moment in turn: the first by the run's own process, the next
by the real process that resumed it."""


@pytest.fixture(scope="module")
def config_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("config") / "tiny.json"
    path.write_text(json.dumps(TINY))
    return path


def arguments(config_file, out, *extra):
    return ["--method", "auxss", "--config", str(config_file), "--out", str(out), "--no-progress", *extra]


def command(config_file, out, *extra):
    return [sys.executable, "-m", "lava_bridge_mj.eval.cli", *arguments(config_file, out, *extra)]


def exit_code_in_process(argv):
    """The exit code of `python -m lava_bridge_mj.eval.cli ARGV`, run in this process."""
    try:
        return cli.main(argv)
    except SystemExit as exit_:  # argparse's usage errors
        return exit_.code


def metrics(out):
    with open(out / "metrics.csv") as f:
        return [{k: v for k, v in row.items() if k != "wall_time"} for row in csv.DictReader(f)]


@pytest.fixture(scope="module")
def reference_run(config_file, tmp_path_factory):
    """The uninterrupted run of the tiny configuration: tests only read it, or copy it (`copy_of`)."""
    out = tmp_path_factory.mktemp("reference") / "run"
    subprocess.run(command(config_file, out), check=True, capture_output=True)
    return out


@pytest.fixture(scope="module")
def reference(reference_run):
    rows = metrics(reference_run)
    assert [int(r["step"]) for r in rows] == list(range(250, 1501, 250))
    return rows


def copy_of(run, tmp_path):
    return shutil.copytree(run, tmp_path / "run", ignore=shutil.ignore_patterns(".lock"))


def checkpoint_mtime(out):
    try:
        return os.stat(out / "checkpoint.pt").st_mtime_ns
    except FileNotFoundError:
        return None


def wait_for_checkpoints(process, out, count, timeout=120):
    """Wait until `process` has written `count` checkpoints after this call."""
    seen, last = 0, checkpoint_mtime(out)
    deadline = time.monotonic() + timeout
    while seen < count:
        assert process.poll() is None, "the run ended before it was interrupted"
        assert time.monotonic() < deadline, "no checkpoint appeared"
        mtime = checkpoint_mtime(out)
        if mtime is not None and mtime != last:
            seen, last = seen + 1, mtime
        time.sleep(0.01)


def resume_to_the_end(config_file, out, *extra):
    """`--resume` to the end, in this process: what a child would do after its torch start-up."""
    assert exit_code_in_process(arguments(config_file, out, "--resume", *extra)) == 0


def resumed_or_new(config_file, out, trial, *extra):
    """The command of a run's `trial`-th process: the first starts it, each later one resumes it."""
    return command(config_file, out, *(("--resume",) if trial else ()), *extra)


def test_sigkill_after_checkpoints_then_resume_matches_the_uninterrupted_run(config_file, reference, tmp_path):
    """Killed after its first checkpoint; the resuming process killed when the run has written its third."""
    out = tmp_path / "run"
    written = 0
    for trial, checkpoints in enumerate(KILL_AFTER_CHECKPOINTS):
        process = subprocess.Popen(resumed_or_new(config_file, out, trial), stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL)
        wait_for_checkpoints(process, out, checkpoints - written)
        process.kill()
        process.wait()
        written = checkpoints
        rows_at_kill = metrics(out)  # whatever was written is complete and parseable
        assert all(len(row) == len(reference[0]) for row in rows_at_kill)
        assert rows_at_kill == reference[: len(rows_at_kill)], f"rows written before kill {trial + 1} differ"
    resume_to_the_end(config_file, out)
    assert metrics(out) == reference
    assert not list(out.glob(".*.tmp*")), "a temporary file was left behind"


def test_sigkill_at_an_arbitrary_moment_then_resume_matches(config_file, reference, tmp_path):
    """Killed 0.5 s after its process started; the resuming process killed 4 s after it started."""
    out = tmp_path / "run"
    for trial, seconds in enumerate(KILL_AFTER_SECONDS):
        process = subprocess.Popen(resumed_or_new(config_file, out, trial), stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL)
        time.sleep(seconds)
        process.kill()
        process.wait()
        if (out / "metrics.csv").exists():
            assert metrics(out) == reference[: len(metrics(out))]
    resume_to_the_end(config_file, out)
    assert metrics(out) == reference


def test_a_signal_stops_cleanly_with_a_checkpoint_and_resume_continues(config_file, reference, tmp_path):
    """SIGTERM after the run's first checkpoint; SIGINT to the resuming process after its first."""
    out = tmp_path / "run"
    for trial, sig in enumerate((signal.SIGTERM, signal.SIGINT)):
        process = subprocess.Popen(resumed_or_new(config_file, out, trial), stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE, text=True)
        wait_for_checkpoints(process, out, 1)
        before = checkpoint_mtime(out)
        process.send_signal(sig)
        _, stderr = process.communicate(timeout=60)
        assert process.returncode == 128 + sig, stderr
        reason = "interrupted by the user (SIGINT)" if sig == signal.SIGINT else "stopped by SIGTERM"
        assert f"lava-bridge-bench: {reason} at step " in stderr, stderr
        assert "after writing a checkpoint" in stderr and "--resume" in stderr
        assert checkpoint_mtime(out) != before, f"the stop by {sig.name} did not write a fresh checkpoint"
    resume_to_the_end(config_file, out)
    assert metrics(out) == reference


def caught_signals(pid):
    """The signals process `pid` has handlers for (Linux: SigCgt of /proc/PID/status)."""
    with open(f"/proc/{pid}/status") as status:
        mask = int(next(line for line in status if line.startswith("SigCgt:")).split()[1], 16)
    return {sig for sig in signal.Signals if mask >> (sig - 1) & 1}


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process's signal handlers from /proc")
@pytest.mark.parametrize("inherited", ["ignored", "default"])
def test_a_signal_during_start_up_stops_the_run_in_one_line(config_file, tmp_path, inherited):
    """SIGINT while the command still loads (here: as soon as it has its handlers, before torch). Launched
    in the background from a script, it inherits SIGINT ignored, and the signal used to be lost: it
    trained to the end with exit 0. From a terminal, a Ctrl-C in its first seconds printed a traceback."""
    out = tmp_path / "run"
    ignore = (lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) if inherited == "ignored" else None
    process = subprocess.Popen(command(config_file, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, preexec_fn=ignore)
    deadline = time.monotonic() + 120
    while {signal.SIGINT, signal.SIGTERM} - caught_signals(process.pid):
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.005)
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stdout + stderr
    assert stderr == ("lava-bridge-bench: interrupted by the user (SIGINT) during start-up, before anything was "
                      "written; run the same command again to start\n")
    assert not out.exists()


def test_a_second_process_cannot_write_a_run_directory_in_use(config_file, tmp_path, capsys):
    out = tmp_path / "run"
    first = subprocess.Popen(command(config_file, out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for_checkpoints(first, out, 1)
        assert exit_code_in_process(arguments(config_file, out, "--resume")) == 2  # this process is the second
        stderr = capsys.readouterr().err
        assert "being written by another process" in stderr
        assert "Traceback" not in stderr
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
def test_bad_config_files_are_refused_without_writing(tmp_path, capsys, content, message):
    config = tmp_path / "bad.json"
    config.write_text(content)
    out = tmp_path / "run"
    assert exit_code_in_process(arguments(config, out)) == 2
    stderr = capsys.readouterr().err
    assert message in stderr
    assert "Traceback" not in stderr
    assert not out.exists()


def test_a_corrupt_checkpoint_falls_back_and_two_are_refused_keeping_earlier_results(config_file, reference, tmp_path,
                                                                                      capsys):
    out = tmp_path / "run"
    assert exit_code_in_process(arguments(config_file, out, "--steps", "1000")) == 0
    (out / "checkpoint.pt").write_bytes(b"not a checkpoint")
    capsys.readouterr()
    assert exit_code_in_process(arguments(config_file, out, "--resume")) == 0
    stderr = capsys.readouterr().err
    assert "warning:" in stderr and "checkpoint.pt is damaged or not a torch file" in stderr
    assert metrics(out) == reference
    for name in ("checkpoint.pt", "checkpoint.prev.pt"):
        (out / name).write_bytes(b"not a checkpoint")
    kept = (out / "metrics.csv").read_text()
    result = subprocess.run(command(config_file, out, "--resume", "--steps", "1750"), capture_output=True, text=True)
    assert result.returncode == 2  # a real process: its whole stderr is this one line
    assert "every checkpoint of" in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert (out / "metrics.csv").read_text() == kept


def test_a_checkpoint_of_an_older_format_is_refused_by_version(config_file, reference_run, tmp_path, capsys):
    out = copy_of(reference_run, tmp_path)
    for name in ("checkpoint.pt", "checkpoint.prev.pt"):
        state = torch.load(out / name, weights_only=False)
        torch.save({**state, "version": 2}, out / name)
    kept = (out / "metrics.csv").read_text()
    assert exit_code_in_process(arguments(config_file, out, "--resume")) == 2
    stderr = capsys.readouterr().err
    assert "Traceback" not in stderr
    assert "format version 2" in stderr and "reads version 3" in stderr
    assert (out / "metrics.csv").read_text() == kept


def test_resume_with_another_configuration_is_refused(config_file, reference_run, tmp_path, capsys):
    out = copy_of(reference_run, tmp_path)
    kept = (out / "metrics.csv").read_text()
    assert exit_code_in_process([*arguments(config_file, out, "--resume"), "--seed", "7"]) == 2
    assert "another configuration" in capsys.readouterr().err
    assert (out / "metrics.csv").read_text() == kept


def test_overwrite_replaces_the_previous_run(config_file, reference_run, reference, tmp_path):
    """The finished reference run replaced by a 250-step run: only the new run's row is left (a resume
    would refuse the shorter run, an append would keep the old rows)."""
    out = copy_of(reference_run, tmp_path)
    assert len(metrics(out)) == len(reference) > 1
    assert exit_code_in_process(arguments(config_file, out, "--steps", "250", "--overwrite")) == 0
    assert metrics(out) == reference[:1]


def test_a_killed_batch_resumes_and_each_seed_matches_its_single_seed_run(config_file, reference, tmp_path):
    """Seeds 0 and 1 trained together, killed after two checkpoints, resumed: seed 0's metrics equal the
    reference run of seed 0 alone (one torch thread, the CLI's default)."""
    out = tmp_path / "batch"
    batch = command(config_file, out, "--seeds", "0,1")
    process = subprocess.Popen(batch, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_for_checkpoints(process, out / "seed1", 2)
    process.kill()
    process.wait()
    assert exit_code_in_process(arguments(config_file, out, "--seeds", "0,1", "--resume")) == 0
    assert metrics(out / "seed0") == reference
    assert metrics(out / "seed1") != reference


def wait_for(predicate, process, what, timeout=120):
    """Poll every millisecond until `predicate()`; the process must still be running."""
    deadline = time.monotonic() + timeout
    while not predicate():
        assert process.poll() is None, f"the run ended before {what}"
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.001)


def test_a_stop_before_the_first_evaluation_resumes(config_file, reference, tmp_path):
    """Ctrl-C before the first evaluation writes a checkpoint with no evaluation rows; --resume must
    continue from it (it failed reshaping the empty weight history) and match the uninterrupted run."""
    out = tmp_path / "run"
    process = subprocess.Popen(command(config_file, out, "--eval-every", "1500"), stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
    wait_for(lambda: (out / "provenance.json").exists(), process, "training started")
    time.sleep(1.0)  # inside the loop, far from its only evaluation at the last step
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + signal.SIGINT, stderr
    assert not (out / "metrics.csv").exists(), "the stop came after the first evaluation: the trial tests nothing"
    assert torch.load(out / "checkpoint.pt", weights_only=False)["step"] > 0
    assert f"--out {out}" in stderr and "--resume" in stderr
    resume_to_the_end(config_file, out, "--eval-every", "1500")
    full = tmp_path / "full"
    assert exit_code_in_process(arguments(config_file, full, "--eval-every", "1500")) == 0
    assert metrics(out) == metrics(full)
    assert (out / "checkpoint.pt").read_bytes() != b""


def provenance_mtime(out):
    try:
        return os.stat(out / "provenance.json").st_mtime_ns
    except FileNotFoundError:
        return None


def test_signals_at_seeded_random_moments_then_resume_match(config_file, reference, tmp_path):
    """SIGINT or SIGTERM at random moments of a run (a seeded draw over its whole length, training and
    evaluation alike): each stops with a checkpoint, the next moment falls in the process that resumed
    it, and the run resumed to its end equals the uninterrupted one."""
    moments = np.sort(np.random.default_rng(17).uniform(0.0, 4.0, size=3))  # seconds of training
    out = tmp_path / "run"
    for trial, delay in enumerate(np.diff(moments, prepend=0.0)):
        session = provenance_mtime(out)  # each process that trains records its session when it starts
        process = subprocess.Popen(resumed_or_new(config_file, out, trial), stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE, text=True)
        wait_for(lambda: provenance_mtime(out) != session, process, "training started")
        time.sleep(delay)
        process.send_signal((signal.SIGINT, signal.SIGTERM)[trial % 2])
        _, stderr = process.communicate(timeout=60)
        assert process.returncode in (0, 128 + signal.SIGINT, 128 + signal.SIGTERM), stderr
        assert "Traceback" not in stderr
        if process.returncode == 0:  # the run ended before this moment: so do the later ones
            break
    resume_to_the_end(config_file, out)
    assert metrics(out) == reference, f"stopped {', '.join(f'{m:.2f}' for m in moments)} s into training"


BATCH = {**TINY, "steps": 750, "eval_episodes": 10}


@pytest.fixture(scope="module")
def batch_config(tmp_path_factory):
    path = tmp_path_factory.mktemp("batch-config") / "batch.json"
    path.write_text(json.dumps(BATCH))
    return path


@pytest.fixture(scope="module")
def batch_reference(batch_config, tmp_path_factory):
    out = tmp_path_factory.mktemp("batch-reference")
    assert exit_code_in_process(arguments(batch_config, out, "--seeds", "0,1")) == 0
    return [metrics(out / f"seed{s}") for s in (0, 1)]


@pytest.mark.parametrize("moment", ["during an evaluation", "during the final write"])
def test_sigkill_of_a_batch_at_a_critical_moment_then_resume_matches(batch_config, batch_reference, tmp_path, moment):
    """Killed while seed 1 is evaluated (seed 0's snapshot of that evaluation is written, seed 1's not
    yet), or between the two seeds' final.pt: the resumed batch equals the uninterrupted one."""
    for attempt in range(3):  # the moment between the seeds' final writes lasts milliseconds: try again if missed
        out = tmp_path / f"batch{attempt}"
        batch = command(batch_config, out, "--seeds", "0,1")
        process = subprocess.Popen(batch, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        first, second = ((out / f"seed{s}" / "policies" / "step_500.pt") for s in (0, 1)) \
            if moment == "during an evaluation" else ((out / f"seed{s}" / "final.pt") for s in (0, 1))
        wait_for(first.exists, process, moment)
        process.kill()
        process.wait()
        if not second.exists():
            break
    assert not second.exists(), f"the kill came too late to be {moment}, three times"
    assert exit_code_in_process(arguments(batch_config, out, "--seeds", "0,1", "--resume")) == 0
    assert [metrics(out / f"seed{s}") for s in (0, 1)] == batch_reference
    assert all((out / f"seed{s}" / "final.pt").exists() for s in (0, 1))


def test_a_write_that_fails_mid_run_is_one_line_and_loses_nothing(config_file, reference, tmp_path):
    """A full disk, stood in for by a file-size limit (RLIMIT_FSIZE: writes past it fail with EFBIG,
    as a full disk fails with ENOSPC): the first checkpoint (about 70 kB) fits, the second (about
    87 kB) does not. One line names the file and how to continue; the files already written stay
    intact, and the resume reaches the uninterrupted run."""
    import resource

    out = tmp_path / "run"

    def limit_file_size():
        resource.setrlimit(resource.RLIMIT_FSIZE, (80_000, 80_000))

    result = subprocess.run(command(config_file, out), capture_output=True, text=True, preexec_fn=limit_file_size)
    assert result.returncode == 1, result.stderr
    assert "Traceback" not in result.stderr and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert f"cannot write {out / 'checkpoint.pt'}: File too large" in result.stderr
    assert f"--out {out}" in result.stderr and "--resume" in result.stderr
    assert torch.load(out / "checkpoint.pt", weights_only=False)["step"] == 250
    assert not list(out.glob(".*.tmp*")), "a temporary file was left behind"
    assert metrics(out) == reference[: len(metrics(out))]
    resume_to_the_end(config_file, out)
    assert metrics(out) == reference
