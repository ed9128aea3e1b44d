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
        names |= set(re.findall(r"<!-- generated: ([a-z0-9-]+) -->", text))
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
            run = tmp_path / doc_tables.MAIN_BUDGET.folder / folder / f"seed{seed}"
            run.mkdir(parents=True)
            with (run / "metrics.csv").open("w", newline="") as f:
                writer = csv.writer(f)
                writer.writerow(["step", "success_p0"])
                writer.writerows([[10_000 * (i + 1), s] for i, s in enumerate(successes)])
    table = doc_tables.budget_table(doc_tables.budget_source(doc_tables.MAIN_BUDGET)(tmp_path))
    assert table == [
        "| | seed 0 | seed 1 | seed 2 |", "|---|---:|---:|---:|",
        "| AuxSS: first step at p0 success >= 0.8 | 50,000 | 70,000 | not by 80,000 |",
        "| SAC from p0: first step at p0 success >= 0.8 | not by 80,000 | not by 80,000 | not by 80,000 |",
        "", "| budget | AuxSS: seeds reached | SAC from p0: seeds reached | Fisher's exact p |", "|---:|---:|---:|---:|",
        "| 40,000 | 0 of 3 | 0 of 3 | 1 |", "| 50,000 | 1 of 3 | 0 of 3 | 1 |", "| 60,000 | 1 of 3 | 0 of 3 | 1 |",
        "| 70,000 | 2 of 3 | 0 of 3 | 0.4 |", "| 80,000 | 2 of 3 | 0 of 3 | 0.4 |"]


def test_the_main_budget_source_names_a_folder_without_runs(tmp_path):
    with pytest.raises(doc_tables.SourceError, match="auxss-d500 holds no runs"):
        doc_tables.budget_source(doc_tables.MAIN_BUDGET)(tmp_path)


def screening_runs(tmp_path, demo, sac, every=25_000):
    """A hand-built screening folder: per group, per seed, success from p0 at every `every` steps."""
    task = doc_tables.EXTERNAL_SCREENING / "Maze-v0"
    for folder, curves in (("auxss-d500", demo), ("sac-d500", sac)):
        for seed, successes in enumerate(curves, start=100):
            run = tmp_path / task / folder / f"seed{seed}"
            run.mkdir(parents=True)
            with (run / "metrics.csv").open("w", newline="") as f:
                writer = csv.writer(f)
                writer.writerow(["step", "success_p0"])
                writer.writerows([[every * (i + 1), s] for i, s in enumerate(successes)])
    return doc_tables.budget_source(doc_tables.BudgetRuns(task, doc_tables.SCREENING_BUDGETS))(tmp_path)


def test_the_screening_rule_picks_the_first_budget_where_the_demo_strategy_solves_and_sac_does_not(tmp_path):
    # AuxSS seeds first reach 0.8 at 50k, 50k, 75k, 100k and never; SAC's at 100k (two seeds) and never
    demo = [[0, .8, 1, 1], [0, .9, 1, 1], [0, .5, .8, 1], [0, 0, .1, .8], [0, 0, 0, 0]]
    sac = [[0, 0, 0, .9], [0, 0, .2, .85], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]]
    data = screening_runs(tmp_path, demo, sac)
    assert doc_tables.screening_budget(data) is None  # 4 of 5 AuxSS seeds by 100k, but 2 of 5 SAC seeds too
    assert doc_tables.screening_table(data)[-1] == (
        "By the screening rule, **no budget up to 100,000 steps**: this task does not separate a demo strategy "
        "from SAC from p0.")
    sac[1] = [0, 0, .2, .7]  # one SAC seed at 100k: the rule holds there
    assert doc_tables.screening_budget(screening_runs(tmp_path / "b", demo, sac)) == 100_000
    demo[3] = [0, .8, 1, 1]  # four AuxSS seeds by 75k
    table = doc_tables.screening_table(screening_runs(tmp_path / "c", demo, sac))
    assert table[-1] == "By the screening rule, the study's budget: **75,000 steps**."
    assert "| 75,000 | 4 of 5 | 0 of 5 | 0.0476 |" in table


