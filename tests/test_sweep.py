"""`lava-bridge-bench sweep`: the job plan, and tiny real sweeps (local worker processes and Ray)
that finish, skip what is finished, resume what is not, isolate failing jobs and refuse bad usage."""

import dataclasses
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import metrics_without_wall_time
import lava_bridge_mj
from lava_bridge_mj.eval import arguments, cli
from lava_bridge_mj.eval.sweeps import sweep, sweep_jobs, sweep_ray
from lava_bridge_mj.eval.arguments import format_seeds
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.training.run_files import checkpoint_step, run_status, save_torch, write_config
from lava_bridge_mj.eval.sweeps.sweep import plan
from lava_bridge_mj.eval.sweeps.sweep_jobs import Job, progress_line
from lava_bridge_mj.eval.training.tracking import ProgressReport

TINY = {"sac": {"hidden_sizes": [16, 16], "batch_size": 32, "buffer_size": 500, "learning_starts": 100},
        "bc": {"hidden_sizes": [16, 16], "batch_size": 32}}


def tiny_argv(out, config_file, methods="sac,bc", seeds="0-1", steps=300, *extra, eval_every=150):
    return ["--methods", methods, "--seeds", seeds, "--steps", str(steps), "--eval-every", str(eval_every),
            "--eval-episodes", "2", "--config", str(config_file), "--out", str(out), "--workers", "2", *extra]


@pytest.fixture(scope="module")
def config_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("config") / "tiny.json"
    path.write_text(json.dumps(TINY))
    return path


@pytest.fixture(scope="module")
def finished(tmp_path_factory, config_file):
    """A tiny sweep (sac and bc, seeds 0-1, 300 steps, two jobs on two local workers), run once."""
    out = tmp_path_factory.mktemp("sweep") / "out"
    code = sweep.main(tiny_argv(out, config_file))
    return out, code


