"""The training runner and the lava-bridge-bench CLI: run directories, resume, bad arguments."""

import csv
import dataclasses
import json
import shutil
import subprocess

import numpy as np
import pytest
import torch

import lava_bridge_mj

from conftest import episode_rows, flip_a_data_bit, interrupted_copy, metrics_without_wall_time

from lava_bridge_mj.agents.sac import SACConfig
from lava_bridge_mj.agents.goaldist_ss import GoalDistSS
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.training.provenance import git_state, processor
from lava_bridge_mj.agents.methods import METHODS as METHOD_SPECS
from lava_bridge_mj.eval.training.config import METHODS, RunConfig
from lava_bridge_mj.eval.training.run_files import EPISODE_FIELDS, EPISODE_LOG, METRIC_FIELDS, RunDirectoryError, run_status, save_torch
from lava_bridge_mj.eval.training.runner import Run, train

TINY_SAC = SACConfig(hidden_sizes=(16, 16), batch_size=32, buffer_size=500, learning_starts=100)


def tiny_config(method="auxss", **overrides):
    values = dict(method=method, seed=3, steps=700, eval_every=100, eval_episodes=2, demo_subset=20, sac=TINY_SAC,
                  bc={"hidden_sizes": [16, 16], "batch_size": 32}, iql={"hidden_sizes": [16, 16], "batch_size": 32},
                  jsrl={"guide": "iql", "guide_steps": 50, "initial_horizon": 40})
    values.update(overrides)
    return RunConfig(**values)


def read_metrics(path):
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """`trained(config)`: the directory and Run of `config` trained from scratch, once per module for
    each configuration. Tests only read both; a test that changes a run directory copies it first
    (`copy_run`)."""
    runs = {}

    def get(config):
        key = json.dumps(config.to_dict(), sort_keys=True)
        if key not in runs:
            out = tmp_path_factory.mktemp("trained") / "run"
            runs[key] = out, train(config, out, progress=False)
        return runs[key]

    return get


@pytest.fixture(scope="module")
def finished_run(trained):
    """A tiny finished auxss run of 300 steps (both checkpoints present)."""
    return trained(tiny_config(steps=300))[0]


def copy_run(source, target):
    shutil.copytree(source, target, ignore=shutil.ignore_patterns(".lock"))
    return target


@pytest.mark.parametrize("method", METHODS)
def test_every_method_writes_a_complete_run_directory(trained, method):
    config = tiny_config(method, steps=300)
    tmp_path, run = trained(config)
    rows = read_metrics(tmp_path / "metrics.csv")
    assert [int(r["step"]) for r in rows] == [100, 200, 300]
    assert list(rows[0]) == list(METRIC_FIELDS)
    for row in rows:
        assert 0.0 <= float(row["success_p0"]) <= 1.0 and 0.0 <= float(row["success_ood"]) <= 1.0
    assert json.loads((tmp_path / "config.json").read_text()) == config.to_dict()
    assert (tmp_path / "final.pt").exists()
    assert sorted(p.name for p in (tmp_path / "policies").iterdir()) == ["step_100.pt", "step_200.pt", "step_300.pt"]
    weights = np.load(tmp_path / "start_weights.npz")
    assert weights["steps"].tolist() == [100, 200, 300]
    candidates = 20 if METHOD_SPECS[method].candidates == "subset" else len(run.seed_runs[0].states)
    expected_states = 0 if METHOD_SPECS[method].start == "p0" else candidates
    assert weights["probabilities"].shape == (3, expected_states)
    assert weights["states"].shape == (candidates, 4)
    assert run.step == 300


@pytest.mark.parametrize("method, steps", [("auxss", 700), ("sac", 1200)])  # p0 episodes run up to 500 steps
def test_the_episode_log_accounts_for_every_training_step_and_start(trained, method, steps):
    config = tiny_config(method, steps=steps)
    tmp_path, run = trained(config)
    log = episode_rows(tmp_path)
    assert list(log[0]) == list(EPISODE_FIELDS)
    assert len(log) == int(read_metrics(tmp_path / "metrics.csv")[-1]["episodes"]) > 1
    episode, step, index, length = (np.array([int(r[k]) for r in log]) for k in ("episode", "step", "start_index",
                                                                                   "length"))
    assert episode.tolist() == list(range(1, len(log) + 1))
    # one env, stepped once per training step: each episode ends `length` steps after the one before
    np.testing.assert_array_equal(np.diff(step, prepend=0), length)
    assert step[-1] <= config.steps and (length <= 500).all()
    success = np.array([int(r["success"]) for r in log])
    # the goal's +1 is the only non-zero reward (lava 0), so an episode's return is its success
    np.testing.assert_array_equal([float(r["return"]) for r in log], success)
    start = np.array([[float(r["start_x"]), float(r["start_y"])] for r in log])
    if method == "sac":
        assert (index == -1).all()
        assert np.isfinite(start).all() and (start[:, 0] < 0).all(), "p0 starts lie in the start room (x < 0)"
    else:  # a candidate start resets the ball exactly onto that demo state's position
        assert ((0 <= index) & (index < config.demo_subset)).all()
        np.testing.assert_array_equal(start, run.seed_runs[0].states[index, :2])


