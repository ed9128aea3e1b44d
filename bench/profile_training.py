"""Where a batched training job's time goes: env stepping, replay sampling, the update's parts, acting,
evaluation, checkpoints, as shares of the job's wall time.

A protocol-shaped job (default: 25 seeds of AuxSS, 3,000 steps with updates from step 1,000, one
evaluation round of 50 p0 + 50 ood episodes per seed at the end, one torch thread) runs through the
trainer (`Run.train`) with light stopwatches around its parts. Nothing in the package is changed: the
stopwatches wrap methods of this process's classes, and the update is split at its optimisers' step
hooks (critics, then actor, then entropy coefficient, then the target critics' Polyak step).
A stopwatch costs about a microsecond per call, against tens of microseconds per timed call.

    python bench/profile_training.py                    # the default job (minutes on 2 cores)
    python bench/profile_training.py --quick            # a tiny job that checks the script runs
"""

from __future__ import annotations

import argparse
import functools
import platform
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import mujoco
import numpy as np
import torch

from lava_bridge_mj.agents.sac import SACConfig
from lava_bridge_mj.eval.training import runner
from lava_bridge_mj.eval.training.runner import Run, RunConfig
from lava_bridge_mj.task_physics import LavaBridgeTask
from lava_bridge_mj.vector import LavaBridgeVectorEnv
from difficulty import code_version  # bench/ is on sys.path when this script runs

seconds: defaultdict[str, float] = defaultdict(float)
calls: defaultdict[str, int] = defaultdict(int)
in_evaluation = False


def timed(function, label):
    """`function` with its wall time added to `seconds[label]` (a callable label picks it per call;
    None: not counted, e.g. a call that an outer stopwatch already times)."""
    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            name = label() if callable(label) else label
            if name is not None:
                seconds[name] += time.perf_counter() - start
                calls[name] += 1
    return wrapper


def instrument_classes() -> None:
    """Stopwatches on the trainer's parts (this process only)."""
    global in_evaluation
    LavaBridgeVectorEnv.step = timed(LavaBridgeVectorEnv.step, "train: env step (vector env)")
    Run._start_episodes = timed(Run._start_episodes, "train: episode resets")
    runner.SeedRun.observe = timed(runner.SeedRun.observe, "train: store transitions")
    runner.SeedRun.sample = timed(runner.SeedRun.sample, "train: replay sampling")
    runner.stack_batches = timed(runner.stack_batches, "train: replay sampling")
    # evaluation steps each episode's MjData with the task itself (eval/training/evaluate.py); in training the
    # same calls run inside the vector env's step and resets, which are timed as a whole
    LavaBridgeTask.step = timed(LavaBridgeTask.step, lambda: "eval: env step (task.step)" if in_evaluation else None)
    LavaBridgeVectorEnv.reset = timed(LavaBridgeVectorEnv.reset, lambda: "eval: env reset" if in_evaluation else None)
    Run.save = timed(Run.save, "checkpoints")
    evaluate = Run.evaluate

    def evaluate_flagged(self):
        global in_evaluation
        in_evaluation = True
        try:
            return evaluate(self)
        finally:
            in_evaluation = False
    Run.evaluate = timed(evaluate_flagged, "eval: total")