def copy_of(finished, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(finished[0], out)  # copy2: modification times are kept
    return out


def record(out):
    return json.loads((out / "sweep.json").read_text())


def _alive(pid: int) -> bool:
    """Whether process `pid` still runs (a zombie no one has reaped yet does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


needs_proc = pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads process states from /proc")


def statuses(out):
    return {job["job"]: job["status"] for job in record(out)["jobs"]}


# --- the plan --------------------------------------------------------------------------------------
def test_format_seeds_inverts_parse_seeds():
    for text in ("0", "0-24", "0,3,5-7", "2,1"):
        assert format_seeds(arguments.parse_seeds(text)) == text


@pytest.mark.parametrize("methods, demos, seeds, workers, per_job, expected", [
    # 6 groups cover 2 workers: one job of 25 seeds per group
    (["auxss", "omega_ss", "sac"], [500, 7500], range(25), 2, 25,
     [(m, d, tuple(range(25))) for m in ("auxss", "omega_ss", "sac") for d in (500, 7500)]),
    # 16 workers over 6 groups: 3 jobs per group, sizes 9, 8, 8
    (["auxss", "omega_ss", "sac"], [500, 7500], range(25), 16, 25,
     [(m, d, s) for m in ("auxss", "omega_ss", "sac") for d in (500, 7500)
      for s in (tuple(range(0, 9)), tuple(range(9, 17)), tuple(range(17, 25)))]),
    # at most 2 seeds per job
    (["sac"], [500], range(5), 1, 2, [("sac", 500, (0, 1)), ("sac", 500, (2, 3)), ("sac", 500, (4,))]),
    # more workers than seeds: one seed per job, never an empty job
    (["bc"], [7500], [3, 7], 8, 25, [("bc", 7500, (3,)), ("bc", 7500, (7,))]),
    # seeds in the order given, non-contiguous
    (["iql"], [500], [5, 0, 2], 2, 25, [("iql", 500, (5, 0)), ("iql", 500, (2,))]),
])
def test_plan_splits_each_group_into_the_fewest_batches_that_keep_the_workers_busy(
        methods, demos, seeds, workers, per_job, expected):
    assert plan(methods, demos, list(seeds), workers, per_job) == [Job(*e) for e in expected]


def test_job_names_and_run_directories():
    job = Job("auxss", 7500, (0, 1, 2, 5))
    assert job.name == "auxss-d7500 seeds 0-2,5"
    assert job.run_dirs(Path("study")) == [Path("study/auxss-d7500/seed0"), Path("study/auxss-d7500/seed1"),
                                           Path("study/auxss-d7500/seed2"), Path("study/auxss-d7500/seed5")]


def test_what_a_run_directory_holds_decides_what_its_job_does(tmp_path):
    """run_status: a seed is trained (todo), skipped (finished) or refused (foreign); checkpoint_step
    groups the seeds to train by the step they resume from."""
    config = RunConfig(method="sac", steps=300)
    run = tmp_path / "seed0"
    assert (run_status(config, run), checkpoint_step(run)) == ("todo", None)
    run.mkdir()
    write_config(run, config.to_dict())
    save_torch(run / "checkpoint.pt", {"step": 150})
    assert (run_status(config, run), checkpoint_step(run)) == ("todo", 150)
    (run / "final.pt").touch()
    assert run_status(config, run) == "finished"
    assert run_status(dataclasses.replace(config, steps=450), run) == "todo"  # extended to the larger budget
    assert run_status(dataclasses.replace(config, seed=1), run) == "foreign"
    (run / "checkpoint.pt").write_text("not a checkpoint")
    assert checkpoint_step(run).startswith(f"unreadable {run / 'checkpoint.pt'}: ")
    (run / "config.json").write_text("{")
    assert run_status(config, run) == "foreign"


def test_runs_of_another_task_go_to_its_own_directory():
    job = Job("auxss", 500, (0, 1), "LavaBridgeBend-v0")
    assert job.run_dirs(Path("study")) == [Path("study/LavaBridgeBend-v0/auxss-d500/seed0"),
                                           Path("study/LavaBridgeBend-v0/auxss-d500/seed1")]
    assert job.log_name == "LavaBridgeBend-v0_auxss-d500_seeds0-1.log"
    assert [(j.env_id, j.method) for j in plan(["sac", "auxss"], [500], [0], 1, env_ids=["LavaBridge-v0",
            "LavaBridgeBend-v0"])] == [("LavaBridge-v0", "sac"), ("LavaBridge-v0", "auxss"),
                                       ("LavaBridgeBend-v0", "sac"), ("LavaBridgeBend-v0", "auxss")]


def test_a_sweep_over_tasks_trains_each_task_into_its_directory(config_file, tmp_path):
    out = tmp_path / "out"
    assert sweep.main(tiny_argv(out, config_file, "sac", "0", 150, "--envs", "LavaBridge-v0,LavaBridgeBend-v0")) == 0
    for task, group in (("LavaBridge-v0", out / "sac-d500"), ("LavaBridgeBend-v0", out / "LavaBridgeBend-v0/sac-d500")):
        assert json.loads((group / "seed0" / "config.json").read_text())["env_id"] == task
        assert (group / "seed0" / "final.pt").exists()
    assert record(out)["arguments"]["envs"] == ["LavaBridge-v0", "LavaBridgeBend-v0"]


def test_a_sweep_over_a_demo_file_trains_what_the_shipped_set_it_holds_trains(config_file, tmp_path):
    """A demo file holding the shipped 500 set: its runs go to METHOD-dNAME, config.json records the
    file and its hash, and the numbers are those of the shipped set's runs."""
    demo_file = tmp_path / "expert.npz"
    lava_bridge_mj.save_demos(lava_bridge_mj.load_demos(500), demo_file)
    out = tmp_path / "out"
    assert sweep.main(tiny_argv(out, config_file, "auxss", "0", 150, "--demos", f"500,{demo_file}")) == 0
    config = json.loads((out / "auxss-dexpert" / "seed0" / "config.json").read_text())
    assert config["demos"] == str(demo_file) and len(config["demos_sha256"]) == 64
    assert metrics_without_wall_time(out / "auxss-dexpert/seed0") == metrics_without_wall_time(out / "auxss-d500/seed0")
    assert record(out)["arguments"]["demos"] == [500, str(demo_file)]


# --- local sweeps ----------------------------------------------------------------------------------
def test_a_local_sweep_writes_every_run_as_a_single_run_would(finished, config_file):
    out, code = finished
    assert code == 0
    assert statuses(out) == {"sac-d500 seeds 0-1": "done", "bc-d500 seeds 0-1": "done"}
    for method in ("sac", "bc"):
        for seed in (0, 1):
            run = out / f"{method}-d500" / f"seed{seed}"
            assert [row["step"] for row in metrics_without_wall_time(run)] == ["150", "300"]
            assert (run / "final.pt").exists() and (run / "policies" / "step_300.pt").exists()
            # the configuration a single `lava-bridge-bench` run of the same options writes
            parser = cli.build_parser()
            args = parser.parse_args(["--method", method, "--seed", str(seed), "--steps", "300", "--eval-every",
                                      "150", "--eval-episodes", "2", "--config", str(config_file)])
            assert json.loads((run / "config.json").read_text()) == cli._config_from(args, parser).to_dict()
    entry = record(out)["jobs"][0]
    assert entry["trained"] == [0, 1] and entry["error"] is None and entry["wall_time"] > 0
    assert record(out)["arguments"]["methods"] == ["sac", "bc"] and record(out)["status"] == "finished"
    assert record(out)["arguments"]["device"] == "cpu"
    assert json.loads((out / "sac-d500/seed0/provenance.json").read_text())[0]["device"] == "cpu"


def test_running_a_finished_sweep_again_skips_every_run(finished, config_file, tmp_path):
    out = copy_of(finished, tmp_path)
    metrics = sorted(out.glob("*/seed*/metrics.csv"))
    before = [m.stat().st_mtime_ns for m in metrics]
    assert sweep.main(tiny_argv(out, config_file)) == 0
    assert set(statuses(out).values()) == {"skipped"}
    assert [m.stat().st_mtime_ns for m in metrics] == before


def make_unfinished(run):
    """What a run killed between its checkpoints at steps 150 and 300 leaves."""
    (run / "final.pt").unlink()
    shutil.copy(run / "checkpoint.prev.pt", run / "checkpoint.pt")


HOLD_LOCK = ("import fcntl, sys, time; lock = open(sys.argv[1], 'a+'); fcntl.flock(lock, fcntl.LOCK_EX); "
             "lock.truncate(0); lock.write('4242'); lock.flush(); print('locked', flush=True); "
             "time.sleep(float(sys.argv[2]))")
"""A process that holds a run directory's lock, as a training process does, for argv[2] seconds."""


def hold_lock(run, seconds):
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LOCK, str(run / ".lock"), str(seconds)],
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline() == "locked\n"
    return holder