def test_auxss_weights_move_during_training(finished_run):
    probabilities = np.load(finished_run / "start_weights.npz")["probabilities"]
    assert not np.allclose(probabilities[-1], probabilities[-1].mean()), "AuxSS never updated its weights"


def test_same_seed_same_metrics(finished_run, tmp_path):
    train(tiny_config(steps=300), tmp_path / "a", progress=False)  # finished_run's configuration
    assert metrics_without_wall_time(tmp_path / "a") == metrics_without_wall_time(finished_run)


@pytest.mark.parametrize("method", ["auxss", "hysac_auxss"])
def test_resume_from_checkpoint_equals_uninterrupted_run(trained, tmp_path, method):
    config = tiny_config(method)
    full_dir, full = trained(config)
    resumed = resume_from_mid_episode_checkpoint(config, full_dir, full, tmp_path / "resumed")
    np.testing.assert_array_equal(full.strategy.weights, resumed.strategy.weights)


def resume_from_mid_episode_checkpoint(config, full_dir, full, resumed_dir):
    """Resume a copy of the finished run `full_dir` cut back to its mid-episode checkpoint.prev.pt; assert
    that its metrics, episode log and actor equal the uninterrupted run's; return the resumed run."""
    checkpoint = torch.load(full_dir / "checkpoint.prev.pt", weights_only=False)
    assert 0 < checkpoint["step"] < config.steps, "the test needs a checkpoint from the middle of the run"
    assert checkpoint["wrapper"]["episode_length"] > 0, "the test needs a checkpoint from the middle of an episode"

    # An interrupted run: only the files as they were at that checkpoint, plus a stale row past it.
    interrupted_copy(full_dir, resumed_dir)
    resumed = train(config, resumed_dir, resume=True, progress=False)

    assert metrics_without_wall_time(resumed_dir) == metrics_without_wall_time(full_dir)
    assert (resumed_dir / EPISODE_LOG).read_bytes() == (full_dir / EPISODE_LOG).read_bytes()
    for name, tensor in full.agent.actor.state_dict().items():
        assert torch.equal(tensor, resumed.agent.actor.state_dict()[name]), name
    return resumed


def test_an_extension_stopped_short_of_its_budget_is_not_finished(finished_run, tmp_path, monkeypatch):
    # extending 300 -> 500 steps and stopping at 400: the old budget's final.pt must not make the run
    # read as finished at 500, or a rerun of the sweep would skip it for good
    out = copy_run(finished_run, tmp_path / "run")
    save = Run.save

    def save_then_die(self, name="checkpoint.pt"):
        save(self, name)
        if self.step == 400:
            raise RuntimeError("killed at step 400")

    monkeypatch.setattr(Run, "save", save_then_die)
    longer = tiny_config(steps=500)
    with pytest.raises(RuntimeError, match="killed at step 400"):
        train(longer, out, resume=True, progress=False)
    monkeypatch.undo()
    assert not (out / "final.pt").exists()
    assert run_status(longer, out) == "todo"
    train(longer, out, resume=True, progress=False)
    assert run_status(longer, out) == "finished"
    assert torch.load(out / "final.pt", weights_only=False)["step"] == 500


def test_a_resume_says_from_which_step_it_continues(finished_run, tmp_path, capsys):
    out = copy_run(finished_run, tmp_path / "run")
    train(tiny_config(steps=300), out, resume=True, progress=False)  # finished at its budget: nothing to resume
    assert "resuming" not in capsys.readouterr().out
    train(tiny_config(steps=400), out, resume=True, progress=False)
    assert capsys.readouterr().out.startswith("auxss seed 3: resuming from step 300\n")


def test_resume_refuses_a_checkpoint_of_another_configuration(finished_run, tmp_path):
    out = copy_run(finished_run, tmp_path / "run")
    with pytest.raises(ValueError, match="another configuration"):
        train(tiny_config(steps=300, seed=4), out, resume=True, progress=False)


@pytest.mark.parametrize("method", ["auxss", "jsrl"])
def test_a_finished_run_extended_to_more_steps_equals_one_trained_to_them(trained, tmp_path, method):
    # the 300k-step rows of a 100k-step protocol run come from extending it, not retraining
    copy_run(trained(tiny_config(method, steps=300))[0], tmp_path / "extended")
    short_rows = metrics_without_wall_time(tmp_path / "extended")
    extended = train(tiny_config(method, steps=500), tmp_path / "extended", resume=True, progress=False)
    straight_dir, straight = trained(tiny_config(method, steps=500))

    rows = metrics_without_wall_time(tmp_path / "extended")
    assert rows == metrics_without_wall_time(straight_dir)
    assert rows[:len(short_rows)] == short_rows and len(rows) == 5
    for name, tensor in straight.agent.actor.state_dict().items():
        assert torch.equal(tensor, extended.agent.actor.state_dict()[name]), name
    assert json.loads((tmp_path / "extended/config.json").read_text())["steps"] == 500
    assert torch.load(tmp_path / "extended/final.pt", weights_only=False)["step"] == 500


