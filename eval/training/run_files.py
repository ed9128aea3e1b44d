"""The files of a run directory: their names and formats, their writer's lock, and verified torch files.

A run directory holds:
    config.json         the full configuration (a resumed run must match it)
    provenance.json     per training session (the first, each resume): its steps, the code and library
                        versions that ran it, the torch device it trained on and the start strategy's
                        settings, defaults filled in
    metrics.csv         one row per evaluation (METRIC_FIELDS): steps, success from p0 and ood, returns,
                        SAC stats
    metrics.csv.sha256  its checksum (eval/training/checksums.py): readers refuse a metrics.csv changed since it
                        was written
    start_weights.npz   the start strategy's candidate states and its weights at every evaluation
    episodes.csv.gz     one row per training episode of an online method (EPISODE_FIELDS), gzip CSV
                        (`write_episode_log`; logs written before it was compressed are plain episodes.csv:
                        `episode_log_file` finds either, `read_episode_log` reads either)
    checkpoint.pt       the latest checkpoint: everything needed to continue exactly
    checkpoint.prev.pt  the one before it (a resume falls back to it when the latest is damaged); a
                        kill while the latest is replaced leaves it alone, never two names of one file
    policies/step_N.pt  the actor's weights at every evaluation (for videos and later analysis)
    final.pt            the checkpoint at the end of training
    videos/step_N.mp4   rollouts from p0 and ood at every evaluation (only with --log-videos)
    tensorboard/, wandb/  live tracking sinks (only with --log; eval/training/tracking.py)
    .lock               held by the process writing the run
The trainer, sweep and video read and write them through this module.

Checkpoints and policy snapshots are torch's zip archives, whose every record carries a CRC-32 that
torch itself never checks on load, read by torch's own zip reader, which a damaged central directory
can make return a tensor it never filled: a flipped bit would silently change a resumed run or a
video. `save_torch` adds one record to the archive, the `content_digest` of what it holds, and
`load_torch` checks every record's CRC (the standard library's `zipfile.testzip`) before loading and
that digest on what torch loaded after, so a damaged file is refused by name, never used. A file
written before digests were kept loads with its CRCs checked alone. `save_torch` serialises to
memory first, so a failing write (a full disk) surfaces as the OSError naming it rather than deep
inside torch's writer, and the file is replaced atomically.

A process killed mid-write leaves a temporary file (eval/training/atomic.py) that `remove_leftovers` clears
when the run is resumed or overwritten.
"""

from __future__ import annotations

import csv
import gzip
import io
import json
import os
import shutil
import zipfile
import zlib
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from lava_bridge_mj.eval.training.atomic import atomic_write, atomic_write_text, remove_stale_temporaries
from lava_bridge_mj.eval.training.checksums import (CHECKSUM_SUFFIX, DamagedFileError, content_digest, read_checked,
                                                    write_checked)

CHECKPOINTS = ("checkpoint.pt", "checkpoint.prev.pt")
"""The latest checkpoint and the one before it (a resume falls back to it when the latest is damaged)."""
EPISODE_LOG = "episodes.csv.gz"
"""The episode log as the trainer writes it: EPISODE_FIELDS as CSV, gzip-compressed (`gzip_bytes`)."""
PLAIN_EPISODE_LOG = "episodes.csv"
"""The same CSV uncompressed, as runs wrote it before: still read, and converted by eval/training/compress.py."""
START_WEIGHTS = "start_weights.npz"
"""The start strategy's candidate states and weights (`write_results`), a compressed .npz (`npz_bytes`)."""
NPZ_DATE = (1980, 1, 1, 0, 0, 0)
"""The date of every member of an .npz this package writes: the earliest a zip archive can hold."""
RUN_FILES = ("config.json", "provenance.json", "metrics.csv", f"metrics.csv{CHECKSUM_SUFFIX}", START_WEIGHTS,
             EPISODE_LOG, PLAIN_EPISODE_LOG, *CHECKPOINTS, "final.pt", "rollouts.mp4")
