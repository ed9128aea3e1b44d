"""The commands that only read arguments or results load no torch: `--help` of every command and
`report` stay quick, and the configuration layer imports no learner."""

import subprocess
import sys

import pytest

# Runs the CLI in a fresh interpreter, then says whether torch was ever imported.
PROBE = """
import sys
from lava_bridge_mj.eval import cli
try:
    cli.main(sys.argv[1:])
except SystemExit:
    pass
print("TORCH" if "torch" in sys.modules else "NO TORCH")
"""


@pytest.mark.parametrize("argv", [["--help"], ["sweep", "--help"], ["report", "--help"], ["video", "--help"],
                                  ["report", "no-such-directory", "--out", "unused"], ["export", "--help"],
                                  ["export", "no-such-directory", "unused"]])
def test_help_and_report_do_not_import_torch(argv):
    result = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip().splitlines()[-1] == "NO TORCH", result.stdout + result.stderr


def test_the_configuration_layer_imports_no_learner():
    code = ("import sys; from lava_bridge_mj.eval.training.config import RunConfig; RunConfig(method='iql'); "
            "import lava_bridge_mj.eval.training.run_files, lava_bridge_mj.eval.arguments, lava_bridge_mj.agents.methods; "
            "print('torch' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip() == "False", result.stdout + result.stderr


def test_the_package_api_loads_torch_only_when_training_is_asked_for():
    code = ("import sys, lava_bridge_mj; config = lava_bridge_mj.RunConfig(method='omega_ss'); "
            "print('torch' in sys.modules); "
            "from lava_bridge_mj.eval.training import runner; "
            "print(lava_bridge_mj.train is runner.train, lava_bridge_mj.RunConfig is type(config))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.stdout.split() == ["False", "True", "True"], result.stdout + result.stderr
