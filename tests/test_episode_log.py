"""Run files stored compressed: the episode log's deterministic gzip writer, one reader for both forms,
start weights as reproducible compressed .npz, the in-place conversion of both (eval/training/compress.py),
a resumed run from a plain log, and reports that read the same from either form."""

import gzip
import io
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from conftest import interrupted_copy
from test_runner import tiny_config, trained  # noqa: F401 (trained: the module's fixture, shared)

from lava_bridge_mj.eval import cli
from lava_bridge_mj.eval.training import compress, run_files
from lava_bridge_mj.eval.training.run_files import EPISODE_LOG, PLAIN_EPISODE_LOG, START_WEIGHTS, npz_bytes, read_npz
from lava_bridge_mj.eval.training.runner import train
from lava_bridge_mj.eval.analysis.summary import EPISODE_COLUMNS
from lava_bridge_mj.eval.training.run_files import read_csv

ROOT = Path(__file__).resolve().parent.parent
ROWS = [(1, 8, 141, 0.8869671685798248, -3.16e-10, 8, 0, 0.0), (2, 29, -1, 3.17, 0.5385, 21, 1, 1.0)]


def write_plain(run_dir, rows):
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / PLAIN_EPISODE_LOG).write_bytes(run_files.episode_log_text(rows))


def test_the_gzip_writer_gives_the_same_bytes_for_the_same_rows(tmp_path):
    for name, rows in (("a", ROWS), ("b", [tuple(row) for row in ROWS])):
        (tmp_path / name).mkdir()
        run_files.write_episode_log(tmp_path / name, rows)
    first, second = ((tmp_path / name / EPISODE_LOG).read_bytes() for name in "ab")
    assert first == second
    # the header: gzip magic, deflate, no flags (so no file name), mtime 0, the level-9 flag, OS 255
    assert first[:10] == b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x02\xff"
    assert gzip.decompress(first) == b"episode,step,start_index,start_x,start_y,length,success,return\n" \
        b"1,8,141,0.8869671685798248,-3.16e-10,8,0,0.0\n2,29,-1,3.17,0.5385,21,1,1.0\n"
    run_files.write_episode_log(tmp_path / "b", ROWS[:1])
    assert (tmp_path / "b" / EPISODE_LOG).read_bytes() != first


def test_the_reader_reads_both_forms_to_the_same_rows_and_prefers_the_compressed_one(tmp_path):
    write_plain(tmp_path / "plain", ROWS)
    (tmp_path / "gzip").mkdir()
    run_files.write_episode_log(tmp_path / "gzip", ROWS)
    plain, packed = (run_files.episode_log_file(tmp_path / name) for name in ("plain", "gzip"))
    assert (plain.name, packed.name) == (PLAIN_EPISODE_LOG, EPISODE_LOG)
    rows = read_csv(plain, EPISODE_COLUMNS, run_files.read_episode_log)
    assert rows == read_csv(packed, EPISODE_COLUMNS, run_files.read_episode_log)
    assert [r["start_x"] for r in rows] == [0.8869671685798248, 3.17]
    assert run_files.episode_log_file(tmp_path) is None
    # both present (a conversion killed before the plain file went): the compressed log is the run's
    write_plain(tmp_path / "gzip", ROWS[:1])
    assert run_files.episode_log_file(tmp_path / "gzip").name == EPISODE_LOG


def test_a_damaged_compressed_log_is_refused_by_name(tmp_path):
    run_files.write_episode_log(tmp_path, ROWS)
    path = tmp_path / EPISODE_LOG
    data = bytearray(path.read_bytes())
    data[20] ^= 0x01
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="episodes.csv.gz is not a whole gzip file"):
        read_csv(path, EPISODE_COLUMNS, run_files.read_episode_log)
    path.write_bytes(run_files.gzip_bytes(run_files.episode_log_text(ROWS))[:-3])
    with pytest.raises(ValueError, match="episodes.csv.gz is not a whole gzip file"):
        run_files.read_episode_log(path)