def test_a_resume_refuses_to_change_the_start_strategy_a_run_began_with(trained, tmp_path):
    # as if the code's default temperature growth had changed since the run's first session
    config = tiny_config("goaldist_ss", steps=300)
    out = copy_run(trained(config)[0], tmp_path / "run")
    sessions = json.loads((out / "provenance.json").read_text())
    sessions[0]["strategy"]["temperature_growth"] = 1.01
    (out / "provenance.json").write_text(json.dumps(sessions))
    before = {name: (out / name).read_bytes() for name in ("config.json", "provenance.json", "metrics.csv")}
    growth = GoalDistSS(np.zeros((1, 4)), goal=(0, 0)).temperature_growth
    with pytest.raises(RunDirectoryError, match=rf"temperature_growth=1.01 .*continue it with temperature_growth={growth}"):
        train(dataclasses.replace(config, steps=400), out, resume=True, progress=False)
    assert {name: (out / name).read_bytes() for name in before} == before

    # a setting the record lacks was added since, its default the old behaviour: the run continues
    del sessions[0]["strategy"]["schedule"]
    sessions[0]["strategy"]["temperature_growth"] = growth
    (out / "provenance.json").write_text(json.dumps(sessions))
    train(dataclasses.replace(config, steps=400), out, resume=True, progress=False)
    assert json.loads((out / "config.json").read_text())["steps"] == 400


def test_a_checkpoint_whose_start_strategy_state_this_code_cannot_continue_is_named_and_left_intact(trained, tmp_path):
    # as if the checkpoints were written by a GoalDist-SS that did not yet count steps
    config = tiny_config("goaldist_ss", steps=300)
    out = copy_run(trained(config)[0], tmp_path / "run")
    for name in ("checkpoint.pt", "checkpoint.prev.pt"):
        state = torch.load(out / name, weights_only=False)
        del state["wrapper"]["strategy"]["steps"]
        save_torch(out / name, state)
    (out / "final.pt").unlink()
    def files():  # the run's files, not the lock every writer takes (kept by design)
        return {path.name: path.read_bytes() for path in out.iterdir() if path.is_file() and path.name != ".lock"}

    before = files()
    with pytest.raises(ValueError, match=rf"checkpoint of {out} at step 300 cannot be resumed: goaldist_ss state_dict "
                                         r"lacks \['steps'\].*another version of goaldist_ss"):
        train(dataclasses.replace(config, steps=400), out, resume=True, progress=False)
    assert files() == before


def test_provenance_records_each_training_session_with_the_strategy_settings(trained, tmp_path):
    config = tiny_config("goaldist_ss", steps=300)
    tmp_path = copy_run(trained(config)[0], tmp_path / "run")
    first, = json.loads((tmp_path / "provenance.json").read_text())
    assert (first["from_step"], first["to_step"]) == (0, 300)
    goal = lava_bridge_mj.LavaBridgeEnv().layout.goal
    assert first["strategy"] == {"goal": [float(goal[0]), float(goal[1])], "temperature": 0.5,
                                 "temperature_growth": GoalDistSS(np.zeros((1, 4)), goal=(0, 0)).temperature_growth,
                                 "max_temperature": 50.0, "schedule": "episodes", "budget": None}
    assert first["code"]["lava_bridge_mj"] and first["code"]["torch"] == torch.__version__
    # the processor and torch's vector instructions: another processor may round the update differently
    assert first["code"]["processor"] == processor() and first["code"]["processor"]
    assert first["code"]["torch_cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    assert first["device"] == "cpu"  # a run option, recorded per session, not in config.json

    train(config, tmp_path, resume=True, progress=False)  # finished at its budget: trains nothing, records nothing
    assert len(json.loads((tmp_path / "provenance.json").read_text())) == 1
    train(dataclasses.replace(config, steps=500), tmp_path, resume=True, progress=False)
    sessions = json.loads((tmp_path / "provenance.json").read_text())
    assert [(s["from_step"], s["to_step"]) for s in sessions] == [(0, 300), (300, 500)]
    assert sessions[0] == first

    # a stray record makes a run directory: refused, kept, and replaced only on overwrite
    (tmp_path / "fresh").mkdir()
    (tmp_path / "fresh/provenance.json").write_text(json.dumps(sessions))
    with pytest.raises(RunDirectoryError, match=r"already holds a run \(provenance.json\)"):
        train(config, tmp_path / "fresh", progress=False)
    assert json.loads((tmp_path / "fresh/provenance.json").read_text()) == sessions
    train(dataclasses.replace(config, steps=100), tmp_path / "fresh", overwrite=True, progress=False)
    assert [s["from_step"] for s in json.loads((tmp_path / "fresh/provenance.json").read_text())] == [0]
    omega = tiny_config("omega_ss", steps=100, seed=7)
    train(omega, tmp_path / "omega", progress=False)
    assert json.loads((tmp_path / "omega/provenance.json").read_text())[0]["strategy"] == {
        "k": 4, "rollouts": 32, "seed": 7, "clamp": 0.05}  # the rollouts are seeded with the run's seed


def test_processor_names_the_first_entry_of_cpuinfo(tmp_path, monkeypatch):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nvendor_id\t: AuthenticAMD\ncpu family\t: 26\nmodel\t\t: 2\n"
                       "model name\t: AMD EPYC\nflags\t\t: fpu avx2\n\n"
                       "processor\t: 1\nvendor_id\t: GenuineIntel\nmodel name\t: other\n")
    assert processor(cpuinfo) == "AuthenticAMD AMD EPYC (cpu family 26, model 2)"
    cpuinfo.write_text("processor\t: 0\nmodel name\t: ARMv8 Processor\n")  # no family or model numbers
    assert processor(cpuinfo) == "ARMv8 Processor"
    monkeypatch.setattr("platform.processor", lambda: "arm")
    assert processor(tmp_path / "missing") == "arm"  # no /proc/cpuinfo (macOS, Windows)
    cpuinfo.write_text("processor\t: 0\n")
    assert processor(cpuinfo) == "arm"


