"""The committed reports (docs/report*/report.md, which docs/results.md and the README quote) are what
`make report` makes from the committed metrics in results/: a changed metric, a changed aggregate or
a hand-edited table fails here. The commands are read from the Makefile, the one place they live."""

import importlib.util
import re
from pathlib import Path

import pytest

import lava_bridge_mj
from conftest import makefile_commands, makefile_sweeps

pytest.importorskip("rliable", reason="the report needs the plots extra: pip install -e '.[plots]'")

from lava_bridge_mj.eval import report  # noqa: E402
from lava_bridge_mj.eval.claims import UNDECIDED  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


COMMANDS = makefile_commands("report", "report")
"""The argument lists of the `lava-bridge-bench report` lines of the Makefile's report target."""
[STUDY_REPORT] = [argv for argv in COMMANDS if argv[argv.index("--out") + 1] == "docs/report_study"]
"""The study report's argument list."""


def held_back_tasks():
    """Task -> seeds, for each task the study report reads at other seeds than its --seeds (--task-seeds)."""
    return dict(STUDY_REPORT[i + 1].split("=") for i, arg in enumerate(STUDY_REPORT) if arg == "--task-seeds")


def test_the_report_target_makes_every_committed_report():
    assert [argv[argv.index("--out") + 1] for argv in COMMANDS] == [
        "docs/report", "docs/report_300k", "docs/report_ablations", "docs/report_calibration",
        "docs/report_calibration_confirm", "docs/report_screening", "docs/report_screening_300k", "docs/report_study",
        "docs/report_reverse_limit"]


@pytest.mark.parametrize("argv", COMMANDS, ids=[argv[argv.index("--out") + 1] for argv in COMMANDS])
def test_committed_report_is_regenerated_exactly_from_results(argv, tmp_path, monkeypatch):
    committed = ROOT / argv[argv.index("--out") + 1] / "report.md"
    argv = list(argv)
    argv[argv.index("--out") + 1] = str(tmp_path)
    monkeypatch.chdir(ROOT)  # the report names its directories as given, relative to the repository
    assert report.main(argv) == 0
    assert (tmp_path / "report.md").read_text() == committed.read_text(), \
        f"{committed} is stale: run `make report` and commit what it writes"
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
    assert f"GoalDist-SS on reaching 0.8, {quoted}" in " ".join((ROOT / "docs/findings.md").read_text().split())


def test_results_md_answers_the_study_per_task_as_the_study_report_gives_it():
    # every task the study report answers a question on is quoted in its own subsection, row for row;
    # a task of the suite it does not answer yet is named, never left out
    report_text = (ROOT / "docs/report_study/report.md").read_text()
    reported = study_rows(report_text)
    quoted = section((ROOT / "docs/results.md").read_text(), "## The study on the task suite")
    answered = task_sections(quoted, "###")
    assert {task: re.findall(STUDY_ROW, text, re.MULTILINE) for task, text in answered.items()} == reported
    for task in set(lava_bridge_mj.SUITE) - set(reported):
        assert f"`{task}`" in quoted, f"docs/results.md's study section does not say {task} is still to run"
    # and every count (18/20) and decimal (0.0136) its prose quotes is in the report's part on that task
    for task, text in answered.items():
        prose = "\n".join(line for line in text.splitlines() if not line.startswith("|"))
        assert_quoted_from(prose, report_parts(report_text)[task], f"docs/results.md on {task}")
    # so is every number of docs/findings.md's paragraph on the study
    findings = (ROOT / "docs/findings.md").read_text()
    paragraph = findings[findings.index("**The study on the task suite**"):]
    assert_quoted_from(paragraph[:paragraph.index("\n\n")], report_text, "docs/findings.md's study paragraph")


OVERVIEW_ROW = r"^\| (LavaBridge\w*-v0) \| (\d\. [^|]+) \| ([^|]+) \| ([^|]+) \| ([^|]+) \|$"
"""A row of the study's answers, task by task: task, question, verdict counts, decided comparisons, seeds
needed where undecided."""


def test_results_md_and_the_readme_give_the_studys_answers_task_by_task_as_the_study_report_does():
    report = (ROOT / "docs/report_study/report.md").read_text()
    reported = re.findall(OVERVIEW_ROW, section(report, "## The study's answers, task by task"), re.MULTILINE)
    quoted = section((ROOT / "docs/results.md").read_text(), "## The study on the task suite")
    overview = quoted[:quoted.index("\n### ")]  # the table stands before the first task's subsection
    assert reported and re.findall(OVERVIEW_ROW, overview, re.MULTILINE) == reported
    readme = (ROOT / "README.md").read_text()
    assert re.findall(OVERVIEW_ROW, readme, re.MULTILINE) == reported, "the README's table of the study's answers"
    # each task answered there has its subsection with the same comparisons
    assert {task for task, *_ in reported} == set(task_sections(quoted, "###"))