def test_an_unfinished_run_resumes_from_its_checkpoint_once_its_writer_stops(finished, config_file, tmp_path,
                                                                              capsys):
    """A run killed between its checkpoints, its directory still locked for two seconds by another
    process (a job of a killed sweep writing its last checkpoint): the sweep says it waits, then
    resumes that run alone from its checkpoint, instead of failing its job."""
    out = copy_of(finished, tmp_path)
    stopped = out / "sac-d500" / "seed1"
    make_unfinished(stopped)
    os.utime(stopped / "policies" / "step_150.pt", (1e9, 1e9))  # a restart would rewrite it
    done = out / "sac-d500" / "seed0" / "metrics.csv"
    done_mtime = done.stat().st_mtime_ns

    holder = hold_lock(stopped, 2)
    try:
        assert sweep.main(tiny_argv(out, config_file)) == 0
    finally:
        holder.kill()
        holder.wait()
    assert "still being written by another process (pid 4242); waiting up to 60 s" in capsys.readouterr().err
    sac = record(out)["jobs"][0]
    assert (sac["status"], sac["trained"], sac["skipped"], sac["resumed"]) == ("done", [1], [0], {"1": 150})
    assert statuses(out)["bc-d500 seeds 0-1"] == "skipped"
    assert (stopped / "policies" / "step_150.pt").stat().st_mtime == 1e9
    assert (stopped / "final.pt").exists() and done.stat().st_mtime_ns == done_mtime
    assert metrics_without_wall_time(stopped) == metrics_without_wall_time(finished[0] / "sac-d500" / "seed1")


