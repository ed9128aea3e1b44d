"""eval/'s rooms (docs/design.md, section 9): each folder holds the modules the design notes list, the
installed packages include every room, and imports follow the flow: training imports neither the sweeps
nor the analysis, and analysis and sweeps do not import each other."""

import ast
import configparser
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
EVAL = ROOT / "eval"
PACKAGE = "lava_bridge_mj.eval"
ROOMS = ("training", "sweeps", "analysis")
FORBIDDEN = {"training": {"sweeps", "analysis"}, "sweeps": {"analysis"}, "analysis": {"sweeps"}}
"""room -> the rooms its modules must not import."""


def documented_rooms() -> dict[str, set[str]]:
    """{"eval/training/": {"config", ...}, ...} from the listing in docs/design.md's section 9."""
    section = (ROOT / "docs" / "design.md").read_text().split("## 9. The rooms of eval/", 1)[1]
    listing = re.findall(r"^(eval/(?:\w+/)?) {2,}([\w ]+)$", section, re.M)
    return {folder: set(modules.split()) for folder, modules in listing}


def imported_modules(source: str, module: str) -> set[str]:
    """Every lava_bridge_mj.eval module `source` (the code of `module`) imports, at any depth of its
    code (imports inside functions included); `from PACKAGE import name` counts as PACKAGE.name."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the module's own package up
                parent = module.split(".")[:-node.level]
                base = ".".join(parent + ([base] if base else []))
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return {name for name in found if name.startswith(PACKAGE + ".")}


def room_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and parts[2] in ROOMS else None


def module_name(path: Path) -> str:
    return ".".join([PACKAGE, *path.relative_to(EVAL).with_suffix("").parts])


def test_the_rooms_hold_what_the_design_notes_list():
    documented = documented_rooms()
    assert set(documented) == {"eval/", *(f"eval/{room}/" for room in ROOMS)}
    for folder, modules in documented.items():
        present = {path.stem for path in (ROOT / folder).glob("*.py")} - {"__init__"}
        assert present == modules, f"{folder}: on disk {sorted(present)}, in docs/design.md {sorted(modules)}"
    for room in ROOMS:
        assert (EVAL / room / "__init__.py").is_file()


def test_setup_cfg_installs_every_room():
    config = configparser.ConfigParser()
    config.read(ROOT / "setup.cfg")
    packages = set(config["options"]["packages"].split())
    assert {f"{PACKAGE}.{room}" for room in ROOMS} <= packages


def test_the_import_check_sees_imports_inside_functions():
    source = ("import os\nfrom lava_bridge_mj.eval.training import run_files\n"
              "def f():\n    from lava_bridge_mj.eval import video\n"
              "    from ..analysis.summary import read_config\n")
    found = imported_modules(source, f"{PACKAGE}.training.runner")
    assert {f"{PACKAGE}.training.run_files", f"{PACKAGE}.video", f"{PACKAGE}.analysis.summary"} <= found
    assert {room_of(name) for name in found} == {"training", "analysis", None}


@pytest.mark.parametrize("room", sorted(FORBIDDEN))
def test_a_room_imports_no_room_it_must_not(room):
    files = sorted((EVAL / room).glob("*.py"))
    assert files
    crossings = [f"{path.relative_to(ROOT)} imports {name}"
                 for path in files for name in sorted(imported_modules(path.read_text(), module_name(path)))
                 if room_of(name) in FORBIDDEN[room]]
    assert not crossings, "\n".join(crossings)


def test_importing_the_training_loop_loads_no_sweep_or_analysis_module():
    code = f"import sys, {PACKAGE}.training.runner; print('\\n'.join(sorted(sys.modules)))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    loaded = set(result.stdout.split())
    assert {f"{PACKAGE}.training.runner", f"{PACKAGE}.training.run_files", f"{PACKAGE}.training.config"} <= loaded
    assert not {name for name in loaded if room_of(name) in FORBIDDEN["training"]}
