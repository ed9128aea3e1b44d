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
import shlex
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import zipfile

import numpy as np
import pytest
import torch

from lava_bridge_mj.eval import cli

TINY = {"steps": 1500, "eval_every": 250, "eval_episodes": 2, "demo_subset": 20,
        "sac": {"hidden_sizes": [16, 16], "batch_size": 32, "buffer_size": 500, "learning_starts": 100}}
KILL_AFTER_CHECKPOINTS = (1, 3)
KILL_AFTER_SECONDS = (0.5, 4.0)  # before any checkpoint (likely), and at an arbitrary moment
"""Kill-and-resume trials: docs/reliability.md counts them (4 SIGKILL + 1 SIGTERM + 1 SIGINT, and 1 SIGKILL of a batch).
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


def blocked_signals(pid):
    """The signals process `pid` blocks (Linux: SigBlk of /proc/PID/status)."""
    with open(f"/proc/{pid}/status") as status:
        mask = int(next(line for line in status if line.startswith("SigBlk:")).split()[1], 16)
    return {sig for sig in signal.Signals if mask >> (sig - 1) & 1}


PROGRAM = os.path.join(os.path.dirname(sys.executable), "lava-bridge-bench")  # the installed console script
START_UP_STOP = ("lava-bridge-bench: interrupted by the user (SIGINT) during start-up, before anything was written; "
                 "run the same command again to start\n")


def test_a_signal_while_the_package_loads_in_a_background_run_is_not_lost(config_file, tmp_path):
    """`lava-bridge-bench train ... &` from a script, `kill -INT` 0.3 s later: the run still loads the package
    (gymnasium, MuJoCo), before any handler of its own, and its SIGINT is inherited ignored. The signal was
    discarded and the run trained to the end; the program now blocks SIGINT until its handler is in place."""
    out = tmp_path / "run"
    script = f"{shlex.join([PROGRAM, *arguments(config_file, out)])} & P=$!; sleep 0.3; kill -INT $P; wait $P"
    result = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=300)
    assert result.returncode == 130, result.stdout + result.stderr
    assert result.stderr == START_UP_STOP and not out.exists()


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process's signal mask from /proc")
def test_a_signal_at_the_programs_first_moment_stops_it(config_file, tmp_path):
    """SIGINT, inherited ignored, as soon as the program blocks it (its first act) and before any handler of
    its own: the earliest moment a signal can be kept, whatever the machine's speed."""
    out = tmp_path / "run"
    process = subprocess.Popen([PROGRAM, *arguments(config_file, out)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    deadline = time.monotonic() + 120
    while signal.SIGINT not in blocked_signals(process.pid):
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.001)
    assert signal.SIGINT not in caught_signals(process.pid), "the handler came first: the window was missed"
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stdout + stderr
    assert stderr == START_UP_STOP and not out.exists()


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


# --- damaged checkpoints: what torch itself loads is checked, and any failure falls back -------------------
def central_directory_entry(data, name):
    """The offset of the central-directory entry of record `name` in the zip archive `data`."""
    offset = data.find(b"PK\x01\x02")
    while offset >= 0:
        name_length, extra_length, comment_length = struct.unpack_from("<HHH", data, offset + 28)
        if data[offset + 46:offset + 46 + name_length].decode() == name:
            return offset
        offset = data.find(b"PK\x01\x02", offset + 46 + name_length + extra_length + comment_length)
    raise KeyError(name)


def flip(path, offset, mask):
    data = bytearray(path.read_bytes())
    data[offset] ^= mask
    path.write_bytes(bytes(data))


def flip_attributes_of_a_tensor_record(path):
    """Bit 0x10 of the external attributes (offset 38) of record archive/data/15's central-directory entry:
    torch's zip reader then leaves that tensor's memory unfilled, and every record's CRC still holds."""
    flip(path, central_directory_entry(path.read_bytes(), "archive/data/15") + 38, 0x10)


def flip_compression_method(path, mask=0x01):
    """A bit of the first central-directory entry's compression method (offset 10): stored (0) becomes
    1, which no reader supports (NotImplementedError), or 8, deflate, which fails to inflate (zlib.error)."""
    flip(path, path.read_bytes().find(b"PK\x01\x02") + 10, mask)


def test_a_tensor_torch_leaves_unfilled_is_caught_by_the_content_digest(reference_run, tmp_path):
    from lava_bridge_mj.eval.training.run_files import DamagedFileError, load_torch

    path = shutil.copy(reference_run / "checkpoint.pt", tmp_path / "checkpoint.pt")
    load_torch(path)  # intact: its digest matches
    flip_attributes_of_a_tensor_record(path)
    with zipfile.ZipFile(path) as archive:
        assert archive.testzip() is None, "the flip is one no CRC sees"
    with pytest.raises(DamagedFileError, match="checkpoint.pt is damaged: what torch loaded from it differs"):
        load_torch(path)


@pytest.mark.parametrize("mask, raised_by_zipfile", [(0x01, "NotImplementedError"), (0x08, "zlib.error")])
def test_a_checkpoint_that_fails_to_decompress_is_damaged_not_a_crash(reference_run, tmp_path, mask, raised_by_zipfile):
    from lava_bridge_mj.eval.training.run_files import DamagedFileError, load_torch

    path = shutil.copy(reference_run / "checkpoint.pt", tmp_path / "checkpoint.pt")
    flip_compression_method(path, mask)
    with pytest.raises(DamagedFileError, match=f"damaged or not a torch file \\({raised_by_zipfile}: "):
        load_torch(path)


@pytest.mark.parametrize("damage", [flip_attributes_of_a_tensor_record, flip_compression_method])
def test_a_resume_falls_back_from_a_checkpoint_damaged_anywhere(config_file, reference, reference_run, tmp_path,
                                                                capsys, damage):
    """The red team's two flips of checkpoint.pt of a finished run: the resume warns, sets the file aside
    and continues from checkpoint.prev.pt (step 1250) to the uninterrupted run's end."""
    out = copy_of(reference_run, tmp_path)
    damage(out / "checkpoint.pt")
    assert exit_code_in_process(arguments(config_file, out, "--resume")) == 0
    stderr = capsys.readouterr().err
    assert stderr.count("warning:") == 1 and "checkpoint.pt is damaged" in stderr, stderr
    assert (out / "checkpoint.pt.damaged").exists()
    assert metrics(out) == reference


def test_both_checkpoints_failing_to_load_is_one_line_and_changes_nothing(config_file, reference_run, tmp_path):
    out = copy_of(reference_run, tmp_path)
    for name in ("checkpoint.pt", "checkpoint.prev.pt"):
        flip_compression_method(out / name)
    files = lambda: {p.name: p.read_bytes() for p in out.iterdir() if p.is_file() and p.name != ".lock"}  # noqa: E731
    before = files()
    result = subprocess.run(command(config_file, out, "--resume", "--steps", "1750"), capture_output=True, text=True)
    assert result.returncode == 2, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert "every checkpoint of" in result.stderr and "NotImplementedError" in result.stderr
    assert files() == before


# --- what killed writers leave behind --------------------------------------------------------------------
def a_dead_pid():
    """The pid of a process that has exited (and been reaped)."""
    process = subprocess.Popen([sys.executable, "-c", ""])
    process.wait()
    return process.pid


LEFTOVERS = (".checkpoint.pt.tmp{pid}", ".metrics.csv.tmp{pid}", "policies/.step_250.pt.tmp{pid}",
             ".final.pt.tmp{pid}", ".checkpoint.prev.pt.link{pid}")


@pytest.mark.parametrize("option", ["--resume", "--overwrite"])
def test_resume_and_overwrite_remove_the_temporary_files_of_killed_writers(config_file, reference_run, tmp_path,
                                                                           option):
    """Files a killed writer left (its pid gone) are removed; one of a live process stays."""
    out = copy_of(reference_run, tmp_path)
    stale = [out / name.format(pid=a_dead_pid()) for name in LEFTOVERS]
    writer = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    live = out / f".checkpoint.pt.tmp{writer.pid}"
    try:
        for path in (*stale, live):
            path.write_bytes(b"partial")
        steps = ("--steps", "250") if option == "--overwrite" else ()
        assert exit_code_in_process(arguments(config_file, out, option, *steps)) == 0
        assert [path.name for path in stale if path.exists()] == []
        assert live.exists()
    finally:
        writer.kill()
        writer.wait()


class Killed(BaseException):
    """Stands in for SIGKILL at one moment: nothing after it runs (no except clause catches it)."""


def test_a_kill_between_rotating_and_writing_a_checkpoint_leaves_a_real_fallback(config_file, reference, tmp_path,
                                                                                monkeypatch):
    """Killed as the third checkpoint (step 750) is about to take its name: checkpoint.prev.pt holds step
    500 and is not a second name of checkpoint.pt (a kill there once left one file under both names, and
    step 250 lost); the resume continues from step 500 to the uninterrupted run's end."""
    from lava_bridge_mj.eval.training.run_files import checkpoint_step

    out = tmp_path / "run"
    replace, writes = os.replace, []

    def killed_at_the_third_checkpoint(source, target):
        if os.path.basename(target) == "checkpoint.pt" and os.path.basename(source).startswith(".checkpoint.pt.tmp"):
            writes.append(target)
            if len(writes) == 3:
                raise Killed
        replace(source, target)

    monkeypatch.setattr(os, "replace", killed_at_the_third_checkpoint)
    with pytest.raises(Killed):
        exit_code_in_process(arguments(config_file, out))
    monkeypatch.setattr(os, "replace", replace)
    latest, previous = out / "checkpoint.pt", out / "checkpoint.prev.pt"
    assert not (latest.exists() and os.path.samefile(latest, previous))
    assert torch.load(previous, weights_only=False)["step"] == 500
    assert checkpoint_step(out) == 500  # what a sweep resumes this run from
    resume_to_the_end(config_file, out)
    assert metrics(out) == reference


def running_process(pid):
    """Whether process `pid` runs (a zombie no one has reaped yet does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="tells a running process by /proc")
def test_the_result_folder_of_a_killed_sweep_is_removed_by_the_next(config_file, tmp_path, monkeypatch):
    """SIGKILL of a sweep's own process leaves its folder of job results in the temporary directory; the
    next sweep removes it, and leaves the folder of a sweep still running (this process) alone."""
    from lava_bridge_mj.eval.sweeps import sweep_jobs

    temp = tmp_path / "tmp"
    temp.mkdir()
    argv = [sys.executable, "-m", "lava_bridge_mj.eval.sweeps.sweep", "--methods", "sac", "--seeds", "0", "--steps", "1500",
            "--config", str(config_file), "--out", str(tmp_path / "out"), "--workers", "1"]
    sweep = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                             env={**os.environ, "TMPDIR": str(temp)})
    started = next(line for line in sweep.stdout if "(pid " in line)
    job = int(started.rsplit("(pid ", 1)[1].rstrip(")\n"))
    sweep.kill()
    sweep.communicate(timeout=60)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and running_process(job):  # it stops with its sweep
        time.sleep(0.05)
    left = [folder.name for folder in temp.iterdir()]
    assert len(left) == 1 and left[0].startswith(f"lava-bridge-sweep-{sweep.pid}-"), left
    running = temp / f"lava-bridge-sweep-{os.getpid()}-x"
    running.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    sweep_jobs.run_local([], None, workers=1)
    assert [folder.name for folder in temp.iterdir()] == [running.name]


# --- metrics.csv is verified where it is read --------------------------------------------------------------
def test_a_changed_metrics_csv_is_refused_by_the_reports_in_one_line(reference_run, tmp_path, capsys):
    """The red team's edit: an evaluation's success_p0 raised from 0.0 to 0.9. report and summary refuse
    it naming the file, export refuses to copy it; the run as written, and one without a checksum file
    (written before checksums were kept, as the committed results/), read as before."""
    from lava_bridge_mj.eval.analysis import summary

    out = copy_of(reference_run, tmp_path)
    assert summary.main([str(out)]) == 0
    lines = (out / "metrics.csv").read_text().splitlines()
    column, row = lines[0].split(",").index("success_p0"), lines[2].split(",")
    assert row[0] == "500" and row[column] == "0.0"
    row[column] = "0.9"
    (out / "metrics.csv").write_text("\n".join([*lines[:2], ",".join(row), *lines[3:]]) + "\n")
    capsys.readouterr()
    for argv in (["report", str(out), "--out", str(tmp_path / "report")], ["summary", str(out)]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
        assert f"{out / 'metrics.csv'} does not match its checksum in metrics.csv.sha256" in err
    assert not (tmp_path / "report").exists()
    runs = tmp_path / "runs"
    shutil.copytree(out, runs / "auxss" / "seed0")
    assert cli.main(["export", str(runs), str(tmp_path / "results")]) == 1
    assert "auxss/seed0: " in capsys.readouterr().out and not (tmp_path / "results" / "auxss").exists()
    (out / "metrics.csv.sha256").unlink()  # a run written before checksums: unverified, read as it is
    assert summary.main([str(out)]) == 0


def test_a_kill_between_the_checksum_and_the_metrics_write_leaves_a_file_that_verifies(tmp_path, monkeypatch):
    """The checksum file goes first and lists the version it replaces too: a kill before metrics.csv is
    replaced leaves the earlier, whole metrics.csv, which still verifies; a changed one never does."""
    from lava_bridge_mj.eval.training import checksums

    path = tmp_path / "metrics.csv"
    checksums.write_checked(path, b"step\n250\n")
    write = checksums.atomic_write

    def killed_before_the_file(target, *args, **kwargs):
        if target == path:
            raise Killed
        write(target, *args, **kwargs)

    monkeypatch.setattr(checksums, "atomic_write", killed_before_the_file)
    with pytest.raises(Killed):
        checksums.write_checked(path, b"step\n250\n500\n")
    monkeypatch.setattr(checksums, "atomic_write", write)
    assert checksums.read_checked(path) == b"step\n250\n"
    checksums.write_checked(path, b"step\n250\n500\n")
    assert checksums.read_checked(path) == b"step\n250\n500\n"
    path.write_bytes(b"step\n250\n750\n")
    with pytest.raises(checksums.DamagedFileError, match="metrics.csv does not match its checksum"):
        checksums.read_checked(path)


# --- messages ---------------------------------------------------------------------------------------------
def test_a_run_directory_refused_in_python_names_the_keywords_that_continue_it(reference_run, tmp_path):
    from lava_bridge_mj.eval.training.config import RunConfig
    from lava_bridge_mj.eval.training.run_files import RunDirectoryError
    from lava_bridge_mj.eval.training.runner import train

    out = copy_of(reference_run, tmp_path)
    with pytest.raises(RunDirectoryError, match=r"already holds a run .*resume=True.*overwrite=True"):
        train(RunConfig.from_dict({**TINY, "method": "auxss"}), out, progress=False)


def test_a_full_disk_at_the_first_write_names_the_lock_file(config_file, tmp_path):
    """A file-size limit of one byte (EFBIG, as a full disk gives ENOSPC) fails the run's first write, its pid
    into .lock: one line naming that file."""
    import resource

    out = tmp_path / "run"
    result = subprocess.run(command(config_file, out), capture_output=True, text=True,
                            preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (1, 1)))
    assert result.returncode == 1, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert f"cannot write {out / '.lock'}: File too large" in result.stderr
    assert [p.name for p in out.iterdir()] == [".lock"]


@pytest.mark.parametrize("option", ["--resume", "--overwrite"])
def test_a_checkpoint_that_is_a_directory_is_named_as_one(config_file, reference_run, tmp_path, capsys, option):
    out = copy_of(reference_run, tmp_path)
    (out / "checkpoint.pt").unlink()
    (out / "checkpoint.pt").mkdir()
    kept = (out / "metrics.csv").read_text()
    assert exit_code_in_process(arguments(config_file, out, option)) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "cannot write" not in err
    assert f"{out / 'checkpoint.pt'} is a directory" in err
    assert (out / "checkpoint.pt").is_dir() and (out / "metrics.csv").read_text() == kept
