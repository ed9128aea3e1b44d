"""Env-step throughput of LavaBridge-v0 against raw MuJoCo on the same compiled model.

Four loops, each doing the same number of env steps (frame_skip physics steps each) with the same
pre-generated uniform random actions:

  (a) gymnasium.make("LavaBridge-v0").step, resetting from p0 whenever an episode ends
  (b) the same on env.unwrapped (no TimeLimit / OrderEnforcing / PassiveEnvChecker wrappers)
  (c) mujoco.mj_step called frame_skip times per env step in a Python loop
  (d) mujoco.mj_step(model, data, nstep=frame_skip): the physics alone, looped in C

Target: (a) / (c) >= 0.5, i.e. the gymnasium layer (validation, per-physics-step lava and goal
checks, observation copies, wrappers) at most doubles the cost of the physics it drives.

Then vector envs at K = 1, 8, 32 sub-envs, the same total number of env steps:

  (e) gymnasium.make_vec("LavaBridge-v0", num_envs=K): the native LavaBridgeVectorEnv
  (f) gymnasium.vector.SyncVectorEnv over K gymnasium.make envs

Target: (e) at K = 32 >= 0.5 x (d), i.e. an env step inside the vector env costs at most twice
the raw C-looped physics of one env.

Last, before and after the free-motion path, side by side: the same loops with the task checking
every physics step (`task.skip_free_contacts = False`, the path every step took before) and with the
default (an env step that `free_motion` shows can meet nothing runs in C without collision
detection), alternated repeat by repeat, for the single env and the native vector env at K = 25.

Times are this process's CPU time (`time.process_time`), so that other programs on a shared machine
do not count; on an idle machine it equals the wall time of these single-threaded loops.

    python bench/env_throughput.py            # 50k env steps per loop, best of 3
    python bench/env_throughput.py --quick    # a few hundred steps: a smoke test for CI
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import lava_bridge_mj  # noqa: F401  (registers LavaBridge-v0; sets MUJOCO_GL before mujoco loads)
import gymnasium
import mujoco
import numpy as np

TARGET_RATIO = 0.5


def run_wrapped(env: gymnasium.Env, actions: np.ndarray) -> None:
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()


def run_unwrapped(env, actions: np.ndarray) -> None:
    t = 0  # no TimeLimit wrapper here: truncate by hand so episodes match (a)
    for action in actions:
        _, _, terminated, _, _ = env.step(action)
        t += 1
        if terminated or t == lava_bridge_mj.MAX_EPISODE_STEPS:
            env.reset()
            t = 0


def run_mj_step_loop(model, data, actions: np.ndarray, frame_skip: int) -> None:
    for action in actions:
        data.ctrl[:] = action
        for _ in range(frame_skip):
            mujoco.mj_step(model, data)


def run_mj_step_nstep(model, data, actions: np.ndarray, frame_skip: int) -> None:
    for action in actions:
        data.ctrl[:] = action
        mujoco.mj_step(model, data, nstep=frame_skip)


def run_vector(envs, actions: np.ndarray) -> None:
    """actions: (steps, K, 2); autoreset is the vector env's own (next step)."""
    for batch in actions:
        envs.step(batch)


def best_rate(run, n_steps: int, repeats: int) -> float:
    """Best-of-`repeats` env steps per CPU second of `run()`, which performs n_steps env steps."""
    best = float("inf")
    for _ in range(repeats):
        start = time.process_time()
        run()
        best = min(best, time.process_time() - start)
    return n_steps / best


def set_checked(env, checked: bool) -> None:
    """Make `env` (single or vector) check every physics step (the path before free motion) or not."""
    env.unwrapped.task.skip_free_contacts = not checked


def before_after(cases: dict, repeats: int) -> dict[str, tuple[float, float]]:
    """(checked, free-motion) env steps per CPU second of each case (env, run, n_steps), the two paths
    alternated repeat by repeat so that both see the same machine."""
    best = {name: [float("inf"), float("inf")] for name in cases}
    for _ in range(repeats):
        for name, (env, run, n_steps) in cases.items():
            for index, checked in enumerate((True, False)):
                set_checked(env, checked)
                start = time.process_time()
                run()
                best[name][index] = min(best[name][index], time.process_time() - start)
            set_checked(env, False)
    return {name: (cases[name][2] / old, cases[name][2] / new) for name, (old, new) in best.items()}


