"""The committed reports (docs/report*/report.md, which docs/results.md and the README quote) are what
`make report` makes from the committed metrics in results/: a changed metric, a changed aggregate or
a hand-edited table fails here. The commands are read from the Makefile, the one place they live."""

import importlib.util
import json
import re
import shlex
from pathlib import Path

import pytest

import lava_bridge_mj
from conftest import held_back_tasks, makefile_commands, makefile_sweeps, study_report_command

pytest.importorskip("rliable", reason="the report needs the plots extra: pip install -e '.[plots]'")

from lava_bridge_mj.eval.analysis import doc_tables, report  # noqa: E402
from lava_bridge_mj.eval.analysis import statistics as stats  # noqa: E402
from lava_bridge_mj.eval.analysis.claims import NO_DIFFERENCE, UNDECIDED  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


COMMANDS = makefile_commands("report", "report")
"""The argument lists of the `lava-bridge-bench report` lines of the Makefile's report target."""
STUDY_REPORT = study_report_command()
"""The study report's argument list."""


def test_the_report_target_makes_every_committed_report():
    assert [argv[argv.index("--out") + 1] for argv in COMMANDS] == [
        "docs/report", "docs/report_300k", "docs/report_ablations", "docs/report_calibration",
        "docs/report_calibration_confirm", "docs/report_screening", "docs/report_screening_300k", "docs/report_study",
        "docs/report_reverse_limit", "docs/report_rfcl_limit"]


def test_results_md_names_each_report_by_the_command_that_makes_it():
    # the table of reports atop docs/results.md: each command it spells out is the Makefile's, flag for flag,
    # and every report the Makefile makes has a row
    table = (ROOT / "docs/results.md").read_text().split("## How a verdict is read")[0]
    rows = re.findall(r"^\| \[docs/(report\w*)/report\.md\].*\| (`lava-bridge-bench report [^`]+`|see the Makefile) \|$",
                      table, re.MULTILINE)
    named = {f"docs/{name}" for name in re.findall(r"\[docs/(report\w*)/report\.md\]", table)}
    made = {argv[argv.index("--out") + 1]: argv for argv in COMMANDS}
    assert named == set(made)
    spelled = [(f"docs/{name}", command) for name, command in rows if command != "see the Makefile"]
    assert len(spelled) >= 4
    for out, command in spelled:
        assert shlex.split(command.strip("`"))[2:] == made[out], f"docs/results.md's command for {out} is not the Makefile's"


@pytest.mark.parametrize("argv", COMMANDS, ids=[argv[argv.index("--out") + 1] for argv in COMMANDS])
def test_committed_report_is_regenerated_exactly_from_results(argv, tmp_path, monkeypatch):
    committed = ROOT / argv[argv.index("--out") + 1] / "report.md"
    argv = list(argv)
    argv[argv.index("--out") + 1] = str(tmp_path)
    monkeypatch.chdir(ROOT)  # the report names its directories as given, relative to the repository

    def drawn(*args):
        raise AssertionError("a committed verdict rests on a p-value drawn at random: it must be exact")

    monkeypatch.setattr(stats, "_monte_carlo_sum_p", drawn)  # so no reseeding can change a verdict
    assert report.main(argv) == 0
    for name in ("report.md", "answers.json"):
        if (tmp_path / name).exists():
            assert (tmp_path / name).read_text() == (committed.parent / name).read_text(), \
                f"{committed.parent / name} is stale: run `make report` and commit what it writes"
    # a figure the report no longer writes (a renamed or dropped plot) must not linger beside it
    written = sorted(path.name for path in tmp_path.iterdir())
    kept = sorted(path.name for path in committed.parent.iterdir())
    assert kept == written, (f"{committed.parent} holds {sorted(set(kept) - set(written))} that the report no longer "
                             f"writes and lacks {sorted(set(written) - set(kept))}: git rm the first, run `make report`")


def test_the_difficulty_tables_sac_section_is_what_the_committed_sac_runs_give(monkeypatch):
    # bench/difficulty.py's full run takes a quarter of an hour; its SAC section only reads runs
    spec = importlib.util.spec_from_file_location("difficulty", ROOT / "bench" / "difficulty.py")
    difficulty = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(difficulty)
    committed = (ROOT / "results/suite/difficulty.md").read_text()
    monkeypatch.chdir(ROOT)  # the section names its directory as given, relative to the repository
    assert committed[committed.index("## SAC from p0"):] == difficulty.sac_from_p0(Path("results/suite/sac_p0"))