def instrument_update(agent) -> None:
    """Split SAC.update at its optimisers' step hooks: the critics' step ends the critic part, the actor's
    the actor part, the entropy coefficient's the alpha part; the rest is the Polyak step and statistics."""
    marks: dict[str, float] = {}
    update, td_target = agent.update, agent.td_target

    def mark(name):
        def hook(optimizer, args, kwargs):
            marks[name] = time.perf_counter()
        return hook

    def adam_start(optimizer, args, kwargs):
        marks["adam"] = time.perf_counter()

    def adam_end(optimizer, args, kwargs):
        seconds["  of which Adam steps (3 optimisers)"] += time.perf_counter() - marks["adam"]

    for name, optimizer in (("critic", agent.critic_optimizer), ("actor", agent.actor_optimizer),
                            ("alpha", agent.alpha_optimizer)):
        optimizer.register_step_pre_hook(adam_start)
        optimizer.register_step_post_hook(adam_end)
        optimizer.register_step_post_hook(mark(name))

    def timed_target(batch):
        start = time.perf_counter()
        result = td_target(batch)
        seconds["update: TD target (actor + target critics, no grad)"] += time.perf_counter() - start
        return result

    def timed_update(batch):
        start = time.perf_counter()
        target_before = seconds["update: TD target (actor + target critics, no grad)"]
        result = update(batch)
        end = time.perf_counter()
        target = seconds["update: TD target (actor + target critics, no grad)"] - target_before
        seconds["update: critics (forward, backward, Adam)"] += marks["critic"] - start - target
        seconds["update: actor (forward through critics, backward, Adam)"] += marks["actor"] - marks["critic"]
        seconds["update: alpha (loss, backward, Adam)"] += marks["alpha"] - marks["actor"]
        seconds["update: Polyak step of target critics, statistics"] += end - marks["alpha"]
        seconds["update: total"] += end - start
        calls["update: total"] += 1
        return result

    agent.td_target, agent.update = timed_target, timed_update
    agent.act = timed(agent.act, lambda: "eval: actor forward" if in_evaluation else "train: actor forward (acting)")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--method", default="auxss")
    parser.add_argument("--seeds", type=int, default=25)
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--learning-starts", type=int, default=1000)
    parser.add_argument("--eval-episodes", type=int, default=50, help="per start distribution, in the one round")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--quick", action="store_true", help="2 seeds, 300 steps, 2+2 evaluation episodes")
    args = parser.parse_args(argv)
    if args.quick:
        args.seeds, args.steps, args.learning_starts, args.eval_episodes = 2, 300, 100, 2
    torch.set_num_threads(args.threads)
    commit = code_version()
    sac = SACConfig(learning_starts=args.learning_starts)
    configs = [RunConfig(method=args.method, seed=s, steps=args.steps, eval_every=args.steps,
                         eval_episodes=args.eval_episodes, sac=sac) for s in range(args.seeds)]
    instrument_classes()
    with tempfile.TemporaryDirectory() as out:
        dirs = [Path(out) / f"seed{s}" for s in range(args.seeds)]
        for d in dirs:
            d.mkdir()
        run = Run(configs, dirs)
        instrument_update(run.agent)
        start = time.perf_counter()
        run.train(progress=False)
        total = time.perf_counter() - start

    rows = dict(seconds)
    eval_parts = ("eval: env step (task.step)", "eval: env reset", "eval: actor forward")
    rows["eval: rest (loop, episode bookkeeping, metric and policy files)"] = (
        rows.get("eval: total", 0.0) - sum(rows.get(k, 0.0) for k in eval_parts))
    train_parts = [k for k in rows if k.startswith(("train:", "checkpoints")) or k == "update: total"]
    rows["other (training loop, bookkeeping)"] = total - rows.get("eval: total", 0.0) - sum(rows[k] for k in train_parts)
    updates = calls["update: total"]
    given = sys.argv[1:] if argv is None else argv
    print(f"# python bench/profile_training.py {' '.join(given)}".rstrip() + f" (commit {commit})")
    print(f"python {platform.python_version()} | torch {torch.__version__} | mujoco {mujoco.__version__} | "
          f"numpy {np.__version__} | {args.threads} torch thread(s)")
    print(f"job: {args.method}, {args.seeds} seeds, {args.steps} steps (updates from step {args.learning_starts}: "
          f"{updates}), one evaluation round of {args.eval_episodes} p0 + {args.eval_episodes} ood episodes per seed")
    print(f"wall time {total:.1f} s; training {total - rows.get('eval: total', 0.0):.1f} s "
          f"({args.seeds * args.steps / (total - rows.get('eval: total', 0.0)):.0f} seed-steps/s without evaluation)")
    print(f"\n{'part':<66} {'seconds':>8} {'share':>7}")
    order = ["train: env step (vector env)", "train: episode resets", "train: store transitions",
             "train: actor forward (acting)", "train: replay sampling", "update: total",
             "update: TD target (actor + target critics, no grad)", "update: critics (forward, backward, Adam)",
             "update: actor (forward through critics, backward, Adam)", "update: alpha (loss, backward, Adam)",
             "update: Polyak step of target critics, statistics", "  of which Adam steps (3 optimisers)",
             "eval: total", *eval_parts, "eval: rest (loop, episode bookkeeping, metric and policy files)",
             "checkpoints", "other (training loop, bookkeeping)"]
    for name in order:
        value = rows.get(name, 0.0)
        indent = "  " if name.startswith(("update: ", "eval: ")) and not name.endswith("total") else ""
        print(f"{indent + name:<66} {value:>8.1f} {value / total:>7.1%}")
    env = rows.get("train: env step (vector env)", 0.0) + rows.get("eval: env step (task.step)", 0.0)
    print(f"\nenv stepping, training and evaluation together: {env:.1f} s ({env / total:.1%}); "
          f"update: {rows.get('update: total', 0.0) / total:.1%}; evaluation round: {rows.get('eval: total', 0.0):.1f} s")


if __name__ == "__main__":
    main()
