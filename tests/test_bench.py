"""The bench/ scripts run (quick mode: tiny sizes, figures printed, nothing asserted about speed)."""

import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "bench"


@pytest.mark.parametrize("argv, expected", [
    (["env_throughput.py", "--quick"], "mj_step"),
    (["sac_throughput.py", "--quick"], "ours K=2"),
    (["single_seed_speed.py", "--quick"], "ratio this tree / 5eff605"),
    (["sweep_scaling.py", "--quick"], "local, 2 workers"),  # about 45 s, most of it process and Ray start-up
    (["threads_under_load.py", "--seconds", "6"], "PASSIVE (CLI default)"),
    (["difficulty.py", "--random-episodes", "5", "--expert-episodes", "2", "--rollouts", "2"], "random"),
])
def test_bench_script_runs_and_prints_figures(argv, expected):
    result = subprocess.run([sys.executable, str(BENCH / argv[0]), *argv[1:]], capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr
    assert expected in result.stdout
