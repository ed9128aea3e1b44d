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
about 3x more seed-steps per second than one seed alone (README, Speed); enough jobs to keep every
worker busy.

Re-running a sweep continues it: a run whose final.pt exists and whose config.json matches is
skipped, an unfinished one resumes from its checkpoints, and a directory holding another
configuration is an error of its job, never overwritten. A failing job (a configuration its method
rejects, a foreign run directory, a crash) is reported and the other jobs go on. OUT/sweep.json
records the arguments and every job's status, error and wall time, rewritten atomically as jobs
finish; each job's output goes to OUT/logs/JOB.log. Ctrl-C (or SIGTERM) asks every running job to
write a checkpoint and stop (a second Ctrl-C kills them); the same command then resumes. A local job
also stops that way when the sweep's process dies without asking (SIGKILL, a crash): it never trains on
as an orphan. A rerun that finds a run directory still locked by such a stopping job waits for it (at
most LOCK_WAIT seconds) instead of failing the job.
"""

from __future__ import annotations

import argparse
import ctypes
import dataclasses
import json
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Sequence
from contextlib import redirect_stderr, redirect_stdout
from datetime import datetime, timezone
from pathlib import Path

import lava_bridge_mj
from lava_bridge_mj.eval.atomic import atomic_write_text
from lava_bridge_mj.eval.arguments import (check_writable, format_seeds, in_main_thread, parse_seeds, positive_int,
                                           raise_keyboard_interrupt, read_config_file)
from lava_bridge_mj.eval.config import METHODS, RunConfig
from lava_bridge_mj.eval.run_files import DamagedFileError, load_torch, lock_holder, read_config

DEMO_SETS = (500, 7500)
SEEDS_PER_JOB = 25
"""Default batch limit: the paper's 25 seeds of one method fit one job."""
RAY_EXTRA = "pip install 'lava-bridge-mj[ray]'"
JOB_COMMAND = ("import sys; from lava_bridge_mj.eval.sweep import job_main; "
               "job_main(sys.argv[1], sys.argv[2], int(sys.argv[3]))")
"""How a local worker process is started: python -c JOB_COMMAND SPEC_JSON RESULT_FILE SWEEP_PID."""
LOCK_WAIT = 60.0
"""Seconds a sweep waits for run directories still locked by another process (a job of a killed sweep
writing its last checkpoint) before starting its jobs, which then fail on a directory still in use."""
PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
RAY_CONNECT_TIMEOUT = 30.0
"""Seconds `--address` may take to answer before the sweep gives up (ray.init itself retries for many
minutes against an address where no cluster answers)."""
RAY_PROBE = "import sys, ray; ray.init(address=sys.argv[1], log_to_driver=False); ray.shutdown()"
MAX_SEEDS = 1000
"""Most seeds one --seeds list may name: a typo such as 0-99999999 is refused instead of planning for hours."""


@dataclasses.dataclass(frozen=True)
class Job:
    """A batch of seeds of one (task, method, demos) group, trained together in one process."""

    method: str
    demos: int
    seeds: tuple[int, ...]
    env_id: str = lava_bridge_mj.ENV_ID

    @property
    def group(self) -> str:
        """The directory under the sweep's OUT that holds this method's runs on this demo set:
        METHOD-dDEMOS for LavaBridge-v0, ENV_ID/METHOD-dDEMOS for the suite's other tasks."""
        name = f"{self.method}-d{self.demos}"
        return name if self.env_id == lava_bridge_mj.ENV_ID else f"{self.env_id}/{name}"

    @property
    def name(self) -> str:
        return f"{self.group} seeds {format_seeds(self.seeds)}"

    @property
    def log_name(self) -> str:
        return f"{self.group.replace('/', '_')}_seeds{format_seeds(self.seeds)}.log"

    def run_dirs(self, out: Path) -> list[Path]:
        return [Path(out) / self.group / f"seed{seed}" for seed in self.seeds]


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


def seed_status(config: RunConfig, directory: Path) -> str:
    """'finished' (final.pt and this configuration), 'foreign' (config.json of another run, or
    unreadable) or 'todo' (nothing yet, this configuration unfinished, or finished at another budget)."""
    try:
        existing = read_config(directory)
    except DamagedFileError:
        return "foreign"
    if existing is None:
        return "todo"
    if not config.continues(existing):
        return "foreign"
    # a run finished at a smaller budget is todo: the resume extends it to this one
    return "finished" if existing == config.to_dict() and (directory / "final.pt").exists() else "todo"