def test_the_screening_rule_waits_for_every_seed_to_reach_a_budget(tmp_path):
    demo = [[0, .8, 1, 1]] * 5
    sac = [[0, 0, 0, 0]] * 4 + [[0, 0]]  # one SAC seed evaluated only to 50k
    data = screening_runs(tmp_path, demo, sac)
    assert doc_tables.screening_budget(data) == 50_000
    data = screening_runs(tmp_path / "b", [[0, .1, .8, 1]] * 5, sac)  # solved only at 75k: past the last SAC seed
    assert doc_tables.screening_budget(data) is None
    assert "no budget up to 50,000 steps" in doc_tables.screening_table(data)[-1]


def test_the_external_study_trains_each_screened_maze_at_the_budget_its_screening_picked():
    makefile = (ROOT / "Makefile").read_text()
    target = makefile[makefile.index("\nstudy-external:"):]
    target = target[:target.index("\n\n")]
    steps = {}
    for env, budget in re.findall(r"--envs (\S+) --steps (\d+)", target):
        steps.setdefault(env, set()).add(int(budget))
    assert set(steps) == set(doc_tables.SCREENED_TASKS)
    for task in doc_tables.SCREENED_TASKS:
        runs = doc_tables.BudgetRuns(doc_tables.EXTERNAL_SCREENING / task, doc_tables.SCREENING_BUDGETS)
        budget = doc_tables.screening_budget(doc_tables.budget_source(runs)(ROOT))
        assert steps[task] == {budget}, (task, steps[task], budget)


def difficulty_record(histogram, unsafe_x=(-1.714, 1.426)):
    """What `bench/difficulty.py --json` writes for LavaBridge-v0, with hand-picked figures."""
    return {"command": "python bench/difficulty.py --env LavaBridge-v0 --json d.json", "commit": "abc1234",
            "settings": {"random_episodes": 1000, "expert_episodes": 200, "rollouts": 64, "demos": 500,
                         "candidate_seeds": [0, 1]},
            "tasks": {"LavaBridge-v0": {
                "random": {"success": 0.0, "lava": 0.692, "truncated": 0.308, "mean_length": 313.6},
                "expert_p0": {"success": 1.0, "lava": 0.0, "truncated": 0.0, "mean_length": 170.2},
                "expert_ood": {"success": 0.995, "lava": 0.005, "truncated": 0.0, "mean_length": 162.5},
                "unsafe": 0.448,
                "demo_states": {"count": 500, "demos": 500, "on_bridge": 0.426, "unsafe_on_bridge": 0.97653,
                                "unsafe_off_bridge": 0.05575, "unsafe_x": list(unsafe_x) if unsafe_x else None,
                                "bridge_x": [-1.5, 1.5], "lava_probability_histogram": histogram},
                "omega_ratios": [2.0, 1.8]}}}


def test_lava_bridge_difficulty_gives_the_command_the_table_and_the_histogram(tmp_path):
    histogram = [[0, 0.01, 259], [0.01, 0.1, 17], [0.1, 0.2, 12], [0.2, 0.3, 122], [0.3, 0.5, 90], [0.5, 1, 0]]
    assert doc_tables.lava_bridge_difficulty(difficulty_record(histogram)) == [
        "`python bench/difficulty.py --env LavaBridge-v0 --json d.json` (1,000 random episodes, 200 expert episodes "
        "per start distribution, 64 random rollouts per demo state):", "",
        "| measure | value |", "|---|---|",
        "| uniformly random policy from p0: success | **0.00%** of 1,000 episodes |",
        "| uniformly random policy from p0: ends in lava / times out | 69.2% / 30.8% (mean length 314 steps) |",
        "| scripted expert from p0 / from ood: success | 100% / 100% of 200 episodes each (mean length 170 / 162 "
        "steps) |",
        "| demo states (500 set) on the bridge | 42.6% |",
        "| demo states whose 4-step random-action lava probability is >= 0.1 | 44.8% (97.7% of bridge states, 5.6% "
        "of the others; all at x in [-1.71, 1.43]) |", "",
        "Histogram of the 4-step random-action lava probability (1 - Omega) over the 500 demo states:",
        "259 in [0, 0.01), 17 in [0.01, 0.1), 12 in [0.1, 0.2), 122 in [0.2, 0.3), 90 in [0.3, 0.5), none above."]
    # a filled top bin is closed at 1 and nothing is "above" it; no unsafe state: no x range
    lines = doc_tables.lava_bridge_difficulty(difficulty_record([[0, 0.5, 0], [0.5, 1, 3]], unsafe_x=None))
    assert lines[-1] == "0 in [0, 0.5), 3 in [0.5, 1]."
    assert lines[8].endswith("(97.7% of bridge states, 5.6% of the others) |")
    (tmp_path / "results/suite").mkdir(parents=True)
    (tmp_path / doc_tables.LAVA_BRIDGE_DIFFICULTY).write_text(json.dumps({"tasks": {"LavaBridgeLong-v0": {}}}))
    with pytest.raises(doc_tables.SourceError, match="difficulty_LavaBridge-v0.json holds no figures of LavaBridge-v0"):
        doc_tables.lava_bridge_difficulty_source(tmp_path)