SECOND_QUESTION_ROW = (r"^\| (LavaBridge\w*-v0) \| (\d+/\d+, \d+/\d+) \| ([+-]\d\.\d\d \[[+-]\d\.\d\d, [+-]\d\.\d\d\]) \| "
                       r"([^|]+) \| (\d+/\d+, \d+/\d+) \| ([+-]\d\.\d\d \[[+-]\d\.\d\d, [+-]\d\.\d\d\]) \| ([^|]+) \|$")
"""A row of results.md's table of AuxSS against the reverse curriculum: task, reach counts, effect, verdict,
robust-seed counts, effect, verdict."""


def test_results_md_gives_auxss_against_the_reverse_curriculum_on_every_task_as_the_study_report_does():
    # one row per task of the suite, each count, effect and verdict the report's comparison of that task
    report = (ROOT / "docs/report_study/report.md").read_text()
    expected = []
    for task, text in sorted(report_parts(report).items()):
        faster, robust = (re.search(rf"^\| auxss against reverse_ss \| {aspect} \| [^|]*?(\d+/\d+) \[[^]]+\] "
                                    rf"against (\d+/\d+) \[[^|]*\| ([^|]+) \|.*\*\*([^*]+)\*\* \|$", text, re.MULTILINE)
                          for aspect in ("learns faster", "more robust"))
        expected.append((task, f"{faster[1]}, {faster[2]}", faster[3].strip(), faster[4],
                         f"{robust[1]}, {robust[2]}", robust[3].strip(), robust[4]))
    quoted = section((ROOT / "docs/results.md").read_text(), "## The study on the task suite")
    rows = [tuple(cell.strip() for cell in row) for row in re.findall(SECOND_QUESTION_ROW, quoted, re.MULTILINE)]
    assert rows == expected and {row[0] for row in rows} == set(lava_bridge_mj.SUITE)


BASELINE_ROW = r"^\| (LavaBridge\w*-v0) \| ([^|]+) \| ([^|]+) \| ([^|]+) \| ([^|]+) \|$"
"""A row of results.md's table of AuxSS against the baselines: task, then per baseline (SAC, HySAC+AuxSS)
the reach counts and the pairwise table's verdict, or 'not run' twice."""


def test_results_md_gives_auxss_against_the_baselines_on_every_task_as_the_study_report_does():
    # one row per task of the suite; a baseline's cells are the reach counts and verdict of the report's
    # pairwise row "auxss (0.5K) | BASELINE (0.5K)" on that task (its labels name tasks other than
    # LavaBridge-v0, "auxss (0.5K) on TASK", which the table leaves out), or 'not run' where the report has none
    report = (ROOT / "docs/report_study/report.md").read_text()
    parts = report_parts(report)
    expected = []
    for task in sorted(lava_bridge_mj.SUITE):
        row = [task]
        for baseline in ("sac", "hysac_auxss"):
            pairwise = section(parts[task], "### Pairwise tests").replace(f" on {task}", "") if task in parts else ""
            found = re.search(rf"^\| auxss \(0\.5K\) \| {baseline} \(0\.5K\) \| [\d,]+ \| (\d+/\d+, \d+/\d+) \|"
                              rf".* \| ([^|]+) \|$", pairwise, re.MULTILINE)
            row += [found[1], found[2].strip()] if found else ["not run", "not run"]
        expected.append(tuple(row))
    quoted = section((ROOT / "docs/results.md").read_text(), "## The study on the task suite")
    rows = [tuple(cell.strip() for cell in row) for row in re.findall(BASELINE_ROW, quoted, re.MULTILINE)
            if row[1].strip() == "not run" or re.fullmatch(r"\d+/\d+, \d+/\d+", row[1].strip())]
    assert rows == expected


