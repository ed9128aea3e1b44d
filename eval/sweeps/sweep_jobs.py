"""One sweep job and the local worker pool: a `Job` (a batch of seeds of one group) trained by
`run_job` into its run directories, the worker process that runs it (`job_main`, which stops when its
sweep dies), the pool that runs jobs in such processes (`run_local`) and OUT/sweep.json (`SweepRecord`),
which every backend fills with the jobs' results."""

from __future__ import annotations

import ctypes
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from datetime import datetime, timezone
from pathlib import Path

import lava_bridge_mj
from lava_bridge_mj.eval.arguments import format_seeds, signal_of, stop_reason, stopping_on_signals
from lava_bridge_mj.eval.training.atomic import atomic_write_text, process_alive
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.training.run_files import DamagedFileError, checkpoint_step, read_config, run_status

JOB_COMMAND = ("import sys; from lava_bridge_mj.eval.sweeps.sweep_jobs import job_main; "
               "job_main(sys.argv[1], sys.argv[2], int(sys.argv[3]))")
"""How a local worker process is started: python -c JOB_COMMAND SPEC_JSON RESULT_FILE SWEEP_PID."""
PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
RESULT_FOLDER = "lava-bridge-sweep-"
"""The local pool's folder of job results in the temporary directory: lava-bridge-sweep-PID-XXXX."""


@dataclasses.dataclass(frozen=True)
class Job:
    """A batch of seeds of one (task, method, demos) group, trained together in one process."""

    method: str
    demos: int | str
    seeds: tuple[int, ...]
    env_id: str = lava_bridge_mj.ENV_ID

    @property
    def group(self) -> str:
        """The directory under the sweep's OUT that holds this method's runs on this demo set:
        METHOD-dDEMOS for LavaBridge-v0, ENV_ID/METHOD-dDEMOS for the suite's other tasks; DEMOS is a
        demo file's name without its suffix, or the last part of a Minari dataset's id (minari:NS/ENV/NAME)."""
        name = f"{self.method}-d{Path(self.demos).stem if isinstance(self.demos, str) else self.demos}"
        return name if self.env_id == lava_bridge_mj.ENV_ID else f"{self.env_id}/{name}"

    @property
    def name(self) -> str:
        return f"{self.group} seeds {format_seeds(self.seeds)}"

    @property
    def log_name(self) -> str:
        return f"{self.group.replace('/', '_')}_seeds{format_seeds(self.seeds)}.log"

    def run_dirs(self, out: Path) -> list[Path]:
        return [Path(out) / self.group / f"seed{seed}" for seed in self.seeds]

    def finished(self, config: RunConfig, out: Path) -> bool:
        """Whether every seed's run under `out` is finished with `config` (its seed replaced)."""
        return all(run_status(dataclasses.replace(config, seed=seed), directory) == "finished"
                   for seed, directory in zip(self.seeds, self.run_dirs(out)))

    def spec(self, config: RunConfig, out: Path, threads: int, device: str = "cpu") -> dict:
        """What a worker process or a Ray task is given to run this job (JSON)."""
        return {"method": self.method, "demos": self.demos, "seeds": list(self.seeds), "env_id": self.env_id,
                "config": config.to_dict(),
                "out": str(out.resolve()), "threads": threads, "device": device}

    @classmethod
    def from_spec(cls, spec: dict) -> "Job":
        return cls(spec["method"], spec["demos"], tuple(spec["seeds"]), spec["env_id"])


def _foreign_error(config: RunConfig, directory: Path) -> str:
    try:
        existing = read_config(directory)
    except DamagedFileError as error:
        return f"{error}; not training into it"
    differ = sorted(k for k, v in config.to_dict().items()
                    if k != "steps" and (not isinstance(existing, dict) or existing.get(k) != v))
    return (f"{directory} holds a run with another configuration (differs in {', '.join(differ)}); not "
            "overwriting it: move it away or sweep into another --out")