"""What a run directory holds besides policies/: what --overwrite removes."""
POLICIES = "policies"
"""policies/step_N.pt: the actor's weights at every evaluation."""
VIDEOS = "videos"
"""videos/step_N.mp4: the policy's rollouts at every evaluation, when asked for."""
RUN_FOLDERS = (POLICIES, VIDEOS, "tensorboard", "wandb")
"""The folders of a run: any non-empty one makes a run directory; --overwrite removes them."""
LOCK = ".lock"
"""Locked (flock) by the process writing the run; it holds that process's pid."""


METRIC_FIELDS = ("step", "episodes", "success_p0", "success_ood", "return_p0", "return_ood",
                 "train_return", "train_success", "q_mean", "alpha", "critic_loss", "actor_loss", "guide_horizon",
                 "wall_time")
"""metrics.csv: one row per evaluation."""
EPISODE_FIELDS = ("episode", "step", "start_index", "start_x", "start_y", "length", "success", "return")
"""The episode log's columns: the episode's number (1-based), the training step it ended at, the
candidate state it started from (-1: the env's own p0 start) and that start's position, its length,
whether it reached the goal, its return. What separates 'never tried from there' from 'tried and failed' per start."""
CHECKPOINT_VERSION = 3  # 3: optimisers in two parameter groups (seed_adam)


class RunDirectoryError(ValueError):
    """The run directory cannot be used: another run's results, or another process writing it."""


def run_files(directory: str | Path) -> list[str]:
    """The names of the run files `directory` holds (policies/ included): any one makes it a run
    directory, which nothing replaces without --overwrite."""
    directory = Path(directory)
    found = [name for name in RUN_FILES if (directory / name).exists()]
    found += [f"{name}/" for name in RUN_FOLDERS if (directory / name).is_dir() and any((directory / name).iterdir())]
    return found


def remove_run(directory: Path) -> None:
    """Delete the run files of `directory` (what --overwrite replaces) and what killed writers left."""
    for name in RUN_FILES:
        (directory / name).unlink(missing_ok=True)
    for name in RUN_FOLDERS:
        shutil.rmtree(directory / name, ignore_errors=True)
    remove_leftovers(directory)


def remove_leftovers(directory: Path) -> None:
    """Delete the temporary files that writers killed mid-write left in the run `directory` (a
    checkpoint's, metrics', a policy snapshot's, a video's), those of a live process excepted."""
    for folder in (directory, directory / POLICIES, directory / VIDEOS):
        remove_stale_temporaries(folder)


def read_config(directory: Path) -> dict[str, Any] | None:
    """The values of directory/config.json; None without one; DamagedFileError naming the file when it
    cannot be read, is not valid JSON or is not a JSON object."""
    path = Path(directory) / "config.json"
    if not path.exists():
        return None
    try:
        values = json.loads(path.read_text())
    except OSError as error:
        raise DamagedFileError(f"{path} cannot be read: {error.strerror or error}") from None
    except ValueError as error:  # invalid JSON or bytes that are no text
        raise DamagedFileError(f"{path} is not valid JSON: {error}") from None
    if not isinstance(values, dict):
        raise DamagedFileError(f"{path} does not hold a run configuration (a JSON object)")
    return values


METRIC_COLUMNS = ("step", "success_p0", "success_ood")
"""The metrics.csv columns every reader needs (of METRIC_FIELDS, which the trainer writes)."""


def read_csv(path: Path, columns: tuple[str, ...],
             read: Callable[[Path], bytes] = read_checked) -> list[dict[str, float]]:
    """The rows of a CSV file of numbers as dicts, its bytes from `read` (`read_checked`, or
    `read_episode_log` for an episode log); ValueError naming the file (and the line) when it
    cannot be read, does not match its checksum file (where it has one: eval/training/checksums.py), lacks one
    of `columns`, or holds something other than numbers."""
    try:
        with io.StringIO(read(path).decode(), newline="") as f:
            reader = csv.DictReader(f)
            missing = [name for name in columns if name not in (reader.fieldnames or ())]
            if missing:
                raise ValueError(f"{path} is not a table as the trainer writes it: no column {', '.join(missing)}")
            rows = []
            for row in reader:
                try:
                    if None in row or None in row.values():
                        raise ValueError("a row with another number of fields than the header")
                    rows.append({name: float(value) for name, value in row.items()})
                except ValueError as error:
                    raise ValueError(f"{path} line {reader.line_num}: {error}") from None
            return rows
    except OSError as error:
        raise ValueError(f"{path} cannot be read: {error.strerror or error}") from None
    except (UnicodeDecodeError, csv.Error) as error:
        raise ValueError(f"{path} is not a CSV table of numbers ({error})") from None


