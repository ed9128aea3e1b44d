"""Peak memory of a tiny training run per task, for K = 1 and 10 seeds batched in one process.

Each run is `lava-bridge-bench train --method auxss --seeds 0-(K-1) --steps 300 --eval-every 300
--threads 1` (one evaluation round from p0 and ood, 50 episodes each, the default) in its own
process; the figure is that process's peak resident set size (the kernel's ru_maxrss). With
`--ref COMMIT` each run is trained with that commit's code too, side by side, and the table says
whether its metrics.csv (every column but wall_time) is bit-identical to the working tree's.

A run of an external task holds one whole env, with its own MuJoCo model, per training seed and per
evaluation episode running at once (the "eval sub-envs" column); a Lava Bridge run shares one model.

    python bench/memory.py                   # writes results/bench/memory.txt
    python bench/memory.py --ref main --tasks PointMaze_Medium-v3 LavaBridge-v0

Usage: python bench/memory.py [--tasks ID ...] [--seeds 1 10] [--steps 300] [--ref COMMIT] [--out FILE] [--quick]
"""

from __future__ import annotations

import argparse
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from difficulty import code_version, write_atomically  # bench/ is on sys.path when this script runs
from identity import LAUNCH, git, metrics_without_wall_time
from single_seed_speed import commit_tree, importable_tree

ROOT = Path(__file__).resolve().parent.parent
TASKS = ("PointMaze_Medium-v3", "cube-single-singletask-task1-v0", "LavaBridge-v0")


def peak_rss(tree: Path, env_id: str, seeds: int, steps: int, out: Path) -> tuple[int, float]:
    """(peak resident set size in bytes, wall seconds) of one training process on the code importable
    from `tree`."""
    command = [sys.executable, "-c", LAUNCH, "--env", env_id, "--method", "auxss", "--seeds", f"0-{seeds - 1}",
               "--steps", str(steps), "--eval-every", str(steps), "--threads", "1", "--no-progress", "--out", str(out)]
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1"}
    start = time.perf_counter()
    with open(out.with_suffix(".log"), "w") as log:
        process = subprocess.Popen(command, env=env, cwd=tree, stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(process.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{shlex.join(command)} failed: {out.with_suffix('.log').read_text()[-2000:]}")
    return usage.ru_maxrss * 1024, time.perf_counter() - start  # ru_maxrss: KiB on Linux


def eval_sub_envs(env_id: str, seeds: int) -> int:
    """The sub-envs of the working tree's evaluation vector env for `seeds` seeds of `env_id`."""
    from lava_bridge_mj.eval.training.config import RunConfig
    from lava_bridge_mj.eval.training.evaluate import members_at_once

    config = RunConfig(env_id=env_id, method="auxss")
    env = None if config.lava_bridge else config.make_env()
    return members_at_once(seeds, config.eval_episodes, env) * config.eval_episodes


def same_metrics(a: Path, b: Path) -> bool:
    return all(metrics_without_wall_time(a / seed / "metrics.csv") == metrics_without_wall_time(b / seed / "metrics.csv")
               for seed in sorted(p.name for p in a.iterdir() if p.is_dir()))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), help=f"default: {' '.join(TASKS)}")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 10], help="seeds per process, K (default: 1 10)")
    parser.add_argument("--steps", type=int, default=300, help="training steps (default: 300)")
    parser.add_argument("--ref", help="also train each run with this commit's code and compare")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "bench" / "memory.txt")
    parser.add_argument("--quick", action="store_true", help="LavaBridge-v0, K=1, 20 steps; print, write no file")
    args = parser.parse_args(argv)
    if args.quick:
        args.tasks, args.seeds, args.steps, args.out = ["LavaBridge-v0"], [1], 20, None
    if min(args.seeds) < 1 or args.steps < 1:
        parser.error(f"--seeds {args.seeds} and --steps {args.steps} must be positive")
    scratch_dir = tempfile.TemporaryDirectory(prefix="memory-")
    scratch = Path(scratch_dir.name)
    trees = {"working": importable_tree(ROOT, scratch / "path-working")}
    if args.ref:
        try:
            trees["ref"] = commit_tree(args.ref, scratch)
        except ValueError as error:
            parser.error(f"--ref: {error}")
    lines = ["# Peak memory of a tiny auxss run per task", "",
             f"$ python bench/memory.py {shlex.join(argv if argv is not None else sys.argv[1:])}",
             f"code: {code_version()}" + (f"; ref: {git('rev-parse', args.ref)}" if args.ref else ""),
             f"machine: {platform.machine()}, {os.cpu_count()} CPUs, python {platform.python_version()}; "
             f"one-minute load average {os.getloadavg()[0]:.2f} as it began",
             f"runs: --method auxss --steps {args.steps} --eval-every {args.steps} --threads 1, 50 eval episodes "
             "from p0 and ood", ""]
    header = "| task | K | eval sub-envs | peak RSS (MiB) | wall s |"
    lines += [header + (" ref peak RSS (MiB) | ref wall s | metrics.csv |" if args.ref else ""),
              "|---|---:|---:|---:|---:|" + ("---:|---:|---|" if args.ref else "")]
    print("\n".join(lines), flush=True)
    with scratch_dir:
        for env_id in args.tasks:
            for seeds in args.seeds:
                peaks, seconds, outs = {}, {}, {}
                for name, tree in trees.items():
                    outs[name] = scratch / f"{name}-{env_id}-{seeds}"
                    peaks[name], seconds[name] = peak_rss(tree, env_id, seeds, args.steps, outs[name])
                row = (f"| {env_id} | {seeds} | {eval_sub_envs(env_id, seeds)} | {peaks['working'] / 2**20:,.0f} "
                       f"| {seconds['working']:.0f} |")
                if args.ref:
                    same = "identical" if same_metrics(outs["working"], outs["ref"]) else "DIFFERENT"
                    row += f" {peaks['ref'] / 2**20:,.0f} | {seconds['ref']:.0f} | {same} |"
                lines.append(row)
                print(row, flush=True)
    if args.out is not None:
        write_atomically(args.out, "\n".join(lines) + "\n")  # a failed or interrupted run leaves the old file
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
