"""The batched SAC update alone, this tree against a reference commit, side by side.

Times `SAC.update` (64x64 networks, batch 256, one torch thread) on a fixed random batch at each
number of seeds K, in subprocesses that alternate between the working tree's code and `--ref`'s
(extracted with `git archive`), `--repeats` times each; prints the median milliseconds per update
(CPU time of the process), seed-updates per second, and ref / this tree. Both trees start from the
same seeds and batch, so it also prints whether their weights after the timed updates are identical.

With `--compiled` the reference is this tree again with every network (the actor's MLP, each
critic's and target critic's Q-network) under `torch.compile`, the actor's noise still drawn eagerly
from each seed's generator: what fused kernels would buy the update, and whether they round alike.
Its compilation happens in the untimed warm-up updates.

Usage: python bench/update_speed.py [--ref COMMIT | --compiled] [--seeds 1,13,25] [--updates 60] [--repeats 3] [--quick]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from difficulty import code_version  # bench/ is on sys.path when this script runs
from single_seed_speed import commit_tree, importable_tree

ROOT = Path(__file__).resolve().parents[1]
TIMED = """
import hashlib, sys, time, torch
from lava_bridge_mj.agents.configs import SACConfig
from lava_bridge_mj.agents.sac import SAC
torch.set_num_threads(1)
k, updates, hidden, compiled = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4] == "compiled"
agent = SAC(4, 2, SACConfig(hidden_sizes=(hidden, hidden)), seeds=range(k))
if compiled:
    agent.actor.net = torch.compile(agent.actor.net)
    for twin in (agent.critic, agent.target_critic):
        twin.q1, twin.q2 = torch.compile(twin.q1), torch.compile(twin.q2)
g = torch.Generator().manual_seed(0)
batch = {"obs": torch.randn(k, 256, 4, generator=g), "action": torch.rand(k, 256, 2, generator=g) * 2 - 1,
         "reward": (torch.rand(k, 256, generator=g) < 0.1).float(), "next_obs": torch.randn(k, 256, 4, generator=g),
         "terminated": (torch.rand(k, 256, generator=g) < 0.05).float()}
for _ in range(5):
    agent.update(batch)
start = time.process_time()
for _ in range(updates):
    agent.update(batch)
seconds = (time.process_time() - start) / updates
digest = hashlib.sha256(b"".join(p.detach().numpy().tobytes() for p in agent.actor.parameters())).hexdigest()
print(seconds, digest[:16])
"""


def timed(path: Path, k: int, updates: int, hidden: int, compiled: bool = False) -> tuple[float, str]:
    env = {**os.environ, "PYTHONPATH": str(path), "OMP_NUM_THREADS": "1"}
    result = subprocess.run([sys.executable, "-c", TIMED, str(k), str(updates), str(hidden),
                             "compiled" if compiled else "eager"], env=env,
                            cwd=path, capture_output=True, text=True, check=True)
    seconds, digest = result.stdout.split()
    return float(seconds), digest


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ref", default="228f864", help="the reference commit (default: 228f864)")
    parser.add_argument("--compiled", action="store_true",
                        help="the reference is this tree with its networks under torch.compile, not --ref")
    parser.add_argument("--seeds", default="1,13,25", help="numbers of seeds K (default: 1,13,25)")
    parser.add_argument("--updates", type=int, default=60, help="timed updates per subprocess (default: 60)")
    parser.add_argument("--repeats", type=int, default=3, help="subprocesses per tree and K (default: 3)")
    parser.add_argument("--quick", action="store_true", help="K = 2, 16 units, 5 updates, one repeat")
    args = parser.parse_args(argv)
    try:
        ks = [2] if args.quick else [int(k) for k in args.seeds.split(",")]
    except ValueError:
        parser.error(f"--seeds must be comma-separated numbers of seeds, got {args.seeds!r}")
    if min(ks) < 1 or args.updates < 1 or args.repeats < 1:
        parser.error(f"--seeds, --updates and --repeats must be >= 1, got {args.seeds}, {args.updates}, {args.repeats}")
    updates, repeats, hidden = (5, 1, 16) if args.quick else (args.updates, args.repeats, 64)
    print(f"$ python bench/update_speed.py {' '.join(argv if argv is not None else sys.argv[1:])}")
    ref_name = "this tree, torch.compile" if args.compiled else args.ref
    print(f"this tree: {code_version()}; ref: {ref_name}; {hidden}x{hidden}, batch 256, one thread, "
          f"{updates} updates x {repeats} repeats")
    with tempfile.TemporaryDirectory(prefix="update-speed-") as scratch:
        scratch = Path(scratch)
        try:
            here = importable_tree(ROOT, scratch / "path-working")
            trees = {"this tree": (here, False),
                     "ref": (here, True) if args.compiled else (commit_tree(args.ref, scratch), False)}
        except ValueError:
            parser.error(f"--ref {args.ref!r} is not a commit of this repository")
        print(f"{'K':>3} {'this tree: ms':>14} {'ref: ms':>9} {'seed-updates/s':>15} {'ref / this tree':>16}  weights")
        for k in ks:
            times: dict[str, list[float]] = {name: [] for name in trees}
            digests: dict[str, str] = {}
            for _ in range(repeats):
                for name, (path, compiled) in trees.items():  # alternated, so load changes hit both alike
                    seconds, digests[name] = timed(path, k, updates, hidden, compiled)
                    times[name].append(seconds)
            ours, ref = statistics.median(times["this tree"]), statistics.median(times["ref"])
            same = "identical" if digests["this tree"] == digests["ref"] else "differ"
            print(f"{k:>3} {ours * 1e3:>14.2f} {ref * 1e3:>9.2f} {k / ours:>15.0f} {ref / ours:>16.2f}  {same}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