def test_the_readmes_summary_in_words_still_says_what_the_study_report_decides():
    # the README's paragraph under the answers table names which comparisons a test decided, task by task; when
    # a new group changes that, this fails until the paragraph is rewritten
    report = (ROOT / "docs/report_study/report.md").read_text()
    decided = {(task, question[0]): cell.strip()
               for task, question, _, cell, _ in re.findall(OVERVIEW_ROW, section(report, "## The study's answers, task by task"),
                                                         re.MULTILINE) if cell.strip() != "-"}
    assert decided == {
        ("LavaBridge-v0", "1"): "goaldist_ss ahead of omega_ss: learns faster",
        ("LavaBridgeDecoy-v0", "1"): "auxss ahead of uniform_ss: learns faster, more robust",
        ("LavaBridgeDecoy-v0", "2"): "auxss ahead of reverse_ss: more robust (at 0.05 only)",
        ("LavaBridgeFarStart-v0", "1"): ("auxss ahead of uniform_ss: learns faster, more robust; "
                                         "goaldist_ss ahead of omega_ss: learns faster"),
        ("LavaBridgeFarStart-v0", "2"): "auxss ahead of reverse_ss: learns faster, more robust",
        ("LavaBridgeNarrow-v0", "1"): "auxss ahead of uniform_ss: learns faster, more robust",
        ("LavaBridgeNarrow-v0", "2"): "reverse_ss ahead of auxss: learns faster",
        ("LavaBridgeTwoCrossings-v0", "1"): "auxss ahead of uniform_ss: learns faster, more robust",
        ("LavaBridgeTwoCrossings-v0", "2"): "auxss ahead of reverse_ss: learns faster, more robust",
    }
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert ("In words: AuxSS beats U-SS, learning faster and more robust from ood, on four of the five tasks (the "
            "decoy, the far start, the narrow bridge and the two crossings); on LavaBridge-v0 the two are *no "
            "difference found* (a bounded negative). No safety-derived start beats GoalDist-SS on any task") in readme
    assert ("GoalDist-SS learns faster than Omega-SS on LavaBridge-v0 and the far start. Omega-SS beats neither "
            "undirected distribution anywhere.") in readme
    assert ("Against RFCL's reverse curriculum AuxSS learns faster and is more robust on the far start and the two "
            "crossings") in readme and "on the narrow bridge the curriculum learns faster" in readme
    # results.md: "At 49 seeds every comparison on every task is decided either way": no comparison of a task read
    # at the second look is short of power
    second_look = {task: rows for task, rows in study_rows(report).items() if task not in held_back_tasks()}
    assert set(second_look) == set(lava_bridge_mj.SUITE)
    assert all(verdict != UNDECIDED for rows in second_look.values() for *_, verdict in rows)


CURRICULUM_ROW = (r"^\| group \| curriculum done \| per seed[^\n]*\n\|[-:|]+\|\n"
                  r"\| reverse_ss \(0\.5K\)(?: on (LavaBridge\w*-v0))? \| (\d+ of \d+) \| (.*) \|$")
"""The study report's curriculum table of a task (one group): task (empty for LavaBridge-v0, which a report
does not name in its labels), the seeds whose curriculum is done, every seed's cell."""


STALL_ROW = (r"^\| reverse_ss \(0\.5K\)(?: on (LavaBridge\w*-v0))? \| \d+ \| [\d,]+ \| [\d.-]+ \| [\d.-]+ "
             r"\| [\d.-]+ \| (\d+ of \d+) \|")
"""The study report's row of how a task's unfinished curricula's episodes ended: task (empty for
LavaBridge-v0), the unfinished seeds whose episodes mostly ended at the time limit."""


def test_results_md_says_how_far_the_reverse_curriculum_came_as_the_study_report_gives_it():
    # "N of M seeds finish the curriculum" in a task's subsection is the report's count for that task, and
    # "between A% and B% of the way back" the least and most of its unfinished seeds' shares
    report = (ROOT / "docs/report_study/report.md").read_text()
    table = {task or lava_bridge_mj.ENV_ID: (done, [int(share) for share in re.findall(r"(\d+)% back", cells)])
             for task, done, cells in re.findall(CURRICULUM_ROW, report, re.MULTILINE)}
    answered = task_sections(section((ROOT / "docs/results.md").read_text(), "## The study on the task suite"), "###")
    said = {}
    for task, text in answered.items():
        prose = " ".join(text.split())
        for done in re.findall(r"(\d+ of \d+) seeds finish the curriculum", prose):
            said[task] = done
            assert done == table[task][0], f"docs/results.md on {task}: {done} seeds finish; the report: {table[task][0]}"
        for low, high in re.findall(r"between (\d+)% and (\d+)% of the way back", prose):
            assert (int(low), int(high)) == (min(table[task][1]), max(table[task][1])), task
    # every task with a curriculum table is described; the far start and the decoy are (checked by hand)
    assert set(said) == set(table) and {"LavaBridgeDecoy-v0", "LavaBridgeFarStart-v0"} <= set(said)
    # "mostly at the time limit on K of N unfinished seeds" is the report's count, for every task whose
    # unfinished curricula the report says how their episodes ended
    endings = {task or lava_bridge_mj.ENV_ID: count for task, count in re.findall(STALL_ROW, report, re.MULTILINE)}
    quoted = {}
    for task, text in answered.items():
        prose = " ".join(text.split())
        for count in re.findall(r"mostly at the time limit on (\d+ of \d+) unfinished seeds", prose):
            quoted[task] = count
            assert count == endings[task], f"docs/results.md on {task}: {count}; the report: {endings[task]}"
    assert set(quoted) == set(endings) and "LavaBridgeTwoCrossings-v0" in quoted


