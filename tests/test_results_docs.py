"""The committed reports (docs/report*/report.md, which docs/results.md and the README quote) are what
`make report` makes from the committed metrics in results/: a changed metric, a changed aggregate or
a hand-edited table fails here. The commands are read from the Makefile, the one place they live."""

import importlib.util
import re
import shlex
from pathlib import Path

import pytest
from conftest import makefile_recipe

pytest.importorskip("rliable", reason="the report needs the plots extra: pip install -e '.[plots]'")

from lava_bridge_mj.eval import report  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def make_report_commands():
    """The argument lists of the `lava-bridge-bench report` lines of the Makefile's report target."""
    return [shlex.split(line.split("lava-bridge-bench report", 1)[1]) for line in makefile_recipe("report")
            if "lava-bridge-bench report" in line]


COMMANDS = make_report_commands()


def test_the_report_target_makes_every_committed_report():
    assert [argv[argv.index("--out") + 1] for argv in COMMANDS] == [
        "docs/report", "docs/report_300k", "docs/report_ablations", "docs/report_calibration",
        "docs/report_calibration_confirm", "docs/report_screening", "docs/report_screening_300k"]


@pytest.mark.parametrize("argv", COMMANDS, ids=[argv[argv.index("--out") + 1] for argv in COMMANDS])
def test_committed_report_is_regenerated_exactly_from_results(argv, tmp_path, monkeypatch):
    committed = ROOT / argv[argv.index("--out") + 1] / "report.md"
    argv = list(argv)
    argv[argv.index("--out") + 1] = str(tmp_path)
    monkeypatch.chdir(ROOT)  # the report names its directories as given, relative to the repository
    assert report.main(argv) == 0
    assert (tmp_path / "report.md").read_text() == committed.read_text(), \
        f"{committed} is stale: run `make report` and commit what it writes"


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
    readme = (ROOT / "README.md").read_text()
    verdicts = "|".join(map(re.escape, set(expected.values())))
    assert findings_verdicts(readme, rf"^\| (\d) \| [^|]+ \| ({verdicts})\b") == expected, "README findings table"


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


def study_rows(report_text):
    """Task id -> the comparison rows of its section "The study's questions", in a report on one task or
    on several (a task's section then holds its own)."""
    one_task = re.match(r"# (LavaBridge\w*-v0) report", report_text)
    tasks = {one_task[1]: report_text} if one_task else task_sections(report_text, "##")
    return {task: re.findall(STUDY_ROW, text[text.index("# The study's questions"):], re.MULTILINE)
            for task, text in tasks.items() if "# The study's questions" in text}


def test_results_md_quotes_the_study_question_on_lavabridge_v0_as_the_report_gives_it():
    report_rows = study_rows((ROOT / "docs/report/report.md").read_text())["LavaBridge-v0"]
    results = (ROOT / "docs/results.md").read_text()
    quoted = section(results, "## The study's first question on LavaBridge-v0: do safety-derived starts beat "
                              "undirected ones?")
    assert len(report_rows) == 8 and re.findall(STUDY_ROW, quoted, re.MULTILINE) == report_rows
    # the README's summary quotes the one interval that leaves little room on one side
    [quoted] = [effect for pair, aspect, effect, _ in report_rows
                if (pair, aspect) == ("auxss against goaldist_ss", "learns faster")]
    assert f"GoalDist-SS on reaching 0.8, {quoted}" in " ".join((ROOT / "README.md").read_text().split())


def test_every_folder_of_results_is_described_in_its_readme():
    # results/README.md says how each folder's runs were made and by which commit; a folder it does not
    # name would be metrics without a command
    first_column = re.findall(r"^\| ([^|]+) \|", (ROOT / "results/README.md").read_text(), re.MULTILINE)
    described = {name.split("/")[0] for cell in first_column for name in re.findall(r"`([\w/]+)/`", cell)}
    assert {path.name for path in (ROOT / "results").iterdir() if path.is_dir()} <= described
