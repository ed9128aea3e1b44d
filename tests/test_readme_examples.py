"""The Python examples of the README and the documentation pages run as they stand and do what their text says."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import lava_bridge_mj

ROOT = Path(__file__).resolve().parents[1]


def example(page: str, heading: str) -> str:
    """The first python code block under the heading line `heading` of the markdown file `page`."""
    section = (ROOT / page).read_text().split(f"\n{heading}\n", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def run_example(page: str, heading: str, cwd: Path) -> str:
    script = cwd / "example.py"
    script.write_text(example(page, heading))
    done = subprocess.run([sys.executable, str(script)], cwd=cwd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def numbers(text: str) -> np.ndarray:
    return np.array([float(x) for x in text.split()])


def test_the_readmes_example_resets_to_a_state_starts_from_auxss_and_trains(tmp_path):
    out = run_example("README.md", "## Use it from Python", tmp_path)
    # the reset to a given state returns exactly that state
    assert np.array_equal(numbers(re.search(r"^reset to \[(.*?)\]$", out, re.M | re.S)[1]), [-1.0, 0.0, 0.4, 0.0])
    # the wrapper's reset starts from the demo state AuxSS drew, the one its info names
    index, count, state = re.search(r"^reset to state (\d+) of (\d+): \[(.*?)\]$", out, re.M | re.S).groups()
    candidates = lava_bridge_mj.load_demos(500)["observations"][::10]
    assert int(count) == len(candidates) and 0 <= int(index) < len(candidates)
    np.testing.assert_allclose(numbers(state), candidates[int(index)], atol=1e-6)
    # and training wrote a run whose evaluations the example printed
    printed = re.search(r"^success from p0 at each evaluation: \[(.*)\]$", out, re.M)[1]
    rows = (tmp_path / "runs" / "readme" / "metrics.csv").read_text().splitlines()
    assert [row.split(",")[0] for row in rows[1:]] == ["500", "1000"]
    assert len(printed.split(",")) == 2 and all(0.0 <= float(p) <= 1.0 for p in printed.split(","))


def test_the_python_api_example_trains_two_seeds_into_their_directories(tmp_path):
    out = run_example("docs/training.md", "## Use it from Python", tmp_path)
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
    out = run_example("docs/start-strategies.md", "## Use the start strategies with Stable-Baselines3", tmp_path)
    most, least, uniform = map(float, re.search(
        r"most likely start ([0-9.]+), least likely ([0-9.]+) \(uniform: ([0-9.]+)\)", out).groups())
    assert uniform == pytest.approx(1 / 150, abs=1e-4)  # the benchmark's 150 candidate states
    assert most > uniform > least, "AuxSS's weights never moved: SB3's episodes were not fed back"


def test_the_start_strategies_example_runs_them_on_hopper_states(tmp_path):
    out = run_example("docs/start-strategies.md", "## On a task of any kind", tmp_path)
    weights = dict(re.findall(r"^(\w+): 58-D states, weights from ([0-9.]+) to 1\.000$", out, re.M))
    assert set(weights) == {"auxss", "goaldist_ss"}, out
    # AuxSS's weights moved below 1 where the short random-policy episodes started; GoalDist-SS's
    # weights fall away from the state furthest forward
    assert 0.0 < float(weights["auxss"]) < 1.0 and 0.0 < float(weights["goaldist_ss"]) < 1.0


def test_the_any_env_example_records_hopper_demos_and_trains_auxss_on_them(tmp_path):
    code = example("docs/any-env.md", "## From `gymnasium.make` to AuxSS")
    assert len(code.strip().splitlines()) < 20
    small = {"n_transitions=2000": "n_transitions=200", "steps=20_000": "steps=300",
             "eval_every=5_000": "eval_every=150", "eval_episodes=10": "eval_episodes=2"}
    for number, smaller in small.items():
        assert number in code
        code = code.replace(number, smaller)
    (tmp_path / "example.py").write_text(code)
    done = subprocess.run([sys.executable, "example.py"], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    printed = re.findall(r"^step (\d+): return from p0 (\S+)$", done.stdout, re.M)
    assert [step for step, _ in printed] == ["150", "300"] and all(float(r) > 0 for _, r in printed)
    demos = lava_bridge_mj.load_demos(path=tmp_path / "hopper_demos.npz")
    assert demos["env_id"] == "Hopper-v5" and len(demos["states"]) == 200
    for seed in (0, 1):
        run = tmp_path / "runs" / "hopper" / f"seed{seed}"
        config = json.loads((run / "config.json").read_text())
        assert config["env_id"] == "Hopper-v5" and config["demos"] == str(tmp_path / "hopper_demos.npz")
        assert [row.split(",")[0] for row in (run / "metrics.csv").read_text().splitlines()[1:]] == ["150", "300"]