def free_share(envs, batches: np.ndarray) -> float:
    """Share of sub-env steps that take the free-motion path under `batches` of actions (untimed)."""
    task, free = envs.unwrapped.task, 0
    envs.reset(seed=0)
    for batch in batches:
        free += sum(task.free_motion(data) for data in envs.unwrapped.datas)
        envs.step(batch)
    return free / batches.shape[0] / batches.shape[1]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=50_000, help="env steps per timed loop (default 50000)")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats per loop; the best counts")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="a tiny run (300 steps) to check the script works")
    args = parser.parse_args(argv)
    n = 300 if args.quick else args.steps
    if n < 1 or args.repeats < 1:
        parser.error("--steps and --repeats must be positive")

    cores = os.cpu_count()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else cores
    print(f"python {platform.python_version()} | mujoco {mujoco.__version__} | gymnasium {gymnasium.__version__} "
          f"| numpy {np.__version__}")
    print(f"machine: {platform.machine()} {platform.processor() or ''}".rstrip()
          + f", {cores} cores ({usable} usable by this process), {sys.platform}")

    rng = np.random.default_rng(args.seed)
    actions = rng.uniform(-1, 1, size=(n, 2)).astype(np.float32)
    warmup = actions[: min(n, 1000)]

    wrapped = gymnasium.make("LavaBridge-v0")
    wrapped.reset(seed=args.seed)
    unwrapped = gymnasium.make("LavaBridge-v0").unwrapped
    unwrapped.reset(seed=args.seed)
    model = unwrapped.model
    frame_skip = unwrapped.frame_skip
    data_loop, data_nstep = mujoco.MjData(model), mujoco.MjData(model)
    for data in (data_loop, data_nstep):  # start where the envs start: at rest in a p0 blob
        data.qpos[:] = unwrapped.get_state()[:2]
        mujoco.mj_forward(model, data)

    loops = {
        "(a) gymnasium.make(...).step": lambda acts: run_wrapped(wrapped, acts),
        "(b) env.unwrapped.step": lambda acts: run_unwrapped(unwrapped, acts),
        f"(c) mj_step x{frame_skip}, Python loop": lambda acts: run_mj_step_loop(model, data_loop, acts, frame_skip),
        f"(d) mj_step(nstep={frame_skip})": lambda acts: run_mj_step_nstep(model, data_nstep, acts, frame_skip),
    }
    rates = {}
    for name, run in loops.items():
        run(warmup)
        rates[name] = best_rate(lambda: run(actions), n, args.repeats)
    wrapped.close()

    print(f"\n{n} env steps x {frame_skip} physics steps of {model.opt.timestep:g} s, best of {args.repeats}")
    print(f"{'loop':<34} {'env steps/s':>12} {'us/env step':>12} {'physics steps/s':>16}")
    for name, rate in rates.items():
        print(f"{name:<34} {rate:>12,.0f} {1e6 / rate:>12.1f} {rate * frame_skip:>16,.0f}")
    a, b, c, d = rates.values()
    print()
    for label, ratio in (("(a)/(c)", a / c), ("(a)/(d)", a / d), ("(b)/(c)", b / c), ("(b)/(d)", b / d)):
        print(f"ratio {label}: {ratio:.3f}")
    vector_rates = {}
    for k in (1, 8, 32):
        batches = rng.uniform(-1, 1, size=(max(1, n // k), k, 2)).astype(np.float32)
        for label, envs in ((f"(e) make_vec native, K={k}", gymnasium.make_vec("LavaBridge-v0", num_envs=k)),
                            (f"(f) SyncVectorEnv, K={k}", gymnasium.make_vec("LavaBridge-v0", num_envs=k,
                                                                              vectorization_mode="sync"))):
            envs.reset(seed=args.seed)
            run_vector(envs, batches[: max(1, 1000 // k)])
            vector_rates[label] = best_rate(lambda: run_vector(envs, batches), batches.shape[0] * k, args.repeats)
            envs.close()
    print(f"\n{'vector env':<34} {'env steps/s':>12} {'us/env step':>12} {'x (d)':>8}")
    for name, rate in vector_rates.items():
        print(f"{name:<34} {rate:>12,.0f} {1e6 / rate:>12.1f} {rate / d:>8.3f}")
    native32, sync32 = vector_rates["(e) make_vec native, K=32"], vector_rates["(f) SyncVectorEnv, K=32"]
    print(f"native / SyncVectorEnv at K=32: {native32 / sync32:.2f}x")

    k = 25
    batches = rng.uniform(-1, 1, size=(max(1, n // k), k, 2)).astype(np.float32)
    single, vector = gymnasium.make("LavaBridge-v0").unwrapped, gymnasium.make_vec("LavaBridge-v0", num_envs=k)
    single.reset(seed=args.seed)
    vector.reset(seed=args.seed)
    compared = before_after({
        "env.unwrapped.step": (single, lambda: run_unwrapped(single, actions), n),
        f"make_vec native, K={k}": (vector, lambda: run_vector(vector, batches), batches.shape[0] * k),
    }, args.repeats)
    print(f"\nbefore / after the free-motion path (same actions, alternated; {free_share(vector, batches):.0%} of "
          f"the K={k} sub-env steps took it)")
    print(f"{'loop':<34} {'checked steps/s':>16} {'free-motion steps/s':>20} {'after / before':>15}")
    for name, (old, new) in compared.items():
        print(f"{name:<34} {old:>16,.0f} {new:>20,.0f} {new / old:>15.2f}")
    print(f"{'(d) mj_step(nstep=10), for scale':<34} {d:>16,.0f}")
    vector.close()

    met = a / c >= TARGET_RATIO
    print(f"\ntarget (a)/(c) >= {TARGET_RATIO} (gymnasium layer costs at most 2x the raw mj_step loop): "
          f"{'MET' if met else 'NOT MET'} ({a / c:.3f}); against C-looped physics (a)/(d) = {a / d:.3f}"
          f" {'>=' if a / d >= TARGET_RATIO else '<'} {TARGET_RATIO}")
    print(f"target (e) at K=32 >= {TARGET_RATIO} x (d): {'MET' if native32 / d >= TARGET_RATIO else 'NOT MET'} "
          f"({native32 / d:.3f})")


if __name__ == "__main__":
    main()
