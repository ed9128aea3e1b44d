"""`lava-bridge-bench sweep`: every method x demo set x seed of a study, as batched jobs on local
worker processes or on a Ray cluster.

    lava-bridge-bench sweep --methods auxss,omega_ss,sac --seeds 0-24 --demos 500,7500 --steps 300000 --out runs/study
    lava-bridge-bench sweep ... --backend ray                           # the same jobs on a local Ray cluster
    lava-bridge-bench sweep ... --backend ray --address HEAD_IP:6379    # ... or on a running one

An --address where no Ray cluster answers within RAY_CONNECT_TIMEOUT (30) seconds is refused before
anything is written.

Every run is the directory a single `lava-bridge-bench --method M --demos D --seed S` run writes,
at OUT/M-dD/seedS. A job is a batch of seeds of one (method, demos) trained together in one process
(`runner.train(config, dirs, seeds=batch)`); with one torch thread per job (the default) a seed's
results do not depend on its batch mates, so how the seeds are split into jobs changes the speed,
never the numbers.

Splitting: each (method, demos) group's seeds are cut into contiguous chunks of near-equal size, as
few as possible such that no job has more than --seeds-per-job seeds and the sweep has at least
--workers jobs where there are seeds enough. Few big batches, because a batch of 25 seeds trains
about 3x more seed-steps per second than one seed alone (docs/speed.md); enough jobs to keep every
worker busy.

Re-running a sweep continues it: a run whose final.pt exists and whose config.json matches is
skipped, an unfinished one resumes from its checkpoints, and a directory holding another
configuration is an error of its job, never overwritten. A failing job (a configuration its method
rejects, a foreign run directory, a crash) is reported and the other jobs go on. OUT/sweep.json
records the arguments and every job's status, error and wall time, rewritten atomically as jobs
finish; each job's output goes to OUT/logs/JOB.log, and a job that resumes its runs says from which
step. A job whose batch cannot fit in the memory available here is refused before anything is written.
Ctrl-C (or SIGTERM) asks every running job to write a checkpoint and stop, passing on the signal, so
the record says the user interrupted it (a second Ctrl-C kills them); the same command then resumes.
A local job also stops that way when the sweep's process dies without asking (SIGKILL, a crash): it
never trains on as an orphan. A rerun that finds a run directory still locked by such a stopping job waits for it (at
most LOCK_WAIT seconds) instead of failing the job.

This module holds the command and the job plan; eval/sweeps/sweep_jobs.py runs one job and the local worker
pool, eval/sweeps/sweep_ray.py the Ray backend.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import lava_bridge_mj
from lava_bridge_mj.eval.arguments import (MAX_SEEDS, apply_settings, check_writable, config_source, demo_set, device,
                                           directory, positive_int, read_config_file, seed_list, setting, signal_of,
                                           stop_reason, stopping_on_signals, usable_cpus)
from lava_bridge_mj.demos import MINARI_PREFIX
from lava_bridge_mj.eval.training.config import METHODS, RunConfig, check_batch_fits
from lava_bridge_mj.eval.sweeps import sweep_ray
from lava_bridge_mj.eval.training.run_files import lock_holder
from lava_bridge_mj.eval.sweeps.sweep_jobs import Job, SweepRecord, run_local, summary

DEMO_SETS = (500, 7500)
SEEDS_PER_JOB = 25
"""Default batch limit: the paper's 25 seeds of one method fit one job."""
RAY_EXTRA = "pip install 'lava-bridge-mj[ray]'"
LOCK_WAIT = 60.0
"""Seconds a sweep waits for run directories still locked by another process (a job of a killed sweep
writing its last checkpoint) before starting its jobs, which then fail on a directory still in use."""
PROGRESS_EVERY = 60.0
"""Seconds between the sweep's progress lines, by default."""


def split(seeds: Sequence[int], parts: int) -> list[tuple[int, ...]]:
    """`seeds` in `parts` contiguous chunks whose sizes differ by at most one, the larger first."""
    size, extra = divmod(len(seeds), parts)
    chunks, start = [], 0
    for i in range(parts):
        end = start + size + (i < extra)
        chunks.append(tuple(seeds[start:end]))
        start = end
    return chunks