def read_metrics(run_dir: Path) -> list[dict[str, float]]:
    """metrics.csv of a run directory, one dict of numbers per evaluation; ValueError naming the file."""
    return read_csv(run_dir / "metrics.csv", METRIC_COLUMNS)


def write_config(directory: Path, values: dict[str, Any]) -> None:
    """config.json: the run's full configuration (RunConfig.to_dict)."""
    atomic_write_text(directory / "config.json", json.dumps(values, indent=2) + "\n")


def check_run_directory(config: Any, directory: Path, resume: bool, overwrite: bool) -> None:
    """Refuse (RunDirectoryError) a directory holding any run file unless resuming the same
    configuration (`config.continues` its config.json) or overwriting."""
    found = run_files(directory)
    folders = [name for name in RUN_FILES if (directory / name).is_dir()]
    if folders:  # nothing the trainer wrote: neither read as a run file nor removed by an overwrite
        raise RunDirectoryError(f"{directory / folders[0]} is a directory, where the run keeps a file of that name; "
                                "move it aside")
    if not found or overwrite:
        return
    if not resume:
        raise RunDirectoryError(f"{directory} already holds a run ({', '.join(found)}); resume it (--resume, or "
                                "resume=True in Python) or overwrite it (--overwrite, or overwrite=True)")
    config_file = directory / "config.json"
    if not config_file.exists():
        raise RunDirectoryError(f"{directory} holds run files ({', '.join(found)}) but no config.json, so "
                                "nothing shows they belong to this configuration; not resuming into it "
                                "(overwrite it, or choose another directory)")
    try:
        existing = read_config(directory)
    except DamagedFileError as error:
        raise RunDirectoryError(f"{error}; not resuming into it") from None
    if (existing.get("demos") == config.demos and isinstance(config.demos, str)
            and existing.get("demos_sha256") != config.demos_sha256):
        raise RunDirectoryError(f"{config.demos_source} changed since the run in {directory} began (content hash "
                                f"{config.demos_sha256}, config.json records {existing.get('demos_sha256')}); "
                                "not resuming: restore it, or train into another directory")
    if not config.continues(existing):
        steps = ("the same --steps too: its GoalDist-SS temperature schedule is spread over its budget"
                 if config.budget_tied else "--steps may change")
        raise RunDirectoryError(f"{directory} holds a run with another configuration; resume it "
                                f"with the same options ({steps}), or choose another directory")
    read_provenance(directory)  # refuse a damaged record before training changes anything


def run_status(config: Any, directory: Path) -> str:
    """'finished' (final.pt and this configuration), 'foreign' (config.json of another run, or
    unreadable) or 'todo' (nothing yet, this configuration unfinished, or finished at another budget)."""
    try:
        existing = read_config(directory)
    except DamagedFileError:
        return "foreign"
    if existing is None:
        return "todo"
    if not config.continues(existing):
        return "foreign"
    # a run finished at a smaller budget is todo: the resume extends it to this one
    return "finished" if existing == config.to_dict() and (directory / "final.pt").exists() else "todo"


def checkpoint_step(directory: Path) -> int | str | None:
    """The step of the run's latest checkpoint (the one before it where a kill left only that); None
    without one; the error text if it is unreadable."""
    path = next((directory / name for name in CHECKPOINTS if (directory / name).exists()), None)
    if path is None:
        return None
    try:
        return int(load_torch(path)["step"])
    except Exception as error:  # noqa: BLE001 - whatever it is, the trainer names it
        return f"unreadable {path}: {error}"