def run_job(job: Job, config_values: dict, out: str | Path, threads: int = 1, progress: str | None = None,
            device: str = "cpu") -> dict:
    """Train the unfinished seeds of `job` into their run directories. Never raises: the result's
    "status" is done, skipped (every seed already finished), failed (with "error") or interrupted.

    Seeds already finished are skipped; seeds with checkpoints resume from them, grouped into one
    batch per checkpoint step (a batch resumes only from a step all its seeds share); a directory
    that holds another configuration is an error, and the job's other seeds still train. `progress`:
    the path of the file that says how far the job is (tracking.ProgressReport), for the sweep's lines."""
    from lava_bridge_mj.eval.training.runner import RunInterrupted, train  # loads torch: the planner does not

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
            status = run_status(seed_config, directory)
            if status == "finished":
                result["skipped"].append(seed)
            elif status == "foreign":
                errors.append(_foreign_error(seed_config, directory))
            else:
                # an unreadable checkpoint (its error text) trains in a batch of its own, where the trainer names it
                batches.setdefault(checkpoint_step(directory), []).append(seed)
        for step, seeds in batches.items():
            resumed = f" from their checkpoints at step {step}" if isinstance(step, int) else ""
            print(f"{job.group}: training seeds {format_seeds(seeds)}{resumed}", flush=True)
            try:
                run = train(config, [Path(out) / job.group / f"seed{s}" for s in seeds], seeds=seeds,
                            resume=True, progress=progress or False, device=device)
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
    except KeyboardInterrupt as stop:  # a signal while loading, or a second one that skips the checkpoint
        result.update(status="interrupted", error="; ".join([*errors, f"{stop_reason(signal_of(stop))} outside "
                                                             "the training loop; its runs keep their last checkpoints"]))
    except Exception as error:  # noqa: BLE001 - reported in the result, never raised
        traceback.print_exc()
        result.update(status="failed", error="; ".join([*errors, f"{type(error).__name__}: {error}"]))
    result["wall_time"] = round(time.perf_counter() - started, 2)
    print(f"{job.name}: {result['status']} in {result['wall_time']} s", flush=True)
    return result


def run_spec(spec: dict) -> dict:
    """`run_job` of a `Job.spec`."""
    return run_job(Job.from_spec(spec), spec["config"], spec["out"], spec["threads"], spec.get("progress"),
                   spec.get("device", "cpu"))


def job_main(spec_json: str, result_file: str, sweep_pid: int | None = None) -> None:
    """A local worker process: run one job, write its result (JSON) to `result_file`. With
    `sweep_pid`, the job stops (checkpoint first) when that process, its parent, dies."""
    with stopping_on_signals():  # a signal while the job loads stops it too, with a result that says so
        if sweep_pid is not None:
            die_with_parent(sweep_pid)
        atomic_write_text(result_file, json.dumps(run_spec(json.loads(spec_json))))


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


def worker_environment(threads: int) -> dict[str, str]:
    """Environment variables for job processes, where the user has not set them: OpenMP threads
    that sleep rather than spin while waiting (spinning threads of several processes on shared
    cores slow training many times over: docs/speed.md, "A busy machine"), and a pool of `threads` threads."""
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


