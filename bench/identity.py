"""Do the working tree's code and a reference commit train bit-identical runs?

Trains a fixed short run of every training method (2 seeds batched, tiny networks, a few thousand
steps, a few evaluation episodes; some methods on the 7,500-transition demo set) once with the
working tree's code and once with the code of `--ref` (extracted with `git archive`), through the
`lava-bridge-bench` command of each, side by side. Per method it prints whether metrics.csv (every
column but wall_time), the episode log (its CSV, compressed or not) and start_weights.npz of every
seed are bit-identical, and exits 1 if any differ or a run fails.

Usage: python bench/identity.py [--ref COMMIT] [--steps 1500] [--jobs 2] [--keep DIR]
(default --ref: the merge-base of HEAD and main)
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from lava_bridge_mj.eval.training import run_files
from single_seed_speed import commit_tree, importable_tree  # bench/ is on sys.path when this script runs

ROOT = Path(__file__).resolve().parent.parent
DEMOS_7500 = ("hysac", "iql")
"""Methods run on the 7,500-transition demo set; the others use the 500 set."""
SEEDS = "0-1"
TINY = {"demo_subset": 30,
        "sac": {"hidden_sizes": [16, 16], "batch_size": 32, "buffer_size": 2000, "learning_starts": 100},
        "bc": {"hidden_sizes": [16, 16], "batch_size": 32},
        "iql": {"hidden_sizes": [16, 16], "batch_size": 32},
        "jsrl": {"guide_steps": 100, "initial_horizon": 60, "window": 2, "stages": 3}}
"""The tiny hyperparameters every run uses (a --config file)."""
LAUNCH = "import sys; from lava_bridge_mj.eval.cli import main; sys.exit(main())"


def git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()


def train(name: str, path: Path, method: str, out: Path, config: Path, steps: int) -> tuple[str, str, float]:
    """Train `method` with the code on `path`; (name, method, seconds) or RuntimeError with its stderr."""
    demos = 7500 if method in DEMOS_7500 else 500
    command = [sys.executable, "-c", LAUNCH, "--method", method, "--seeds", SEEDS, "--steps", str(steps),
               "--eval-every", str(steps // 2), "--eval-episodes", "2", "--demos", str(demos),
               "--config", str(config), "--out", str(out), "--no-progress"]
    env = {**os.environ, "PYTHONPATH": str(path), "OMP_NUM_THREADS": "1"}
    start = time.perf_counter()
    result = subprocess.run(command, env=env, capture_output=True, text=True, cwd=out.parent)
    if result.returncode != 0:
        raise RuntimeError(f"{name} {method} exited {result.returncode}: {result.stderr.strip()[-2000:]}")
    return name, method, time.perf_counter() - start


def metrics_without_wall_time(path: Path) -> list[list[str]]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    keep = [i for i, field in enumerate(rows[0]) if field != "wall_time"]
    return [[row[i] for i in keep] for row in rows]


def compare(a: Path, b: Path) -> dict[str, str]:
    """Per file kind, 'identical', 'absent' (in both) or what differs, over every seed directory."""
    verdict = {}
    seeds = sorted(p.name for p in a.iterdir() if p.is_dir())
    for kind in ("metrics.csv", "episodes.csv", "start_weights.npz"):
        problems = []
        present = 0
        for seed in seeds:
            fa, fb = a / seed / kind, b / seed / kind
            if kind == "episodes.csv":  # the log compressed or plain: the ref may predate compression
                fa, fb = (run_files.episode_log_file(d / seed) or d / seed / kind for d in (a, b))
            if fa.exists() != fb.exists():
                problems.append(f"{seed}: only in {'working tree' if fa.exists() else 'ref'}")
                continue
            if not fa.exists():
                continue
            present += 1
            if kind == "metrics.csv":
                same = metrics_without_wall_time(fa) == metrics_without_wall_time(fb)
            elif kind == "episodes.csv":
                same = run_files.read_episode_log(fa) == run_files.read_episode_log(fb)
            else:
                same = run_files.same_arrays(run_files.read_npz(fa), run_files.read_npz(fb))
            if not same:
                problems.append(f"{seed} differs")
        verdict[kind] = "; ".join(problems) if problems else ("identical" if present else "absent")
    return verdict


def tree_methods(path: Path) -> list[str]:
    """The CLI's methods in the tree importable from `path` (the methods both trees have are compared)."""
    listed = subprocess.run([sys.executable, "-c", "from lava_bridge_mj.eval import cli; print(','.join(cli.METHODS))"],
                            env={**os.environ, "PYTHONPATH": str(path)}, capture_output=True, text=True, check=True,
                            cwd=path)  # not this checkout, whose own package `python -c` would import first
    return listed.stdout.strip().split(",")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ref", help="the reference commit (default: the merge-base of HEAD and main)")
    parser.add_argument("--steps", type=int, default=1500, help="training steps per run (default: 1500)")
    parser.add_argument("--jobs", type=int, default=2, help="runs trained at once (default: 2)")
    parser.add_argument("--keep", type=Path, help="train into this (new) directory and keep it")
    args = parser.parse_args(argv)
    if args.steps < 2 or args.jobs < 1:
        parser.error(f"--steps must be >= 2 and --jobs >= 1, got {args.steps} and {args.jobs}")
    try:
        ref = git("rev-parse", "--verify", f"{args.ref or git('merge-base', 'HEAD', 'main')}^{{commit}}")
    except subprocess.CalledProcessError as error:
        parser.error(f"--ref {args.ref!r} is not a commit of this repository ({error.stderr.strip()})")
    head = git("rev-parse", "HEAD")
    dirty = bool(git("status", "--porcelain", "--untracked-files=no"))
    print(f"$ python bench/identity.py {shlex.join(argv if argv is not None else sys.argv[1:])}")
    print(f"working tree: {head}{' (with uncommitted changes)' if dirty else ''}; ref: {ref}")
    print(f"runs: seeds {SEEDS} batched, {args.steps} steps, eval every {args.steps // 2}, 2 eval episodes, "
          f"demo set 7500 for {', '.join(DEMOS_7500)} and 500 otherwise; config {json.dumps(TINY)}")

    with tempfile.TemporaryDirectory(prefix="identity-") as scratch:
        work = args.keep or Path(scratch)
        work.mkdir(parents=True, exist_ok=args.keep is None)
        paths = {"working": importable_tree(ROOT, Path(scratch) / "path-working"),
                 "ref": commit_tree(ref, Path(scratch))}
        config = work / "tiny.json"
        config.write_text(json.dumps(TINY))
        methods = {name: tree_methods(path) for name, path in paths.items()}
        new = [method for method in methods["working"] if method not in methods["ref"]]
        compared = [method for method in methods["working"] if method in methods["ref"]]
        for name in paths:
            (work / name).mkdir()
        failures, seconds = [], {}
        with ThreadPoolExecutor(args.jobs) as pool:
            futures = [pool.submit(train, name, path, method, work / name / method, config, args.steps)
                       for method in compared for name, path in paths.items()]
            for future in futures:
                try:
                    name, method, took = future.result()
                    seconds[name, method] = took
                except RuntimeError as error:
                    failures.append(str(error))
        for failure in failures:
            print(f"FAILED: {failure}")
        identical = not failures
        print(f"{'method':<12} {'demos':>5}  {'metrics.csv':<12} {'episodes.csv':<12} {'start_weights':<13}  seconds (working/ref)")
        for method in compared:
            a, b = work / "working" / method, work / "ref" / method
            if (("working", method) not in seconds) or (("ref", method) not in seconds):
                print(f"{method:<12} run failed")
                continue
            verdict = compare(a, b)
            identical &= all(v in ("identical", "absent") for v in verdict.values())
            print(f"{method:<12} {7500 if method in DEMOS_7500 else 500:>5}  {verdict['metrics.csv']:<12} "
                  f"{verdict['episodes.csv']:<12} {verdict['start_weights.npz']:<13}  "
                  f"{seconds['working', method]:.1f}/{seconds['ref', method]:.1f}")
        for method in new:
            print(f"{method:<12} new since the ref: nothing to compare with")
    print("bit-identical" if identical else "NOT bit-identical")
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
