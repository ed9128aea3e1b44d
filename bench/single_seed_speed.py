"""The single-seed training path against an earlier revision of this package, side by side in one run.

The target: batching seeds must not make one seed slower. This extracts REV's code (default 5eff605,
the last commit before the batched trainer) into a temporary folder with `git archive`, and times the same
single-seed `train()` call (SAC from p0, 64x64, one update per step after 1,000 warm-up steps, one
final evaluation episode per start distribution) in fresh subprocesses, alternating the two trees so
that background load hits both alike. Figure: env steps per second, whole run included; the median of
the repeats, and the ratio this tree / REV (above 1: this tree is faster). `--out FILE` also writes
the report, headed by the command and the commit it ran at, to FILE (docs/speed.md's figures come
from results/bench/single_seed_speed.txt).

Usage: python bench/single_seed_speed.py [--rev 5eff605] [--steps 3000] [--repeats 3] [--quick] [--out FILE]
Needs git and this repository's history.
"""

from __future__ import annotations

import argparse
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from difficulty import code_version, write_atomically  # bench/ is on sys.path when this script runs

ROOT = Path(__file__).resolve().parent.parent
# the repository's folders and the import names setup.cfg maps them to
PACKAGE_DIRS = {"lava_bridge_mj": "lava_bridge_mj", "agents": "lava_bridge_mj/agents",
                "eval": "lava_bridge_mj/eval", "assets": "lava_bridge_mj/assets"}

TIMED = """
import sys, time, tempfile, torch
torch.set_num_threads(1)
try:
    from lava_bridge_mj.eval.training.runner import RunConfig, train
except ImportError:  # a reference tree from before eval/ was split into rooms
    from lava_bridge_mj.eval.runner import RunConfig, train
steps = int(sys.argv[1])
config = RunConfig.from_dict({"method": "sac", "seed": 0, "steps": steps, "eval_every": steps,
                              "eval_episodes": 1, "sac": {"learning_starts": 1000}})
with tempfile.TemporaryDirectory() as out:
    start = time.perf_counter()
    train(config, out, progress=False)
    print(steps / (time.perf_counter() - start))
"""


def commit_tree(ref: str, scratch: Path) -> Path:
    """A folder under `scratch` where `import lava_bridge_mj` finds commit `ref`'s code, extracted with
    `git archive`; ValueError naming `ref` when it is not a commit of this repository."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref], capture_output=True)
    if archive.returncode != 0:
        raise ValueError(f"{ref!r} is not a commit of this repository ({archive.stderr.decode().strip()})")
    tree = scratch / "ref-tree"
    tree.mkdir()
    subprocess.run(["tar", "-x", "-C", str(tree)], input=archive.stdout, check=True)
    return importable_tree(tree, scratch / "path-ref")


def importable_tree(source: Path, into: Path) -> Path:
    """A folder where `import lava_bridge_mj` finds `source`'s code laid out as setup.cfg installs it."""
    package = into / "lava_bridge_mj"
    package.mkdir(parents=True)
    for entry in (source / "lava_bridge_mj").iterdir():
        (package / entry.name).symlink_to(entry)
    for folder in ("agents", "eval", "assets"):
        (package / folder).symlink_to(source / folder)
    return into


def rate(tree: Path, steps: int) -> float:
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1"}
    result = subprocess.run([sys.executable, "-c", TIMED, str(steps)], env=env, cwd=tree, check=True,
                            capture_output=True, text=True)
    return float(result.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rev", default="5eff605")
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="1,200 steps, one repeat (CI: it runs, figures not asserted)")
    parser.add_argument("--out", type=Path, metavar="FILE", help="also write the report to FILE")
    args = parser.parse_args(argv)
    steps, repeats = (1200, 1) if args.quick else (args.steps, args.repeats)
    known = subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", f"{args.rev}^{{commit}}"], capture_output=True)
    if known.returncode != 0:
        sys.exit(f"revision {args.rev} is not in this clone's history (a shallow clone?): nothing to compare against")
    command = shlex.join(["python", "bench/single_seed_speed.py", *(sys.argv[1:] if argv is None else argv)])
    version = code_version()  # before the run: what the figures came from
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        trees = {"this tree": importable_tree(ROOT, tmp / "head"), args.rev: commit_tree(args.rev, tmp)}
        rates: dict[str, list[float]] = {name: [] for name in trees}
        for _ in range(repeats):
            for name, tree in trees.items():
                rates[name].append(rate(tree, steps))
    lines = [f"$ {command}", f"this tree: {version}; ref: {args.rev}",
             f"single-seed SAC from p0, 64x64, {steps} steps (1,000 warm-up), 1 torch thread, "
             f"median of {repeats}; load average before {load_before:.2f}, after {os.getloadavg()[0]:.2f}"]
    for name, values in rates.items():
        lines.append(f"  {name:>10}: {statistics.median(values):7.1f} steps/s   runs: {', '.join(f'{v:.1f}' for v in values)}")
    ratio = statistics.median(rates["this tree"]) / statistics.median(rates[args.rev])
    lines.append(f"  ratio this tree / {args.rev}: {ratio:.2f}")
    print("\n".join(lines))
    if args.out:
        write_atomically(args.out, "\n".join(lines) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
