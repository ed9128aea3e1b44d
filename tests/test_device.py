"""`--device`: where the learners' tensors live. The CUDA path needs a GPU; these tests check the
plumbing on the CPU: the option's checks, that an explicit cpu is the default bit for bit, that
checkpoints hold CPU tensors and record their generators' device, and (on the meta device, which
computes shapes only) that the networks create no tensor off their own device."""

import json
import shutil

import numpy as np
import pytest
import torch

from conftest import metrics_without_wall_time

from lava_bridge_mj.agents.configs import BCConfig, IQLConfig, SACConfig
from lava_bridge_mj.agents.networks import TanhGaussianActor, TwinQ
from lava_bridge_mj.agents.offline import BC, IQL
from lava_bridge_mj.agents.sac import SAC
from lava_bridge_mj.agents.seed_batch import stack_batches
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.sweeps import sweep_jobs
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.training.run_files import EPISODE_LOG, load_torch, save_torch



def jsrl_argv(out, steps=120):
    """A tiny JSRL run of two seeds: SAC learner and IQL guide, so both learners' states are checked."""
    return ["--method", "jsrl", "--seeds", "0-1", "--set", "jsrl.guide_steps=20", "--set", "sac.hidden_sizes=[8, 8]",
            "--set", "sac.learning_starts=50", "--set", "sac.batch_size=16", "--set", "iql.hidden_sizes=[8, 8]",
            "--steps", str(steps), "--eval-every", "60", "--eval-episodes", "1", "--no-progress", "--out", str(out)]

LEARNERS = [(SAC, SACConfig(hidden_sizes=(8, 8))), (BC, BCConfig(hidden_sizes=(8, 8))),
            (IQL, IQLConfig(hidden_sizes=(8, 8)))]


def tensors_in(tree):
    if isinstance(tree, dict):
        return [t for value in tree.values() for t in tensors_in(value)]
    if isinstance(tree, (list, tuple)):
        return [t for value in tree for t in tensors_in(value)]
    return [tree] if isinstance(tree, torch.Tensor) else []


def random_batch(k, rng):
    return stack_batches([{"obs": torch.from_numpy(rng.normal(size=(16, 4)).astype(np.float32)),
                           "action": torch.from_numpy(rng.uniform(-1, 1, (16, 2)).astype(np.float32)),
                           "reward": torch.from_numpy(rng.normal(size=16).astype(np.float32)),
                           "next_obs": torch.from_numpy(rng.normal(size=(16, 4)).astype(np.float32)),
                           "terminated": torch.zeros(16)} for _ in range(k)])


@pytest.fixture(scope="module")
def default_and_cpu_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("device")
    for name, extra in (("default", []), ("cpu", ["--device", "cpu"])):
        assert cli.main([*jsrl_argv(root / name), *extra]) == 0
    return root


def test_an_explicit_cpu_device_trains_as_the_default_and_provenance_records_it(default_and_cpu_runs):
    for seed in (0, 1):
        default, cpu = (default_and_cpu_runs / name / f"seed{seed}" for name in ("default", "cpu"))
        assert metrics_without_wall_time(cpu) == metrics_without_wall_time(default)
        assert (cpu / EPISODE_LOG).read_bytes() == (default / EPISODE_LOG).read_bytes()
        assert json.loads((cpu / "provenance.json").read_text())[-1]["device"] == "cpu"
        assert json.loads((cpu / "config.json").read_text()) == json.loads((default / "config.json").read_text())


def test_checkpoints_and_snapshots_hold_cpu_tensors_and_their_generators_device(default_and_cpu_runs):
    run = default_and_cpu_runs / "cpu" / "seed0"
    state = load_torch(run / "final.pt")
    assert state["agent"]["generator_device"] == "cpu" and state["guide"]["generator_device"] == "cpu"
    snapshot = load_torch(run / "policies" / "step_120.pt", weights_only=True)
    found = tensors_in(state) + tensors_in(snapshot)
    assert found and {t.device.type for t in found} == {"cpu"}


@pytest.mark.parametrize("device, message", [
    ("gpu", "argument --device: expected cpu, cuda or cuda:N, got 'gpu'"),
    ("cuda", "argument --device: cuda requested but torch.cuda.is_available() is False; use --device cpu"),
    ("cuda:1", "argument --device: cuda:1 requested but torch.cuda.is_available() is False; use --device cpu"),
    ("cuda:x", "argument --device: expected cpu, cuda or cuda:N, got 'cuda:x'"),
])
@pytest.mark.parametrize("command", [["--method", "sac"], ["sweep", "--methods", "sac", "--seeds", "0"]])
def test_a_device_this_machine_lacks_is_one_usage_line_and_writes_nothing(device, message, command, tmp_path,
                                                                         monkeypatch, capsys):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)  # as on a machine without CUDA
    with pytest.raises(SystemExit) as stop:
        cli.main([*command, "--device", device, "--out", str(tmp_path / "out")])
    assert stop.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1].endswith(message)
    assert list(tmp_path.iterdir()) == []