def findings_verdicts(text, pattern):
    """Finding number -> verdict, read from `text` by `pattern` (two groups: number, verdict)."""
    return {int(n): verdict.strip() for n, verdict in re.findall(pattern, text, re.MULTILINE)}


REPORT_ROW = r"^\| (\d) \| [^|]+ \| \*\*([^*]+)\*\* \|$"


def test_results_md_and_the_readme_state_the_verdicts_the_committed_reports_give():
    # findings 1-7 stand on docs/report (every method at 100k), finding 8 on docs/report_ablations;
    # test_committed_report_is_regenerated_exactly_from_results ties those to the data
    main = findings_verdicts((ROOT / "docs/report/report.md").read_text(), REPORT_ROW)
    ablations = findings_verdicts((ROOT / "docs/report_ablations/report.md").read_text(), REPORT_ROW)
    expected = {n: main[n] for n in range(1, 8)} | {8: ablations[8]}
    results = (ROOT / "docs/results.md").read_text()
    assert findings_verdicts(results, r"^\| (\d) \| [^|]+ \| \*\*([^*]+)\*\*") == expected, "docs/results.md table"
    assert findings_verdicts(results, r"^### (\d)\. .*: \*\*([^*]+)\*\*") == expected, "docs/results.md headings"
    findings = (ROOT / "docs/findings.md").read_text()
    verdicts = "|".join(map(re.escape, set(expected.values())))
    assert findings_verdicts(findings, rf"^\| (\d) \| [^|]+ \| ({verdicts})\b") == expected, "docs/findings.md table"


RETIRED_VERDICTS = ("not enough seeds to decide", "not enough seeds;", "*not enough seeds")
"""What *undecided* was called before negatives needed an equivalence test; results/CHANGELOG.md, the
record of the change, is the one text that still names it."""


def test_the_docs_name_no_verdict_outside_the_stated_vocabulary():
    texts = [ROOT / "README.md", ROOT / "results/README.md", *sorted((ROOT / "docs").rglob("*.md")),
             *sorted((ROOT / "eval").rglob("*.py"))]
    flat = {path.relative_to(ROOT).as_posix(): " ".join(path.read_text().split()) for path in texts}
    assert [(path, name) for path, text in flat.items() for name in RETIRED_VERDICTS if name in text] == []
    assert f"| **{UNDECIDED}** |" in flat["docs/results.md"] and f"| **{NO_DIFFERENCE}** |" in flat["docs/results.md"]


# one comparison of the study's questions: the pair, the aspect, the effect with its interval ("-" where the
# pair was not run) and the verdict
STUDY_ROW = (r"^\| (\w+ against \w+) \| (learns faster|more robust) \| "
             r".*?([+-]\d\.\d\d \[[+-]\d\.\d\d, [+-]\d\.\d\d\]|-) \|.* \*\*([^*]+)\*\* \|$")


def section(text, heading):
    """The part of markdown `text` from the line `heading` to the next heading of the same level or higher."""
    body = text.index(f"\n{heading}\n") + len(heading) + 2
    level = heading.split(" ", 1)[0]
    end = re.search(rf"^#{{1,{len(level)}}} ", text[body:], re.MULTILINE)
    return text[body:body + end.start()] if end else text[body:]


def task_sections(text, level):
    """Task id -> the part of `text` under its heading at `level` ("##" or "###")."""
    parts = re.split(rf"^{level} (LavaBridge\w*-v0)\n", text, flags=re.MULTILINE)
    return dict(zip(parts[1::2], parts[2::2]))


def report_parts(report_text):
    """Task id -> its part of a report: the whole report on one task, a task's section of one on several."""
    one_task = re.match(r"# (LavaBridge\w*-v0) report", report_text)
    return {one_task[1]: report_text} if one_task else task_sections(report_text, "##")


def study_rows(report_text):
    """Task id -> the comparison rows of its section "The study's questions" in a report."""
    return {task: re.findall(STUDY_ROW, text[text.index("# The study's questions"):], re.MULTILINE)
            for task, text in report_parts(report_text).items() if "# The study's questions" in text}


