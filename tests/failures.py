"""Print the tests that failed, read from the results log that pytest-reportlog appends to as each test
finishes (`pytest --report-log=FILE`): `make test` names them even when pytest's own summary never
comes, because its controller died first (a crash in pytest-xdist's teardown once hid them).

    python tests/failures.py .pytest-results.jsonl
"""

import json
import sys


def read_log(path: str) -> tuple[list[str], bool]:
    """The failed tests and collection errors in the log at `path`, as `FAILED nodeid` lines (with the
    phase where it is not the test itself), and whether the session reached its end."""
    failed, finished = [], False
    with open(path) as log:
        for line in log:
            try:
                record = json.loads(line)
            except ValueError:  # the last line, cut short by a crash
                continue
            kind = record.get("$report_type")
            if kind == "SessionFinish":
                finished = True
            elif kind in ("TestReport", "CollectReport") and record.get("outcome") == "failed":
                phase = record.get("when")
                where = f" (in {phase})" if phase not in (None, "call", "collect") else ""
                failed.append(f"FAILED {record['nodeid'] or '(collection)'}{where}")
    return failed, finished


def main(argv: list[str]) -> int:
    path = argv[0]
    try:
        failed, finished = read_log(path)
    except OSError as error:
        print(f"no test results in {path}: {error.strerror}")
        return 1
    # on a line of its own: a pytest that died may have left its progress line unfinished
    print(f"\n{len(failed)} failed test(s), from {path}:" if failed else f"\nno failed test in {path}")
    for line in failed:
        print(line)
    if not finished:
        print("the test session stopped before its end: tests that were still running are not in the log")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
