"""The generated parts of the documentation (eval/analysis/doc_tables.py): each render function on hand-built inputs
against hand-written tables, the mechanism that rewrites a part between its markers, and the committed
documents equal to what the committed data gives."""

import csv
import json
import re
from pathlib import Path

import pytest

from lava_bridge_mj.eval.analysis import doc_tables

ROOT = Path(__file__).resolve().parent.parent


def test_every_generated_part_in_the_committed_documents_is_what_the_committed_data_gives():
    names = set()
    for document in doc_tables.DOCUMENTS:
        text = (ROOT / document).read_text()
        assert doc_tables.fill(text) == text, f"{document} is stale: run `python -m lava_bridge_mj.eval.analysis.doc_tables`"
        names |= set(re.findall(r"<!-- generated: ([a-z-]+) -->", text))
    assert names == set(doc_tables.PARTS), "every part is used in a document, and only known parts are"
    assert doc_tables.main(["--check"]) == 0


def test_fill_rewrites_a_hand_edit_inside_a_part_and_leaves_the_rest(tmp_path):
    (tmp_path / "results/bench").mkdir(parents=True)
    (tmp_path / "results/bench/threads_under_load.txt").write_text(
        "load average before: 2.91; 2 CPUs\nOMP_WAIT_POLICY          idle steps/s  loaded steps/s  loaded / idle\n"
        "PASSIVE (CLI default)            91.2            94.0           1.03\n\nlater runs\n"
        "PASSIVE (CLI default)            78.6            48.5           0.62\n")
    text = ("Before, typed.\n<!-- generated: speed-threads -->\n| stale |\n<!-- end: speed-threads -->\n"
            "After, typed: 1.03.\n")
    assert doc_tables.fill(text, tmp_path) == (
        "Before, typed.\n<!-- generated: speed-threads -->\n"
        "| OpenMP wait policy | idle: steps/s | beside a busy process: steps/s | busy / idle |\n|---|---:|---:|---:|\n"
        "| `PASSIVE` (what the CLI sets) | 91.2 | 94.0 | 1.03 |\n<!-- end: speed-threads -->\nAfter, typed: 1.03.\n")
    with pytest.raises(ValueError, match="unknown generated part 'speed-nothing'"):
        doc_tables.fill("<!-- generated: speed-nothing -->\n<!-- end: speed-nothing -->", tmp_path)


def test_the_check_exits_1_naming_a_stale_document_and_writes_nothing(tmp_path, monkeypatch, capsys):
    (tmp_path / "results/bench").mkdir(parents=True)
    (tmp_path / "results/bench/threads_under_load.txt").write_text(
        "PASSIVE (CLI default)            91.2            94.0           1.03\n")
    page = tmp_path / "page.md"
    page.write_text("<!-- generated: speed-threads -->\n| stale |\n<!-- end: speed-threads -->\n")
    monkeypatch.setattr(doc_tables, "ROOT", tmp_path)
    monkeypatch.setattr(doc_tables, "DOCUMENTS", (Path("page.md"),))
    assert doc_tables.main(["--check"]) == 1
    assert "page.md" in capsys.readouterr().err and "| stale |" in page.read_text()
    assert doc_tables.main([]) == 0 and "| 91.2 | 94.0 | 1.03 |" in page.read_text()
    assert doc_tables.main(["--check"]) == 0


def test_a_source_without_the_lines_a_table_needs_is_an_error_naming_the_file():
    with pytest.raises(doc_tables.SourceError, match="update_speed.txt"):
        doc_tables.update_speed_table("nothing timed here\n")


def test_the_study_answer_table():
    record = {"T-v0": {"questions": [{"number": 1, "short": "faster?", "summary": "2 undecided",
                                      "decided": ["a > b"], "seeds_to_decide": 30}]}}
    assert doc_tables.answer_table(record) == [
        "| task | question | verdicts | decided | seeds per group to decide the undecided |", "|---|---|---|---|---:|",
        "| T-v0 | 1. faster? | 2 undecided | a > b | 30 |"]