def read_provenance(directory: Path) -> list[dict[str, Any]]:
    """The run's earlier training sessions; none for a new run or one made before provenance was recorded."""
    path = directory / "provenance.json"
    if not path.exists():
        return []
    try:
        sessions = json.loads(path.read_text())
    except ValueError:
        sessions = None
    if not (isinstance(sessions, list) and all(isinstance(s, dict) for s in sessions)):
        raise RunDirectoryError(f"{path} is not a JSON list of training sessions; not resuming into it "
                                "(move it aside to continue without the earlier sessions' record)")
    return sessions


def check_strategy_unchanged(directory: Path, settings: dict[str, Any] | None) -> None:
    """Refuse (RunDirectoryError) to continue a run whose start strategy would change part-way: each
    setting its latest training session recorded against the value the code gives it now (defaults filled in).
    A default changed between commits would otherwise switch a resumed run to another strategy without
    a word. A setting the record lacks is one added since, whose default keeps the old behaviour
    (GoalDist-SS's `schedule`, "episodes": the only schedule before it existed)."""
    recorded = next((s["strategy"] for s in reversed(read_provenance(directory)) if s.get("strategy")), None)
    now = json.loads(json.dumps(settings or {}))  # as provenance.json holds them: tuples become lists
    keys = sorted(k for k in recorded or {} if now.get(k) != recorded[k])
    if not keys:
        return
    was = ", ".join(f"{k}={recorded[k]!r}" for k in keys)
    changed = ", ".join(f"{k}={now.get(k)!r}" for k in keys)
    raise RunDirectoryError(f"{directory} trained with start strategy settings {was} (provenance.json); this code "
                            f"would continue it with {changed}, a default changed since. Resume it with its "
                            "settings (--set strategy.KEY=VALUE, or its config's strategy section), or train it anew")


def append_provenance(directory: Path, session: dict[str, Any], resume: bool) -> None:
    """Record a training session in provenance.json (after the earlier ones when resuming)."""
    sessions = read_provenance(directory) if resume else []
    atomic_write_text(directory / "provenance.json", json.dumps([*sessions, session], indent=2) + "\n")