def test_results_md_quotes_the_study_question_on_lavabridge_v0_as_the_report_gives_it():
    report_rows = study_rows((ROOT / "docs/report/report.md").read_text())["LavaBridge-v0"]
    results = (ROOT / "docs/results.md").read_text()
    quoted = section(results, "## The study's first question on LavaBridge-v0: do safety-derived starts beat "
                              "undirected ones?")
    assert len(report_rows) == 8 and re.findall(STUDY_ROW, quoted, re.MULTILINE) == report_rows
    # docs/findings.md's summary quotes the one interval that leaves little room on one side
    [quoted] = [effect for pair, aspect, effect, _ in report_rows
                if (pair, aspect) == ("auxss against goaldist_ss", "learns faster")]
    assert quoted in (ROOT / "docs/findings.md").read_text()


def test_the_readme_and_results_md_hold_the_study_parts_generated_from_the_study_report():
    # every sentence and table that summarises the study's verdicts is generated from answers.json, which
    # test_committed_report_is_regenerated_exactly_from_results ties to the runs in results/study (that the parts
    # equal what answers.json gives is tests/test_doc_tables.py's)
    record = json.loads((ROOT / doc_tables.ANSWERS).read_text())
    studied = {task.name for task in (ROOT / "results/study").iterdir() if task.is_dir()}
    assert set(record) == studied >= set(lava_bridge_mj.SUITE)  # every task with study runs, the suite's at least
    readme, results = ((ROOT / document).read_text() for document in ("README.md", "docs/results.md"))
    for name in ("study-answers", "study-in-words"):
        assert f"<!-- generated: {name} -->" in readme
    for name in (name for name in doc_tables.PARTS if name.startswith("study-")):
        assert f"<!-- generated: {name} -->" in results


def test_every_no_difference_found_shows_equivalence_inside_the_margin_and_every_undecided_its_seeds():
    record = json.loads((ROOT / doc_tables.ANSWERS).read_text())
    interval = re.compile(r"[+-]\d\.\d\d \[([+-]\d\.\d\d), ([+-]\d\.\d\d)\]")
    for task, answers in record.items():
        for c in answers["comparisons"]:
            if c["verdict"] == NO_DIFFERENCE:
                bounds = [(float(low), float(high)) for low, high in interval.findall(c["equivalence"])]
                assert len(bounds) == 2 and all(-0.3 <= low and high <= 0.3 for low, high in bounds), (task, c)
            elif c["verdict"] == UNDECIDED:
                assert "power needs" in c["seeds_to_decide"], (task, c)


def assert_quoted_from(prose, report_text, where):
    """Every count (18/20) and decimal (0.0136) in `prose` is in `report_text`."""
    for number in re.findall(r"\d+/\d+|\d\.\d+", prose):
        assert number in report_text, f"{where} quotes {number}; the report does not"


def study_seed_range():
    """The first and last evaluation seed of `make study`."""
    first, last = makefile_sweeps("study")[0]["--seeds"].split("-")
    return int(first), int(last)


EXTENSIONS = ("study-extension", "study-external-extension")
"""The seed extensions of `make study` (the suite) and of `make study-external` (the external tasks)."""


def extension_sweeps():
    """The sweep lines of both seed extensions."""
    return [sweep for target in EXTENSIONS for sweep in makefile_sweeps(target)]


def extension_groups():
    """(task, method) of each group the two seed extensions train, once per sweep line that names it."""
    return [(task, method) for sweep in extension_sweeps() for task in sweep["--envs"].split(",")
            for method in sweep["--methods"].split(",")]


def study_budgets():
    """Task -> the --steps `make study` or `make study-external` trains it to."""
    return {task: sweep["--steps"] for target in ("study", "study-external") for sweep in makefile_sweeps(target)
            for task in sweep["--envs"].split(",")}


def study_looks():
    """The seeds per group of the study's two looks, as the study report's --looks gives them."""
    first, second = map(int, STUDY_REPORT[STUDY_REPORT.index("--looks") + 1].split(","))
    return first, second


RFCL_METHODS = ("rfcl", "rfcl_reverse")
"""The methods of `make study-rfcl`, which trained after the study's extension was decided."""


def first_look(without=()):
    """(task, question) -> its answers at the study's first look: results/study read at the study's seeds,
    every verdict checked at the two-look level of the study report's --looks; `without`: methods left out."""
    from lava_bridge_mj.eval.analysis.aggregate import find_runs, group_runs
    from lava_bridge_mj.eval.analysis.study import answer_questions

    first, last = study_seed_range()
    groups = [g for g in group_runs(find_runs(ROOT / "results/study", seeds=range(first, last + 1)))
              if g.method not in without]
    return {(task, question.short): question.answers for task in {g.task for g in groups}
            for question in answer_questions([g for g in groups if g.task == task], study_looks())}