SINGLE_SEED = """$ python bench/single_seed_speed.py --steps 5000 --repeats 3
this tree: abc1234; ref: 5eff605
single-seed SAC from p0, 64x64, 5000 steps (1,000 warm-up), 1 torch thread, median of 3; load average before 5.28, after 5.42
   this tree:   110.7 steps/s   runs: 110.7, 102.7, 123.3
     5eff605:   134.0 steps/s   runs: 124.2, 155.7, 134.0
  ratio this tree / 5eff605: 0.83
"""


def test_the_single_seed_sentence_gives_each_report_of_the_file():
    assert doc_tables.single_seed_speed(SINGLE_SEED) == [
        "`python bench/single_seed_speed.py --steps 5000 --repeats 3` gave **0.83** (this tree 110.7 steps/s, "
        "5eff605 134.0; medians of 3 runs of 5,000 steps each, single runs 102.7-123.3 and 124.2-155.7 steps/s): "
        "this tree was slower."]
    again = (SINGLE_SEED.replace("--repeats 3", "--repeats 1").replace("median of 3", "median of 1")
             .replace("110.7, 102.7, 123.3", "140.0").replace("110.7 steps/s", "140.0 steps/s")
             .replace("124.2, 155.7, 134.0", "133.3").replace("134.0 steps/s", "133.3 steps/s")
             .replace("0.83", "1.05").replace("5000 steps", "3000 steps"))
    assert doc_tables.single_seed_speed(SINGLE_SEED + again)[0].endswith(
        "this tree was slower; `python bench/single_seed_speed.py --steps 5000 --repeats 1` gave **1.05** (this tree "
        "140.0 steps/s, 5eff605 133.3; medians of 1 runs of 3,000 steps each, single runs 140.0-140.0 and "
        "133.3-133.3 steps/s): this tree was not slower.")
    assert doc_tables.single_seed_speed(SINGLE_SEED + SINGLE_SEED.replace("0.83", "0.99"))[0].endswith(
        "this tree was slower; run again, it gave **0.99** (this tree 110.7 steps/s, 5eff605 134.0; medians of 3 runs "
        "of 5,000 steps each, single runs 102.7-123.3 and 124.2-155.7 steps/s): this tree was slower.")
    overlapping = SINGLE_SEED.replace("110.7, 102.7, 123.3", "110.7, 102.7, 124.2")  # one run ties the ref's slowest
    assert doc_tables.single_seed_speed(overlapping)[0].endswith(
        "single runs 102.7-124.2 and 124.2-155.7 steps/s): this tree's median was lower, within the overlap of the "
        "two trees' single runs.")
    with pytest.raises(doc_tables.SourceError, match="single_seed_speed.txt holds no report"):
        doc_tables.single_seed_speed("ratio this tree / 5eff605: 1.09\n")