def test_a_larger_steps_extends_finished_runs_from_their_last_checkpoint(finished, config_file, tmp_path):
    out = copy_of(finished, tmp_path)
    assert sweep.main(tiny_argv(out, config_file, "sac", "0-1", 450, "--workers", "1")) == 0
    jobs = record(out)["jobs"]  # both seeds in one job: one worker
    assert [(job["status"], job["trained"], job["resumed"]) for job in jobs] == [
        ("done", [0, 1], {"0": 300, "1": 300})]
    for seed in (0, 1):
        run = out / "sac-d500" / f"seed{seed}"
        assert [row["step"] for row in metrics_without_wall_time(run)] == ["150", "300", "450"]
        assert json.loads((run / "config.json").read_text())["steps"] == 450
    # asking for fewer steps than a run has is that job's error, and its files stay as they were
    metrics = (out / "sac-d500" / "seed0" / "metrics.csv").read_bytes()
    assert sweep.main(tiny_argv(out, config_file, "sac", "0-1", 300, "--workers", "1")) == 1
    assert [job["status"] for job in record(out)["jobs"]] == ["failed"]
    assert all("past steps=300" in job["error"] for job in record(out)["jobs"])
    assert (out / "sac-d500" / "seed0" / "metrics.csv").read_bytes() == metrics


def test_a_run_directory_locked_past_the_wait_fails_only_its_job(finished, config_file, tmp_path, capsys,
                                                                  monkeypatch):
    monkeypatch.setattr(sweep, "LOCK_WAIT", 0.5)
    out = copy_of(finished, tmp_path)
    stopped = out / "sac-d500" / "seed1"
    make_unfinished(stopped)
    holder = hold_lock(stopped, 120)
    try:
        assert sweep.main(tiny_argv(out, config_file)) == 1
    finally:
        holder.kill()
        holder.wait()
    assert f"still being written after 0.5 s: {stopped}" in capsys.readouterr().err
    sac = record(out)["jobs"][0]
    assert sac["status"] == "failed" and "being written by another process (pid 4242)" in sac["error"]
    assert not (stopped / "final.pt").exists()


def test_a_job_killed_after_its_last_write_is_recorded_done(finished, config_file, tmp_path, monkeypatch):
    """The job's process dies without a result (SIGKILL) just after writing its runs' final.pt: its
    runs are finished, so the record says done, not failed."""
    out = copy_of(finished, tmp_path)
    final = out / "sac-d500" / "seed1" / "final.pt"
    aside = final.with_name("final.aside")
    final.rename(aside)  # unfinished when the sweep looks, so the job is started
    monkeypatch.setattr(sweep_jobs, "JOB_COMMAND", f"import os, signal; os.replace({str(aside)!r}, {str(final)!r}); "
                                              "os.kill(os.getpid(), signal.SIGKILL)")
    assert sweep.main(tiny_argv(out, config_file)) == 0
    sac = record(out)["jobs"][0]
    assert (sac["status"], sac["error"]) == ("done", None)


@needs_proc
def test_without_prctl_a_job_still_dies_with_its_parent(tmp_path):
    """die_with_parent's fallback (polling os.getppid(), for systems without PR_SET_PDEATHSIG): a
    grandchild whose parent is SIGKILLed gets SIGTERM."""
    grandchild = ("import os, sys, time; from lava_bridge_mj.eval.sweeps.sweep_jobs import die_with_parent; "
                  "die_with_parent(os.getppid(), poll_interval=0.05, use_prctl=False); print('armed', flush=True); "
                  "time.sleep(120)")
    parent = ("import subprocess, sys, time; child = subprocess.Popen([sys.executable, '-c', sys.argv[1]], "
              "stdout=subprocess.PIPE, text=True); assert child.stdout.readline() == 'armed\\n'; "
              "print(child.pid, flush=True); time.sleep(120)")
    process = subprocess.Popen([sys.executable, "-c", parent, grandchild], stdout=subprocess.PIPE, text=True)
    pid = int(process.stdout.readline())
    assert _alive(pid)
    process.kill()
    process.wait()
    deadline = time.monotonic() + 10
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    alive = _alive(pid)
    if alive:
        os.kill(pid, signal.SIGKILL)
    assert not alive, "the grandchild outlived its parent"