DIFFICULTY = """# Difficulty

| task | random | expert |
|---|---|---|
| `A-v0` | 0.00% | 100% |
| `B-v0` | 0.10% | 99% |

## SAC from p0

| task | seed 1 |
|---|---|
| `A-v0` | 0.00 / 0.00 |
"""


def write_run(run, seed, successes):
    run.mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"method": "sac", "seed": seed}))
    with (run / "metrics.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["step", "success_p0", "wall_time"])
        writer.writerows([[10_000 * (i + 1), s, 100.0 * (i + 1)] for i, s in enumerate(successes)])


def test_the_difficulty_table_is_the_difficulty_files_first_table_with_the_sac_runs_best_success(tmp_path):
    (tmp_path / "results/suite").mkdir(parents=True)
    (tmp_path / "results/suite/difficulty.md").write_text(DIFFICULTY)
    write_run(tmp_path / "results/suite/sac_p0/A-v0/sac-d500/seed5", 5, [0.0, 0.25, 0.5])
    write_run(tmp_path / "results/suite/sac_p0/A-v0/sac-d500/seed6", 6, [0.75, 0.0, 0.0])
    lines = doc_tables.difficulty_table(doc_tables.difficulty_source(tmp_path))
    assert lines == ["| task | random | expert | SAC from p0 at 30,000 steps: best success from p0 |",
                     "|---|---|---|---|",
                     "| `A-v0` | 0.00% | 100% | 0.75 (seeds 5-6) |",
                     "| `B-v0` | 0.10% | 99% | - |"]
    with pytest.raises(doc_tables.SourceError, match="no table"):
        doc_tables.read_difficulty("# Difficulty\n\nno table yet\n")


ENV_THROUGHPUT = """20000 env steps x 10 physics steps of 0.01 s, best of 5
loop                                env steps/s  us/env step  physics steps/s
(a) gymnasium.make(...).step             20,000         50.0          200,000
(d) mj_step(nstep=10)                    25,000         40.0          250,000

vector env                          env steps/s  us/env step    x (d)
(e) make_vec native, K=1                 10,000        100.0    0.400
(f) SyncVectorEnv, K=1                    9,000        111.1    0.360
(e) make_vec native, K=32                24,000         41.7    0.960
(f) SyncVectorEnv, K=32                  15,000         66.7    0.600

before / after the free-motion path (same actions, alternated; 86% of the K=25 sub-env steps took it)
loop                                checked steps/s  free-motion steps/s  after / before
env.unwrapped.step                           20,000               22,000            1.10
(d) mj_step(nstep=10), for scale             25,000
"""


def test_the_env_throughput_tables():
    assert doc_tables.env_loops_table(ENV_THROUGHPUT) == [
        "| loop | env steps/s | us per env step |", "|---|---:|---:|",
        '| (a) `gymnasium.make("LavaBridge-v0").step` | 20,000 | 50.0 |', "| (d) `mj_step(nstep=10)` | 25,000 | 40.0 |"]
    assert doc_tables.free_motion_table(ENV_THROUGHPUT)[2:] == [
        "| `env.unwrapped.step` | 20,000 | 22,000 | 1.10 |", "| raw `mj_step(nstep=10)`, for scale | 25,000 |  |  |"]
    assert doc_tables.vector_table(ENV_THROUGHPUT)[2:] == [
        "| raw `mj_step(nstep=10)`, one MjData | 25,000 | 1.00 |",
        '| `gymnasium.make_vec("LavaBridge-v0", num_envs=32)` (native `LavaBridgeVectorEnv`) | 24,000 | 0.96 |',
        "| `SyncVectorEnv` of 32 `gymnasium.make` envs | 15,000 | 0.60 |",
        "| native, K = 1 | 10,000 | 0.40 |"]


def test_the_protocol_table_bolds_the_fastest_layout():
    text = ("case                                   wall s    CPU s  seed-steps/s  x target  x first\n"
            "sweep (working tree)                   1000.0   1999.6           500      0.25     1.00\n"
            "train (working tree)                   2000.4   2100.0           250      0.12     0.50\n"
            "target: 2,000 seed-steps/s; load average after: 1.14 / 1.28\n")
    assert doc_tables.protocol_table(text)[1:] == [
        "|---|---:|---:|---:|---:|",
        f"| {doc_tables.PROTOCOL_LAYOUTS['sweep']} | 1,000 | 2,000 | **500** | 0.25 |",
        f"| {doc_tables.PROTOCOL_LAYOUTS['train']} | 2,000 | 2,100 | 250 | 0.12 |"]
    assert doc_tables.protocol_table(text)[0].endswith("| x the 2,000 target |")


PROFILE = """job: auxss, 4 seeds, 100 steps (updates from step 50: 51), one evaluation round of 5 p0 + 5 ood episodes per seed
wall time 100.0 s

part                                                                seconds   share
train: env step (vector env)                                            1.0    1.0%
train: episode resets                                                   0.5    0.5%
train: store transitions                                                0.5    0.5%
train: actor forward (acting)                                           2.0    2.0%
train: replay sampling                                                  3.0    3.0%
update: total                                                          40.0   40.0%
  update: TD target (actor + target critics, no grad)                  10.0   10.0%
  update: critics (forward, backward, Adam)                            12.0   12.0%
  update: actor (forward through critics, backward, Adam)              14.0   14.0%
  update: alpha (loss, backward, Adam)                                  2.5    2.5%
  update: Polyak step of target critics, statistics                     1.5    1.5%
  of which Adam steps (3 optimisers)                                    4.0    4.0%
eval: total                                                            50.0   50.0%
  eval: env step (single envs)                                         40.0   40.0%
  eval: env reset                                                       1.0    1.0%
  eval: actor forward                                                   5.0    5.0%
  eval: rest (loop, episode bookkeeping, metric and policy files)       4.0    4.0%
checkpoints                                                             1.5    1.5%
other (training loop, bookkeeping)                                      1.5    1.5%
"""


def test_the_profile_table_sums_the_parts_it_merges():
    assert doc_tables.profile_table(PROFILE)[2:] == [
        "| update (51 batched updates) | 40.0 | 40.0% |",
        "| - TD target (actor and target critics, no gradient) | 10.0 | 10.0% |",
        "| - critics (forward, backward, Adam) | 12.0 | 12.0% |",
        "| - actor (forward through the critics, backward, Adam) | 14.0 | 14.0% |",
        "| - entropy coefficient; Polyak step and statistics | 4.0 | 4.0% |",
        "| - (of these, the three Adam steps) | 4.0 | 4.0% |",
        "| training env steps (vector env, 400 sub-env steps) | 1.0 | 1.0% |",
        "| replay sampling (per-seed samples, stacked) | 3.0 | 3.0% |",
        "| actor forward for acting | 2.0 | 2.0% |",
        "| resets, storing transitions, checkpoints, loop | 4.0 | 4.0% |",
        "| evaluation round (4 seeds x 10 episodes) | 50.0 | 50.0% |",
        "| - single-env steps | 40.0 | 40.0% |",
        "| - actor forward (each seed's policy called on its own) | 5.0 | 5.0% |",
        "| - resets, bookkeeping, metric and policy files | 5.0 | 5.0% |"]
    with pytest.raises(doc_tables.SourceError, match="no part 'checkpoints'"):
        doc_tables.profile_table(PROFILE.replace("checkpoints   ", "saving   "))


EVAL_ROUND = """actors                              p0 / ood success  per seed: wall, CPU s  batched, checked: wall, CPU s  batched: wall, CPU s  ratio  ratio  results
untrained SAC actors (64x64)             0.00 / 0.00         60.0,    60.0     40.0,    40.0        30.0,    30.0      2.00     1.33  identical

## earlier, without the walls-only column
actors                              p0 / ood success  per seed: wall, CPU s  batched: wall, CPU s ratio wall ratio CPU  results
BC actors, 300 updates (64x64)           0.00 / 0.00         88.8,    10.8        22.7,     5.4       3.91      2.00  identical
"""


def test_the_evaluation_round_tables_read_each_run_of_the_file():
    assert doc_tables.walls_only_table(EVAL_ROUND)[2:] == [
        "| untrained SAC actors, 64x64 | 60.0 | 40.0 | 30.0 | 2.00 | 1.33 |"]
    assert doc_tables.eval_round_table(EVAL_ROUND)[2:] == [
        "| behaviour-cloned actors, 300 updates, 64x64 | 10.8 | 5.4 | 2.00 |"]


def test_the_update_speed_table_puts_the_reference_first():
    text = ("  K  this tree: ms   ref: ms  seed-updates/s  ref / this tree  weights\n"
            "  1           4.00      8.00             250             2.00  identical\n"
            " 25          40.00     50.00             625             1.25  differ\n")
    assert doc_tables.update_speed_table(text)[2:] == ["| 1 | 8.00 | 4.00 | 2.00 | identical |",
                                                       "| 25 | 50.00 | 40.00 | 1.25 | differ |"]


def test_the_sac_throughput_table_joins_the_one_and_two_thread_runs():
    one = (" hidden      trainer  seed-steps/s   x SB3   x K=1  of matmul\n"
           "     64      SB3 SAC           100    1.00               7.3%\n"
           "     64    ours K=25           400    4.00    3.22      26.9%\n")
    two = one.replace("100    1.00", "120    1.00").replace("400    4.00", "600    5.00")
    assert doc_tables.sac_throughput_table((one, two))[2:] == [
        "| Stable-Baselines3 SAC, one seed | 100 | 1.00 | 120 | 1.00 |",
        "| ours, K = 25 seeds in one process | 400 | 4.00 | **600** | **5.00** |"]


def test_the_sweep_scaling_table_has_a_column_per_run():
    run = ("case                             wall s   jobs s  x 1 worker  load avg 1/5 min before\n"
           "local, 1 worker                    40.0     40.0       1.00x  4.07 / 3.35\n"
           "Ray, local cluster of 2 CPUs       {wall}     {jobs}       {ratio}x  4.41 / 3.60\n")
    text = ("# run 1 (11:51)\n" + run.format(wall="30.0", jobs="25.0", ratio="1.33")
            + "# run 2 (11:54)\n" + run.format(wall="50.0", jobs="45.5", ratio="0.80"))
    assert doc_tables.sweep_scaling_table(text) == [
        "| backend | wall time, run 1 / run 2 | x 1 worker |", "|---|---:|---:|",
        "| local, 1 worker | 40.0 s / 40.0 s | 1.00 / 1.00 |",
        "| Ray, local cluster of 2 CPUs | 30.0 s / 50.0 s (jobs alone 25.0 s / 45.5 s) | 1.33 / 0.80 |"]


def session(commit, dirty, started, platform="Linux-x"):
    return {"started": started, "code": {"git": {"commit": commit, "dirty": dirty}, "platform": platform}}


def test_the_results_index_groups_runs_by_folder_with_their_provenance(tmp_path):
    results = tmp_path / "results"
    for seed in (0, 1, 3):
        write_run(results / "study/Task-v0/auxss-d500" / f"seed{seed}", seed, [0.0, 1.0])
    (results / "study/Task-v0/auxss-d500/seed0/provenance.json").write_text(json.dumps(
        [session("b" * 40, False, "2026-01-02T00:00:00Z"),
         session("a" * 40, True, "2026-01-03T00:00:00Z", "Linux-y")]))
    (results / "study/Task-v0/auxss-d500/seed1/provenance.json").write_text(json.dumps(
        [session("a" * 40, True, "2026-01-01T00:00:00Z")]))
    write_run(results / "old_run", 7, [0.5])  # a run directly under results/ with no provenance
    runs = doc_tables.read_runs(results)
    assert [(r.folder, r.seed) for r in runs] == [("old_run", 7), ("study/Task-v0", 0), ("study/Task-v0", 1),
                                                  ("study/Task-v0", 3)]
    assert doc_tables.results_index((runs, {"old_run": "abc1234"}))[2:] == [
        "| `old_run/` | sac | 7 | 1 | 1 run without provenance.json, noted as abc1234 | - | 0.0 h |",
        "| `study/Task-v0/` | sac | 0-1,3 | 3 | aaaaaaa+, bbbbbbb, 1 run without provenance.json | Linux-x; Linux-y "
        "| 0.2 h |"]


def test_every_folder_the_code_notes_name_holds_runs_without_provenance():
    runs, noted = doc_tables.results_source(ROOT)
    unrecorded = {run.folder for run in runs if not run.sessions}
    assert noted and set(noted) <= unrecorded, sorted(set(noted) - unrecorded)


def test_the_network_size_table_counts_seeds_reaching_the_threshold_within_the_shortest_budget():
    groups = [(64, {1: [(10_000, 0.0), (20_000, 0.0), (30_000, 0.9)], 2: [(10_000, 0.8), (20_000, 0.1), (30_000, 0.0)]}),
              (256, {1: [(10_000, 0.0), (20_000, 0.5)], 2: [(10_000, 0.0), (20_000, 0.0)]})]
    assert doc_tables.netsize_table(groups) == [
        "| hidden units | seed 1 | seed 2 | reached by 20k |", "|---:|---:|---:|---:|",
        "| 64 | 30k | 10k | 1 of 2 |",
        "| 256 | not by 20k (0.50) | not by 20k | 0 of 2 |"]


def test_the_main_budget_table_counts_seeds_reaching_08_by_each_budget(tmp_path):
    # AuxSS seeds first reach 0.8 at 50k, 70k and never (its best 0.78); SAC never
    auxss = [0.0] * 4 + [0.8, 0.9, 1.0, 1.0]
    later = [0.0] * 6 + [0.85, 0.9]
    never = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.78]
    for folder, curves in (("auxss-d500", (auxss, later, never)), ("sac-d500", ([0.0] * 8,) * 3)):
        for seed, successes in enumerate(curves):
            run = tmp_path / doc_tables.MAIN_BUDGET / folder / f"seed{seed}"
            run.mkdir(parents=True)
            with (run / "metrics.csv").open("w", newline="") as f:
                writer = csv.writer(f)
                writer.writerow(["step", "success_p0"])
                writer.writerows([[10_000 * (i + 1), s] for i, s in enumerate(successes)])
    table = doc_tables.main_budget_table(doc_tables.main_budget_source(tmp_path))
    assert table == [
        "| | seed 0 | seed 1 | seed 2 |", "|---|---:|---:|---:|",
        "| AuxSS: first step at p0 success >= 0.8 | 50,000 | 70,000 | not by 80,000 |",
        "| SAC from p0: first step at p0 success >= 0.8 | not by 80,000 | not by 80,000 | not by 80,000 |",
        "", "| budget | AuxSS: seeds reached | SAC from p0: seeds reached | Fisher's exact p |", "|---:|---:|---:|---:|",
        "| 40,000 | 0 of 3 | 0 of 3 | 1 |", "| 50,000 | 1 of 3 | 0 of 3 | 1 |", "| 60,000 | 1 of 3 | 0 of 3 | 1 |",
        "| 70,000 | 2 of 3 | 0 of 3 | 0.4 |", "| 80,000 | 2 of 3 | 0 of 3 | 0.4 |"]


def test_the_main_budget_source_names_a_folder_without_runs(tmp_path):
    with pytest.raises(ValueError, match="auxss-d500 holds no runs"):
        doc_tables.main_budget_source(tmp_path)