def group_holds(task, method, seeds):
    """Whether results/study holds a run of `method` on `task` at every one of `seeds`."""
    return all((ROOT / "results/study" / task / f"{method}-d500" / f"seed{seed}" / "metrics.csv").is_file()
               for seed in seeds)


def external_tasks_at_their_first_look():
    """The external tasks every start group of whose `make study-external` sweep (both questions' groups, which
    train together) is in results/study at the study's seeds: a maze's extension is decided on all of them,
    so a maze whose groups are still landing one by one is not read for it yet."""
    first, last = study_seed_range()
    starts = [sweep for sweep in makefile_sweeps("study-external") if "auxss" in sweep["--methods"].split(",")]
    return {task for sweep in starts for task in sweep["--envs"].split(",")
            if all(group_holds(task, method, range(first, last + 1)) for method in sweep["--methods"].split(","))}


def test_the_seed_extension_trains_exactly_the_groups_the_first_look_leaves_undecided():
    # at the first look (the study's 20 seeds): every group of a comparison still open (undecided, or decided at
    # 0.05 but not at the two-look level), on its task at the study's budget, from the seed after the study's last
    # to the second look; groups whose every comparison is decided (or that no question compares) stay at the
    # study's seeds. (The second look's 49 seeds were what Fisher's power alone asked for; the equivalence
    # rule asks more of an undecided comparison, and the answer table says how many seeds each would need.)
    # The suite's extension was decided on the study's own groups, before RFCL as published had runs; the
    # external tasks' extension on all of their groups, rfcl among them, once every one of a maze's groups is in.
    first_look_seeds, second_look = study_looks()
    external = external_tasks_at_their_first_look()
    answers = {**{key: found for key, found in first_look(without=RFCL_METHODS).items()
                  if key[0] in lava_bridge_mj.SUITE},
               **{key: found for key, found in first_look().items() if key[0] in external}}
    still_open = [(task, answer) for (task, _), found in answers.items() for answer in found
                  if answer.verdict == UNDECIDED or answer.at_one_look_only]
    open_groups = {(task, method) for task, answer in still_open for method in (answer.a, answer.b)}
    study_steps = study_budgets()
    cells = extension_groups()
    assert len(cells) == len(set(cells)) and set(cells) == open_groups
    study_first, study_last = study_seed_range()
    options = {key: value for key, value in makefile_sweeps("study")[0].items()
               if key not in ("--methods", "--envs", "--steps", "--out", "--seeds")}
    assert first_look_seeds == study_last - study_first + 1 < second_look
    for sweep in extension_sweeps():
        assert sweep["--seeds"] == f"{study_last + 1}-{study_first + second_look - 1}"
        assert all(sweep["--steps"] == study_steps[task] for task in sweep["--envs"].split(","))
        assert {key: value for key, value in sweep.items() if key in options} == options


def test_rfcl_extension_trains_rfcl_where_the_second_question_against_it_is_open_at_the_first_look():
    # the same rule for the comparisons against rfcl, on the suite's tasks whose rfcl runs are in results/study:
    # rfcl trains the second look's seeds where AuxSS against it is undecided or decided at 0.05 only (the
    # external tasks trained rfcl with their other groups, so their own extension covers it)
    _, second_look = study_looks()
    study_first, study_last = study_seed_range()
    answers = {key: found for key, found in first_look().items() if key[0] in lava_bridge_mj.SUITE}
    with_rfcl = {task for (task, _), found in answers.items() for answer in found if answer.b == "rfcl"}
    open_rfcl = {(task, "rfcl") for (task, _), found in answers.items() for answer in found
                 if answer.b == "rfcl" and (answer.verdict == UNDECIDED or answer.at_one_look_only)}
    extended = set(extension_groups())
    assert with_rfcl and all((task, "auxss") in extended for task in with_rfcl)  # AuxSS has the seeds already
    sweeps = makefile_sweeps("study-rfcl-extension")
    cells = [(task, method) for sweep in sweeps for task in sweep["--envs"].split(",")
             for method in sweep["--methods"].split(",")]
    assert len(cells) == len(set(cells)) and set(cells) == open_rfcl
    options = {key: value for key, value in makefile_sweeps("study-extension")[0].items()
               if key not in ("--methods", "--envs", "--steps", "--out")}
    study_steps = study_budgets()
    for sweep in sweeps:
        assert {key: value for key, value in sweep.items() if key in options} == options
        assert sweep["--seeds"] == f"{study_last + 1}-{study_first + second_look - 1}"
        assert all(sweep["--steps"] == study_steps[task] for task in sweep["--envs"].split(","))