def plan(methods: Sequence[str], demo_sets: Sequence[int], seeds: Sequence[int], workers: int,
         seeds_per_job: int = SEEDS_PER_JOB, env_ids: Sequence[str] = (lava_bridge_mj.ENV_ID,)) -> list[Job]:
    """The sweep's jobs, group by group (task-major, then method), each group's seeds split into the
    fewest chunks that keep every job at most `seeds_per_job` seeds and give at least `workers` jobs."""
    groups = [(env_id, method, demos) for env_id in env_ids for method in methods for demos in demo_sets]
    parts = max(math.ceil(len(seeds) / seeds_per_job), math.ceil(workers / len(groups)))
    parts = min(parts, len(seeds))
    return [Job(method, demos, chunk, env_id) for env_id, method, demos in groups for chunk in split(seeds, parts)]


def wait_for_writers(directories: Sequence[Path], timeout: float, poll: float = 0.2) -> dict[Path, str]:
    """Wait until no other process holds a lock on any of `directories` (a job of a killed sweep still
    writing its last checkpoint), at most `timeout` seconds, saying so once; returns the directories
    still locked then (their pids), {} when none is."""
    busy = {d: pid for d in directories if (pid := lock_holder(d)) is not None}
    if not busy:
        return {}
    pids = ", ".join(sorted(set(busy.values())))
    print(f"sweep: {len(busy)} run director{'y is' if len(busy) == 1 else 'ies are'} still being written by "
          f"another process (pid {pids}); waiting up to {timeout:g} s for it to stop", file=sys.stderr, flush=True)
    deadline = time.monotonic() + timeout
    while busy and time.monotonic() < deadline:
        time.sleep(poll)
        busy = {d: pid for d in busy if (pid := lock_holder(d)) is not None}
    return busy


# --- the command -------------------------------------------------------------------------------------
def _error(message: str) -> int:
    """An environment failure (not a usage error): one line, exit code 2."""
    print(f"lava-bridge-bench sweep: error: {message}", file=sys.stderr, flush=True)
    return 2


def _demo_sets(text: str) -> list:
    """An argparse type: comma-separated distinct demo sets (500, 7500, demo file paths or minari:IDs)."""
    values = [demo_set(part.strip()) for part in text.split(",")]
    values = [str(Path(value).expanduser().resolve()) if isinstance(value, str) and not value.startswith(MINARI_PREFIX)
              else value for value in values]
    names = [Path(value).stem if isinstance(value, str) else value for value in values]
    if len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(f"demo sets {text!r} name one set twice (a file's name without .npz, a "
                                         f"Minari dataset's last part, names its runs' directory)")
    return values


def _env_ids(text: str) -> list[str]:
    """An argparse type: comma-separated distinct tasks (Lava Bridge, external) or registered gymnasium ids."""
    from lava_bridge_mj.state_vector import env_spec

    known = (*lava_bridge_mj.TASKS, *lava_bridge_mj.EXTERNAL_TASKS)
    env_ids = [part.strip() for part in text.split(",")]
    for env_id in env_ids:
        if env_id not in known:
            try:
                env_spec(env_id)
            except ValueError:
                raise argparse.ArgumentTypeError(f"unknown task {env_id!r}; expected some of {', '.join(known)} "
                                                 f"or a registered gymnasium id (\"module:Id\" imports module "
                                                 f"first)") from None
    if len(set(env_ids)) != len(env_ids):
        raise argparse.ArgumentTypeError(f"tasks must be distinct, got {text!r}")
    return env_ids


def _choices(kind: str, allowed: Sequence, convert=str):
    """An argparse type: a comma-separated list of distinct values from `allowed`."""
    def parse(text: str) -> list:
        values = []
        for part in text.split(","):
            try:
                value = convert(part.strip())
            except ValueError:
                value = part.strip()
            if value not in allowed:
                raise argparse.ArgumentTypeError(f"unknown {kind} {part.strip()!r}; expected some of "
                                                 f"{', '.join(map(str, allowed))}")
            if value in values:
                raise argparse.ArgumentTypeError(f"{kind} {value} given twice")
            values.append(value)
        return values
    return parse