TRACKING_COST = """$ python bench/tracking_cost.py --out results/bench/tracking_cost.txt
at commit abc1234, torch 2.13.0+cpu, 1 thread; auxss, 5 seed(s) batched, 5000 steps, one evaluation of 10 + 10 episodes; TensorBoard every 1000 steps; load average before 5.38
  repeat 1: without       80.00 s wall,   46.30 s CPU
  repeat 1: tensorboard  101.00 s wall,   53.10 s CPU
  repeat 2: tensorboard   90.00 s wall,   64.20 s CPU
  repeat 2: without       84.00 s wall,   45.70 s CPU
median wall time without sinks    82.00 s, with TensorBoard    95.50 s: ratio 1.1646
median CPU  time without sinks    46.00 s, with TensorBoard    58.65 s: ratio 1.2750
time in the logging calls              10.20 ms per write of 5 seed(s), 10 writes: 0.053% of the logged runs' wall time
the sink's whole work, replayed         3.10 ms CPU per write of 5 seed(s): 0.034% of the CPU time without sinks
load average after: 5.10
"""


def test_the_tracking_cost_sentences_give_the_direct_figures_then_the_side_by_side_ones():
    assert doc_tables.tracking_cost(TRACKING_COST) == [
        "`python bench/tracking_cost.py --out results/bench/tracking_cost.txt` (AuxSS, 5 seeds batched, 5,000 steps, "
        "2 runs each way with and without `--log tensorboard` writing every 1,000 steps, alternating) measured 10.20 ms "
        "in the loop's logging calls per write of the 5 seeds' scalars, **0.053%** of the logged runs' wall time, and "
        "the sink's whole work replayed alone (its writer thread's included) 3.10 ms of CPU per write, 0.034% of the "
        "runs' CPU time. The same run's side-by-side medians: wall 82 s without the sink and 96 s with it, CPU 46.0 s "
        "and 58.6 s (ratios 1.16 and 1.27); single runs ranged from 45.7 to 46.3 s of CPU without the sink and from "
        "53.1 to 64.2 s with it. `--log-every 100` writes 10 times as often, about 0.53% of the wall time here."]
    every_100 = TRACKING_COST.replace("TensorBoard every 1000 steps", "TensorBoard every 100 steps")
    assert doc_tables.tracking_cost(every_100)[0].endswith("s with it.")
    with pytest.raises(doc_tables.SourceError, match="tracking_cost.txt"):
        doc_tables.tracking_cost(TRACKING_COST.replace("time in the logging calls", "logging"))


def test_the_committed_lava_bridge_difficulty_adds_up():
    record = doc_tables.lava_bridge_difficulty_source(ROOT)
    task = record["tasks"]["LavaBridge-v0"]
    demo, random_policy = task["demo_states"], task["random"]
    histogram = demo["lava_probability_histogram"]
    assert sum(count for _, _, count in histogram) == demo["count"] == demo["demos"]
    assert [low for low, _, _ in histogram[1:]] == [high for _, high, _ in histogram[:-1]] and histogram[-1][1] == 1
    unsafe = sum(count for low, _, count in histogram if low >= 0.1)
    assert task["unsafe"] == pytest.approx(unsafe / demo["count"])
    every_end = random_policy["success"] + random_policy["lava"] + random_policy["truncated"]
    assert every_end == pytest.approx(1.0)  # an episode ends at the goal, in lava, or at the time limit
    assert record["command"].startswith("python bench/difficulty.py --env LavaBridge-v0")


def test_the_external_tasks_table_puts_each_policys_two_starts_on_one_row():
    text = ("| task | policy | start | episodes | success rate | mean episode length |\n|---|---|---|---|---|---|\n"
            "| Maze-v0 | expert | p0 | 100 | 1.00 | 451.4 |\n| Maze-v0 | expert | ood | 100 | 0.90 | 283.8 |\n"
            "| Maze-v0 | random | p0 | 100 | 0.00 | 800.0 |\n\n"
            "Maze-v0: 25,488 env steps/s of random actions through make_task_env's wrappers (20000 steps)\n"
            "Cube-v0: 858 env steps/s of random actions through make_task_env's wrappers (20000 steps)\n")
    assert doc_tables.external_tasks(text)[2:] == [
        "| Maze-v0 | expert | 1.00 | 451.4 | 0.90 | 283.8 |", "| Maze-v0 | random | 0.00 | 800.0 | - | - |", "",
        "Env steps/s of random actions through `make_task_env`'s wrappers: 25,488 on Maze-v0, 858 on Cube-v0."]


