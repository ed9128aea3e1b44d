"""The study's report on an external task's runs (PointMaze_Medium-v3), alone and beside a Lava Bridge
task's: hand-built run directories as the trainer writes them (config.json and metrics.csv), under
OUT/TASK/ as a sweep puts them (OUT/TASK/METHOD-d500/seedN), read by `lava-bridge-bench report` as `make report`
reads results/study, and by the generated documentation tables (eval/analysis/doc_tables.py).

AuxSS succeeds from p0 and ood on every seed, every other group on none: Fisher's p for all against none of
10 seeds is 2 / C(20, 10) = 1.08e-05, which Holm's correction over a question's family (16 p-values for the
first question, 4 for the second) and the two-look level of 5 and 10 seeds leave a rejection: AuxSS ahead.
Omega-SS ties U-SS and GoalDist-SS (none solves): no test rejects."""

import json

import pytest
from conftest import write_metric_runs

pytest.importorskip("rliable", reason="the report needs the plots extra: pip install -e '.[plots]'")

from lava_bridge_mj.eval.analysis import doc_tables, report, summary  # noqa: E402

TASK = "PointMaze_Medium-v3"
LAVA_BRIDGE_TASK = "LavaBridgeNarrow-v0"
SOLVED = {seed: [0.0, 1.0] for seed in range(10)}
FAILED = {seed: [0.0, 0.0] for seed in range(10)}
STUDY = {"auxss": SOLVED, "uniform_ss": FAILED, "omega_ss": FAILED, "goaldist_ss": FAILED, "rfcl": FAILED,
         "sac": FAILED}
"""The external task's sweep: the study's start distributions, RFCL as published, SAC from p0."""
FIRST_QUESTION = {("auxss", "uniform_ss"), ("auxss", "goaldist_ss"), ("omega_ss", "uniform_ss"),
                  ("omega_ss", "goaldist_ss")}
ASPECTS = ["learns faster", "more robust"]


def write_sweep(root, task, groups):
    """ROOT/TASK/METHOD-d500/seedN for each method's seeds, as `lava-bridge-bench sweep --envs TASK` writes."""
    for method, p0_by_seed in groups.items():
        write_metric_runs(root / task, method, p0_by_seed, env_id=task)


def study_report(root, out, *options):
    """The report as `make report` writes docs/report_study (with 10 seeds read at looks of 5 and 10)."""
    assert report.main([str(root), "--seeds", "0-9", "--looks", "5,10", "--reps", "50", "--out", str(out),
                        *options]) == 0
    return (out / "report.md").read_text(), json.loads((out / "answers.json").read_text())


def check_external_answers(answers):
    """Both questions on the external task, each with its comparisons: AuxSS ahead wherever it plays."""
    assert [q["number"] for q in answers["questions"]] == [1, 2]
    by_question = {n: [(c["a"], c["b"], c["aspect"], c["verdict"])
                       for c in answers["comparisons"] if c["question"] == n] for n in (1, 2)}
    assert {(a, b) for a, b, _, _ in by_question[1]} == FIRST_QUESTION
    assert [aspect for *_, aspect, _ in by_question[1]] == ASPECTS * 4
    for a, b, aspect, verdict in by_question[1]:
        assert verdict == ("auxss ahead" if a == "auxss" else "undecided"), (a, b, aspect)
    # the task has rfcl runs: the second question reads AuxSS against RFCL as published
    assert by_question[2] == [("auxss", "rfcl", aspect, "auxss ahead") for aspect in ASPECTS]
    assert answers["looks"] == [5, 10]
    assert answers["seeds"] == {method: list(range(10)) for method in STUDY}


def test_the_study_report_answers_both_questions_on_an_external_task(tmp_path, capsys):
    write_sweep(tmp_path / "study", TASK, STUDY)
    text, record = study_report(tmp_path / "study", tmp_path / "report")
    assert list(record) == [TASK]
    check_external_answers(record[TASK])
    assert text.startswith(f"# {TASK} report")
    assert "### 1. Does a safety-derived start distribution" in text
    assert "| auxss against rfcl | learns faster |" in text and "| auxss against rfcl | more robust |" in text
    # no Lava Bridge maze to paint start weights on: said so, nothing drawn, no findings of LavaBridge-v0
    assert f"*Skipped: {TASK} is not a Lava Bridge maze" in text
    assert not list((tmp_path / "report").glob("*maze*")) and "The paper's findings" not in text
    # a seed extension of the external task can be read at its first seeds, as a Lava Bridge task's
    text, record = study_report(tmp_path / "study", tmp_path / "first_look", "--task-seeds", f"{TASK}=0-4")
    assert record[TASK]["seeds"]["auxss"] == [0, 1, 2, 3, 4]


