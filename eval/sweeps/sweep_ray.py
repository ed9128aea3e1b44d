"""The sweep's Ray backend: connect to a cluster (or start a local one), run each job as a Ray task
asking for its torch threads as CPUs, and record each result in the sweep's record as it arrives.
OUT must be on a filesystem every node sees. Ray is imported only here, and only on use."""

from __future__ import annotations

import socket
import subprocess
import sys
from contextlib import redirect_stderr, redirect_stdout

from lava_bridge_mj.eval.sweeps.sweep_jobs import SweepRecord, print_finished, run_spec, without_result, worker_environment

RAY_CONNECT_TIMEOUT = 30.0
"""Seconds `--address` may take to answer before the sweep gives up (ray.init itself retries for many
minutes against an address where no cluster answers)."""
RAY_PROBE = "import sys, ray; ray.init(address=sys.argv[1], log_to_driver=False); ray.shutdown()"


class RayUnavailable(Exception):
    """Ray cannot run the sweep's jobs; the message says why in one line, and no cluster is left started."""


def start(address: str | None, threads: int, workers: int | None) -> int:
    """Connect to the running cluster at `address`, or (address None) start a local one of `workers`
    x `threads` CPUs; returns how many jobs to run at once: `workers`, by default the cluster's CPUs
    divided by `threads`. Job processes get `worker_environment(threads)`."""
    import ray

    env = {"env_vars": worker_environment(threads)}
    if address is not None:
        reason = ray_unreachable(address)
        if reason is not None:
            raise RayUnavailable(f"--address {address}: cannot connect to a Ray cluster: {reason}")
    try:
        if address is None:
            ray.init(num_cpus=workers * threads, include_dashboard=False, runtime_env=env)
        else:
            ray.init(address=address, runtime_env=env)
    except Exception as error:  # noqa: BLE001 - ConnectionError, a bad address, a version mismatch, ...
        where = f"--address {address}: cannot connect to Ray" if address else "cannot start a local Ray"
        raise RayUnavailable(f"{where} ({type(error).__name__}: {_last_line(str(error))})") from None
    if address is None:
        return workers
    largest = max((node["Resources"].get("CPU", 0) for node in ray.nodes() if node.get("Alive")), default=0)
    if threads > largest:
        ray.shutdown()
        raise RayUnavailable(f"--threads {threads}: no node of the Ray cluster at {address} has that many "
                             f"CPUs (the most: {largest:g}); its tasks would wait forever")
    return workers or max(1, int(ray.cluster_resources().get("CPU", 1) // threads))


def _ray_job(spec: dict, log: str) -> dict:
    """A Ray task: one job, its output appended to the job's log (OUT must be on a filesystem every
    node sees, as the run directories are)."""
    with open(log, "a") as stream, redirect_stdout(stream), redirect_stderr(stream):
        return run_spec(spec)


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
        result = without_result(spec, "interrupted" if stopped else "failed", f"{type(error).__name__}: {error}")
    record.update(index, **result)
    print_finished(record.jobs[index])


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
