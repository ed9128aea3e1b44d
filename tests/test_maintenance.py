"""`python -m lava_bridge_mj model|demos --check`: the shipped assets match their generators."""

import subprocess
import sys
import types
from importlib import resources

import lava_bridge_mj.demos as demos_module
import lava_bridge_mj.mjcf as mjcf
from lava_bridge_mj import TASKS
from lava_bridge_mj.__main__ import main
from lava_bridge_mj.demos import MANIFEST, SHIPPED_SIZES, demo_file


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


def test_demos_check_covers_every_task(capsys):
    assert main(["demos", "--check"]) == 0
    out = capsys.readouterr().out
    for env_id in TASKS:
        for size in SHIPPED_SIZES:
            assert f"{demo_file(env_id, size)}: identical" in out, (env_id, size)


def test_demos_check_fails_on_a_stale_task_set_and_writes_nothing(tmp_path, monkeypatch, capsys):
    assets = resources.files("lava_bridge_mj.assets")
    for name in [MANIFEST, *(demo_file(env_id, size) for env_id in TASKS for size in SHIPPED_SIZES)]:
        (tmp_path / name).write_bytes(assets.joinpath(name).read_bytes())
    stale = demo_file("LavaBridgeBend-v0", 500)
    (tmp_path / stale).write_bytes(assets.joinpath(demo_file("LavaBridge-v0", 500)).read_bytes())
    before = {path.name: path.read_bytes() for path in tmp_path.iterdir()}
    monkeypatch.setattr(demos_module, "resources", types.SimpleNamespace(files=lambda package: tmp_path))
    assert main(["demos", "--check"]) == 1
    out = capsys.readouterr().out
    assert f"{stale}: DIFFERENT" in out and f"{demo_file('LavaBridgeLong-v0', 500)}: identical" in out
    assert {path.name: path.read_bytes() for path in tmp_path.iterdir()} == before