def test_a_cuda_index_past_the_machines_devices_and_cuda_on_ray_are_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    with pytest.raises(SystemExit) as stop:
        cli.main(["--method", "sac", "--device", "cuda:1", "--out", str(tmp_path / "out")])
    assert stop.value.code == 2
    assert "cuda:1 requested but this machine has 1 CUDA device(s), cuda:0 to cuda:0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        cli.main(["sweep", "--methods", "sac", "--seeds", "0", "--device", "cuda:0", "--backend", "ray",
                  "--out", str(tmp_path / "out")])
    assert stop.value.code == 2
    assert "--device cuda:0: Ray tasks ask for CPUs only" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_sweep_job_trains_on_its_specs_device(tmp_path, monkeypatch):
    asked = {}

    class Trained:
        diverged = {}

    def fake_train(config, dirs, **options):
        asked.update(options)
        return Trained()

    monkeypatch.setattr("lava_bridge_mj.eval.training.runner.train", fake_train)
    spec = sweep_jobs.Job("sac", 500, (0,)).spec(RunConfig(method="sac"), tmp_path, 1, "cuda:1")
    assert json.loads(json.dumps(spec))["device"] == "cuda:1"
    assert sweep_jobs.run_spec(spec)["status"] == "done"
    assert asked["device"] == "cuda:1"


def test_a_run_trained_on_another_device_type_is_not_resumed_and_stays_unchanged(default_and_cpu_runs,
                                                                                  tmp_path, capsys):
    """A generator's state loads only into a generator of its device type, so a run started on CUDA
    continues on CUDA: said in one line, before anything is written. (Edited here to read as CUDA's.)"""
    out = tmp_path / "run"
    shutil.copytree(default_and_cpu_runs / "cpu", out, ignore=shutil.ignore_patterns(".lock"))
    for seed in (0, 1):
        for name in ("checkpoint.pt", "checkpoint.prev.pt", "final.pt"):
            path = out / f"seed{seed}" / name
            if path.exists():
                state = load_torch(path)
                state["agent"]["generator_device"] = "cuda"
                save_torch(path, state)
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".lock"}
    assert cli.main([*jsrl_argv(out, steps=180), "--resume"]) == 2
    assert ("seed 0 was trained on device cuda and its random stream cannot continue on cpu: continue it with "
            "--device cuda") in capsys.readouterr().err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".lock"} == before


@pytest.mark.parametrize("learner, config", LEARNERS)
def test_an_agent_on_a_torch_device_object_is_the_agent_on_the_default_device(learner, config):
    default = learner(4, 2, config, seeds=(0, 1))
    placed = learner(4, 2, config, seeds=(0, 1), device=torch.device("cpu"))
    assert placed.device == torch.device("cpu") and {g.device.type for g in placed.generators} == {"cpu"}
    rng = np.random.default_rng(0)
    for _ in range(3):
        batch = random_batch(2, rng)
        stats, placed_stats = default.update(batch), placed.update(batch)
        assert stats.keys() == placed_stats.keys()
        assert all(np.array_equal(stats[name], placed_stats[name]) for name in stats)
    obs = rng.normal(size=(2, 5, 4))
    assert np.array_equal(default.act(obs), placed.act(obs))
    assert np.array_equal(default.act(obs, deterministic=True), placed.act(obs, deterministic=True))
    state = placed.seed_state(1)
    assert state["generator_device"] == "cpu" and {t.device.type for t in tensors_in(state)} == {"cpu"}


def test_the_networks_make_every_tensor_on_their_own_device():
    """On the meta device (shapes, no data) any tensor a forward pass made on the CPU instead, such as
    sampling noise made without a device, fails the pass: the check a CUDA run would make."""
    actor = TanhGaussianActor(3, 4, 2, (8, 8)).to("meta")
    critic = TwinQ(3, 4, 2, (8, 8), layer_norm=True).to("meta")
    obs = torch.empty(3, 5, 4, device="meta")
    action, log_prob = actor(obs)  # stochastic: noise from torch's generator on the actor's device
    assert action.device.type == log_prob.device.type == "meta" and action.shape == (3, 5, 2)
    assert actor.log_prob(obs, action).shape == (3, 5)
    assert critic(obs, action).device.type == "meta"
