"""The bench/ scripts run (quick mode: tiny sizes, figures printed, nothing asserted about speed)."""

import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "bench"


@pytest.mark.parametrize("argv, expected", [
    (["env_throughput.py", "--quick"], "free-motion steps/s"),
    (["profile_training.py", "--quick"], "update: critics"),
    (["sac_throughput.py", "--quick"], "ours K=2"),
    (["single_seed_speed.py", "--quick"], "ratio this tree / 5eff605"),
    (["sweep_scaling.py", "--quick"], "local, 2 workers"),  # about 45 s, most of it process and Ray start-up
    (["threads_under_load.py", "--seconds", "6"], "PASSIVE (CLI default)"),
    (["protocol_throughput.py", "--quick", "--cases", "sweep"], "sweep (working tree)"),
    (["update_speed.py", "--quick"], "ref / this tree"),
    (["update_speed.py", "--quick", "--compiled"], "ref: this tree, torch.compile"),
    (["tracking_cost.py", "--quick"], "time in the logging calls"),
    (["memory.py", "--quick", "--ref", "HEAD"], "| LavaBridge-v0 | 1 | 50 |"),
])  # difficulty.py runs and prints its figures in test_difficulty_writes_a_table_row_per_task_with_its_command
def test_bench_script_runs_and_prints_figures(argv, expected):
    result = subprocess.run([sys.executable, str(BENCH / argv[0]), *argv[1:]], capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr
    assert expected in result.stdout


def test_difficulty_writes_a_table_row_per_task_with_its_command(tmp_path):
    out = tmp_path / "suite" / "difficulty.md"
    argv = ["--random-episodes", "3", "--expert-episodes", "2", "--rollouts", "1", "--candidate-seeds", "0",
            "--env", "LavaBridge-v0", "--env", "LavaBridgeNarrow-v0", "--out", str(out)]
    result = subprocess.run([sys.executable, str(BENCH / "difficulty.py"), *argv], capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr
    assert "random policy from p0" in result.stdout
    text = out.read_text()
    assert "python bench/difficulty.py --random-episodes 3" in text and "at commit " in text
    rows = [line for line in text.splitlines() if line.startswith("| `")]
    assert [row.split("`")[1] for row in rows] == ["LavaBridge-v0", "LavaBridgeNarrow-v0"]
    assert all(row.count("|") == 7 for row in rows)
    assert not list(out.parent.glob("*.tmp"))


@pytest.mark.parametrize("argv, message", [
    (["--env", "LavaBridge-v9"], "--env 'LavaBridge-v9' is not a task; expected one of LavaBridge-v0"),
    (["--rollouts", "0"], "--rollouts must be at least 1"),
    (["--candidate-seeds", "4-2"], "--candidate-seeds"),
    (["--sac-runs", "no-such-directory"], "--sac-runs 'no-such-directory' is not a directory"),
    (["--sac-only"], "--sac-only needs --sac-runs"),
])
def test_difficulty_refuses_bad_options_and_writes_nothing(tmp_path, argv, message):
    out = tmp_path / "difficulty.md"
    result = subprocess.run([sys.executable, str(BENCH / "difficulty.py"), *argv, "--out", str(out)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and message in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()