def test_every_group_of_the_study_holds_the_seeds_of_one_look():
    # a comparison reads the seeds both of its groups have, so a group between two looks (an extension
    # exported in part) would be read at a look the two-look level does not cover
    study_first, _ = study_seed_range()
    looks = study_looks()
    for group in sorted(ROOT.glob("results/study/*/*-d500")):
        seeds = sorted(int(run.name[4:]) for run in group.glob("seed*") if (run / "metrics.csv").is_file())
        assert seeds in [list(range(study_first, study_first + look)) for look in looks], group


def test_the_study_report_reads_a_tasks_extension_once_every_group_of_it_has_all_its_seeds():
    # the study report reads the study's and the extension's seeds; a task named in --task-seeds stays at the
    # study's seeds, and it is named exactly when some group the extension trains on it lacks a seed in results/study
    study_first, study_last = study_seed_range()
    _, second_look = study_looks()
    assert STUDY_REPORT[STUDY_REPORT.index("--seeds") + 1] == f"{study_first}-{study_first + second_look - 1}"
    held_back = held_back_tasks()
    assert set(held_back.values()) <= {f"{study_first}-{study_last}"}
    incomplete = {task for task, method in extension_groups()
                  if not group_holds(task, method, range(study_first, study_first + second_look))}
    assert set(held_back) == incomplete


def test_every_folder_of_results_is_described_in_its_readme():
    # results/README.md says how each folder's runs were made and by which commit; a folder it does not
    # name would be metrics without a command
    first_column = re.findall(r"^\| ([^|]+) \|", (ROOT / "results/README.md").read_text(), re.MULTILINE)
    described = {name.split("/")[0] for cell in first_column for name in re.findall(r"`([\w/.-]+)/`", cell)}
    assert {path.name for path in (ROOT / "results").iterdir() if path.is_dir()} <= described


def test_results_md_on_the_reverse_curriculums_time_limit_quotes_its_report():
    # every count and decimal of the section, table included, is in docs/report_reverse_limit, whose three
    # groups it describes
    report = (ROOT / "docs/report_reverse_limit/report.md").read_text()
    quoted = section((ROOT / "docs/results.md").read_text(),
                     "## The reverse curriculum without its shortened time limit, on the far start")
    assert_quoted_from(quoted, report, "docs/results.md on the reverse curriculum's time limit")


def reverse_stage_handover(steps, probabilities, demo_count):
    """The first evaluation step of an rfcl run whose start weights hold no demo state (the first
    `demo_count` candidates): where its reverse stage handed over to the forward stage; None if it never did."""
    import numpy as np

    off_demos = probabilities[:, :demo_count].sum(axis=1) == 0
    return int(steps[np.argmax(off_demos)]) if off_demos.any() else None