def write_results(directory: Path, rows: Sequence[dict], steps: np.ndarray, states: np.ndarray,
                  probabilities: np.ndarray, episode_log: Sequence[tuple] | None) -> None:
    """metrics.csv (`rows`), start_weights.npz (the candidate `states` and their `probabilities` at
    each evaluation's step) and, unless `episode_log` is None, the episode log (`write_episode_log`)."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=METRIC_FIELDS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_checked(directory / "metrics.csv", text.getvalue().encode())
    payload = npz_bytes(steps=steps, states=states, probabilities=probabilities)
    atomic_write(directory / START_WEIGHTS, lambda f: f.write(payload))
    if episode_log is not None:
        write_episode_log(directory, episode_log)


GZIP_LEVEL = 9
"""zlib's strongest level (its default, 6, leaves the study's logs 0.3% larger): an episode log shrinks
to about a sixth, and a 300,000-step run's log, a few hundred kB, still compresses in tens of
milliseconds at each evaluation (bench/episode_log_read.py measures reading)."""


def gzip_bytes(data: bytes) -> bytes:
    """`data` gzip-compressed reproducibly: a fixed level, no file name and mtime 0 in the header (and
    the standard library's fixed OS byte), so the same bytes always give the same file with one zlib."""
    buffer = io.BytesIO()
    with gzip.GzipFile(filename="", mode="wb", compresslevel=GZIP_LEVEL, fileobj=buffer, mtime=0) as f:
        f.write(data)
    return buffer.getvalue()


def npz_bytes(**arrays: np.ndarray) -> bytes:
    """`arrays` as an .npz archive that `np.load` reads, deflate-compressed and reproducible: every
    member carries a fixed date (`np.savez_compressed` stamps the current time), so the same arrays
    always give the same bytes with one zlib. Pickled objects are refused."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, array in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asanyarray(array), allow_pickle=False)
            archive.writestr(zipfile.ZipInfo(f"{name}.npy", date_time=NPZ_DATE), member.getvalue(),
                             compress_type=zipfile.ZIP_DEFLATED, compresslevel=GZIP_LEVEL)
    return buffer.getvalue()


def read_npz(path: Path | io.BytesIO) -> dict[str, np.ndarray]:
    """Every array of an .npz file, pickles refused; ValueError naming the file when it cannot be read."""
    try:
        with np.load(path) as saved:
            return {key: saved[key] for key in saved.files}
    except Exception as error:  # noqa: BLE001 - a damaged file fails in many ways (BadZipFile, EOFError, ...)
        reason = (str(error).splitlines() or [""])[0]
        raise ValueError(f"{path} is damaged ({type(error).__name__}: {reason})") from None


def same_arrays(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> bool:
    """Whether two `read_npz` results hold the same arrays: names, dtypes, shapes and bytes."""
    return sorted(a) == sorted(b) and all(a[k].dtype == b[k].dtype and a[k].shape == b[k].shape
                                          and a[k].tobytes() == b[k].tobytes() for k in a)


def episode_log_text(rows: Sequence[tuple]) -> bytes:
    """The episode log's CSV: the EPISODE_FIELDS header, then one line per row."""
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(EPISODE_FIELDS)
    writer.writerows(rows)
    return text.getvalue().encode()


def write_episode_log(directory: Path, rows: Sequence[tuple]) -> None:
    """The episode log `rows` as episodes.csv.gz, replaced atomically (the trainer rewrites the whole log
    at every evaluation). A plain episodes.csv left by earlier code goes once the compressed log is
    whole: a kill in between leaves both, and readers take the compressed one."""
    payload = gzip_bytes(episode_log_text(rows))
    atomic_write(directory / EPISODE_LOG, lambda f: f.write(payload))
    (directory / PLAIN_EPISODE_LOG).unlink(missing_ok=True)


def episode_log_file(run_dir: Path) -> Path | None:
    """The run's episode log: episodes.csv.gz, else a plain episodes.csv, else None (offline methods and
    runs from before episodes were logged have none)."""
    for name in (EPISODE_LOG, PLAIN_EPISODE_LOG):
        if (Path(run_dir) / name).is_file():
            return Path(run_dir) / name
    return None


def read_episode_log(path: Path) -> bytes:
    """The CSV bytes of an episode log file, compressed (.gz) or plain; ValueError naming the file when
    its compressed form is damaged (truncated, a flipped bit: gzip checks its CRC-32 and length)."""
    data = Path(path).read_bytes()
    if Path(path).suffix != ".gz":
        return data
    try:
        return gzip.decompress(data)
    except (OSError, EOFError, zlib.error) as error:
        raise ValueError(f"{path} is not a whole gzip file ({error}); restore it from its run") from None


def save_checkpoint(directory: Path, state: dict, name: str = CHECKPOINTS[0]) -> None:
    """Write `state` atomically; the checkpoint it replaces becomes checkpoint.prev.pt once the new one
    is complete (a kill in between leaves it there and no checkpoint.pt: a resume continues from it)."""
    save_torch(directory / name, state, previous=directory / CHECKPOINTS[1] if name == CHECKPOINTS[0] else None)


def read_checkpoint(path: Path, config: Any) -> dict:
    """A checkpoint's state; DamagedFileError when the file is damaged or not a checkpoint (a resume
    then falls back to the other one), ValueError when it belongs to another configuration (one that
    `config.continues` refuses) or format."""
    state = load_torch(path)
    if not isinstance(state, dict) or not {"version", "config", "step"} <= state.keys():
        raise DamagedFileError(f"{path} is not a lava-bridge-mj checkpoint")
    if state["version"] != CHECKPOINT_VERSION:
        raise ValueError(f"checkpoint {path} has format version {state['version']!r} and this lava-bridge-mj "
                         f"reads version {CHECKPOINT_VERSION}: continue it with the version that wrote it, "
                         "or start a new run directory")
    if not config.continues(state["config"]):
        raise ValueError(f"checkpoint {path} was written with another configuration; "
                         "resume with the same options (--steps may change) or start a new run directory")
    return state


DIGEST_RECORD = "lava_bridge_mj_content.sha256"
"""The record, beside torch's own in its archive folder, holding the `content_digest` of the saved object."""


def save_torch(path: str | Path, obj: Any, previous: str | Path | None = None) -> None:
    """torch.save `obj` to `path` atomically, with its content digest (OSError names the file when the
    write fails). With `previous`, the file `path` held moves there once the new one is complete."""
    import torch  # on use: readers of metrics and configs never load torch

    buffer = io.BytesIO()
    torch.save(obj, buffer)
    with zipfile.ZipFile(buffer, "a") as archive:  # torch reads only the records it wrote
        folder = archive.namelist()[0].split("/")[0]
        archive.writestr(f"{folder}/{DIGEST_RECORD}", content_digest(obj))
    payload = buffer.getvalue()
    atomic_write(path, lambda f: f.write(payload), previous=previous)


def load_torch(path: str | Path, *, weights_only: bool = False) -> Any:
    """torch.load `path` after checking the CRC of every record of its zip archive, then the content
    digest of what torch loaded (where the file has one); DamagedFileError naming the file when it is
    truncated, bit-flipped, not a torch file or not a file at all. FileNotFoundError as usual."""
    import torch

    path = Path(path)
    if path.is_dir():
        raise DamagedFileError(f"{path} is a directory, not a torch file")
    try:
        payload = path.read_bytes()
    except FileNotFoundError:
        raise
    except OSError as error:  # unreadable (permissions, an I/O error): unusable all the same
        raise DamagedFileError(f"{path} cannot be read: {error.strerror or error}") from None
    try:
        with zipfile.ZipFile(io.BytesIO(payload)) as archive:
            bad = archive.testzip()
            digest = next((archive.read(name).decode() for name in archive.namelist()
                           if name.partition("/")[2] == DIGEST_RECORD), None)
    except Exception as error:  # noqa: BLE001 - BadZipFile, NotImplementedError, zlib.error, ...
        raise DamagedFileError(f"{path} is damaged or not a torch file ({_one_line(error)})") from None
    if bad is not None:
        raise DamagedFileError(f"{path} is damaged: its record {bad!r} fails its CRC check")
    try:
        # onto the CPU whatever device a tensor was saved from: every file loads on a machine without CUDA
        obj = torch.load(io.BytesIO(payload), weights_only=weights_only, map_location="cpu")
        loaded = content_digest(obj) if digest is not None else None
    except Exception as error:  # noqa: BLE001 - a damaged archive can fail inside torch in many ways
        raise DamagedFileError(f"{path} cannot be read ({_one_line(error)})") from None
    if loaded != digest:
        raise DamagedFileError(f"{path} is damaged: what torch loaded from it differs from what was saved "
                               "(its content digest does not match)")
    return obj


def _one_line(error: BaseException) -> str:
    """`error`'s type (zlib.error, not error) and the first line of its message."""
    kind = type(error).__qualname__ if type(error).__module__ == "builtins" else \
        f"{type(error).__module__}.{type(error).__qualname__}"
    return f"{kind}: {(str(error).strip().splitlines() or [''])[0]}"


@contextmanager
def locked(directory: Path):
    """Hold an exclusive lock on directory/.lock: two processes never write one run directory."""
    import fcntl  # POSIX only: imported where a lock is taken, so reading runs works anywhere

    path = Path(directory) / LOCK
    try:  # the first write to a run directory: where a full disk fails first
        lock = open(path, "a+b", buffering=0)  # unbuffered: a failed write is not retried on close
    except OSError as error:
        raise _naming(error, path) from None
    with lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.seek(0)
            holder = lock.read().decode(errors="replace").strip()
            raise RunDirectoryError(f"{directory} is being written by another process "
                                    f"(pid {holder or '?'}); not starting a second writer") from None
        try:
            lock.truncate(0)
            pid = str(os.getpid()).encode()
            while pid:
                pid = pid[lock.write(pid):]
        except OSError as error:  # closing the file releases the lock
            raise _naming(error, path) from None
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _naming(error: OSError, path: Path) -> OSError:
    """`error`, naming `path` if it named no file."""
    if error.filename is None:
        error.filename = str(path)
    return error


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
