"""Sweep scaling: the wall time of one small sweep run with 1 local worker, 2 local workers and Ray on
a local cluster of 2 CPUs, side by side in one run, and Ray's overhead against the local backend.

The sweep: sac and auxss, 4 seeds, 2,000 steps each (one evaluation of 5 episodes per start
distribution at the end), so two jobs of 4 seeds, each job one process with one torch thread. Every
case trains the same runs into a fresh directory. "wall" is the whole command (for Ray: starting and
stopping the local cluster included); "jobs" is sweep.json's wall time, from planning to the last job.
The machine's load average is printed before each case: another process busy on a core halves
what 2 workers can gain.

Usage: python bench/sweep_scaling.py [--steps 2000] [--seeds 4] [--quick]
Ray is optional (pip install 'lava-bridge-mj[ray]'); without it the Ray case is left out.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import tempfile
import time
from pathlib import Path

from lava_bridge_mj.eval.sweeps import sweep


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"{one:.2f} / {five:.2f}"


def run_case(argv: list[str], out: Path) -> tuple[float, float]:
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = sweep.main([*argv, "--out", str(out)])
    wall = time.perf_counter() - start
    if code != 0:
        # the temporary directory goes with the exit, so the failed jobs' errors are printed, not pointed to
        try:
            jobs = json.loads((out / "sweep.json").read_text())["jobs"]
            errors = "; ".join(f"{job.get('status')}: {job.get('error')}" for job in jobs
                               if job.get("status") not in ("done", "skipped"))
        except (OSError, ValueError, KeyError) as error:
            errors = f"sweep.json unreadable: {error}"
        raise SystemExit(f"the sweep {' '.join(argv)} failed (exit {code}): {errors}")
    return wall, json.loads((out / "sweep.json").read_text())["wall_time"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--quick", action="store_true", help="tiny sizes (300 steps, 2 seeds, small networks)")
    args = parser.parse_args()
    steps, seeds, episodes = (300, 2, 2) if args.quick else (args.steps, args.seeds, 5)
    try:
        import ray  # noqa: F401
        have_ray = True
    except ImportError:
        have_ray = False

    with tempfile.TemporaryDirectory(prefix="sweep-bench-") as tmp:
        argv = ["--methods", "sac,auxss", "--seeds", f"0-{seeds - 1}", "--steps", str(steps),
                "--eval-every", str(steps), "--eval-episodes", str(episodes)]
        if args.quick:
            config = Path(tmp) / "tiny.json"
            config.write_text(json.dumps({"sac": {"hidden_sizes": [16, 16], "batch_size": 32, "learning_starts": 100}}))
            argv += ["--config", str(config)]
        cases = [("local, 1 worker", ["--workers", "1"]), ("local, 2 workers", ["--workers", "2"])]
        if have_ray:
            cases.append(("Ray, local cluster of 2 CPUs", ["--workers", "2", "--backend", "ray"]))
        print(f"sweep: sac + auxss, {seeds} seeds, {steps} steps, one torch thread per job; "
              f"{len(os.sched_getaffinity(0))} CPUs")
        rows = []
        for i, (name, extra) in enumerate(cases):
            before = load()
            wall, jobs = run_case(argv + extra, Path(tmp) / f"case{i}")
            rows.append((name, wall, jobs, before))

    base = rows[0][1]
    print(f"{'case':<30} {'wall s':>8} {'jobs s':>8} {'x 1 worker':>11}  load avg 1/5 min before")
    for name, wall, jobs, before in rows:
        print(f"{name:<30} {wall:>8.1f} {jobs:>8.1f} {base / wall:>10.2f}x  {before}")
    if have_ray:
        local, ray_row = rows[1], rows[2]
        print(f"Ray overhead vs local with 2 workers: {ray_row[1] / local[1]:.2f}x wall, "
              f"{ray_row[2] / local[2]:.2f}x jobs")
    else:
        print("Ray is not installed: pip install 'lava-bridge-mj[ray]' for the Ray case")
    print(f"load average after: {load()}")


if __name__ == "__main__":
    main()
