"""Aggregate throughput of a protocol-shaped job through the real CLI, in the layouts a user would pick.

The job: one method (default AuxSS) on 25 seeds, evaluation every 10,000 steps with 50 episodes from
p0 and 50 from ood per seed, as the benchmark's protocol runs it, for `--steps` steps (default 30,000:
three evaluation rounds, the first while the policies are still untrained, so their episodes run long).
Each case trains the same seeds into a fresh directory, one case after another:

    sweep   lava-bridge-bench sweep --workers 2 --threads 1   two processes (13 and 12 seeds), 1 thread each
    train   lava-bridge-bench --threads 2                      one process of 25 seeds, 2 threads

With `--ref COMMIT` the sweep case runs a second time with that commit's code (`git archive`), so a
change's before and after are measured in one run. Per case it prints the wall time, the seed-steps
per second of wall time with evaluation included (seeds x steps / wall), that rate against the
2,000 seed-steps/s target and against the first case, the CPU seconds the case used, and the load
average before it started: other programs on the machine lower every rate.

Usage: python bench/protocol_throughput.py [--steps 30000] [--seeds 25] [--method auxss]
                                           [--cases sweep,train] [--ref COMMIT] [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from difficulty import code_version  # bench/ is on sys.path when this script runs
from single_seed_speed import commit_tree, importable_tree

ROOT = Path(__file__).resolve().parents[1]
TARGET = 2000.0
"""Seed-steps per second for the whole machine, evaluation included, that the study's budget needs."""
LAUNCH = "import sys; from lava_bridge_mj.eval.cli import main; sys.exit(main())"
CASES = {
    "sweep": ["sweep", "--workers", "2", "--threads", "1", "--progress-every", "0"],
    "train": ["train", "--threads", "2", "--no-progress"],
}
QUICK_CONFIG = {"demo_subset": 30, "sac": {"hidden_sizes": [16, 16], "batch_size": 32, "learning_starts": 100}}


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"{one:.2f} / {five:.2f}"


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_case(case: str, path: Path, job: list[str], out: Path) -> tuple[float, float]:
    """Run one case with the code importable from `path` (`job`: the method, then the shared options);
    (wall seconds, CPU seconds)."""
    subcommand, *options = CASES[case]
    method_flag = "--methods" if case == "sweep" else "--method"
    command = [sys.executable, "-c", LAUNCH, subcommand, method_flag, *job, "--out", str(out), *options]
    env = {**os.environ, "PYTHONPATH": str(path)}
    cpu, start = children_cpu(), time.perf_counter()
    result = subprocess.run(command, env=env, capture_output=True, text=True, cwd=out.parent)
    wall = time.perf_counter() - start
    if result.returncode != 0:
        raise SystemExit(f"{case} exited {result.returncode}: {result.stderr.strip()[-2000:]}")
    return wall, children_cpu() - cpu


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30000, help="training steps per seed (default: 30000)")
    parser.add_argument("--seeds", type=int, default=25, help="seeds 0..N-1 (default: 25)")
    parser.add_argument("--method", default="auxss", help="the method trained (default: auxss)")
    parser.add_argument("--cases", default="sweep,train", help=f"some of {','.join(CASES)} (default: both)")
    parser.add_argument("--ref", help="also run the sweep case with this commit's code")
    parser.add_argument("--quick", action="store_true",
                        help="tiny sizes (2 seeds, 400 steps, small networks): checks that it runs")
    args = parser.parse_args(argv)
    cases = args.cases.split(",")
    if unknown := [c for c in cases if c not in CASES]:
        parser.error(f"--cases: unknown {unknown}, expected some of {sorted(CASES)}")
    seeds, steps, every, episodes = (2, 400, 200, 2) if args.quick else (args.seeds, args.steps, 10000, 50)
    if seeds < 1 or steps < every:
        parser.error(f"--seeds must be >= 1 and --steps >= {every}, got {seeds} and {steps}")

    print(f"$ python bench/protocol_throughput.py {' '.join(argv if argv is not None else sys.argv[1:])}")
    print(f"code: {code_version()}; {len(os.sched_getaffinity(0))} CPUs")
    print(f"job: {args.method}, seeds 0-{seeds - 1}, {steps:,} steps, evaluation every {every:,} steps "
          f"with {episodes} + {episodes} episodes per seed")
    rows = []
    with tempfile.TemporaryDirectory(prefix="protocol-throughput-") as scratch:
        scratch = Path(scratch)
        job = [args.method, "--seeds", f"0-{seeds - 1}", "--steps", str(steps),
               "--eval-every", str(every), "--eval-episodes", str(episodes)]
        if args.quick:
            (scratch / "quick.json").write_text(json.dumps(QUICK_CONFIG))
            job += ["--config", str(scratch / "quick.json")]
        trees = [("working tree", importable_tree(ROOT, scratch / "path-working"), cases)]
        if args.ref:
            try:
                trees.append((f"ref {args.ref}", commit_tree(args.ref, scratch), ["sweep"]))
            except ValueError:
                parser.error(f"--ref {args.ref!r} is not a commit of this repository")
        for name, path, tree_cases in trees:
            for case in tree_cases:
                before = load()
                wall, cpu = run_case(case, path, job, scratch / f"{name.split()[0]}-{case}")
                rows.append((f"{case} ({name})", wall, cpu, seeds * steps / wall, before))
                print(f"  done: {rows[-1][0]} in {wall:.0f} s", flush=True)

    first = rows[0][3]
    print(f"{'case':<36} {'wall s':>8} {'CPU s':>8} {'seed-steps/s':>13} {'x target':>9} {'x first':>8}  load avg before")
    for name, wall, cpu, rate, before in rows:
        print(f"{name:<36} {wall:>8.1f} {cpu:>8.1f} {rate:>13.0f} {rate / TARGET:>9.2f} {rate / first:>8.2f}  {before}")
    print(f"target: {TARGET:,.0f} seed-steps/s; load average after: {load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
