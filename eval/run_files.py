"""The files of a run directory: which names make one, its writer's lock, and verified torch files.

Checkpoints and policy snapshots are torch's zip archives, whose every record carries a CRC-32 that
torch itself never checks on load: a flipped bit would silently change a resumed run or a video.
`load_torch` checks every record's CRC (the standard library's `zipfile.testzip`) before loading,
so a damaged file is refused by name, never used. `save_torch` serialises to memory first, so a
failing write (a full disk) surfaces as the OSError naming it rather than deep inside torch's
writer, and the file is replaced atomically.
"""

from __future__ import annotations

import io
import os
import zipfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import torch

from lava_bridge_mj.eval.atomic import atomic_write

CHECKPOINTS = ("checkpoint.pt", "checkpoint.prev.pt")
"""The latest checkpoint and the one before it (a resume falls back to it when the latest is damaged)."""
RUN_FILES = ("config.json", "provenance.json", "metrics.csv", "start_weights.npz", "episodes.csv", *CHECKPOINTS,
             "final.pt", "rollouts.mp4")
"""What a run directory holds besides policies/: what --overwrite removes."""
POLICIES = "policies"
LOCK = ".lock"
"""Locked (flock) by the process writing the run; it holds that process's pid."""


class RunDirectoryError(ValueError):
    """The run directory cannot be used: another run's results, or another process writing it."""


class DamagedFileError(ValueError):
    """A run file exists but cannot be used: truncated, bit-flipped or not what it should be."""


def run_files(directory: str | Path) -> list[str]:
    """The names of the run files `directory` holds (policies/ included): any one makes it a run
    directory, which nothing replaces without --overwrite."""
    directory = Path(directory)
    found = [name for name in RUN_FILES if (directory / name).exists()]
    policies = directory / POLICIES
    if policies.is_dir() and any(policies.iterdir()):
        found.append(f"{POLICIES}/")
    return found


def save_torch(path: str | Path, obj: Any) -> None:
    """torch.save `obj` to `path` atomically (OSError names the file when the write fails)."""
    buffer = io.BytesIO()
    torch.save(obj, buffer)
    payload = buffer.getvalue()
    atomic_write(path, lambda f: f.write(payload))


def load_torch(path: str | Path, *, weights_only: bool = False) -> Any:
    """torch.load `path` after checking the CRC of every record of its zip archive; DamagedFileError
    naming the file when it is truncated, bit-flipped or not a torch file. FileNotFoundError as usual."""
    path = Path(path)
    payload = path.read_bytes()
    try:
        with zipfile.ZipFile(io.BytesIO(payload)) as archive:
            bad = archive.testzip()
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as error:
        raise DamagedFileError(f"{path} is damaged or not a torch file ({error})") from None
    if bad is not None:
        raise DamagedFileError(f"{path} is damaged: its record {bad!r} fails its CRC check")
    try:
        return torch.load(io.BytesIO(payload), weights_only=weights_only)
    except Exception as error:  # noqa: BLE001 - a damaged archive can fail inside torch in many ways
        raise DamagedFileError(f"{path} cannot be read ({type(error).__name__}: {error})") from None


@contextmanager
def locked(directory: Path):
    """Hold an exclusive lock on directory/.lock: two processes never write one run directory."""
    import fcntl  # POSIX only: imported where a lock is taken, so reading runs works anywhere

    with open(Path(directory) / LOCK, "a+") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.seek(0)
            raise RunDirectoryError(f"{directory} is being written by another process "
                                    f"(pid {lock.read().strip() or '?'}); not starting a second writer") from None
        lock.truncate(0)
        lock.write(str(os.getpid()))
        lock.flush()
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def lock_holder(directory: Path) -> str | None:
    """The pid (as `locked` recorded it, or '?') of the process holding `directory`'s lock; None when
    no process holds it. Only tests the lock (a shared one, released at once); creates nothing."""
    import fcntl

    try:
        lock = open(Path(directory) / LOCK)
    except OSError:  # no lock file (nothing ever trained there) or unreadable: the trainer decides
        return None
    with lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return lock.read().strip() or "?"
        except OSError:
            return None
        fcntl.flock(lock, fcntl.LOCK_UN)
    return None
