"""`python -m lava_bridge_mj model|demos --check`: the shipped assets match their generators."""

import subprocess
import sys

import lava_bridge_mj.mjcf as mjcf
from lava_bridge_mj.__main__ import main


def test_shipped_model_is_current_from_the_command_line():
    result = subprocess.run([sys.executable, "-m", "lava_bridge_mj", "model", "--check"],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "up to date" in result.stdout
    assert "Warning" not in result.stderr


def test_model_check_fails_on_a_stale_file(tmp_path, monkeypatch, capsys):
    (tmp_path / mjcf.ASSET_NAME).write_text(mjcf.shipped_xml().replace('gear="4"', 'gear="5"'))
    monkeypatch.setattr(mjcf.resources, "files", lambda package: tmp_path)
    assert main(["model", "--check"]) == 1
    assert "OUT OF DATE" in capsys.readouterr().out