# --- the local backend: runs `todo` (indices into the record's jobs, with their specs) and records results
def run_local(todo: list[tuple[int, dict]], record: SweepRecord, workers: int, progress_every: float = 0.0) -> None:
    """Run the jobs in at most `workers` worker processes at a time, each a fresh Python process (so a
    crash, even a segfault, fails only its job), printing one progress line per running job every
    `progress_every` seconds (0: never), and a line when a job resumes its runs from a checkpoint.
    KeyboardInterrupt: pass its signal (SIGINT for Ctrl-C) on to the running jobs, which checkpoint and
    stop, then re-raise."""
    env = {**os.environ, **worker_environment(todo[0][1]["threads"])} if todo else {}
    queue, running = list(todo), {}
    last_progress = time.perf_counter()
    remove_stale_result_folders()
    sessions: dict[int, int] = {}  # job index -> the step its latest training session began at
    with tempfile.TemporaryDirectory(prefix=f"{RESULT_FOLDER}{os.getpid()}-") as results:
        try:
            while queue or running:
                if progress_every and running and time.perf_counter() - last_progress >= progress_every:
                    last_progress = time.perf_counter()
                    for index, (_, _, spec) in sorted(running.items()):
                        print(progress_line(record.jobs[index]["job"], Path(spec["progress"])), flush=True)
                while queue and len(running) < workers:
                    index, spec = queue.pop(0)
                    result_file = Path(results) / f"job{index}.json"
                    spec = {**spec, "progress": str(Path(results) / f"job{index}.progress.json")}
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
                        print_finished(record.jobs[index])
                        continue
                    running[index] = (process, result_file, spec)
                    record.update(index, status="running")
                    print(f"started {record.jobs[index]['job']} (pid {process.pid})", flush=True)
                for index, (_, _, spec) in running.items():
                    began = read_progress(Path(spec["progress"])).get("started_at")
                    if began and began != sessions.get(index):  # a session that resumed a run
                        sessions[index] = began
                        print(f"  {record.jobs[index]['job']}: resuming from step {began:,}", flush=True)
                for index in [i for i, (process, *_) in running.items() if process.poll() is not None]:
                    _finish(record, index, *running.pop(index))
                time.sleep(0.1)
        except KeyboardInterrupt as stop:
            print(f"stopping {len(running)} running job(s): each writes a checkpoint first "
                  "(Ctrl-C again to kill them at once)", file=sys.stderr, flush=True)
            for process, *_ in running.values():
                process.send_signal(signal_of(stop))
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


def remove_stale_result_folders() -> None:
    """Remove the result folders that killed sweeps left in the temporary directory (their PID gone)."""
    for folder in Path(tempfile.gettempdir()).glob(f"{RESULT_FOLDER}*"):
        pid, dash, _ = folder.name[len(RESULT_FOLDER):].partition("-")
        if dash and pid.isdigit() and not process_alive(int(pid)) and folder.is_dir():
            shutil.rmtree(folder, ignore_errors=True)


def _finish(record: SweepRecord, index: int, process: subprocess.Popen, result_file: Path, spec: dict,
            stopped: bool = False) -> None:
    if result_file.exists():
        result = json.loads(result_file.read_text())
    else:  # killed, or crashed below Python
        log = Path(record.jobs[index]["log"])
        lines = log.read_text(errors="replace").strip().splitlines() if log.exists() else []
        last = f": {lines[-1]}" if lines else ""
        result = without_result(spec, "interrupted" if stopped else "failed",
                                f"the job's process exited with code {process.returncode} and no result{last} "
                                f"(see {log})")
    record.update(index, **result)
    print_finished(record.jobs[index])


def without_result(spec: dict, status: str, error: str) -> dict:
    """The record of a job that ended without reporting: `status` with `error`, unless every one of
    its runs is finished (it was stopped after its last write), which makes it done."""
    try:
        config = RunConfig.from_dict(spec["config"], source="the sweep")
    except ValueError:
        config = None
    if config is not None and Job.from_spec(spec).finished(config, Path(spec["out"])):
        return {"status": "done", "error": None}
    return {"status": status, "error": error}


def read_progress(path: Path) -> dict:
    """A job's progress file (tracking.ProgressReport); {} before it has one."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):  # not written yet (the job is loading), or replaced while read
        return {}


def progress_line(job: str, path: Path) -> str:
    """`  JOB: step 12,000/100,000 (12%), 95 steps/s, ETA 13m 41s, p0 0.40, ood 0.20` from the job's
    progress file; `  JOB: starting` before it has one."""
    report = read_progress(path)
    if not report:
        return f"  {job}: starting"
    step, steps, rate = report["step"], report["steps"], report["rate"]
    eta = f"ETA {_duration((steps - step) / rate)}" if rate > 0 else "ETA -"
    success = "" if report["success_p0"] is None else \
        f", p0 {report['success_p0']:.2f}, ood {report['success_ood']:.2f}"
    return f"  {job}: step {step:,}/{steps:,} ({100 * step / steps:.0f}%), {rate:.0f} steps/s, {eta}{success}"


def _duration(seconds: float) -> str:
    minutes, seconds = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}h {minutes:02d}m" if hours else f"{minutes}m {seconds:02d}s"


def print_finished(entry: dict) -> None:
    """One line for a job's record entry once the job has ended: its status, wall time, diverged seeds, error."""
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