def test_resume_refuses_a_damaged_provenance_record_and_changes_nothing(finished_run, tmp_path):
    tmp_path = copy_run(finished_run, tmp_path / "run")
    (tmp_path / "provenance.json").write_text('{"from_step": 0}')
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file() and p.name != ".lock"}
    with pytest.raises(ValueError, match=r"provenance.json is not a JSON list of training sessions"):
        train(tiny_config(steps=400), tmp_path, resume=True, progress=False)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file() and p.name != ".lock"} == before


def test_git_state_names_the_commit_of_a_tracked_file_and_nothing_for_an_untracked_one(tmp_path):
    def git(*args):
        return subprocess.run(["git", "-C", str(tmp_path), *args], check=True, capture_output=True,
                              text=True).stdout.strip()

    git("init", "-q")
    (tmp_path / "tracked.py").write_text("x = 1\n")
    git("add", "tracked.py")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "one")
    (tmp_path / "untracked.py").write_text("y = 2\n")
    assert git_state(tmp_path / "tracked.py") == {"commit": git("rev-parse", "HEAD"), "dirty": False}
    assert git_state(tmp_path / "untracked.py") == {"commit": None, "dirty": None}  # e.g. a copy in site-packages
    (tmp_path / "tracked.py").write_text("x = 2\n")
    assert git_state(tmp_path / "tracked.py")["dirty"] is True


def test_resume_refuses_to_shorten_a_run_and_changes_nothing(finished_run, tmp_path):
    tmp_path = copy_run(finished_run, tmp_path / "run")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file() and p.name != ".lock"}
    with pytest.raises(ValueError, match=r"at step 300, past steps=200; a run continues to more steps, never fewer"):
        train(tiny_config(steps=200), tmp_path, resume=True, progress=False)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file() and p.name != ".lock"} == before


@pytest.mark.parametrize("argv, message", [
    (["--method", "ppo"], "invalid choice: 'ppo'"),
    (["--method", "auxss", "--steps", "0"], "expected a positive integer, got 0"),
    (["--method", "auxss", "--steps", "many"], "expected a positive integer, got 'many'"),
    (["--method", "auxss", "--seed", "-1"], "expected an integer seed in [0, 4294967295], got -1"),
    (["--method", "auxss", "--seed", "99999999999999999999999"], "expected an integer seed in [0, 4294967295], got 99999999999999999999999"),
    (["--method", "auxss", "--seeds", "0-99999999999"], "in [0, 4294967295], got '0-99999999999'"),
    (["--method", "auxss", "--eval-episodes", "1000000"], "eval_episodes must be an integer in [1, 1000], got 1000000"),
    (["--method", "auxss", "--demos", "1000"], "or the path of a demo file (lava_bridge_mj.save_demos); '1000' is none of these"),
    (["--method", "auxss", "--eval-every", "-3"], "expected a positive integer, got -3"),
    ([], "the following arguments are required: --method"),
    (["--method", "auxss", "--seeds", "0-x"], "expected seeds like 0-24 or 0,3,5-7, got '0-x'"),
    (["--method", "auxss", "--seeds", "5-2"], "expected a range of seeds low-high in [0, 4294967295], got '5-2'"),
    (["--method", "auxss", "--seeds", "0-3,2"], "seeds must be distinct; repeated: [2]"),
    (["--method", "auxss", "--seeds", "0-3", "--seed", "1"], "not allowed with argument --seeds"),
])
def test_cli_rejects_bad_arguments(argv, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_info:
        cli.main([*argv, "--out", str(tmp_path / "run")])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "run").exists(), "a rejected command must write nothing"


