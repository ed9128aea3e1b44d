"""What the TensorBoard sink costs a training run, side by side: the same run without and with it.

Trains one configuration (AuxSS, default networks, a batch of `--seeds` seeds, one evaluation at the
end) `--repeats` times each way, alternating which goes first, into fresh directories: without
sinks, and with `--log tensorboard` writing the training scalars every `--log-every` steps (the
default interval, `TRAIN_LOG_EVERY`). Prints the median wall time and the median CPU time of this
process (`time.process_time`: every thread's, the event writer's included) of each way and their
ratios. On a shared machine those medians differ by noise larger than the cost being measured, so
two direct figures follow: the time spent inside the loop's logging calls (`Run._log_training`,
timed around each call) as a share of the logged runs' wall time, and the sink's whole work
replayed alone (the same number of writes of the same scalars into fresh SummaryWriters, closed,
so the writer thread's work is counted) in CPU time, as a share of the runs' CPU time without sinks.
`--out FILE` also writes the report to FILE (docs/training.md's figures come from
results/bench/tracking_cost.txt).

    python bench/tracking_cost.py                      # 5 seeds, 5,000 steps, 3 repeats each way
    python bench/tracking_cost.py --seeds 1            # one seed: the fewest steps per second
    python bench/tracking_cost.py --quick              # 1 seed, 600 steps, 1 repeat: a smoke test
"""

from __future__ import annotations

import argparse
import os
import shlex
import statistics
import sys
import tempfile
import time
from pathlib import Path

import torch

from difficulty import code_version, write_atomically  # bench/ is on sys.path when this script runs
from lava_bridge_mj.eval.training import runner
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.training.tracking import TRAIN_LOG_EVERY, training_scalars


class LoggingTimer:
    """Wraps Run._log_training to add up the seconds spent in it."""

    def __init__(self):
        self.seconds, self.calls = 0.0, 0
        self.original = runner.Run._log_training

    def __enter__(self):
        def timed(run, *args):
            start = time.perf_counter()
            self.original(run, *args)
            self.seconds += time.perf_counter() - start
            self.calls += 1

        runner.Run._log_training = timed
        return self

    def __exit__(self, *exc):
        runner.Run._log_training = self.original


def train_once(config: RunConfig, seeds: list[int], root: Path, log: tuple[str, ...],
               log_every: int) -> tuple[float, float]:
    """(wall seconds, this process's CPU seconds) of one training run into fresh directories."""
    dirs = [Path(tempfile.mkdtemp(dir=root)) / f"seed{seed}" for seed in seeds]
    wall, cpu = time.perf_counter(), time.process_time()
    runner.train(config, dirs, seeds=seeds, progress=False, log=log, log_every=log_every)
    return time.perf_counter() - wall, time.process_time() - cpu