def test_a_failing_job_is_reported_and_the_others_finish(config_file, tmp_path, capsys):
    out = tmp_path / "out"
    foreign = out / "bc-d500" / "seed0"
    foreign.mkdir(parents=True)
    (foreign / "config.json").write_text(json.dumps({"method": "bc", "steps": 5}))

    assert sweep.main(tiny_argv(out, config_file, "sac,bc", "0", 150, "--progress-every", "0.2")) == 1
    jobs = {job["job"]: job for job in record(out)["jobs"]}
    assert jobs["sac-d500 seeds 0"]["status"] == "done"
    assert (out / "sac-d500" / "seed0" / "final.pt").exists()
    failed = jobs["bc-d500 seeds 0"]
    assert failed["status"] == "failed" and "another configuration" in failed["error"]
    assert json.loads((foreign / "config.json").read_text()) == {"method": "bc", "steps": 5}  # not overwritten
    printed = capsys.readouterr().out
    assert "error in bc-d500 seeds 0" in printed and "1 done, 1 failed" in printed
    # while it ran, the job's progress lines (the job takes seconds to load torch alone)
    assert re.search(r"^  sac-d500 seeds 0: (starting|step [\d,]+/150 )", printed, re.M), printed


def test_a_progress_line_says_how_far_a_job_is(tmp_path):
    path = tmp_path / "job0.progress.json"
    assert progress_line("auxss-d500 seeds 0-4", path) == "  auxss-d500 seeds 0-4: starting"
    path.write_text(json.dumps({"step": 12000, "steps": 100000, "rate": 95.0, "success_p0": 0.4, "success_ood": 0.2}))
    # ETA: 88,000 steps at 95 steps/s = 926.3 s
    assert progress_line("auxss-d500 seeds 0-4", path) == \
        "  auxss-d500 seeds 0-4: step 12,000/100,000 (12%), 95 steps/s, ETA 15m 26s, p0 0.40, ood 0.20"
    path.write_text(json.dumps({"step": 500, "steps": 300000, "rate": 50.0, "success_p0": None, "success_ood": None}))
    assert progress_line("sac-d500 seeds 0", path) == "  sac-d500 seeds 0: step 500/300,000 (0%), 50 steps/s, ETA 1h 39m"


def test_a_progress_report_is_written_at_evaluations_and_at_most_every_few_seconds(tmp_path):
    path = tmp_path / "progress.json"
    report = ProgressReport(path, step=1000, steps=5000, every=3600)
    report.write(1100)
    assert json.loads(path.read_text())["step"] == 1100 and json.loads(path.read_text())["success_p0"] is None
    report.write(1200)  # within `every` of the last write: skipped
    assert json.loads(path.read_text())["step"] == 1100
    report.evaluated(0.5, 0.25)
    report.write(1500, force=True)  # an evaluation: always written
    written = json.loads(path.read_text())
    assert (written["step"], written["steps"], written["success_p0"], written["success_ood"]) == (1500, 5000, 0.5, 0.25)
    assert written["rate"] > 0


def test_a_configuration_one_method_rejects_fails_only_its_jobs(tmp_path):
    config = tmp_path / "auxss_only.json"
    config.write_text(json.dumps({**TINY, "strategy": {"sigma": 0.2}}))  # start-strategy options: bc has none
    out = tmp_path / "out"
    assert sweep.main(tiny_argv(out, config, "auxss,bc", "0", 150)) == 1
    jobs = {job["job"]: job for job in record(out)["jobs"]}
    assert jobs["auxss-d500 seeds 0"]["status"] == "done"
    assert jobs["bc-d500 seeds 0"]["status"] == "failed" and "sigma" in jobs["bc-d500 seeds 0"]["error"]
    assert not (out / "bc-d500").exists()


def test_a_worker_that_dies_without_a_result_fails_only_its_job(config_file, tmp_path, monkeypatch):
    monkeypatch.setattr(sweep_jobs, "JOB_COMMAND", "import sys; print('boom'); sys.exit(3)")
    out = tmp_path / "out"
    assert sweep.main(tiny_argv(out, config_file, "sac,bc", "0")) == 1
    for job in record(out)["jobs"]:
        assert job["status"] == "failed" and "code 3" in job["error"] and "boom" in job["error"]


