"""Training speed of the quick AuxSS batch (5 seeds, --threads 2) on an idle machine and beside one
CPU-bound process, with OpenMP's waiting threads sleeping (OMP_WAIT_POLICY=PASSIVE, the CLI's default) and with libgomp's
own default (spin, then sleep: what the CLI did before it set a policy), side by side in one run.

Each case runs `lava-bridge-bench --method auxss --seeds 0-4 --threads 2` (the main job's batch) with
updates from step 200 and an evaluation (one episode per start distribution) every 200 steps, for
`--seconds` of wall time; its speed is the steps over the training time at its last progress update
(tqdm's count and elapsed time), so start-up is left out and evaluation kept in.
The load is one Python busy loop. The target: loaded speed within 2x of idle speed.

Usage: python bench/threads_under_load.py [--seconds 45]
Run it on an otherwise idle machine: the idle cases are the baseline.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CONFIG = {"steps": 10_000_000, "eval_every": 1000, "eval_episodes": 1, "sac": {"learning_starts": 100}}
POLICIES = {"PASSIVE (CLI default)": "PASSIVE", "libgomp default": ""}
"""OMP_WAIT_POLICY per case; an empty value is not a policy libgomp knows, so it keeps its default."""
BUSY_LOOP = "while True: pass"
PROGRESS = re.compile(r"(\d+)/\d+ \[(?:(\d+):)?(\d+):(\d+)<")
"""tqdm's progress line: steps done / total [elapsed (h:)mm:ss < ..."""


def steps_per_second(progress: str) -> float:
    """Steps over elapsed seconds at the last progress update (NaN before the first one)."""
    updates = PROGRESS.findall(progress)
    if not updates:
        return float("nan")
    steps, hours, minutes, seconds = updates[-1]
    elapsed = int(hours or 0) * 3600 + int(minutes) * 60 + int(seconds)
    return int(steps) / elapsed if elapsed else float("nan")


def run_case(policy: str, loaded: bool, seconds: float, root: Path) -> float:
    out = root / f"{policy or 'default'}-{'loaded' if loaded else 'idle'}"
    config = root / "config.json"
    config.write_text(json.dumps(CONFIG))
    env = {**os.environ, "OMP_WAIT_POLICY": policy}
    env.pop("OMP_NUM_THREADS", None)
    load = subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) if loaded else None
    try:
        with open(root / "progress.txt", "w+") as progress:
            train = subprocess.Popen([sys.executable, "-m", "lava_bridge_mj.eval.cli", "--method", "auxss",
                                      "--seeds", "0-4", "--threads", "2", "--config", str(config), "--out", str(out)],
                                     env=env, stdout=subprocess.DEVNULL, stderr=progress)
            time.sleep(seconds)
            train.kill()
            train.wait()
            progress.seek(0)
            return steps_per_second(progress.read())
    finally:
        if load is not None:
            load.kill()
            load.wait()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=45.0, help="wall time per case (default: 45)")
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f}; {os.cpu_count()} CPUs")
    print(f"{'OMP_WAIT_POLICY':<24} {'idle steps/s':>12} {'loaded steps/s':>15} {'loaded / idle':>14}")
    with tempfile.TemporaryDirectory(prefix="threads-under-load-") as root:
        for name, policy in POLICIES.items():
            idle = run_case(policy, False, args.seconds, Path(root))
            loaded = run_case(policy, True, args.seconds, Path(root))
            print(f"{name:<24} {idle:>12.1f} {loaded:>15.1f} {loaded / idle:>14.2f}", flush=True)


if __name__ == "__main__":
    main()