def test_results_md_on_where_rfcl_stalls_on_the_medium_maze_reads_its_start_weights():
    # the section's account of the stall is read from the study's committed rfcl runs on the maze: from which
    # evaluation every seed's starts stop moving, which demo states they are, how many expert steps those are
    # before the goal and the time limit RFCL gives an episode from them
    import numpy as np

    from lava_bridge_mj.agents.rfcl import RFCLReverseSS
    from lava_bridge_mj.agents.reverse_curriculum import goal_reaching_demos
    from lava_bridge_mj.eval.analysis.summary import read_start_weights

    task = "PointMaze_Medium-v3"
    demo_states, ids = goal_reaching_demos(lava_bridge_mj.load_demos(500, env_id=task), "states")
    curriculum = RFCLReverseSS(demo_states, ids)
    frozen_from, starts = [], set()
    runs = sorted((ROOT / "results/study" / task / "rfcl-d500").glob("seed*"))
    assert len(runs) == 20
    for run in runs:
        steps, states, probabilities = read_start_weights(run / "start_weights.npz")
        assert np.array_equal(states[:len(demo_states)], demo_states)  # the demo episodes come first
        drawn = [frozenset(np.flatnonzero(row > 0).tolist()) for row in probabilities]
        moved = [i for i in range(1, len(drawn)) if drawn[i] != drawn[i - 1]]
        frozen_from.append(int(steps[moved[-1]] if moved else steps[0]))
        starts |= drawn[-1]
    first, last = min(starts), max(starts)
    back = sorted(curriculum.steps_back(i) for i in (first, last))
    limits = sorted(curriculum.time_limit(i) for i in (first, last))
    # with the limit off (results/study_ablations), the seeds whose reverse stage handed over: the first
    # evaluation whose start weights hold no demo state
    handed_over = []
    for run in sorted((ROOT / "results/study_ablations" / task / "rfcl-no_limit-d500").glob("seed*")):
        steps, _, probabilities = read_start_weights(run / "start_weights.npz")
        step = reverse_stage_handover(steps, probabilities, len(demo_states))
        if step is not None:
            handed_over.append(step)
    quoted = " ".join(section((ROOT / "docs/results.md").read_text(),
                              "## RFCL without its shortened time limit, on the medium maze").split())
    assert len(np.unique(ids)) == 1 and starts == set(range(first, last + 1))
    for fact in (f"from {max(frozen_from):,} steps on", f"{len(demo_states)} states", f"states {first}-{last}",
                 f"{back[0]} to {back[1]} of the expert's steps", f"{limits[0]} to {limits[1]} steps",
                 f"on {len(handed_over)} of 20 seeds, from {min(handed_over):,} to {max(handed_over):,} steps"):
        assert fact in quoted, f"docs/results.md on where rfcl stalls should say {fact!r}, as its runs do"


def test_results_md_on_where_rfcl_stops_on_the_two_crossings_reads_its_runs():
    # the section's account is read from the study's rfcl runs on the task at seeds 0-19 (the first look): the
    # seeds reaching p0 success 0.8 are those whose reverse stage handed over (start weights without a demo
    # state), and the others' last starts lie within the quoted span of expert steps and time limits
    import numpy as np

    from lava_bridge_mj.agents.reverse_curriculum import goal_reaching_demos
    from lava_bridge_mj.agents.rfcl import RFCLReverseSS
    from lava_bridge_mj.eval.analysis.aggregate import find_runs, group_runs, steps_to_threshold
    from lava_bridge_mj.eval.analysis.summary import read_start_weights

    task = "LavaBridgeTwoCrossings-v0"
    demo_states, ids = goal_reaching_demos(lava_bridge_mj.load_demos(500, env_id=task))
    curriculum = RFCLReverseSS(demo_states, ids)

    def reached(method, seeds=range(20)):
        """Seed -> step, for those of `seeds` (the first look's) that reach p0 success 0.8, as the report counts them."""
        [group] = group_runs(find_runs(ROOT / "results/study" / task / f"{method}-d500", seeds=seeds))
        return {seed: step for seed, step in steps_to_threshold(group).per_seed.items() if step < float("inf")}

    def handover(seed):
        """rfcl's step of handing over to the forward stage on `seed` (None: never), and its last start weights."""
        steps, _, probabilities = read_start_weights(ROOT / "results/study" / task / "rfcl-d500" / f"seed{seed}"
                                                     / "start_weights.npz")
        return reverse_stage_handover(steps, probabilities, len(demo_states)), probabilities[-1]

    handed_over, stalled = {}, []
    for seed in range(20):
        step, last_weights = handover(seed)
        if step is not None:
            handed_over[seed] = step
        else:
            window = np.flatnonzero(last_weights[:len(demo_states)] > 0)
            assert len(window) == 5 and np.all(np.diff(window) == 1), seed  # five consecutive demo states
            stalled.extend(window.tolist())
    rfcl_reached = sorted(reached("rfcl"))
    assert len(np.unique(ids)) == 1 and rfcl_reached == sorted(handed_over)
    reverse_alone = reached("rfcl_reverse")  # the reverse stage without the forward one
    assert sorted(reverse_alone) == rfcl_reached
    back = [curriculum.steps_back(i) for i in stalled]
    limits = [curriculum.time_limit(i) for i in stalled]
    named = ", ".join(map(str, rfcl_reached[:-1])) + f" and {rfcl_reached[-1]}"
    quoted = " ".join(section((ROOT / "docs/results.md").read_text(),
                              "## Where RFCL's reverse stage stops on the two crossings").split())
    for fact in (f"on {len(rfcl_reached)} of 20 seeds, against {len(reached('auxss'))} of 20 for AuxSS",
                 f"seeds {named}", f"the other {20 - len(rfcl_reached)}",
                 f"between {min(handed_over.values()):,} and {max(handed_over.values()):,} steps",
                 f"({len(demo_states)} states)", f"between {min(back)} and {max(back)} of the expert's steps",
                 f"{min(limits)} to {max(limits)} steps",
                 f"reaches 0.8 on the same seeds, between {min(reverse_alone.values()):,.0f} and "
                 f"{max(reverse_alone.values()):,.0f} steps"):
        assert fact in quoted, f"docs/results.md on where rfcl stops on the two crossings should say {fact!r}"
    left = " ".join(section((ROOT / "docs/results.md").read_text(), "## What is left").split())
    assert f"RFCL's reverse stage stops on {20 - len(rfcl_reached)} of 20 seeds" in left
    # the extension's seeds, read the same way: which hand over, which of those reach 0.8, and that no other does
    (study_first, study_last), (_, second_look) = study_seed_range(), study_looks()
    extension = range(study_last + 1, study_first + second_look)
    reached_later = set(reached("rfcl", extension))
    later = {seed: step for seed in extension if (step := handover(seed)[0]) is not None}
    assert reached_later <= set(later)
    [missed] = sorted(set(later) - reached_later)
    for fact in (f"{len(later)} of the {len(extension)} hand over", f"{len(reached_later)} of those reach 0.8",
                 f"between {min(later.values()):,} and {max(later.values()):,} steps",
                 f"seed {missed} hands over at {later[missed]:,} steps",
                 f"none of the other {len(extension) - len(later)} reaches it"):
        assert fact in quoted, f"docs/results.md on where rfcl stops on the two crossings should say {fact!r}"