def test_the_external_throughput_table_prices_ten_seeds_at_300k_steps_per_task(tmp_path):
    bench = tmp_path / doc_tables.BENCH
    bench.mkdir(parents=True)
    table = "| hidden | trainer | seed-steps/s | x SB3 | x K=1 |\n|---|---|---|---|---|\n"
    (bench / "external_throughput_Cube-v0.txt").write_text(
        "# SAC throughput on Cube-v0: this package's trainer against SB3\n\n"
        "`python bench/external_throughput.py --env Cube-v0 --seeds 1 10`\n\n"
        "python 3.11 | 2 CPUs, load average 4.75 at the start\n\n" + table +
        "| 64 | SB3 SAC | 25 | 1.00 | |\n| 64 | ours K=10 | 125 | 5.00 | 4.84 |\n")
    (bench / "external_throughput.txt").write_text(
        "# SAC throughput on Maze-v0: this package's trainer against SB3\n\n`python bench/external_throughput.py`\n\n"
        + table + "| 64 | ours K=25 | 400 | 8.00 | 7.78 |\n")
    assert doc_tables.external_throughput(doc_tables.external_throughput_source(tmp_path))[2:] == [
        "| Maze-v0 | ours K=25 | 400 | 8.00 | 7.78 | 2.1 |",  # 3,000,000 / 400 / 3600 = 2.08 h
        "| Cube-v0 | SB3 SAC | 25 | 1.00 |  | 33.3 |", "| Cube-v0 | ours K=10 | 125 | 5.00 | 4.84 | 6.7 |", "",
        "Made by `python bench/external_throughput.py` (measured beside other processes; load not recorded); "
        "`python bench/external_throughput.py --env Cube-v0 --seeds 1 10` (one-minute load average 4.75 as it began)."]
    for stale in bench.iterdir():
        stale.unlink()
    with pytest.raises(doc_tables.SourceError, match="no results/bench/external_throughput"):
        doc_tables.external_throughput_source(tmp_path)


MEMORY = """# Peak memory of a tiny auxss run per task

$ python bench/memory.py --ref abc1234 --tasks Maze-v3
code: 0123456789abcdef; ref: abc1234ffff
machine: x86_64, 2 CPUs, python 3.11.7; one-minute load average 1.50 as it began
runs: --method auxss --steps 300 --eval-every 300 --threads 1, 50 eval episodes from p0 and ood

| task | K | eval sub-envs | peak RSS (MiB) | wall s | ref peak RSS (MiB) | ref wall s | metrics.csv |
|---|---:|---:|---:|---:|---:|---:|---|
| Maze-v3 | 10 | 50 | 1,110 | 190 | 6,320 | 246 | identical |
"""


def test_the_memory_table_joins_each_file_and_names_its_command_code_and_load(tmp_path):
    (tmp_path / doc_tables.BENCH).mkdir(parents=True)
    with pytest.raises(doc_tables.SourceError, match="run `python bench/memory.py`"):
        doc_tables.memory_source(tmp_path)
    alone = ("$ python bench/memory.py --tasks Cube-v0 --seeds 1\ncode: fedcba987 (with uncommitted changes)\n"
             "machine: x86_64; one-minute load average 7.82 as it began\n"
             "| task | K | eval sub-envs | peak RSS (MiB) | wall s |\n|---|---:|---:|---:|---:|\n| Cube-v0 | 1 | 50 | 8,796 | 213 |\n")
    (tmp_path / doc_tables.BENCH / "memory_cube.txt").write_text(alone)
    (tmp_path / doc_tables.BENCH / "memory.txt").write_text(MEMORY)
    lines = doc_tables.memory_table(doc_tables.memory_source(tmp_path))
    assert lines[2:4] == ["| Maze-v3 | 10 | 50 | 1,110 | 6,320 | identical |", "| Cube-v0 | 1 | 50 | 8,796 | - | - |"]
    assert lines[-1] == (
        "Made by `python bench/memory.py --ref abc1234 --tasks Maze-v3` (code 0123456 against abc1234; one-minute "
        "load average 1.50 as it began); `python bench/memory.py --tasks Cube-v0 --seeds 1` (code fedcba9 (with "
        "uncommitted changes); one-minute load average 7.82 as it began).")
    with pytest.raises(doc_tables.SourceError, match="memory.txt holds no line"):
        doc_tables.memory_table({"memory.txt": MEMORY.split("| task")[0]})