def test_compressing_converts_every_plain_log_once_to_the_trainers_bytes(tmp_path, capsys):
    runs = {tmp_path / "task" / "auxss-d500" / f"seed{seed}": ROWS[:seed + 1] for seed in (0, 1)}
    for run, rows in runs.items():
        write_plain(run, rows)
    plain_bytes = {run: (run / PLAIN_EPISODE_LOG).read_bytes() for run in runs}
    assert compress.main([str(tmp_path / "task")]) == 0
    assert "compressed 2 episode logs" in capsys.readouterr().out
    for run, rows in runs.items():
        assert not (run / PLAIN_EPISODE_LOG).exists()
        assert gzip.decompress((run / EPISODE_LOG).read_bytes()) == plain_bytes[run]
        (tmp_path / "trainer").mkdir(exist_ok=True)
        run_files.write_episode_log(tmp_path / "trainer", rows)
        assert (run / EPISODE_LOG).read_bytes() == (tmp_path / "trainer" / EPISODE_LOG).read_bytes()
    before = {run: (run / EPISODE_LOG).stat().st_mtime_ns for run in runs}
    assert compress.main([str(tmp_path / "task")]) == 0  # again: nothing left to convert, nothing rewritten
    assert "compressed 0 episode logs" in capsys.readouterr().out
    assert {run: (run / EPISODE_LOG).stat().st_mtime_ns for run in runs} == before


def test_compressing_refuses_a_log_whose_check_fails_and_leaves_it_plain(tmp_path, monkeypatch, capsys):
    write_plain(tmp_path / "seed0", ROWS)
    original = (tmp_path / "seed0" / PLAIN_EPISODE_LOG).read_bytes()
    monkeypatch.setattr(compress, "gzip_bytes", lambda data: run_files.gzip_bytes(data[:-1]))  # loses a byte
    assert compress.main([str(tmp_path)]) == 1
    assert "does not decompress to the same bytes; left plain" in capsys.readouterr().err
    assert (tmp_path / "seed0" / PLAIN_EPISODE_LOG).read_bytes() == original
    assert not (tmp_path / "seed0" / EPISODE_LOG).exists()


def test_compressing_finishes_a_killed_conversion_and_refuses_a_compressed_log_with_other_rows(tmp_path, capsys):
    for seed, rows in ((0, ROWS), (1, ROWS[:1])):
        write_plain(tmp_path / f"seed{seed}", ROWS)
        run_files.write_episode_log(tmp_path / f"seed{seed}", rows)
        write_plain(tmp_path / f"seed{seed}", ROWS)  # the writer removed it: put it back
    assert compress.main([str(tmp_path)]) == 1
    refusal = f"{tmp_path / 'seed1' / PLAIN_EPISODE_LOG}: {EPISODE_LOG} beside it holds other rows"
    assert refusal in capsys.readouterr().err
    assert not (tmp_path / "seed0" / PLAIN_EPISODE_LOG).exists()
    assert (tmp_path / "seed1" / PLAIN_EPISODE_LOG).exists()
    assert run_files.read_episode_log(tmp_path / "seed1" / EPISODE_LOG) == run_files.episode_log_text(ROWS[:1])


def test_compressing_a_directory_that_is_not_one_exits_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        compress.main([str(tmp_path / "missing")])
    assert exit_.value.code == 2
    assert "is not a directory" in capsys.readouterr().err


def weights(seed):
    rng = np.random.default_rng(seed)
    return {"steps": np.array([1000, 2000]), "states": rng.normal(size=(6, 4)),
            "probabilities": rng.dirichlet(np.ones(6), size=2)}


def test_npz_bytes_are_reproducible_compressed_and_load_to_the_same_arrays():
    arrays = weights(0)
    payload = npz_bytes(**arrays)
    assert payload == npz_bytes(**arrays)  # no timestamp: np.savez_compressed's bytes change by the second
    assert npz_bytes(**weights(1)) != payload
    loaded = read_npz(io.BytesIO(payload))
    assert run_files.same_arrays(loaded, arrays)
    assert not run_files.same_arrays(loaded, {**arrays, "steps": arrays["steps"].astype(np.int32)})
    repeated = {"steps": np.zeros(3000), "states": np.zeros((150, 4)), "probabilities": np.zeros((20, 150))}
    stored = io.BytesIO()
    np.savez(stored, **repeated)
    assert len(npz_bytes(**repeated)) < len(stored.getvalue()) / 20  # deflated, where np.savez stores
    with pytest.raises(ValueError, match="Object arrays cannot be saved"):
        npz_bytes(steps=np.array([object()]))