def replay_cpu_seconds(writes: int, seeds: int, root: Path) -> float:
    """CPU seconds of `writes` writes of a SAC seed's training scalars to each of `seeds` fresh
    SummaryWriters, closing them (which waits for their writer threads)."""
    from torch.utils.tensorboard import SummaryWriter

    update = {"critic_loss": 0.1, "actor_loss": -0.2, "alpha": 0.05, "q_mean": 0.3, "entropy": 1.0}
    episodes = [(n, 100 * n, -1, 0.0, 0.0, 100, 0, 0.0) for n in range(1, 101)]
    scalars = training_scalars(update, episodes, {"fps": 500.0, "episodes": 100, "time_elapsed": 1.0})
    start = time.process_time()
    writers = [SummaryWriter(str(Path(tempfile.mkdtemp(dir=root)))) for _ in range(seeds)]
    for step in range(writes):
        for writer in writers:
            for name, value in scalars.items():
                writer.add_scalar(name, value, step)
    for writer in writers:
        writer.close()
    return time.process_time() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="seeds trained together in one batch (default: 5)")
    parser.add_argument("--steps", type=int, default=5_000, help="training steps per run (default: 5000)")
    parser.add_argument("--repeats", type=int, default=3, help="runs each way (default: 3)")
    parser.add_argument("--log-every", type=int, default=TRAIN_LOG_EVERY,
                        help=f"steps between two writes of the training scalars (default: {TRAIN_LOG_EVERY})")
    parser.add_argument("--quick", action="store_true", help="1 seed, 600 steps, 1 repeat, a write every 100 steps")
    parser.add_argument("--out", type=Path, metavar="FILE", help="also write the report to FILE")
    args = parser.parse_args(argv)
    if args.quick:
        args.seeds, args.steps, args.repeats, args.log_every = 1, 600, 1, 100
    if min(args.seeds, args.steps, args.repeats, args.log_every) < 1:
        parser.error("--seeds, --steps, --repeats and --log-every must be at least 1")
    torch.set_num_threads(1)  # the CLI's default
    seeds = list(range(args.seeds))
    config = RunConfig(method="auxss", steps=args.steps, eval_every=args.steps, eval_episodes=10)
    lines = []

    def report(line: str) -> None:
        lines.append(line)
        print(line, flush=True)

    report("$ " + shlex.join(["python", "bench/tracking_cost.py", *(sys.argv[1:] if argv is None else argv)]))
    report(f"at commit {code_version()}, torch {torch.__version__}, 1 thread; auxss, {args.seeds} seed(s) batched, "
           f"{args.steps} steps, one evaluation of 10 + 10 episodes; TensorBoard every {args.log_every} steps; "
           f"load average before {os.getloadavg()[0]:.2f}")
    times: dict[str, list[tuple[float, float]]] = {"without": [], "tensorboard": []}
    with tempfile.TemporaryDirectory(prefix="tracking-cost-") as scratch, LoggingTimer() as timer:
        root = Path(scratch)
        train_once(RunConfig(method="auxss", steps=200, eval_every=200, eval_episodes=2), seeds, root,
                   ("tensorboard",), 100)  # warm-up: imports, first allocations
        timer.seconds, timer.calls = 0.0, 0
        for repeat in range(args.repeats):
            order = ("without", "tensorboard") if repeat % 2 == 0 else ("tensorboard", "without")
            for way in order:
                log = ("tensorboard",) if way == "tensorboard" else ()
                times[way].append(train_once(config, seeds, root, log, args.log_every))
                wall, cpu = times[way][-1]
                report(f"  repeat {repeat + 1}: {way:<11} {wall:7.2f} s wall, {cpu:7.2f} s CPU")
    for index, kind in enumerate(("wall", "CPU")):
        without, logged = (statistics.median(t[index] for t in times[way]) for way in ("without", "tensorboard"))
        report(f"median {kind:<4} time without sinks {without:8.2f} s, with TensorBoard {logged:8.2f} s: "
               f"ratio {logged / without:.4f}")
    writes = max(timer.calls, 1)
    share = timer.seconds / sum(wall for wall, _ in times["tensorboard"])
    report(f"time in the logging calls           {timer.seconds * 1000 / writes:8.2f} ms per write of "
           f"{args.seeds} seed(s), {timer.calls} writes: {100 * share:.3f}% of the logged runs' wall time")
    with tempfile.TemporaryDirectory(prefix="tracking-cost-") as scratch:
        replayed = replay_cpu_seconds(writes, args.seeds, Path(scratch))
    cpu_without = statistics.median(cpu for _, cpu in times["without"])
    report(f"the sink's whole work, replayed     {replayed * 1000 / writes:8.2f} ms CPU per write of {args.seeds} "
           f"seed(s): {100 * replayed / (cpu_without * args.repeats):.3f}% of the CPU time without sinks")
    report(f"load average after: {os.getloadavg()[0]:.2f}")
    if args.out:
        write_atomically(args.out, "\n".join(lines) + "\n")
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
