"""What code made a result: this package's version and git commit, and the libraries' versions.

A run directory's provenance.json holds one entry per training session (the first, then each
resume), so a run extended or continued by different code says so. config.json records what was
asked for; provenance.json records what ran it, the start strategy's settings with the defaults
of that code filled in among them.
"""

from __future__ import annotations

import platform
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

import lava_bridge_mj

LIBRARIES = ("numpy", "torch", "mujoco", "gymnasium")


def git_state(source: str | Path) -> dict[str, Any]:
    """{"commit": sha, "dirty": bool} of the git work tree that tracks the file `source`; both None
    when none does (an installed, non-editable copy, even one in a virtualenv inside a clone) or git
    is missing."""
    source = Path(source).resolve()

    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(source.parent), *args], capture_output=True, text=True,
                              check=True, timeout=10).stdout.strip()

    try:
        git("ls-files", "--error-unmatch", source.name)
        commit = git("rev-parse", "HEAD")
        dirty = bool(git("status", "--porcelain", "--untracked-files=no"))
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}
    return {"commit": commit, "dirty": dirty}


def _version(distribution: str) -> str | None:
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None


def processor(cpuinfo: str | Path = "/proc/cpuinfo") -> str:
    """The processor this process runs on: vendor, model name, family and model of the first entry of
    `cpuinfo` (Linux), else what `platform.processor()` says ("" if nothing).

    It belongs in a result's provenance because the same code and seed give bit-identical numbers on
    one processor, while another may round the float operations of the update differently (torch's
    and MKL's kernels are chosen per processor), and its runs then differ from the first learning
    update on: equally valid draws, not the same numbers."""
    try:
        first = Path(cpuinfo).read_text().split("\n\n", 1)[0]
    except OSError:
        return platform.processor()
    fields = {key.strip(): value.strip() for key, _, value in
              (line.partition(":") for line in first.splitlines()) if value.strip()}
    family = ", ".join(f"{name} {fields[name]}" for name in ("cpu family", "model") if name in fields)
    described = " ".join(fields[name] for name in ("vendor_id", "model name") if name in fields)
    return f"{described} ({family})" if described and family else described or platform.processor()


def code_provenance() -> dict[str, Any]:
    """This process's code: lava-bridge-mj's version and git state, Python and the libraries that
    set a run's numbers, and the machine: its platform, processor and the vector instructions torch
    dispatches to (the same seed gives the same numbers on the same machine; `processor` says why)."""
    import torch

    return {"lava_bridge_mj": _version("lava-bridge-mj"), "git": git_state(lava_bridge_mj.__file__),
            "python": platform.python_version(), **{name: _version(name) for name in LIBRARIES},
            "platform": platform.platform(), "processor": processor(),
            "torch_cpu_capability": torch.backends.cpu.get_cpu_capability()}
