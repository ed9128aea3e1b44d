"""Crash-safe file writes: write a temporary file beside the target, flush, fsync, rename.

A reader (or a resumed run) sees either the old complete file or the new complete file, never a
half-written one, whatever moment the process is killed at.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import IO, Callable


def atomic_write(path: str | Path, write: Callable[[IO[bytes]], None]) -> None:
    """Call `write(f)` on a temporary binary file, then atomically move it to `path`. An OSError
    (disk full, read-only directory, ...) names `path` in its `filename` if it named no file."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
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