def test_a_folder_of_a_lava_bridge_task_and_an_external_task_reports_both(tmp_path):
    write_sweep(tmp_path / "study", TASK, STUDY)
    # the Lava Bridge task: the reverse curriculum (no rfcl runs) ahead of AuxSS, the rest tied
    write_sweep(tmp_path / "study", LAVA_BRIDGE_TASK, {"auxss": FAILED, "uniform_ss": FAILED, "reverse_ss": SOLVED})
    text, record = study_report(tmp_path / "study", tmp_path / "report")
    assert list(record) == [LAVA_BRIDGE_TASK, TASK]  # the suite's tasks first
    check_external_answers(record[TASK])
    narrow = record[LAVA_BRIDGE_TASK]
    assert [(c["a"], c["b"], c["verdict"]) for c in narrow["comparisons"] if c["question"] == 2] == [
        ("auxss", "reverse_ss", "reverse_ss ahead")] * 2
    assert text.startswith(f"# Report on 2 tasks ({LAVA_BRIDGE_TASK}, {TASK})")
    overview = text.split("## The study's answers, task by task")[1].split(f"\n## {LAVA_BRIDGE_TASK}\n")[0]
    for task in (LAVA_BRIDGE_TASK, TASK):
        assert f"| {task} | 1. safety-derived against undirected |" in overview
        assert f"| {task} | 2. AuxSS against RFCL |" in overview
    # the maze figure for the Lava Bridge task only
    assert (tmp_path / "report" / f"{LAVA_BRIDGE_TASK}_maze.png").is_file()
    assert not (tmp_path / "report" / f"{TASK}_maze.png").exists()
    assert f"*Skipped: {TASK} is not a Lava Bridge maze" in text.split(f"\n## {TASK}\n")[1]
    # the second question names the method it was read against on each task
    questions = {task: next(q["text"] for q in record[task]["questions"] if q["number"] == 2) for task in record}
    assert questions == {LAVA_BRIDGE_TASK: "AuxSS or RFCL's reverse curriculum (reverse_ss)?",
                         TASK: "AuxSS or RFCL as published (rfcl: its reverse and forward curricula)?"}
    assert "### 2. AuxSS or RFCL as published (rfcl: its reverse and forward curricula)?" in text.split(f"\n## {TASK}\n")[1]
    # the README's and docs/results.md's tables from that answers.json: both tasks, RFCL's seeds beside reverse_ss's
    table = doc_tables.answer_table(record)
    assert [line.split(" | ")[0] for line in table[2:]] == [f"| {LAVA_BRIDGE_TASK}"] * 2 + [f"| {TASK}"] * 2
    assert f"| {TASK} | 2. AuxSS against RFCL | 2 auxss ahead | auxss ahead of rfcl: " \
           f"learns faster, more robust | - |" in table
    seeds = doc_tables.seeds_table(record)
    assert seeds[0] == "| task | auxss | uniform_ss | omega_ss | goaldist_ss | reverse_ss | rfcl |"
    assert seeds[2:] == [f"| {LAVA_BRIDGE_TASK} | 0-9 (10) | 0-9 (10) | - | - | 0-9 (10) | - |",
                         f"| {TASK} | 0-9 (10) | 0-9 (10) | 0-9 (10) | 0-9 (10) | - | 0-9 (10) |"]
    assert f"(report_study/report.md#{TASK.lower()})" in "\n".join(doc_tables.comparison_tables(record))


def test_the_start_room_measure_says_an_external_task_has_none(tmp_path):
    write_sweep(tmp_path, TASK, {"auxss": {0: [0.0, 1.0], 1: [0.0, 0.0]}})
    table = summary.markdown(tmp_path / TASK / "auxss-500-1", start_room_until=2000)
    rows = table.splitlines()
    assert rows[4].endswith("| no start room | no start room |")  # seed0, seed1, then the batch
    assert rows[5].endswith("| no start room | no start room |") and rows[6].startswith("| **all 2** |")
    assert rows[6].endswith("| no start room | no start room |")
    assert rows[-1] == (f"{TASK} is not a Lava Bridge maze: it has no start room, and seed0, seed1 have no "
                        "start-room measures.")