def test_cli_rejects_an_output_path_that_is_a_file(capsys, tmp_path):
    target = tmp_path / "file"
    target.write_text("precious")
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--method", "auxss", "--out", str(target)])
    assert exit_info.value.code == 2
    assert "is not a directory" in capsys.readouterr().err
    assert target.read_text() == "precious"


def test_cli_refuses_to_overwrite_an_existing_run(capsys, tmp_path):
    (tmp_path / "config.json").write_text("{}")
    (tmp_path / "metrics.csv").write_text("step\n1\n")
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--method", "auxss", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "already holds a run" in capsys.readouterr().err
    assert (tmp_path / "metrics.csv").read_text() == "step\n1\n"


def test_cli_runs_a_tiny_training_job(tmp_path, capsys):
    code = cli.main(["--method", "uniform_ss", "--steps", "200", "--eval-every", "100", "--eval-episodes", "2",
                     "--out", str(tmp_path), "--no-progress"])
    assert code == 0
    assert [int(r["step"]) for r in read_metrics(tmp_path / "metrics.csv")] == [100, 200]
    assert "uniform_ss seed 0: 200 steps" in capsys.readouterr().out


# --- several seeds in one batch ----------------------------------------------------------------------

def seed_files(directory):
    """What a seed's results are: metrics (without wall time), start weights, policy snapshots and
    the episode log."""
    weights = np.load(directory / "start_weights.npz")
    policies = {p.name: torch.load(p) for p in sorted((directory / "policies").iterdir())}
    return (metrics_without_wall_time(directory), weights["probabilities"], policies,
            (directory / EPISODE_LOG).read_bytes())


@pytest.mark.parametrize("method", ["auxss", "sac"])
def test_a_seed_trained_in_a_batch_writes_what_it_writes_alone(trained, tmp_path, method, one_torch_thread):
    config = tiny_config(method, steps=300)  # seed 3
    dirs = [tmp_path / f"batch/seed{s}" for s in (1, 3, 4)]
    run = train(config, dirs, seeds=[1, 3, 4], progress=False)
    assert run.agent.seeds == (1, 3, 4)
    alone, batched = seed_files(trained(config)[0]), seed_files(dirs[1])
    assert alone[0] == batched[0] and alone[3] == batched[3]
    np.testing.assert_array_equal(alone[1], batched[1])
    assert alone[2].keys() == batched[2].keys()
    for name in alone[2]:
        for key, tensor in alone[2][name].items():
            assert torch.equal(tensor, batched[2][name][key]), (name, key)
    assert json.loads((dirs[1] / "config.json").read_text()) == config.to_dict()
    assert json.loads((dirs[0] / "config.json").read_text())["seed"] == 1
    assert seed_files(dirs[0])[0] != batched[0], "different seeds must give different results"


BATCH_CONFIG = tiny_config("auxss", steps=400)


@pytest.fixture(scope="module")
def batch_stopped_at(tmp_path_factory):
    """`batch_stopped_at(steps)`: the seed directories of BATCH_CONFIG's seeds 0 and 1 trained together
    to `steps`, and per seed its (latest, previous) checkpoints as BATCH_CONFIG itself would have written
    them on the way (same trajectory; only the configured length differs). Trained once per module for
    each `steps`; tests only read the directories."""
    batches = {}

    def get(steps):
        if steps not in batches:
            dirs = [tmp_path_factory.mktemp(f"batch-at-{steps}") / f"seed{s}" for s in (0, 1)]
            train(dataclasses.replace(BATCH_CONFIG, steps=steps), dirs, seeds=[0, 1], progress=False)
            batches[steps] = dirs
        pairs = []
        for seed, d in zip((0, 1), batches[steps]):
            states = [torch.load(d / name, weights_only=False) for name in ("checkpoint.pt", "checkpoint.prev.pt")]
            for state in states:
                state["config"] = dataclasses.replace(BATCH_CONFIG, seed=seed).to_dict()
            pairs.append(states)
        return batches[steps], pairs

    return get