def _foreign_error(config: RunConfig, directory: Path) -> str:
    try:
        existing = read_config(directory)
    except DamagedFileError as error:
        return f"{error}; not training into it"
    differ = sorted(k for k, v in config.to_dict().items()
                    if k != "steps" and (not isinstance(existing, dict) or existing.get(k) != v))
    return (f"{directory} holds a run with another configuration (differs in {', '.join(differ)}); not "
            "overwriting it: move it away or sweep into another --out")


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


def _checkpoint_step(directory: Path):
    """The step of the run's latest checkpoint; None without one; the error text if it is unreadable
    (that seed then trains in a batch of its own, where the trainer reports the error)."""
    path = directory / "checkpoint.pt"
    if not path.exists():
        return None
    try:
        return int(load_torch(path)["step"])
    except Exception as error:  # noqa: BLE001 - whatever it is, the trainer names it
        return f"unreadable {path}: {error}"


def run_job(job: Job, config_values: dict, out: str | Path, threads: int = 1) -> dict:
    """Train the unfinished seeds of `job` into their run directories. Never raises: the result's
    "status" is done, skipped (every seed already finished), failed (with "error") or interrupted.

    Seeds already finished are skipped; seeds with checkpoints resume from them, grouped into one
    batch per checkpoint step (a batch resumes only from a step all its seeds share); a directory
    that holds another configuration is an error, and the job's other seeds still train."""
    from lava_bridge_mj.eval.runner import RunInterrupted, train  # loads torch: the planner does not

    started = time.perf_counter()
    result = {"status": "done", "trained": [], "skipped": [], "resumed": {}, "diverged": {}, "error": None}
    errors = []
    try:
        import torch

        torch.set_num_threads(threads)  # before any torch work
        config = RunConfig.from_dict(config_values, source=job.group)
        batches: dict = {}
        for seed, directory in zip(job.seeds, job.run_dirs(Path(out))):
            seed_config = dataclasses.replace(config, seed=seed)
            status = seed_status(seed_config, directory)
            if status == "finished":
                result["skipped"].append(seed)
            elif status == "foreign":
                errors.append(_foreign_error(seed_config, directory))
            else:
                batches.setdefault(_checkpoint_step(directory), []).append(seed)
        for step, seeds in batches.items():
            resumed = f" from their checkpoints at step {step}" if isinstance(step, int) else ""
            print(f"{job.group}: training seeds {format_seeds(seeds)}{resumed}", flush=True)
            try:
                run = train(config, [Path(out) / job.group / f"seed{s}" for s in seeds], seeds=seeds,
                            resume=True, progress=False)
            except RunInterrupted:
                raise
            except Exception as error:  # noqa: BLE001 - one batch's failure must not stop the others
                traceback.print_exc()
                errors.append(f"seeds {format_seeds(seeds)}: {type(error).__name__}: {error}")
                continue
            result["trained"].extend(seeds)
            result["diverged"].update({str(s): at for s, at in run.diverged.items()})  # stopped, the rest trained
            if isinstance(step, int):
                result["resumed"].update({str(s): step for s in seeds})
        if errors:
            result.update(status="failed", error="; ".join(errors))
        elif not result["trained"]:
            result["status"] = "skipped"
    except RunInterrupted as stop:
        result.update(status="interrupted", error="; ".join([*errors, str(stop)]))
    except Exception as error:  # noqa: BLE001 - reported in the result, never raised
        traceback.print_exc()
        result.update(status="failed", error="; ".join([*errors, f"{type(error).__name__}: {error}"]))
    result["wall_time"] = round(time.perf_counter() - started, 2)
    print(f"{job.name}: {result['status']} in {result['wall_time']} s", flush=True)
    return result


def _spec(job: Job, config: RunConfig, out: Path, threads: int) -> dict:
    return {"method": job.method, "demos": job.demos, "seeds": list(job.seeds), "env_id": job.env_id,
            "config": config.to_dict(),
            "out": str(out.resolve()), "threads": threads}


