"""`make test`: it names the tests that failed even when pytest's controller dies before its summary."""

import os
import subprocess
import sys
from pathlib import Path

from conftest import makefile_recipe

REPOSITORY = Path(__file__).resolve().parent.parent

CRASHING_CONTROLLER = '''
import os

import pytest


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session):
    if not hasattr(session.config, "workerinput"):  # the controller, once every test has reported
        os._exit(3)  # as when pytest-xdist's teardown crashed: no summary, no "FAILED" lines
'''


def test_make_test_names_the_failed_tests_when_the_controller_dies_before_its_summary(tmp_path):
    """A `make test` beside a process holding 13,500 threads crashed in pytest-xdist's teardown and never
    named its failing test. The Makefile's own recipe runs here, on a suite of one failing and two passing
    tests whose controller exits at the end of the session, before pytest prints anything about them."""
    (tmp_path / "conftest.py").write_text(CRASHING_CONTROLLER)
    (tmp_path / "test_sample.py").write_text("def test_passes():\n    pass\n\n\n"
                                             "def test_fails():\n    assert 1 == 2\n\n\n"
                                             "def test_passes_too():\n    pass\n")
    [recipe] = [line for line in makefile_recipe("test") if " -m pytest " in line]
    command = (recipe.strip().replace(".venv/bin/python", sys.executable).replace("$$", "$")
               .replace("tests/failures.py", str(REPOSITORY / "tests" / "failures.py")))
    environment = {name: value for name, value in os.environ.items() if not name.startswith("PYTEST")}
    done = subprocess.run(["bash", "-c", command], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                          env=environment)
    assert done.returncode == 3, done.stdout + done.stderr  # pytest's exit status, not the printer's
    assert "test_sample.py::test_fails" not in done.stdout.split("1 failed test(s)")[0]  # pytest named nothing
    assert done.stdout.splitlines()[-3:] == [
        "1 failed test(s), from .pytest-results.jsonl:",
        "FAILED test_sample.py::test_fails",
        "the test session stopped before its end: tests that were still running are not in the log"]