def test_results_md_on_rfcls_time_limit_quotes_its_report():
    # the same for rfcl on the medium maze: every count and decimal is in docs/report_rfcl_limit
    report = (ROOT / "docs/report_rfcl_limit/report.md").read_text()
    quoted = section((ROOT / "docs/results.md").read_text(),
                     "## RFCL without its shortened time limit, on the medium maze")
    assert_quoted_from(quoted, report, "docs/results.md on rfcl's time limit")


def test_a_script_outside_the_package_reproduces_every_verdict_the_docs_state():
    # tests/outside/recompute_study.py reads only results/study and imports nothing of lava_bridge_mj: its own
    # exact tests, equivalence tests and two-look level give every comparison the verdict answers.json holds,
    # from which the README's answer table and docs/results.md's study section are generated
    import ast
    import subprocess
    import sys

    script = ROOT / "tests/outside/recompute_study.py"
    imported = {alias.name.split(".")[0] for node in ast.walk(ast.parse(script.read_text()))
                if isinstance(node, (ast.Import, ast.ImportFrom))
                for alias in (node.names if isinstance(node, ast.Import) else [ast.alias(node.module or "")])}
    assert "lava_bridge_mj" not in imported
    seeds, looks = (STUDY_REPORT[STUDY_REPORT.index(option) + 1] for option in ("--seeds", "--looks"))
    held_back = [argument for task, task_seeds in held_back_tasks().items()
                 for argument in ("--task-seeds", f"{task}={task_seeds}")]
    run = subprocess.run([sys.executable, str(script), str(ROOT / "results/study"), "--seeds", seeds, "--looks", looks,
                          *held_back], capture_output=True, text=True, check=True)
    outside = json.loads(run.stdout)
    record = json.loads((ROOT / doc_tables.ANSWERS).read_text())
    ours = {(task, c["question"], c["a"], c["b"], c["aspect"]): c["verdict"]
            for task, answers in record.items() for c in answers["comparisons"] if c["effect"] is not None}
    theirs = {(task, int(number), c["a"], c["b"], c["aspect"]): c["verdict"]
              for task, questions in outside["answers"].items() for number, comparisons in questions.items()
              for c in comparisons}
    # every task of results/study, each of its comparisons whose two groups have runs
    assert set(record) == {task.name for task in (ROOT / "results/study").iterdir() if task.is_dir()}
    assert len(ours) >= 10 * len(lava_bridge_mj.SUITE) and theirs == ours