def assert_quoted_from(prose, report_text, where):
    """Every count (18/20) and decimal (0.0136) in `prose` is in `report_text`."""
    for number in re.findall(r"\d+/\d+|\d\.\d+", prose):
        assert number in report_text, f"{where} quotes {number}; the report does not"


def study_seed_range():
    """The first and last evaluation seed of `make study`."""
    first, last = makefile_sweeps("study")[0]["--seeds"].split("-")
    return int(first), int(last)


def extension_groups():
    """(task, method) of each group `make study-extension` trains, once per sweep line that names it."""
    return [(task, method) for sweep in makefile_sweeps("study-extension") for task in sweep["--envs"].split(",")
            for method in sweep["--methods"].split(",")]


def test_results_md_says_which_of_the_studys_runs_are_finished_as_results_study_holds_them():
    # each task of the suite: its budget as `make study` trains it, the methods with all their seeds in
    # results/study, and the rest of the study's methods still to run
    sweeps = makefile_sweeps("study")
    first, last = study_seed_range()
    planned = {}  # task -> (steps, methods)
    for sweep in sweeps:
        for task in sweep["--envs"].split(","):
            planned.setdefault(task, (int(sweep["--steps"]), []))[1].extend(sweep["--methods"].split(","))
    rows = re.findall(r"^\| `(LavaBridge\w*-v0)` \| ([\d,]+) \| ([^|]+) \| ([^|]+) \|$",
                      section((ROOT / "docs/results.md").read_text(), "## The study on the task suite"), re.MULTILINE)
    assert {task for task, *_ in rows} == set(lava_bridge_mj.SUITE) == set(planned)
    for task, steps, finished, still in rows:
        names = {"finished": set(finished.split(", ")) - {"-"}, "still": set(still.split(", ")) - {"-"}}
        complete = {method for method in planned[task][1]
                    if all((ROOT / "results/study" / task / f"{method}-d500" / f"seed{seed}" / "metrics.csv").is_file()
                           for seed in range(first, last + 1))}
        assert int(steps.replace(",", "")) == planned[task][0], task
        assert names["finished"] == complete and names["still"] == set(planned[task][1]) - complete, task


def test_results_md_says_which_seeds_of_the_extension_are_trained_as_results_study_holds_them():
    # every group with runs beyond the study's seeds in results/study is listed with exactly those seeds,
    # as one range, and is a group the extension trains (no stray seeds, none claimed that are not there)
    study_last = study_seed_range()[1]
    held = {}
    for metrics in (ROOT / "results/study").glob("*/*-d500/seed*/metrics.csv"):
        seed = int(metrics.parent.name.removeprefix("seed"))
        if seed > study_last:
            held.setdefault((metrics.parents[2].name, metrics.parents[1].name.removesuffix("-d500")), []).append(seed)
    listed = {(task, method): seeds for task, method, seeds in re.findall(
        r"^\| `(LavaBridge\w*-v0)` \| (\w+) \| (\d+-\d+) \|$",
        section((ROOT / "docs/results.md").read_text(), "## The study on the task suite"), re.MULTILINE)}
    assert set(listed) <= set(extension_groups())
    assert {group: f"{min(seeds)}-{max(seeds)}" for group, seeds in held.items()} == listed
    assert all(sorted(seeds) == list(range(min(seeds), max(seeds) + 1)) for seeds in held.values())


def study_looks():
    """The seeds per group of the study's two looks, as the study report's --looks gives them."""
    first, second = map(int, STUDY_REPORT[STUDY_REPORT.index("--looks") + 1].split(","))
    return first, second


def first_look():
    """(task, question) -> its answers at the study's first look: results/study read at the study's seeds,
    every verdict checked at the two-look level of the study report's --looks."""
    from lava_bridge_mj.eval.aggregate import find_runs, group_runs
    from lava_bridge_mj.eval.study import answer_questions

    first, last = study_seed_range()
    groups = group_runs(find_runs(ROOT / "results/study", seeds=range(first, last + 1)))
    return {(task, question.short): question.answers for task in {g.task for g in groups}
            for question in answer_questions([g for g in groups if g.task == task], study_looks())}


