"""A Griffe extension that finds the subpackages setup.cfg's `package_dir` maps to other folders.

The top-level `agents/` and `eval/` folders are installed as `lava_bridge_mj.agents` and
`lava_bridge_mj.eval`. Griffe reads a package from its folder on disk, so without this extension the
API reference would see `lava_bridge_mj` without them. When Griffe has loaded a package, each mapped
subpackage of it is read from its own folder and attached under its installed name, so its
modules' paths, imports and cross-references read as they do at run time.
"""

from __future__ import annotations

import configparser
from pathlib import Path
from typing import Any

import griffe

ROOT = Path(__file__).resolve().parents[1]


def package_dirs(setup_cfg: Path = ROOT / "setup.cfg") -> dict[str, Path]:
    """Each dotted package name of `[options] package_dir` -> its folder (the root entry "" left out)."""
    parser = configparser.ConfigParser()
    parser.read(setup_cfg)
    lines = parser.get("options", "package_dir", fallback="").strip().splitlines()
    mapping = dict(line.split("=", 1) for line in lines if "=" in line)
    return {name.strip(): setup_cfg.parent / folder.strip() for name, folder in mapping.items() if name.strip()}


class PackageDir(griffe.Extension):
    """Attach every `package_dir` subpackage of a loaded package, read from its own folder."""

    def on_package(self, *, pkg: griffe.Module, loader: griffe.GriffeLoader, **kwargs: Any) -> None:
        # parents before children: lava_bridge_mj.agents exists before anything mapped below it
        for name, folder in sorted(package_dirs().items(), key=lambda item: item[0].count(".")):
            parent_path, _, child = name.rpartition(".")
            if not parent_path or name.split(".", 1)[0] != pkg.path or name in loader.modules_collection:
                continue
            parent = pkg if parent_path == pkg.path else loader.modules_collection[parent_path]
            # Griffe has no public call that reads a folder as a named submodule; _load_module is the
            # one its own loader uses for every submodule (and recurses into the folder's modules)
            module = loader._load_module(child, folder / "__init__.py", parent=parent)
            parent.set_member(child, module)
            loader.expand_exports(module)