def build_parser() -> argparse.ArgumentParser:
    defaults = RunConfig()
    parser = argparse.ArgumentParser(
        prog="lava-bridge-bench sweep",
        description="Train every method x demo set x seed combination, each into the run directory a "
                    "single lava-bridge-bench run writes (OUT/METHOD-dDEMOS/seedSEED), as batched jobs on "
                    "local worker processes or Ray. Running it again skips finished runs and resumes "
                    "unfinished ones; OUT/sweep.json records every job's status.")
    parser.add_argument("--envs", type=_env_ids, metavar="LIST",
                        default=[lava_bridge_mj.ENV_ID],
                        help=f"comma-separated tasks, some of {', '.join(lava_bridge_mj.TASKS)} (default: "
                             f"{lava_bridge_mj.ENV_ID}), the external tasks {', '.join(lava_bridge_mj.EXTERNAL_TASKS)}, "
                             f"or other gymnasium ids with --demos FILE (docs/any-env.md); runs of another task "
                             f"go to OUT/TASK/METHOD-dDEMOS")
    parser.add_argument("--methods", required=True, type=_choices("method", METHODS), metavar="LIST",
                        help=f"comma-separated methods, some of {', '.join(METHODS)}")
    parser.add_argument("--seeds", required=True, type=seed_list, metavar="LIST",
                        help=f"e.g. 0-24 or 0,3,5-7 (at most {MAX_SEEDS:,})")
    parser.add_argument("--demos", type=_demo_sets, default=[defaults.demos],
                        metavar="LIST", help=f"comma-separated demo sets: shipped ones, 500 and/or 7500 (default: "
                                             f"{defaults.demos}), demo files (runs from FILE.npz go to "
                                             f"OUT/METHOD-dFILE) or local Minari datasets, minari:DATASET_ID "
                                             f"(runs from minari:NS/ENV/NAME go to OUT/METHOD-dNAME)")
    parser.add_argument("--steps", type=positive_int, help=f"steps per run (default: {defaults.steps})")
    parser.add_argument("--eval-every", type=positive_int, help=f"default: {defaults.eval_every}")
    parser.add_argument("--eval-episodes", type=positive_int, help=f"default: {defaults.eval_episodes}")
    parser.add_argument("--config", type=Path,
                        help="JSON file of RunConfig fields shared by every run (method, demos and seed "
                             "come from the sweep); a field a method rejects fails that method's jobs")
    parser.add_argument("--set", dest="settings", type=setting, action="append", metavar="KEY=VALUE",
                        help="one RunConfig field by its dotted name, over --config (e.g. --set sac.lr=1e-3); "
                             "as in training")
    parser.add_argument("--out", type=directory, required=True, help="directory of the sweep's runs")
    parser.add_argument("--progress-every", type=float, default=PROGRESS_EVERY, metavar="SECONDS",
                        help="print one line per running local job (step, steps/s, ETA, latest success) every "
                             "this many seconds; 0: never (default: %(default)g)")
    parser.add_argument("--workers", type=positive_int,
                        help="jobs running at once (default: the CPUs this process may use; with --backend "
                             "ray, the cluster's CPUs / --threads); also the least number of jobs the seeds "
                             "are split into")
    parser.add_argument("--seeds-per-job", type=positive_int, default=SEEDS_PER_JOB,
                        help="most seeds trained together in one job (default: %(default)s)")
    parser.add_argument("--threads", type=positive_int, default=1,
                        help="torch threads per job, and CPUs a Ray task asks for (default: 1, which keeps "
                             "a seed's numbers independent of its batch)")
    parser.add_argument("--device", type=device, default="cpu",
                        help="torch device every job trains on: cpu (default) or cuda / cuda:N where this "
                             "machine has one; as in training (local backend only: Ray tasks ask for CPUs alone)")
    parser.add_argument("--backend", choices=("local", "ray"), default="local",
                        help="local worker processes (default) or Ray tasks")
    parser.add_argument("--address", help="with --backend ray: the running cluster to use (ray.init's address); "
                                          "without it, a local cluster of --workers x --threads CPUs")
    return parser


def main(argv: list[str] | None = None) -> int:
    with stopping_on_signals():  # before any start-up work: a signal then stops the sweep too
        try:
            return _main(argv)
        except KeyboardInterrupt as stop:  # during start-up: once jobs run, _sweep records the stop
            print(f"lava-bridge-bench sweep: {stop_reason(signal_of(stop))} during start-up; no job started",
                  file=sys.stderr, flush=True)
            return 128 + signal_of(stop)


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.address is not None and args.backend != "ray":
        parser.error("--address needs --backend ray")
    if args.device != "cpu" and args.backend == "ray":
        parser.error(f"--device {args.device}: Ray tasks ask for CPUs only; train on a GPU with --backend local")
    if args.backend == "ray":
        try:
            import ray
        except ImportError:
            parser.error(f"--backend ray needs Ray, an optional extra: {RAY_EXTRA}")
    check_writable(args.out, parser)
    if not (math.isfinite(args.progress_every) and args.progress_every >= 0):
        parser.error(f"--progress-every must be a number of seconds >= 0, got {args.progress_every}")
    values = apply_settings(read_config_file(args.config, parser), args.settings, parser)
    for name in ("steps", "eval_every", "eval_episodes"):
        if getattr(args, name) is not None:
            values[name] = getattr(args, name)
    configs, rejected = {}, {}
    for env_id in args.envs:
        for method in args.methods:
            for demos in args.demos:
                group = env_id, method, demos
                try:
                    configs[group] = RunConfig.from_dict({**values, "env_id": env_id, "method": method,
                                                          "demos": demos, "seed": 0},
                                                         source=config_source(args))
                except ValueError as error:
                    rejected[group] = str(error)
    if not configs:  # wrong for every method: a usage error, not a sweep of failures
        parser.error(next(iter(rejected.values())))

    if args.backend == "local" and args.threads > usable_cpus():
        parser.error(f"--threads {args.threads}: this machine lets the sweep use {usable_cpus()} CPUs")
    if args.backend == "ray":
        try:
            workers = sweep_ray.start(args.address, args.threads,
                                      args.workers or (usable_cpus() if args.address is None else None))
        except sweep_ray.RayUnavailable as error:
            return _error(str(error))
    else:
        workers = args.workers or usable_cpus()
    try:
        return _sweep(args, argv, workers, configs, rejected)
    finally:
        if args.backend == "ray":
            ray.shutdown()


