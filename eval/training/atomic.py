"""Crash-safe file writes: write a temporary file beside the target, flush, fsync, rename.

A reader (or a resumed run) sees either the old complete file or the new complete file, never a
half-written one, whatever moment the process is killed at. The temporary file is named
`.NAME.tmpPID` (PID: the writing process); one left by a killed process is removed by
`remove_stale_temporaries`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import IO, Callable

TEMPORARY = re.compile(r"\.(?P<name>.+)\.(?:tmp|link|partial)(?P<pid>\d+)(?:\.\w+)?")
"""The names of files a writer makes and renames or removes when done: `.NAME.tmpPID` (atomic_write),
`.NAME.linkPID` (checkpoint rotations of earlier versions), `.STEM.partialPID.SUFFIX` (videos)."""


def atomic_write(path: str | Path, write: Callable[[IO[bytes]], None], previous: str | Path | None = None) -> None:
    """Call `write(f)` on a temporary binary file, then atomically move it to `path`. An OSError
    (disk full, read-only directory, ...) names `path` in its `filename` if it named no file.

    With `previous`, the file `path` held moves there first (replacing what `previous` held) once the
    new one is complete: a kill between the two renames leaves the old file as `previous` and none
    as `path`, never one file under both names."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        if previous is not None and path.exists():
            os.replace(path, previous)
        os.replace(tmp, path)
    except OSError as error:
        if error.filename is None or error.filename == str(tmp):
            error.filename = str(path)  # the reader knows the target, not the temporary name
        raise
    finally:
        tmp.unlink(missing_ok=True)
    fsync_directory(path.parent)


def nearest_existing(path: str | Path) -> Path:
    """`path` or its nearest existing ancestor: where missing directories on the way would be made,
    so whether that one is a writable directory decides whether `path` can be written."""
    existing = Path(path)
    while not existing.exists():
        existing = existing.parent
    return existing


def atomic_write_text(path: str | Path, text: str) -> None:
    atomic_write(path, lambda f: f.write(text.encode()))


def fsync_directory(directory: Path) -> None:
    """Make the renames done in `directory` durable (best effort: some systems cannot open one)."""
    # a rename itself is durable only once the directory entry is flushed
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def remove_stale_temporaries(directory: str | Path) -> list[Path]:
    """Remove the temporary files (`TEMPORARY`) in `directory` whose writing process is gone (killed
    before it renamed them); those of a live process stay. Returns the removed paths."""
    removed = []
    try:
        entries = list(Path(directory).iterdir())
    except OSError:  # no such directory: nothing left behind there
        return removed
    for entry in entries:
        match = TEMPORARY.fullmatch(entry.name)
        if match is None or process_alive(int(match["pid"])) or not entry.is_file():
            continue
        try:
            entry.unlink(missing_ok=True)
        except OSError:  # not ours to remove after all (another user's): it harms nothing
            continue
        removed.append(entry)
    return removed


def process_alive(pid: int) -> bool:
    """Whether a process `pid` exists (on this machine: a temporary file names its writer's pid)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):  # none, or a number no pid can be
        return False
    except PermissionError:  # another user's process
        return True
    return True
