"""`lava-bridge-bench export`: compact copies of finished runs only, same relative paths, byte for byte;
an extension replaces its earlier copy, another configuration or a larger budget is refused."""

import json
import shutil

import pytest

from conftest import interrupted_copy
from lava_bridge_mj.agents.configs import SACConfig
from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.training import run_files
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.sweeps.export import CHECKSUMS, COMPACT_FILES, main
from lava_bridge_mj.eval.training.run_files import EPISODE_LOG, PLAIN_EPISODE_LOG
from lava_bridge_mj.eval.training.runner import train

TINY = dict(method="auxss", steps=300, eval_every=100, eval_episodes=2, demo_subset=20,
            sac=SACConfig(hidden_sizes=(16, 16), batch_size=32, learning_starts=50))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """runs/auxss-d500/seed3 and seed4 finished at 300 steps; seed5 a copy of seed4 killed part-way."""
    root = tmp_path_factory.mktemp("export") / "runs"
    group = root / "auxss-d500"
    train(RunConfig(**TINY), [group / "seed3", group / "seed4"], seeds=[3, 4], progress=False)
    interrupted_copy(group / "seed4", group / "seed5")
    return root


def files(directory):
    return {p.relative_to(directory).as_posix(): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


def test_finished_runs_are_copied_byte_for_byte_without_checkpoints_and_unfinished_ones_listed(runs, tmp_path, capsys):
    assert main([str(runs), str(tmp_path / "results")]) == 0
    copied = files(tmp_path / "results")
    expected = {f"auxss-d500/seed{s}/{name}": (runs / f"auxss-d500/seed{s}" / name).read_bytes()
                for s in (3, 4) for name in COMPACT_FILES}
    assert copied == expected  # seed5 has not finished; no .pt file travels
    out = capsys.readouterr().out
    assert "exported 2 run(s)" in out
    # killed after its last evaluation, before final.pt: not finished
    assert "not finished, not exported:\n  auxss-d500/seed5 (last evaluation at step 300 of 300)" in out


def test_a_rerun_rewrites_nothing(runs, tmp_path, capsys):
    results = tmp_path / "results"
    main([str(runs), str(results)])
    stamps = {p: p.stat().st_mtime_ns for p in results.rglob("*") if p.is_file()}
    capsys.readouterr()
    assert main([str(runs), str(results)]) == 0
    assert f"exported 0 run(s) to {results}, 2 unchanged" in capsys.readouterr().out
    assert {p: p.stat().st_mtime_ns for p in results.rglob("*") if p.is_file()} == stamps


def test_a_plain_episode_log_is_copied_compressed_and_replaces_a_plain_copy(runs, tmp_path, capsys):
    old = tmp_path / "old" / "auxss-d500" / "seed3"  # a run written before episode logs were compressed
    shutil.copytree(runs / "auxss-d500/seed3", old, ignore=shutil.ignore_patterns(".lock"))
    (old / PLAIN_EPISODE_LOG).write_bytes(run_files.read_episode_log(old / EPISODE_LOG))
    (old / EPISODE_LOG).unlink()
    results = tmp_path / "results"
    shutil.copytree(old, results / "auxss-d500/seed3")  # an earlier export's copy, its log plain
    assert main([str(tmp_path / "old"), str(results)]) == 0
    assert "exported 1 run(s)" in capsys.readouterr().out
    copy = results / "auxss-d500/seed3"
    assert (copy / EPISODE_LOG).read_bytes() == (runs / "auxss-d500/seed3" / EPISODE_LOG).read_bytes()
    assert not (copy / PLAIN_EPISODE_LOG).exists()
    assert main([str(tmp_path / "old"), str(results)]) == 0
    assert "1 unchanged" in capsys.readouterr().out


def test_unfinished_runs_go_too_when_asked(runs, tmp_path):
    assert main([str(runs), str(tmp_path / "results"), "--unfinished"]) == 0
    seed5 = tmp_path / "results/auxss-d500/seed5"
    assert (seed5 / "metrics.csv").read_bytes() == (runs / "auxss-d500/seed5/metrics.csv").read_bytes()


def test_an_extended_run_replaces_its_copy_and_a_shorter_one_never_replaces_a_longer(runs, tmp_path, capsys):
    longer = tmp_path / "longer"
    shutil.copytree(runs / "auxss-d500/seed3", longer / "auxss-d500/seed3", ignore=shutil.ignore_patterns(".lock"))
    results = tmp_path / "results"
    assert main([str(runs), str(results)]) == 0
    train(RunConfig(**{**TINY, "steps": 400, "seed": 3}), longer / "auxss-d500/seed3", resume=True, progress=False)
    assert main([str(longer), str(results)]) == 0  # the extension replaces the 300-step copy
    copy = results / "auxss-d500/seed3"
    assert json.loads((copy / "config.json").read_text())["steps"] == 400
    assert (copy / "metrics.csv").read_bytes() == (longer / "auxss-d500/seed3/metrics.csv").read_bytes()
    before = files(results)
    capsys.readouterr()
    assert main([str(runs), str(results)]) == 1  # the 300-step run must not replace the 400-step copy
    assert "larger budget (400 steps, here 300)" in capsys.readouterr().out
    assert files(results) == before


def test_a_target_of_another_configuration_is_refused_and_left_alone(runs, tmp_path, capsys):
    results = tmp_path / "results"
    target = results / "auxss-d500/seed4"
    target.mkdir(parents=True)
    other = RunConfig(**{**TINY, "seed": 4, "demo_subset": 30}).to_dict()
    (target / "config.json").write_text(json.dumps(other))
    assert main([str(runs), str(results)]) == 1
    assert "auxss-d500/seed4" in capsys.readouterr().out
    assert files(target) == {"config.json": json.dumps(other).encode()}
    assert (results / "auxss-d500/seed3/metrics.csv").is_file()  # the other runs still go


@pytest.mark.parametrize("where, message", [
    ("missing", "is not a directory"),
    ("inside", "lies inside RUNS"),
])
def test_bad_directories_are_refused_with_a_usage_line_and_nothing_written(runs, tmp_path, capsys, where, message):
    source = tmp_path / "nowhere" if where == "missing" else runs
    results = runs / "results" if where == "inside" else tmp_path / "results"
    with pytest.raises(SystemExit) as stop:
        cli.main(["export", str(source), str(results)])
    assert stop.value.code == 2 and message in capsys.readouterr().err
    assert not results.exists()


def test_a_copy_carries_the_metrics_checksum_and_verifies(runs, tmp_path):
    from lava_bridge_mj.eval.training.run_files import read_metrics

    results = tmp_path / "results"
    assert main([str(runs), str(results)]) == 0
    copy = results / "auxss-d500/seed3"
    assert (copy / CHECKSUMS).read_bytes() == (runs / "auxss-d500/seed3" / CHECKSUMS).read_bytes()
    assert len(read_metrics(copy)) == 3  # verified against the checksum file it came with
    legacy = tmp_path / "legacy"  # a run written before checksums: its copy must not keep an old one
    shutil.copytree(runs / "auxss-d500/seed3", legacy / "auxss-d500/seed3")
    (legacy / "auxss-d500/seed3" / CHECKSUMS).unlink()
    (legacy / "auxss-d500/seed3/metrics.csv").write_text((copy / "metrics.csv").read_text() + "\n")
    assert main([str(legacy), str(results)]) == 0
    assert not (copy / CHECKSUMS).exists() and len(read_metrics(copy)) == 3


def test_a_results_path_blocked_by_a_file_is_one_line_not_an_errno(runs, tmp_path, capsys):
    results = tmp_path / "results"
    results.mkdir()
    (results / "auxss-d500").write_text("")
    assert main([str(runs), str(results)]) == 1
    out = capsys.readouterr().out
    assert f"cannot make the copy's directory {results / 'auxss-d500/seed3'}: {results / 'auxss-d500'} is a file" in out
    assert "Errno" not in out
    with pytest.raises(SystemExit) as stop:
        main([str(runs), str(results / "auxss-d500")])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "exists and is not a directory" in err and "Errno" not in err