def test_the_seed_extension_trains_exactly_the_groups_the_first_look_leaves_undecided():
    # at the first look (the study's 20 seeds): every group of a comparison still open (not enough seeds to
    # decide, or decided at 0.05 but not at the two-look level), on its task at the study's budget, from the seed
    # after the study's last to the second look, which is the most seeds any open comparison needs; groups whose
    # every comparison is decided (or that no question compares) stay at the study's seeds
    first_look_seeds, second_look = study_looks()
    still_open = [(task, answer) for (task, _), found in first_look().items() for answer in found
                  if answer.verdict == UNDECIDED or answer.at_one_look_only]
    open_groups = {(task, method) for task, answer in still_open for method in (answer.a, answer.b)}
    study_steps = {task: sweep["--steps"] for sweep in makefile_sweeps("study") for task in sweep["--envs"].split(",")}
    cells = extension_groups()
    assert len(cells) == len(set(cells)) and set(cells) == open_groups
    needed = [answer.part.seeds_needed for _, answer in still_open if answer.verdict == UNDECIDED]
    study_first, study_last = study_seed_range()
    options = {key: value for key, value in makefile_sweeps("study")[0].items()
               if key not in ("--methods", "--envs", "--steps", "--out", "--seeds")}
    assert (first_look_seeds, second_look) == (study_last - study_first + 1, max(needed))
    for sweep in makefile_sweeps("study-extension"):
        assert sweep["--seeds"] == f"{study_last + 1}-{study_first + second_look - 1}"
        assert all(sweep["--steps"] == study_steps[task] for task in sweep["--envs"].split(","))
        assert {key: value for key, value in sweep.items() if key in options} == options


def test_the_study_report_reads_a_tasks_extension_once_every_group_of_it_has_all_its_seeds():
    # the study report reads the study's and the extension's seeds; a task named in --task-seeds stays at the
    # study's seeds, and it is named exactly when some group the extension trains on it lacks a seed in results/study
    study_first, study_last = study_seed_range()
    _, second_look = study_looks()
    assert STUDY_REPORT[STUDY_REPORT.index("--seeds") + 1] == f"{study_first}-{study_first + second_look - 1}"
    held_back = held_back_tasks()
    assert set(held_back.values()) <= {f"{study_first}-{study_last}"}
    incomplete = {task for task, method in extension_groups()
                  if not all((ROOT / "results/study" / task / f"{method}-d500" / f"seed{seed}" / "metrics.csv").is_file()
                             for seed in range(study_first, study_first + second_look))}
    assert set(held_back) == incomplete


def test_every_folder_of_results_is_described_in_its_readme():
    # results/README.md says how each folder's runs were made and by which commit; a folder it does not
    # name would be metrics without a command
    first_column = re.findall(r"^\| ([^|]+) \|", (ROOT / "results/README.md").read_text(), re.MULTILINE)
    described = {name.split("/")[0] for cell in first_column for name in re.findall(r"`([\w/.-]+)/`", cell)}
    assert {path.name for path in (ROOT / "results").iterdir() if path.is_dir()} <= described


def test_results_md_on_the_reverse_curriculums_time_limit_quotes_its_report():
    # every count and decimal of the section, table included, is in docs/report_reverse_limit, whose three
    # groups it describes; the report tests all three pairs
    report = (ROOT / "docs/report_reverse_limit/report.md").read_text()
    quoted = section((ROOT / "docs/results.md").read_text(),
                     "## The reverse curriculum without its shortened time limit, on the far start")
    assert_quoted_from(quoted, report, "docs/results.md on the reverse curriculum's time limit")
    assert "across the 3 pairs of this table" in report
    done = dict(re.findall(r"^\| reverse_ss \(0\.5K\)( \[strategy\.demo_horizon_to_max_steps_ratio=null\])? on "
                           r"LavaBridgeFarStart-v0 \| (\d+ of \d+) \| 0: ", report, re.MULTILINE))  # the curriculum table
    assert f"finishes on {done[' [strategy.demo_horizon_to_max_steps_ratio=null]'].split()[0]} of 20 seeds instead of " \
           f"{done[''].split()[0]}" in " ".join(quoted.split())
    # and so is every number of the README's sentence on it
    readme = " ".join((ROOT / "README.md").read_text().split())
    sentence = readme[readme.index("On the far start that lead is owed"):]
    assert_quoted_from(sentence[:sentence.index("report_reverse_limit/report.md))")], report, "the README on the time limit")