def _run_spec(spec: dict) -> dict:
    job = Job(spec["method"], spec["demos"], tuple(spec["seeds"]), spec["env_id"])
    return run_job(job, spec["config"], spec["out"], spec["threads"])


def job_main(spec_json: str, result_file: str, sweep_pid: int | None = None) -> None:
    """A local worker process: run one job, write its result (JSON) to `result_file`. With
    `sweep_pid`, the job stops (checkpoint first) when that process, its parent, dies."""
    if sweep_pid is not None:
        die_with_parent(sweep_pid)
    atomic_write_text(result_file, json.dumps(_run_spec(json.loads(spec_json))))


def die_with_parent(parent_pid: int, poll_interval: float = 1.0, use_prctl: bool = True) -> None:
    """Send this process one SIGTERM when its parent `parent_pid` dies, so that a job whose sweep was
    killed writes a checkpoint and stops instead of training on unseen (its own process session shields
    it from the terminal's signals). Linux: the kernel's parent-death signal (prctl PR_SET_PDEATHSIG);
    elsewhere, or if that fails, a daemon thread that polls os.getppid() every `poll_interval` s.

    The kernel's signal is SIGHUP, turned into a single SIGTERM here: it is sent again each time the
    orphan is handed on (from the dying parent's forking thread to its other threads, then to a
    subreaper), and a second SIGTERM would make the trainer stop without its checkpoint."""
    stopped = threading.Event()

    def stop(*_) -> None:
        if not stopped.is_set():
            stopped.set()
            os.kill(os.getpid(), signal.SIGTERM)

    armed = False
    if use_prctl and sys.platform.startswith("linux"):
        signal.signal(signal.SIGHUP, stop)
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(PR_SET_PDEATHSIG, signal.SIGHUP, 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent_pid:  # the parent died before the signal was armed: nothing would send it
        stop()
        return
    if not armed:
        def watch() -> None:
            while os.getppid() == parent_pid:
                time.sleep(poll_interval)
            stop()

        threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def _ray_job(spec: dict, log: str) -> dict:
    """A Ray task: one job, its output appended to the job's log (OUT must be on a filesystem every
    node sees, as the run directories are)."""
    with open(log, "a") as stream, redirect_stdout(stream), redirect_stderr(stream):
        return _run_spec(spec)


def worker_environment(threads: int) -> dict[str, str]:
    """Environment variables for job processes, where the user has not set them: OpenMP threads
    that sleep rather than spin while waiting (spinning threads of several processes on shared
    cores were measured to slow training about 100x), and a pool of `threads` threads."""
    wanted = {"OMP_WAIT_POLICY": "PASSIVE", "OMP_NUM_THREADS": str(threads)}
    return {name: os.environ.get(name, value) for name, value in wanted.items()}


class SweepRecord:
    """OUT/sweep.json: the sweep's arguments and one entry per job, rewritten atomically on each change."""

    def __init__(self, out: Path, arguments: dict, jobs: list[Job]):
        self.path = out / "sweep.json"
        self.arguments = arguments
        self.started_at = datetime.now(timezone.utc).isoformat(timespec="seconds")
        self.start = time.perf_counter()
        self.status = "running"
        self.jobs = [{"job": job.name, "method": job.method, "demos": job.demos, "seeds": list(job.seeds),
                      "dirs": [str(d) for d in job.run_dirs(out)], "log": str(out / "logs" / job.log_name),
                      "status": "pending", "trained": [], "skipped": [], "resumed": {}, "diverged": {}, "error": None,
                      "wall_time": None} for job in jobs]

    def update(self, index: int, **fields) -> None:
        self.jobs[index].update(fields)
        self.write()

    def write(self, strict: bool = False) -> None:
        """Rewrite the record; an OSError (disk full, ...) is raised if `strict`, else reported in one
        line, once per kind of error: the jobs go on, and their run directories hold what they did."""
        record = {"arguments": self.arguments, "started_at": self.started_at, "status": self.status,
                  "wall_time": round(time.perf_counter() - self.start, 2), "jobs": self.jobs}
        try:
            atomic_write_text(self.path, json.dumps(record, indent=2) + "\n")
        except OSError as error:
            if strict:
                raise
            if error.strerror != getattr(self, "_reported", None):
                self._reported = error.strerror
                print(f"sweep: warning: cannot write {self.path} ({error.strerror or error}); the jobs go on and "
                      "their run directories hold their results", file=sys.stderr, flush=True)


# --- backends: each runs `todo` (indices into the record's jobs, with their specs) and records results --
def run_local(todo: list[tuple[int, dict]], record: SweepRecord, workers: int) -> None:
    """Run the jobs in at most `workers` worker processes at a time, each a fresh Python process (so a
    crash, even a segfault, fails only its job). KeyboardInterrupt: stop them, then re-raise."""
    env = {**os.environ, **worker_environment(todo[0][1]["threads"])} if todo else {}
    queue, running = list(todo), {}
    with tempfile.TemporaryDirectory(prefix="lava-bridge-sweep-") as results:
        try:
            while queue or running:
                while queue and len(running) < workers:
                    index, spec = queue.pop(0)
                    result_file = Path(results) / f"job{index}.json"
                    log = Path(record.jobs[index]["log"])
                    try:
                        with open(log, "ab") as stream:  # the child holds its own descriptor
                            stream.write(f"--- {datetime.now().isoformat(timespec='seconds')}: "
                                         f"{record.jobs[index]['job']}\n".encode())
                            stream.flush()
                            # its own session: a terminal's Ctrl-C reaches only this process, which
                            # forwards exactly one SIGTERM (a second one would skip the checkpoint); the
                            # job gets SIGTERM too if this process dies (die_with_parent)
                            process = subprocess.Popen([sys.executable, "-c", JOB_COMMAND, json.dumps(spec),
                                                        str(result_file), str(os.getpid())], env=env,
                                                       stdout=stream, stderr=subprocess.STDOUT,
                                                       start_new_session=True)
                    except OSError as error:  # the log cannot be written (disk full, ...), no process
                        record.update(index, status="failed", error=f"cannot start the job with its log in {log}: "
                                                                    f"{error.strerror or error}")
                        _print_finished(record.jobs[index])
                        continue
                    running[index] = (process, result_file, spec)
                    record.update(index, status="running")
                    print(f"started {record.jobs[index]['job']} (pid {process.pid})", flush=True)
                for index in [i for i, (process, *_) in running.items() if process.poll() is not None]:
                    _finish(record, index, *running.pop(index))
                time.sleep(0.1)
        except KeyboardInterrupt:
            print(f"stopping {len(running)} running job(s): each writes a checkpoint first "
                  "(Ctrl-C again to kill them at once)", file=sys.stderr, flush=True)
            for process, *_ in running.values():
                process.send_signal(signal.SIGTERM)
            try:
                for process, *_ in running.values():
                    process.wait()
            except KeyboardInterrupt:
                for process, *_ in running.values():
                    process.kill()
                    process.wait()
            for index, (process, result_file, spec) in running.items():
                _finish(record, index, process, result_file, spec, stopped=True)
            raise


def _finish(record: SweepRecord, index: int, process: subprocess.Popen, result_file: Path, spec: dict,
            stopped: bool = False) -> None:
    if result_file.exists():
        result = json.loads(result_file.read_text())
    else:  # killed, or crashed below Python
        log = Path(record.jobs[index]["log"])
        lines = log.read_text(errors="replace").strip().splitlines() if log.exists() else []
        last = f": {lines[-1]}" if lines else ""
        result = _without_result(spec, "interrupted" if stopped else "failed",
                                 f"the job's process exited with code {process.returncode} and no result{last} "
                                 f"(see {log})")
    record.update(index, **result)
    _print_finished(record.jobs[index])


def _without_result(spec: dict, status: str, error: str) -> dict:
    """The record of a job that ended without reporting: `status` with `error`, unless every one of
    its runs is finished (it was stopped after its last write), which makes it done."""
    if _all_finished(spec):
        return {"status": "done", "error": None}
    return {"status": status, "error": error}


def _all_finished(spec: dict) -> bool:
    try:
        config = RunConfig.from_dict(spec["config"], source="the sweep")
    except ValueError:
        return False
    job = Job(spec["method"], spec["demos"], tuple(spec["seeds"]), spec["env_id"])
    return all(seed_status(dataclasses.replace(config, seed=seed), directory) == "finished"
               for seed, directory in zip(job.seeds, job.run_dirs(Path(spec["out"]))))


def run_ray(todo: list[tuple[int, dict]], record: SweepRecord) -> None:
    """Submit every job as a Ray task asking for `threads` CPUs; record each result as it arrives.
    KeyboardInterrupt: cancel them (a running task gets SIGINT, checkpoints and stops), then re-raise."""
    import ray

    task = ray.remote(max_retries=0)(_ray_job)  # a failure is reported, not repeated
    specs = dict(todo)
    refs = {task.options(num_cpus=spec["threads"]).remote(spec, record.jobs[index]["log"]): index
            for index, spec in todo}
    for index, _ in todo:
        record.update(index, status="submitted")
    try:
        while refs:
            done, _ = ray.wait(list(refs), num_returns=1)
            for ref in done:
                index = refs.pop(ref)
                _collect_ray(record, index, ref, specs[index])
    except KeyboardInterrupt:
        print(f"cancelling {len(refs)} job(s): running ones write a checkpoint first", file=sys.stderr, flush=True)
        for ref in refs:
            ray.cancel(ref)
        for ref, index in refs.items():
            _collect_ray(record, index, ref, specs[index], stopped=True)
        raise


def _collect_ray(record: SweepRecord, index: int, ref, spec: dict, stopped: bool = False) -> None:
    import ray

    try:
        result = ray.get(ref)
    except ray.exceptions.TaskCancelledError:
        result = {"status": "pending" if record.jobs[index]["status"] == "submitted" else "interrupted"}
    except Exception as error:  # noqa: BLE001 - the worker died, the node was lost, ...
        result = _without_result(spec, "interrupted" if stopped else "failed", f"{type(error).__name__}: {error}")
    record.update(index, **result)
    _print_finished(record.jobs[index])


def _print_finished(entry: dict) -> None:
    error = f": {entry['error']}" if entry.get("error") else ""
    wall = f" in {entry['wall_time']} s" if entry.get("wall_time") is not None else ""
    diverged = ", ".join(f"seed {seed} at step {step}" for seed, step in (entry.get("diverged") or {}).items())
    diverged = f" (diverged and stopped: {diverged})" if diverged else ""
    print(f"{entry['status']} {entry['job']}{wall}{diverged}{error}", flush=True)


def summary(record: SweepRecord) -> str:
    """A table of the jobs (status, seeds trained and skipped, wall time), then their errors."""
    width = max(len("job"), *(len(j["job"]) for j in record.jobs))
    lines = [f"{'job':<{width}}  {'status':<11}  trained  skipped  wall time"]
    for j in record.jobs:
        wall = f"{j['wall_time']:.1f} s" if j["wall_time"] is not None else "-"
        lines.append(f"{j['job']:<{width}}  {j['status']:<11}  {len(j['trained']):>7}  {len(j['skipped']):>7}  "
                     f"{wall:>9}")
    counts = {}
    for j in record.jobs:
        counts[j["status"]] = counts.get(j["status"], 0) + 1
    lines.append(f"{len(record.jobs)} jobs: " + ", ".join(f"{n} {status}" for status, n in counts.items())
                 + f"; {time.perf_counter() - record.start:.1f} s; record in {record.path}")
    lines += [f"error in {j['job']}: {j['error']} (log: {j['log']})" for j in record.jobs
              if j["status"] == "failed"]
    return "\n".join(lines)


# --- the command -------------------------------------------------------------------------------------
def seed_list(text: str) -> list[int]:
    """An argparse type: parse_seeds' list ('0-24', '0,3,5-7'), refused beyond MAX_SEEDS seeds before
    it is built."""
    count = 0
    for part in text.split(","):
        low, dash, high = part.strip().partition("-")
        try:
            count += int(high) - int(low) + 1 if dash else 1
        except ValueError:
            break  # parse_seeds names the malformed part
    if count > MAX_SEEDS:
        raise argparse.ArgumentTypeError(f"expected at most {MAX_SEEDS:,} seeds, got {count:,} in {text!r}")
    return parse_seeds(text)


def ray_unreachable(address: str, timeout: float = RAY_CONNECT_TIMEOUT) -> str | None:
    """Why no Ray cluster can be used at `address` (one line), or None when one answers within
    `timeout` seconds. A host:port that refuses TCP connections is named at once; otherwise ray.init is
    tried in a child process, killed if it has not connected by then."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if host and port.isdigit():
        try:
            socket.create_connection((host.strip("[]"), int(port)), timeout=min(timeout, 10.0)).close()
        except OSError as error:
            return f"nothing accepts connections at {host}:{port} ({error.strerror or error})"
    try:
        probe = subprocess.run([sys.executable, "-c", RAY_PROBE, address], capture_output=True, text=True,
                               timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"no Ray cluster answered within {timeout:g} s"
    if probe.returncode != 0:
        return _last_line(probe.stderr) or f"ray.init exited with code {probe.returncode}"
    return None


def _last_line(text: str) -> str:
    """The last non-empty line of `text` (an exception's own last line says what went wrong), cut to 300
    characters: error messages stay one line."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1][:300] if lines else ""


def _error(message: str) -> int:
    """An environment failure (not a usage error): one line, exit code 2."""
    print(f"lava-bridge-bench sweep: error: {message}", file=sys.stderr, flush=True)
    return 2


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
    parser.add_argument("--envs", type=_choices("task", tuple(lava_bridge_mj.TASKS)), metavar="LIST",
                        default=[lava_bridge_mj.ENV_ID],
                        help=f"comma-separated tasks, some of {', '.join(lava_bridge_mj.TASKS)} (default: "
                             f"{lava_bridge_mj.ENV_ID}); runs of another task go to OUT/TASK/METHOD-dDEMOS")
    parser.add_argument("--methods", required=True, type=_choices("method", METHODS), metavar="LIST",
                        help=f"comma-separated methods, some of {', '.join(METHODS)}")
    parser.add_argument("--seeds", required=True, type=seed_list, metavar="LIST",
                        help=f"e.g. 0-24 or 0,3,5-7 (at most {MAX_SEEDS:,})")
    parser.add_argument("--demos", type=_choices("demo set", DEMO_SETS, int), default=[defaults.demos],
                        metavar="LIST", help=f"comma-separated shipped demo sets, 500 and/or 7500 (default: "
                                             f"{defaults.demos})")
    parser.add_argument("--steps", type=positive_int, help=f"steps per run (default: {defaults.steps})")
    parser.add_argument("--eval-every", type=positive_int, help=f"default: {defaults.eval_every}")
    parser.add_argument("--eval-episodes", type=positive_int, help=f"default: {defaults.eval_episodes}")
    parser.add_argument("--config", type=Path,
                        help="JSON file of RunConfig fields shared by every run (method, demos and seed "
                             "come from the sweep); a field a method rejects fails that method's jobs")
    parser.add_argument("--out", type=Path, required=True, help="directory of the sweep's runs")
    parser.add_argument("--workers", type=positive_int,
                        help="jobs running at once (default: the CPUs this process may use; with --backend "
                             "ray, the cluster's CPUs / --threads); also the least number of jobs the seeds "
                             "are split into")
    parser.add_argument("--seeds-per-job", type=positive_int, default=SEEDS_PER_JOB,
                        help="most seeds trained together in one job (default: %(default)s)")
    parser.add_argument("--threads", type=positive_int, default=1,
                        help="torch threads per job, and CPUs a Ray task asks for (default: 1, which keeps "
                             "a seed's numbers independent of its batch)")
    parser.add_argument("--backend", choices=("local", "ray"), default="local",
                        help="local worker processes (default) or Ray tasks")
    parser.add_argument("--address", help="with --backend ray: the running cluster to use (ray.init's address); "
                                          "without it, a local cluster of --workers x --threads CPUs")
    return parser


def _local_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.address is not None and args.backend != "ray":
        parser.error("--address needs --backend ray")
    if args.backend == "ray":
        try:
            import ray
        except ImportError:
            parser.error(f"--backend ray needs Ray, an optional extra: {RAY_EXTRA}")
    check_writable(args.out, parser)
    values = read_config_file(args.config, parser)
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
                                                         source=f"--config {args.config}" if args.config else "options")
                except ValueError as error:
                    rejected[group] = str(error)
    if not configs:  # wrong for every method: a usage error, not a sweep of failures
        parser.error(next(iter(rejected.values())))

    if args.backend == "local" and args.threads > _local_cpus():
        parser.error(f"--threads {args.threads}: this machine lets the sweep use {_local_cpus()} CPUs")
    if args.backend == "ray":
        env = {"env_vars": worker_environment(args.threads)}
        if args.address is not None:
            reason = ray_unreachable(args.address)
            if reason is not None:
                return _error(f"--address {args.address}: cannot connect to a Ray cluster: {reason}")
        try:
            if args.address is None:
                workers = args.workers or _local_cpus()
                ray.init(num_cpus=workers * args.threads, include_dashboard=False, runtime_env=env)
            else:
                ray.init(address=args.address, runtime_env=env)
        except Exception as error:  # noqa: BLE001 - ConnectionError, a bad address, a version mismatch, ...
            where = f"--address {args.address}: cannot connect to Ray" if args.address else "cannot start a local Ray"
            return _error(f"{where} ({type(error).__name__}: {_last_line(str(error))})")
        if args.address is not None:
            largest = max((node["Resources"].get("CPU", 0) for node in ray.nodes() if node.get("Alive")), default=0)
            if args.threads > largest:
                ray.shutdown()
                return _error(f"--threads {args.threads}: no node of the Ray cluster at {args.address} has that many "
                              f"CPUs (the most: {largest:g}); its tasks would wait forever")
            workers = args.workers or max(1, int(ray.cluster_resources().get("CPU", 1) // args.threads))
    else:
        workers = args.workers or _local_cpus()
    try:
        return _sweep(args, argv, workers, configs, rejected)
    finally:
        if args.backend == "ray":
            ray.shutdown()


def _sweep(args: argparse.Namespace, argv, workers: int, configs: dict, rejected: dict) -> int:
    out = args.out
    jobs = plan(args.methods, args.demos, args.seeds, workers, args.seeds_per_job, args.envs)
    try:
        (out / "logs").mkdir(parents=True, exist_ok=True)
    except OSError as error:
        return _error(f"--out {out}: cannot create {error.filename or out / 'logs'} ({error.strerror or error})")
    arguments = {"argv": list(sys.argv[1:] if argv is None else argv), "envs": args.envs, "methods": args.methods,
                 "seeds": args.seeds, "demos": args.demos, "steps": args.steps, "eval_every": args.eval_every,
                 "eval_episodes": args.eval_episodes, "config": str(args.config) if args.config else None,
                 "out": str(out), "workers": workers, "seeds_per_job": args.seeds_per_job,
                 "threads": args.threads, "backend": args.backend, "address": args.address}
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
        if all(seed_status(dataclasses.replace(config, seed=seed), d) == "finished"
               for seed, d in zip(job.seeds, job.run_dirs(out))):
            record.jobs[index].update(status="skipped", skipped=list(job.seeds))
            continue
        todo.append((index, _spec(job, config, out, args.threads)))
    try:
        record.write(strict=True)
    except OSError as error:
        return _error(f"cannot write {record.path} ({error.strerror or error}); no job started")
    print(f"sweep: {len(jobs)} jobs, {sum(len(job.seeds) for job in jobs)} runs; {len(todo)} jobs to run on "
          f"{args.backend} with {workers} worker(s) x {args.threads} torch thread(s)", flush=True)

    previous = {}
    if args.backend == "local" and in_main_thread():
        # SIGTERM stops the sweep as Ctrl-C does. SIGINT is set explicitly too (as the training CLI
        # does): a process a script starts in the background inherits SIGINT ignored, and Python
        # then leaves it ignored, so Ctrl-C or `kill -INT` would not stop the sweep
        previous = {sig: signal.signal(sig, raise_keyboard_interrupt) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        if args.backend == "ray":
            run_ray(todo, record)
        else:
            run_local(todo, record, workers)
        record.status = "finished"
    except KeyboardInterrupt:
        record.status = "interrupted"
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        record.write()
    print(summary(record), flush=True)
    if record.status == "interrupted":
        print("interrupted: run the same command again to resume", file=sys.stderr)
        return 130
    return 1 if any(j["status"] == "failed" for j in record.jobs) else 0


if __name__ == "__main__":
    sys.exit(main())