def test_a_batch_resumes_when_a_kill_left_seeds_one_checkpoint_apart(batch_stopped_at, tmp_path):
    config = BATCH_CONFIG
    full_dirs, _ = batch_stopped_at(config.steps)

    # Killed between the two seeds' checkpoint writes at step 300: seed 0 has 300 (and 200 as prev),
    # seed 1 still has 200 (and 100). The resume must continue both from 200.
    ahead = batch_stopped_at(300)[1][0]
    behind = batch_stopped_at(200)[1][1]
    dirs = [tmp_path / f"killed/seed{s}" for s in (0, 1)]
    for source, target, states in zip(full_dirs, dirs, (ahead, behind)):
        target.mkdir(parents=True)
        shutil.copy(source / "config.json", target / "config.json")
        for name, state in zip(("checkpoint.pt", "checkpoint.prev.pt"), states):
            torch.save(state, target / name)
    assert [s["step"] for s in ahead + behind] == [300, 200, 200, 100]
    resumed = train(config, dirs, seeds=[0, 1], resume=True, progress=False)
    assert resumed.step == 400
    for source, target in zip(full_dirs, dirs):
        assert metrics_without_wall_time(target) == metrics_without_wall_time(source)


def test_a_batch_refuses_seeds_whose_checkpoints_share_no_step(batch_stopped_at, tmp_path):
    config = BATCH_CONFIG
    early = batch_stopped_at(200)[1][0]  # seed 0 at 200 (and 100)
    late = batch_stopped_at(300)[1][1]  # seed 1 at 300 (and 200): only the latest is kept below
    dirs = [tmp_path / f"mixed/seed{s}" for s in (0, 1)]
    for seed, d, states in zip((0, 1), dirs, (early, late)):
        d.mkdir(parents=True)
        (d / "config.json").write_text(json.dumps(dataclasses.replace(config, seed=seed).to_dict()))
        torch.save(states[0], d / "checkpoint.pt")
    with pytest.raises(ValueError, match="different steps"):
        train(config, dirs, seeds=[0, 1], resume=True, progress=False)


def test_cli_trains_several_seeds_into_one_directory_each(tmp_path, capsys):
    code = cli.main(["--method", "uniform_ss", "--seeds", "2,5", "--steps", "200", "--eval-every", "100",
                     "--eval-episodes", "2", "--out", str(tmp_path), "--no-progress"])
    assert code == 0
    for seed in (2, 5):
        assert [int(r["step"]) for r in read_metrics(tmp_path / f"seed{seed}/metrics.csv")] == [100, 200]
        assert json.loads((tmp_path / f"seed{seed}/config.json").read_text())["seed"] == seed
    out = capsys.readouterr().out
    assert "uniform_ss seed 2: 200 steps" in out and "uniform_ss seed 5: 200 steps" in out


def test_cli_refuses_a_batch_when_any_seed_directory_holds_a_run(tmp_path, capsys):
    (tmp_path / "seed1").mkdir()
    (tmp_path / "seed1/config.json").write_text("{}")
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--method", "auxss", "--seeds", "0-2", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "seed1 already holds a run" in capsys.readouterr().err
    assert not (tmp_path / "seed0").exists(), "a refused batch must write nothing"


# --- HySAC: demo transitions in every minibatch -------------------------------------------------------

@pytest.mark.parametrize("fraction, expected_offline", [(0.5, 16), (0.25, 8), (0.0, 0), (1.0, 32)])
def test_hysac_minibatch_takes_the_configured_share_from_the_demos(tmp_path, fraction, expected_offline):
    run = Run([tiny_config("hysac", hybrid_fraction=fraction)], [tmp_path])
    seed_run = run.seed_runs[0]
    for _ in range(50):  # online transitions that no demo can contain: observations of 100
        seed_run.buffer.add(np.full(4, 100.0), np.zeros(2), 0.0, np.full(4, 100.0), False)
    batch = seed_run.sample()
    assert batch["obs"].shape == (32, 4)
    from_demos = (batch["obs"][:, 0] != 100.0).sum().item()
    assert from_demos == expected_offline
    demo_obs = {tuple(o) for o in lava_bridge_mj.load_demos(500)["observations"].astype(np.float32).tolist()}
    assert all(tuple(o) in demo_obs for o in batch["obs"][batch["obs"][:, 0] != 100.0].tolist())


def test_hysac_offline_buffer_holds_every_demo_and_is_never_overwritten(tmp_path):
    run = train(tiny_config("hysac", steps=300, env={"goal_reward": 2.0}), tmp_path, progress=False)
    offline, demos = run.seed_runs[0].demos, lava_bridge_mj.load_demos(500)
    assert len(offline) == offline.capacity == 500 and offline.pos == 0
    np.testing.assert_array_equal(offline.obs, demos["observations"].astype(np.float32))
    np.testing.assert_array_equal(offline.action, demos["actions"].astype(np.float32))
    # relabelled with the run's rewards: the goal gives 2 here
    np.testing.assert_array_equal(offline.reward, np.where(demos["rewards"] == 1.0, 2.0, 0.0))
    assert offline.reward.sum() == 2.0 * demos["terminations"].sum()