def test_ctrl_c_stops_the_jobs_after_a_checkpoint_and_the_rerun_says_where_it_resumes(config_file, tmp_path, capsys):
    out = tmp_path / "out"
    # started as a script's background job is (`cmd &`): SIGINT inherited ignored; the sweep must still stop on it
    process = subprocess.Popen([sys.executable, "-m", "lava_bridge_mj.eval.sweeps.sweep",
                                *tiny_argv(out, config_file, "sac", "0", 100_000)],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    checkpoint = out / "sac-d500" / "seed0" / "checkpoint.pt"
    # generous limits: they only stop a hang, and a loaded CI machine starts torch slowly
    deadline = time.monotonic() + 600
    while not checkpoint.exists() and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    process.send_signal(signal.SIGINT)
    try:
        output = process.communicate(timeout=600)[0]
    except subprocess.TimeoutExpired:
        process.kill()
        logs = "\n".join(p.read_text() for p in sorted((out / "logs").glob("*.log")))
        pytest.fail(f"the sweep did not stop within 600 s of Ctrl-C; checkpoint written: {checkpoint.exists()}; "
                    f"sweep output: {process.communicate()[0]}; job logs: {logs}")
    assert process.returncode == 130, output
    job = record(out)["jobs"][0]
    assert record(out)["status"] == "interrupted" and job["status"] == "interrupted", job
    # the job is told what the sweep was told: the user's Ctrl-C, not a SIGTERM of unknown origin
    assert re.fullmatch(r"interrupted by the user \(SIGINT\) at step \d+ after writing a checkpoint", job["error"]), job
    assert "SIGTERM" not in output
    assert not (checkpoint.parent / "final.pt").exists()
    # the rerun says where the job's run continues
    step = checkpoint_step(checkpoint.parent)
    assert sweep.main(tiny_argv(out, config_file, "sac", "0", step + 10)) == 0
    assert f"  sac-d500 seeds 0: resuming from step {step:,}\n" in capsys.readouterr().out


# --- Ray ---------------------------------------------------------------------------------------------
def test_the_ray_backend_runs_the_same_sweep(finished, config_file, tmp_path):
    pytest.importorskip("ray")
    out = tmp_path / "out"
    assert sweep.main(tiny_argv(out, config_file, "sac,bc", "0-1", 300, "--backend", "ray")) == 0
    assert set(statuses(out).values()) == {"done"}
    for run in sorted(finished[0].glob("*/seed*")):  # with one torch thread, the same numbers as local
        assert metrics_without_wall_time(out / run.parent.name / run.name) == metrics_without_wall_time(run)


def test_an_unreachable_ray_address_fails_at_once_with_one_line(config_file, tmp_path):
    pytest.importorskip("ray")
    out = tmp_path / "out"
    started = time.monotonic()
    try:  # ray.init alone retries for many minutes
        done = subprocess.run([sys.executable, "-m", "lava_bridge_mj.eval.sweeps.sweep",
                               *tiny_argv(out, config_file, "sac", "0", 300, "--backend", "ray", "--address",
                                          "127.0.0.1:1")], capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail("sweep --address 127.0.0.1:1 still hangs after 120 s")
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip() == ("lava-bridge-bench sweep: error: --address 127.0.0.1:1: cannot connect to a Ray "
                                   "cluster: nothing accepts connections at 127.0.0.1:1 (Connection refused)")
    assert not out.exists()
    assert time.monotonic() - started < 60


def test_a_ray_address_that_accepts_but_never_answers_is_given_up_on(tmp_path):
    """A port that accepts TCP connections but speaks no Ray: given up on after the timeout."""
    pytest.importorskip("ray")
    import socket

    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        address = f"127.0.0.1:{listener.getsockname()[1]}"
        started = time.monotonic()
        assert sweep_ray.ray_unreachable(address, timeout=3) == "no Ray cluster answered within 3 s"
        assert time.monotonic() - started < 30


# --- usage errors -----------------------------------------------------------------------------------
@pytest.mark.parametrize("change, message", [
    ({"--methods": "sac,dqn"}, "unknown method 'dqn'"),
    ({"--methods": "sac,sac"}, "given twice"),
    ({"--seeds": "3-1"}, "expected a range of seeds low-high in [0, 4294967295], got '3-1'"),
    ({"--demos": "500,600"}, "'600' is none of these"),
    ({"--workers": "0"}, "positive integer"),
    ({"--address": "127.0.0.1:6379"}, "--address needs --backend ray"),
    ({"--steps": "-5"}, "positive integer"),
    ({"--seeds": "0-99999999"}, "expected at most 1,000 seeds, got 100,000,000"),
    ({"--threads": "100000"}, "--threads 100000: this machine lets the sweep use"),
    ({"--progress-every": "-1"}, "--progress-every must be a number of seconds >= 0, got -1.0"),
    ({"--set": "sac.lrr=1"}, "/ --set: 'sac': unknown fields ['lrr']"),
])
def test_usage_errors_exit_2_and_write_nothing(change, message, config_file, tmp_path, capsys):
    argv = tiny_argv(tmp_path / "out", config_file)
    for option, value in change.items():
        if option in argv:
            argv[argv.index(option) + 1] = value
        else:
            argv += [option, value]
    with pytest.raises(SystemExit) as exit_:
        cli.main(["sweep", *argv])  # through the lava-bridge-bench entry point
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("out, message", [
    ("", "argument --out: expected a directory, got ''"),  # once swept into the current directory
    ("a" * 300, "cannot be used: File name too long"),
    ("a" * 300 + "/out", "cannot be used: File name too long"),
])
def test_an_out_that_names_no_usable_directory_is_a_usage_error(out, message, config_file, tmp_path, capsys,
                                                                monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        sweep.main(tiny_argv(out, config_file))
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_a_config_nested_thousands_deep_is_a_usage_error(tmp_path, capsys):
    config = tmp_path / "deep.json"
    config.write_text('{"sac": {"hidden_sizes": ' + "[" * 5000 + "]" * 5000 + "}}")
    with pytest.raises(SystemExit) as exit_:
        sweep.main(tiny_argv(tmp_path / "out", config))
    assert exit_.value.code == 2
    assert "it nests arrays and objects more than 32 levels deep" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_job_that_cannot_fit_in_memory_is_refused_before_anything_is_written(config_file, tmp_path, capsys):
    out = tmp_path / "out"
    assert sweep.main(tiny_argv(out, config_file, "sac,bc", "0", 300, "--set", "sac.batch_size=1000000000")) == 2
    # 10^9 transitions of 12 floats, twice, and the twin critics' 16 + 16 activations each: 328 GiB
    assert re.fullmatch(r"lava-bridge-bench sweep: error: sac on LavaBridge-v0 \(500 demos\): "
                        r"SACConfig\.batch_size=1000000000 does not fit in memory: 1 seed needs at least 327\.8 GiB "
                        r"\(.*\), more than the [0-9.]+ [KMG]iB of memory available here; nothing written\n",
                        capsys.readouterr().err)
    assert not out.exists()


def test_an_out_that_cannot_be_created_is_one_line(config_file, capsys):
    """/proc refuses new entries even to root, whom a read-only directory does not stop."""
    try:
        code = sweep.main(tiny_argv("/proc/lava-bridge-sweep", config_file))
    except SystemExit as exit_:  # refused before, as a usage error, where /proc is not writable
        code = exit_.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("lava-bridge-bench sweep: error: --out /proc/lava-bridge-sweep")
    assert not any("Traceback" in line for line in err)
    assert not Path("/proc/lava-bridge-sweep").exists()


def test_a_configuration_every_method_rejects_is_a_usage_error(tmp_path, capsys):
    config = tmp_path / "bad.json"
    config.write_text(json.dumps({"sac": {"hidden_sizes": [16, 16], "no_such_field": 1}}))
    with pytest.raises(SystemExit) as exit_:
        sweep.main(tiny_argv(tmp_path / "out", config))
    assert exit_.value.code == 2 and "no_such_field" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_ray_backend_without_ray_names_the_extra(config_file, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now fails as if it were not installed
    with pytest.raises(SystemExit) as exit_:
        sweep.main(tiny_argv(tmp_path / "out", config_file, "sac", "0", 300, "--backend", "ray"))
    assert exit_.value.code == 2 and "lava-bridge-mj[ray]" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def kill_argv(out, config_file, workers):
    """The sweep the kill tests interrupt: sac seeds 0-1 to 450 steps with a checkpoint every 75, so
    that a kill after its first checkpoints (updates start at step 100) leaves most of the run to go."""
    return tiny_argv(out, config_file, "sac", "0-1", 450, "--workers", str(workers), eval_every=75)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory, config_file):
    """The kill tests' sweep run uninterrupted in one job: what interrupted ones must equal."""
    out = tmp_path_factory.mktemp("reference") / "out"
    assert sweep.main(kill_argv(out, config_file, workers=1)) == 0
    return out


def test_a_sweep_killed_with_sigkill_resumes_to_the_uninterrupted_numbers(config_file, tmp_path, uninterrupted):
    """SIGKILL of the sweep and its job process mid-training (after two checkpoints), then the same
    command: every run finishes with the metrics of an uninterrupted sweep."""
    out = tmp_path / "out"
    argv = kill_argv(out, config_file, workers=1)
    process = subprocess.Popen([sys.executable, "-m", "lava_bridge_mj.eval.sweeps.sweep", *argv],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    started = next(line for line in process.stdout if "(pid " in line)
    job_pid = int(started.rsplit("(pid ", 1)[1].rstrip(")\n"))
    metrics = out / "sac-d500" / "seed1" / "metrics.csv"
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline and (not metrics.exists() or len(metrics.read_text().splitlines()) < 3):
        time.sleep(0.05)
    os.kill(job_pid, signal.SIGKILL)
    process.kill()
    process.communicate(timeout=60)
    assert not (out / "sac-d500" / "seed0" / "final.pt").exists(), "killed before the end"
    early = out / "sac-d500" / "seed0" / "policies" / "step_75.pt"
    written = early.stat().st_mtime_ns
    assert sweep.main(argv) == 0
    assert early.stat().st_mtime_ns == written, "resumed from a checkpoint, not retrained from the start"
    for seed in ("seed0", "seed1"):
        resumed = metrics_without_wall_time(out / "sac-d500" / seed)
        assert resumed == metrics_without_wall_time(uninterrupted / "sac-d500" / seed)
        assert [row["step"] for row in resumed] == ["75", "150", "225", "300", "375", "450"]


@needs_proc
def test_jobs_die_with_a_sweep_killed_alone_and_the_rerun_finishes_them(config_file, tmp_path, uninterrupted):
    """SIGKILL of only the sweep's process, after a checkpoint of each of its two jobs: the jobs write a
    checkpoint and stop within seconds instead of training on as orphans, and the same command at once
    resumes both to the uninterrupted numbers, recorded as done."""
    out = tmp_path / "out"
    argv = kill_argv(out, config_file, workers=2)
    process = subprocess.Popen([sys.executable, "-m", "lava_bridge_mj.eval.sweeps.sweep", *argv],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    pids = []
    for line in process.stdout:
        if "(pid " in line:
            pids.append(int(line.rsplit("(pid ", 1)[1].rstrip(")\n")))
        if len(pids) == 2:
            break
    runs = [out / "sac-d500" / f"seed{seed}" for seed in (0, 1)]
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline and not all((run / "checkpoint.pt").exists() for run in runs):
        time.sleep(0.05)
    process.kill()
    process.communicate(timeout=60)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and any(map(_alive, pids)):
        time.sleep(0.05)
    try:
        assert not any(map(_alive, pids)), "the jobs train on after their sweep was killed"
        assert not any((run / "final.pt").exists() for run in runs), "the jobs trained on to the end"
    finally:
        for pid in filter(_alive, pids):
            os.kill(pid, signal.SIGKILL)
    logs = [p.read_text() for p in sorted((out / "logs").glob("*.log"))]
    assert all("interrupted in" in log for log in logs) and len(logs) == 2, logs  # stopped by the signal

    assert sweep.main(argv) == 0
    assert record(out)["status"] == "finished"
    assert [(job["status"], job["error"]) for job in record(out)["jobs"]] == [("done", None), ("done", None)]
    for run in runs:
        assert metrics_without_wall_time(run) == metrics_without_wall_time(uninterrupted / "sac-d500" / run.name)