def _sweep(args: argparse.Namespace, argv, workers: int, configs: dict, rejected: dict) -> int:
    out = args.out
    jobs = plan(args.methods, args.demos, args.seeds, workers, args.seeds_per_job, args.envs)
    for group, config in configs.items():  # each job's batch alone, before anything is written
        largest = max(len(job.seeds) for job in jobs if (job.env_id, job.method, job.demos) == group)
        try:
            check_batch_fits(config, largest)
        except ValueError as error:
            return _error(f"{config.method} on {config.env_id} ({config.demos} demos): {error}; nothing written")
    try:
        (out / "logs").mkdir(parents=True, exist_ok=True)
    except OSError as error:
        return _error(f"--out {out}: cannot create {error.filename or out / 'logs'} ({error.strerror or error})")
    arguments = {"argv": list(sys.argv[1:] if argv is None else argv), "envs": args.envs, "methods": args.methods,
                 "seeds": args.seeds, "demos": args.demos, "steps": args.steps, "eval_every": args.eval_every,
                 "eval_episodes": args.eval_episodes, "config": str(args.config) if args.config else None,
                 "set": [f"{'.'.join(path)}={json.dumps(value)}" for path, value in args.settings or ()],
                 "out": str(out), "workers": workers, "seeds_per_job": args.seeds_per_job,
                 "threads": args.threads, "device": args.device, "backend": args.backend, "address": args.address}
    # a job of a sweep killed just before may still be writing its last checkpoint: what its runs
    # hold is known only once it has stopped
    still_busy = wait_for_writers([d for job in jobs for d in job.run_dirs(out)], LOCK_WAIT)
    if still_busy:
        print(f"sweep: still being written after {LOCK_WAIT:g} s: {', '.join(map(str, still_busy))}; their jobs "
              "will fail (is another sweep running into this --out?)", file=sys.stderr, flush=True)
    record = SweepRecord(out, arguments, jobs)
    todo = []
    for index, job in enumerate(jobs):
        group = job.env_id, job.method, job.demos
        if group in rejected:
            record.jobs[index].update(status="failed", error=f"configuration rejected for {job.method}: "
                                                              f"{rejected[group]}")
            continue
        config = configs[group]
        if job.finished(config, out):
            record.jobs[index].update(status="skipped", skipped=list(job.seeds))
            continue
        todo.append((index, job.spec(config, out, args.threads, args.device)))
    try:
        record.write(strict=True)
    except OSError as error:
        return _error(f"cannot write {record.path} ({error.strerror or error}); no job started")
    print(f"sweep: {len(jobs)} jobs, {sum(len(job.seeds) for job in jobs)} runs; {len(todo)} jobs to run on "
          f"{args.backend} with {workers} worker(s) x {args.threads} torch thread(s)", flush=True)

    try:  # SIGINT and SIGTERM raise KeyboardInterrupt here (main's stopping_on_signals)
        if args.backend == "ray":
            sweep_ray.run_ray(todo, record)
        else:
            run_local(todo, record, workers, args.progress_every)
        record.status = "finished"
    except KeyboardInterrupt:
        record.status = "interrupted"
    finally:
        record.write()
    print(summary(record), flush=True)
    if record.status == "interrupted":
        print("interrupted: run the same command again to resume", file=sys.stderr)
        return 130
    return 1 if any(j["status"] == "failed" for j in record.jobs) else 0


if __name__ == "__main__":
    sys.exit(main())