# --- run directories are never silently replaced; damaged checkpoints fall back -------------------------
def test_a_directory_with_run_files_but_no_config_is_never_trained_into(finished_run, tmp_path, capsys):
    """Removing config.json used to make a run directory look empty: another configuration then replaced
    its checkpoints and metrics without --overwrite. Any run file now makes it a run directory."""
    out = copy_run(finished_run, tmp_path / "run")
    (out / "config.json").unlink()
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".lock"}
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--method", "sac", "--steps", "200", "--out", str(out), "--no-progress"])
    assert exit_info.value.code == 2
    assert "already holds a run (provenance.json, metrics.csv" in capsys.readouterr().err
    for resume in (False, True):
        with pytest.raises(RunDirectoryError, match="holds run files|already holds a run"):
            train(tiny_config(method="sac", steps=200), out, resume=resume, progress=False)
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".lock"}
    assert after == before


def test_an_unwritable_run_directory_is_one_line_and_exit_2(capsys):
    assert cli.main(["--method", "auxss", "--out", "/proc/forbidden", "--steps", "10", "--no-progress"]) == 2
    assert capsys.readouterr().err == ("lava-bridge-bench: error: cannot create run directory /proc/forbidden: "
                                       "No such file or directory\n")
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--method", "auxss", "--out", "", "--steps", "10", "--no-progress"])
    assert exit_info.value.code == 2
    assert "argument --out: expected a directory, got ''" in capsys.readouterr().err
    with pytest.raises(RunDirectoryError, match="cannot create run directory /proc/forbidden"):
        train(tiny_config(steps=10), "/proc/forbidden", progress=False)


def test_a_bit_flip_in_a_checkpoint_or_snapshot_is_detected(finished_run, tmp_path):
    from lava_bridge_mj.eval.training.run_files import DamagedFileError, load_torch

    out = copy_run(finished_run, tmp_path / "run")
    for path in (out / "checkpoint.pt", out / "policies" / "step_300.pt"):
        intact = load_torch(path)
        flip_a_data_bit(path)
        torch.load(path, weights_only=False)  # torch itself reads the flipped file without complaint
        with pytest.raises(DamagedFileError, match=f"{path.name} is damaged"):
            load_torch(path)
        assert intact is not None


@pytest.mark.parametrize("damaged", [("checkpoint.pt",), ("checkpoint.prev.pt",), ("checkpoint.pt", "checkpoint.prev.pt")])
def test_a_damaged_checkpoint_falls_back_to_the_other_one(finished_run, trained, tmp_path, capsys, damaged):
    """One damaged checkpoint: a warning, the file set aside, and the run continues from the other one
    to the same end as the uninterrupted run; both damaged: the resume stops, changing nothing."""
    out = copy_run(finished_run, tmp_path / "run")
    for name in damaged:
        flip_a_data_bit(out / name)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file() and p.name != ".lock"}
    if len(damaged) == 2:
        with pytest.raises(ValueError, match="every checkpoint of .* is damaged.*--overwrite"):
            train(tiny_config(steps=500), out, resume=True, progress=False)
        assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file() and p.name != ".lock"} == before
        return
    train(tiny_config(steps=500), out, resume=True, progress=False)
    err = capsys.readouterr().err
    assert err.count("warning:") == 1 and f"{damaged[0]} is damaged" in err
    assert (out / f"{damaged[0]}.damaged").read_bytes() == before[damaged[0]]
    assert metrics_without_wall_time(out) == metrics_without_wall_time(trained(tiny_config(steps=500))[0])


@pytest.mark.parametrize("where", ["in training", "in evaluation"])
def test_a_diverged_seed_stops_alone_and_the_batch_trains_on(tmp_path, capsys, where):
    """Seed 1's actor is made NaN before training: its first policy action (a training step after
    warm-up, or an evaluation before it) is not finite. Seed 1 stops with a warning; seed 0's files
    equal its run alone."""
    config = tiny_config(steps=300, eval_every=100 if where == "in training" else 50, seed=0)
    alone = tmp_path / "alone"
    train(config, alone, progress=False)
    dirs = [tmp_path / "batch0", tmp_path / "batch1"]
    for d in dirs:
        d.mkdir()
    run = Run([config, dataclasses.replace(config, seed=1)], dirs)
    with torch.no_grad():
        for parameter in run.agent.actor.parameters():
            parameter[1] = float("nan")
    run.train(progress=False)
    assert run.diverged == {1: 100 if where == "in training" else 50}
    assert "warning: seed 1 stopped at step" in capsys.readouterr().err
    assert metrics_without_wall_time(dirs[0]) == metrics_without_wall_time(alone)
    assert (dirs[0] / "final.pt").exists() and not (dirs[1] / "final.pt").exists()