def test_compressing_rewrites_start_weights_once_to_the_trainers_bytes(tmp_path, capsys):
    runs = [tmp_path / "task" / "auxss-d500" / f"seed{seed}" for seed in (0, 1)]
    for seed, run in enumerate(runs):
        run.mkdir(parents=True)
        np.savez(run / START_WEIGHTS, **weights(seed))  # as the trainer wrote them before
    assert compress.main([str(tmp_path / "task")]) == 0
    assert "2 start weights" in capsys.readouterr().out
    for seed, run in enumerate(runs):
        assert (run / START_WEIGHTS).read_bytes() == npz_bytes(**weights(seed))
    before = {run: (run / START_WEIGHTS).stat().st_mtime_ns for run in runs}
    assert compress.main([str(tmp_path / "task")]) == 0  # again: nothing rewritten
    assert "0 start weights" in capsys.readouterr().out
    assert {run: (run / START_WEIGHTS).stat().st_mtime_ns for run in runs} == before


def test_the_trainer_writes_start_weights_in_the_converted_form(trained):
    run_dir, _ = trained(tiny_config("auxss"))
    written = (run_dir / START_WEIGHTS).read_bytes()
    assert written == npz_bytes(**read_npz(run_dir / START_WEIGHTS))


def test_compressing_refuses_damaged_or_unchecked_start_weights_and_leaves_them(tmp_path, monkeypatch, capsys):
    for seed in (0, 1):
        (tmp_path / f"seed{seed}").mkdir()
        np.savez(tmp_path / f"seed{seed}" / START_WEIGHTS, **weights(seed))
    damaged = tmp_path / "seed0" / START_WEIGHTS
    damaged.write_bytes(damaged.read_bytes()[:-40])  # cut short: the zip directory is gone
    originals = {seed: (tmp_path / f"seed{seed}" / START_WEIGHTS).read_bytes() for seed in (0, 1)}
    monkeypatch.setattr(compress, "npz_bytes", lambda **arrays: npz_bytes(**{**arrays, "steps": arrays["steps"][:1]}))
    assert compress.main([str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert f"{damaged} is damaged" in err
    assert f"{tmp_path / 'seed1' / START_WEIGHTS}: its compressed form does not hold the same arrays" in err
    assert {seed: (tmp_path / f"seed{seed}" / START_WEIGHTS).read_bytes() for seed in (0, 1)} == originals


def test_a_run_killed_with_a_plain_log_resumes_to_the_uninterrupted_compressed_log(trained, tmp_path):
    config = tiny_config("auxss")
    full_dir, _ = trained(config)
    interrupted_copy(full_dir, tmp_path / "resumed")
    resumed = tmp_path / "resumed"
    # the log as code before compression wrote it, with the rows up to the kill
    (resumed / PLAIN_EPISODE_LOG).write_bytes(run_files.read_episode_log(resumed / EPISODE_LOG))
    (resumed / EPISODE_LOG).unlink()
    train(config, resumed, resume=True, progress=False)
    assert (resumed / EPISODE_LOG).read_bytes() == (full_dir / EPISODE_LOG).read_bytes()
    assert not (resumed / PLAIN_EPISODE_LOG).exists()


def test_a_converted_runs_report_equals_its_report_before_conversion(tmp_path):
    # reverse_ss seeds whose curricula were not done: the report counts how their episodes ended from the log
    source = ROOT / "results/study/LavaBridge-v0/reverse_ss-d500"
    runs = tmp_path / "runs" / "reverse_ss-d500"
    for seed in (10, 11):
        shutil.copytree(source / f"seed{seed}", runs / f"seed{seed}")
        log = run_files.episode_log_file(runs / f"seed{seed}")
        data = run_files.read_episode_log(log)
        log.unlink()
        (runs / f"seed{seed}" / PLAIN_EPISODE_LOG).write_bytes(data)
        np.savez(runs / f"seed{seed}" / START_WEIGHTS, **read_npz(runs / f"seed{seed}" / START_WEIGHTS))  # as stored before

    def report(name):
        assert cli.main(["report", str(tmp_path / "runs"), "--seeds", "10-11", "--out", str(tmp_path / name)]) == 0
        return {f: (tmp_path / name / f).read_bytes() for f in ("report.md", "answers.json")
                if (tmp_path / name / f).exists()}

    before = report("plain")
    assert compress.main([str(tmp_path / "runs")]) == 0
    assert report("gzip") == before
    for seed in (10, 11):  # the log is read: without it the report says less
        (runs / f"seed{seed}" / EPISODE_LOG).unlink()
    assert report("none")["report.md"] != before["report.md"]


def run_with_log(run_dir, method, compressed):
    run_dir.mkdir(parents=True)
    if method is not None:
        (run_dir / "config.json").write_text(f'{{"method": "{method}"}}')
    if compressed:
        run_files.write_episode_log(run_dir, ROWS)
    else:
        write_plain(run_dir, ROWS)
    np.savez(run_dir / START_WEIGHTS, **weights(0))


def test_keep_logs_of_deletes_only_the_other_methods_logs(tmp_path, capsys):
    runs = {"auxss": (tmp_path / "auxss-d500" / "seed0", "auxss", True),
            "sac": (tmp_path / "sac-d500" / "seed0", "sac", False),
            "reverse": (tmp_path / "reverse_ss-d500" / "seed0", "reverse_ss", False),
            "unknown": (tmp_path / "loose" / "seed0", None, True)}
    for run_dir, method, compressed in runs.values():
        run_with_log(run_dir, method, compressed)
    assert compress.main([str(tmp_path), "--keep-logs-of", "reverse_ss,rfcl"]) == 1  # one run could not say
    out, err = capsys.readouterr()
    assert "deleted 2 episode logs" in out
    assert f"{runs['unknown'][0]}: no config.json naming its method; its episode log is kept" in err
    for name in ("auxss", "sac"):
        assert run_files.episode_log_file(runs[name][0]) is None
    assert run_files.read_episode_log(runs["reverse"][0] / EPISODE_LOG) == run_files.episode_log_text(ROWS)
    assert not (runs["reverse"][0] / PLAIN_EPISODE_LOG).exists()
    assert (runs["unknown"][0] / EPISODE_LOG).is_file()
    for run_dir, _, _ in runs.values():  # start weights are converted whatever the method
        assert (run_dir / START_WEIGHTS).read_bytes() == npz_bytes(**weights(0))


def test_keep_logs_of_refuses_a_method_it_does_not_know_and_deletes_nothing(tmp_path, capsys):
    run_with_log(tmp_path / "seed0", "auxss", True)
    with pytest.raises(SystemExit) as exit_:
        compress.main([str(tmp_path), "--keep-logs-of", "reverse-ss"])
    assert exit_.value.code == 2
    assert "unknown method(s) 'reverse-ss'; expected some of sac, auxss" in capsys.readouterr().err
    assert (tmp_path / "seed0" / EPISODE_LOG).is_file()


def test_the_study_keeps_the_logs_its_report_reads_and_the_report_is_the_same_without_the_others(tmp_path):
    from lava_bridge_mj.eval.analysis.report import LOG_READ_METHODS

    makefile = (ROOT / "Makefile").read_text()
    [kept] = re.findall(r"^STUDY_KEEP_LOGS := .* results/study --keep-logs-of (\S+)$", makefile, re.MULTILINE)
    assert kept.split(",") == list(LOG_READ_METHODS)
    source = ROOT / "results/study/LavaBridge-v0"
    runs = tmp_path / "runs"
    for method in ("auxss", "reverse_ss"):
        for seed in (10, 11):
            shutil.copytree(source / f"{method}-d500" / f"seed{seed}", runs / f"{method}-d500" / f"seed{seed}")
            # every run with a log, as the trainer leaves it
            reverse_log = run_files.episode_log_file(source / f"reverse_ss-d500/seed{seed}")
            shutil.copy(reverse_log, runs / f"{method}-d500" / f"seed{seed}" / EPISODE_LOG)

    def report(name):
        assert cli.main(["report", str(runs), "--seeds", "10-11", "--out", str(tmp_path / name)]) == 0
        return (tmp_path / name / "report.md").read_bytes()

    before = report("all_logs")
    assert compress.main([str(runs), "--keep-logs-of", kept]) == 0
    assert [run_files.episode_log_file(runs / "auxss-d500" / f"seed{seed}") for seed in (10, 11)] == [None, None]
    assert report("kept_logs") == before


def test_the_committed_results_are_stored_compressed_and_the_study_keeps_only_the_logs_its_report_reads():
    import zipfile

    from lava_bridge_mj.eval.analysis.report import LOG_READ_METHODS

    results = ROOT / "results"
    assert not sorted(results.rglob(PLAIN_EPISODE_LOG))
    weights = sorted(results.rglob(START_WEIGHTS))
    assert len(weights) > 1000
    for path in weights:  # the trainer's form (npz_bytes): deflated members with the fixed date
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
        assert members and all(m.compress_type == zipfile.ZIP_DEFLATED and m.date_time == run_files.NPZ_DATE
                               for m in members), path
    logs = sorted((results / "study").rglob(EPISODE_LOG))
    assert logs
    methods = {run_files.read_config(log.parent)["method"] for log in logs}
    assert methods == set(LOG_READ_METHODS)
