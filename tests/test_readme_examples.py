"""The README's Python examples run as they stand and do what their text says."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def example(heading: str) -> str:
    """The first python code block under the README heading `heading`."""
    section = README.read_text().split(f"\n{heading}\n", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def run_example(heading: str, cwd: Path) -> str:
    script = cwd / "example.py"
    script.write_text(example(heading))
    done = subprocess.run([sys.executable, str(script)], cwd=cwd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def test_the_python_api_example_trains_two_seeds_into_their_directories(tmp_path):
    out = run_example("### Use it from Python", tmp_path)
    steps = re.findall(r"seed (\d): step (\d+), success from p0 ([0-9.]+)", out)
    assert [(seed, step) for seed, step, _ in steps] == [("0", "2000"), ("1", "2000")]
    actions = re.findall(r"first action from p0: \[\s*(\S+)\s+(\S+)\s*\]", out)
    assert len(actions) == 2 and all(abs(float(a)) <= 1.0 for pair in actions for a in pair)
    assert actions[0] != actions[1], "two seeds gave the same first action: one policy served both"
    for seed in (0, 1):
        rows = (tmp_path / "runs" / "api" / f"seed{seed}" / "metrics.csv").read_text().splitlines()
        assert [row.split(",")[0] for row in rows[1:]] == ["1000", "2000"]


def test_the_stable_baselines3_example_trains_through_auxss_start_states(tmp_path):
    pytest.importorskip("stable_baselines3", reason="stable-baselines3 is a test extra: pip install -e '.[test]'")
    out = run_example("### Use the start strategies with Stable-Baselines3", tmp_path)
    most, least, uniform = map(float, re.search(
        r"most likely start ([0-9.]+), least likely ([0-9.]+) \(uniform: ([0-9.]+)\)", out).groups())
    assert uniform == pytest.approx(1 / 150, abs=1e-4)  # the benchmark's 150 candidate states
    assert most > uniform > least, "AuxSS's weights never moved: SB3's episodes were not fed back"