def test_a_minibatch_that_cannot_fit_in_memory_is_refused_before_anything_is_written(tmp_path, capsys, monkeypatch):
    """`--set sac.batch_size=1000000000 --set sac.learning_starts=0 --steps 50` passed, wrote config.json and
    was killed by the kernel at about 22 GB. Here the memory available is 64 MiB, which a 2^18 minibatch
    (twice 12 floats per transition, the twin critics' 16 + 16 activations) exceeds."""
    import lava_bridge_mj.agents.checks as checks

    out = tmp_path / "run"
    monkeypatch.setattr(checks, "available_memory", lambda: 64 * 2**20)
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--method", "sac", "--set", "sac.hidden_sizes=[16, 16]", "--set", "sac.batch_size=262144",
                  "--set", "sac.learning_starts=0", "--steps", "2", "--out", str(out), "--no-progress"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "SACConfig.batch_size=262144 does not fit in memory: 1 seed needs at least 88.5 MiB" in err
    assert "SACConfig.batch_size: 88.0 MiB" in err and err.endswith("more than the 64.0 MiB of memory available here\n")
    assert not out.exists()


def test_a_batch_or_buffer_that_cannot_fit_in_memory_is_refused_at_once(tmp_path, capsys, monkeypatch):
    """A million seeds, a 10^12-transition buffer or 100,000-unit layers used to run for minutes or end
    in MemoryError; the CLI refuses them before it checks any seed's run directory (a million of those
    took minutes)."""
    checked = []
    check_writable = cli.arguments.check_writable
    monkeypatch.setattr(cli.arguments, "check_writable", lambda out, parser: (checked.append(out),
                                                                              check_writable(out, parser)))
    buffer, layers = tmp_path / "buffer.json", tmp_path / "layers.json"
    buffer.write_text(json.dumps({"sac": {"buffer_size": 10**12}}))
    layers.write_text(json.dumps({"sac": {"hidden_sizes": [100000, 100000]}}))
    for argv in (["--seeds", "0-1000000"], ["--config", str(buffer)], ["--config", str(layers)]):
        if argv[0] == "--config":  # train() checks too, for callers of the Python API
            with pytest.raises(ValueError, match="does not fit in memory"):
                train(RunConfig.from_dict(json.loads(open(argv[1]).read())), tmp_path / "api")
            assert not (tmp_path / "api").exists()
        with pytest.raises(SystemExit) as exit_info:
            cli.main(["--method", "auxss", "--out", str(tmp_path / "run"), "--no-progress", *argv])
        assert exit_info.value.code == 2
        assert "does not fit in memory" in capsys.readouterr().err
        assert not (tmp_path / "run").exists()
        assert checked == []


def test_env_selects_the_task_its_demos_and_its_starts(tmp_path, capsys):
    task = "LavaBridgeBend-v0"  # its expert path differs from LavaBridge-v0's (the narrow bridge's does not)
    out = tmp_path / "run"
    assert cli.main(["--method", "auxss", "--env", task, "--steps", "100", "--eval-every", "100",
                     "--eval-episodes", "2", "--out", str(out), "--no-progress"]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["env_id"] == task
    run_config = RunConfig.from_dict(config)
    assert run_config.make_env().layout == lava_bridge_mj.task_layout(task)
    demo_states = lava_bridge_mj.load_demos(500, env_id=task)["observations"]
    with np.load(out / "start_weights.npz") as weights:
        candidates = weights["states"]
    assert all((demo_states == state).all(axis=1).any() for state in candidates)
    assert not all((lava_bridge_mj.load_demos(500)["observations"] == state).all(axis=1).any() for state in candidates)
    with pytest.raises(SystemExit):
        cli.main(["--method", "auxss", "--env", "LavaBridge-v9", "--out", str(tmp_path / "other")])
    assert "unknown env_id 'LavaBridge-v9'" in capsys.readouterr().err
    with pytest.raises(ValueError, match="unknown env_id 'LavaBridge-v9'"):
        RunConfig(env_id="LavaBridge-v9")


def test_a_run_recorded_before_env_id_existed_still_resumes(finished_run, tmp_path):
    out = copy_run(finished_run, tmp_path / "run")
    saved = json.loads((out / "config.json").read_text())
    del saved["env_id"]
    (out / "config.json").write_text(json.dumps(saved))
    assert tiny_config(steps=300).continues(saved)
    assert not dataclasses.replace(tiny_config(steps=300), env_id="LavaBridgeNarrow-v0").continues(saved)
    train(tiny_config(steps=400), out, resume=True, progress=False)
    assert json.loads((out / "config.json").read_text())["env_id"] == "LavaBridge-v0"


def test_an_auxss_horizon_other_than_the_time_limit_is_refused_before_training(tmp_path):
    """AuxSS scores an episode by its length against its horizon: a horizon that is not the env's
    500-step limit would silently mis-score every timeout."""
    with pytest.raises(ValueError, match="AuxSS horizon=200 differs from the env's max_episode_steps=500"):
        train(tiny_config(steps=100, strategy={"horizon": 200}), tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()
