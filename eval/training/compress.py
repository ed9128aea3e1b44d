"""`python -m lava_bridge_mj.eval.training.compress DIR [DIR ...]`: run files compressed in place.

Under each DIR (at any depth), every plain episodes.csv becomes episodes.csv.gz and every
start_weights.npz not already in it takes the form the trainer now writes (`run_files.gzip_bytes`,
`run_files.npz_bytes`: compressed, with reproducible bytes, so a file converted here has the same bytes
as one the trainer wrote with the same contents). Nothing is lost: a converted log is checked to
decompress to exactly the bytes it replaces, and converted weights to hold the same arrays (names,
dtypes, shapes, bytes), once in memory and once as written to disk, before the old file goes; a file
that fails a check is left as it was, named, and the command exits 1. Running it again converts nothing
more (a log killed between the two steps, compressed but with its plain file still there, is finished:
the plain file goes once the compressed one is checked against it).

    python -m lava_bridge_mj.eval.training.compress results/study/LavaBridge-v0     # or: make compress-results

With `--keep-logs-of METHODS`, the episode logs of runs of any other method (config.json's `method`)
are deleted instead: a folder of results keeps the logs its reports read and no others (the study
keeps reverse_ss's, whose curriculum tables the report draws from them). A run's log is rewritten
bit for bit by running the run again with its config.json on the same kind of processor.

    python -m lava_bridge_mj.eval.training.compress results/study --keep-logs-of reverse_ss
"""

from __future__ import annotations

import argparse
import gzip
import io
import sys
from dataclasses import dataclass, field
from pathlib import Path

from lava_bridge_mj.agents.methods import METHODS
from lava_bridge_mj.eval.training.atomic import atomic_write
from lava_bridge_mj.eval.training.run_files import (EPISODE_LOG, PLAIN_EPISODE_LOG, START_WEIGHTS, gzip_bytes,
                                                    npz_bytes, read_config, read_episode_log, read_npz,
                                                    same_arrays)


@dataclass
class Converted:
    """Files of one kind converted, and their bytes before and after."""
    files: int = 0
    bytes_before: int = 0
    bytes_after: int = 0

    def add(self, before: int, after: int) -> None:
        self.files += 1
        self.bytes_before += before
        self.bytes_after += after

    def __str__(self) -> str:
        ratio = f" ({self.bytes_after / self.bytes_before:.1%})" if self.bytes_before else ""
        return f"{self.bytes_before:,} bytes -> {self.bytes_after:,}{ratio}"


@dataclass
class Compressed:
    """What `compress` did: the episode logs and start weights converted, the logs deleted, and the files it
    refused."""
    logs: Converted = field(default_factory=Converted)
    weights: Converted = field(default_factory=Converted)
    deleted: Converted = field(default_factory=Converted)
    refused: list[str] = field(default_factory=list)


def compress_log(plain: Path, done: Compressed) -> None:
    """Replace `plain` (an episodes.csv) by its episodes.csv.gz, checked; or refuse, leaving `plain`."""
    data = plain.read_bytes()
    target = plain.with_name(EPISODE_LOG)
    if target.exists():  # an earlier conversion killed before deleting the plain file, or a run's newer log
        try:
            same = read_episode_log(target) == data
        except ValueError:
            same = False
        if not same:
            done.refused.append(f"{plain}: {target.name} beside it holds other rows; keeping both (delete the "
                                "stale one by hand: a run's trainer writes only the compressed one)")
            return
    else:
        payload = gzip_bytes(data)
        if gzip.decompress(payload) != data:
            done.refused.append(f"{plain}: its compressed form does not decompress to the same bytes; left plain")
            return
        atomic_write(target, lambda f: f.write(payload))
        try:
            same = read_episode_log(target) == data  # what reached the disk
        except ValueError:
            same = False
        if not same:
            target.unlink()
            done.refused.append(f"{plain}: {target.name} as written does not read back the same bytes; left plain")
            return
    done.logs.add(len(data), target.stat().st_size)
    plain.unlink()


def compress_weights(path: Path, done: Compressed) -> None:
    """Rewrite `path` (a start_weights.npz) as `npz_bytes` of its arrays, checked; or refuse, leaving it."""
    data = path.read_bytes()
    try:
        arrays = read_npz(path)
    except ValueError as error:
        done.refused.append(f"{error}; left as it is")
        return
    payload = npz_bytes(**arrays)
    if payload == data:  # already in the trainer's form
        return
    if not same_arrays(read_npz(io.BytesIO(payload)), arrays):
        done.refused.append(f"{path}: its compressed form does not hold the same arrays; left as it is")
        return
    atomic_write(path, lambda f: f.write(payload))
    try:
        same = same_arrays(read_npz(path), arrays)  # what reached the disk
    except ValueError:
        same = False
    if not same:
        atomic_write(path, lambda f: f.write(data))
        done.refused.append(f"{path}: as written it does not read back the same arrays; restored as it was")
        return
    done.weights.add(len(data), len(payload))


def keeps_log(run_dir: Path, keep_logs_of: frozenset[str] | None, done: Compressed) -> bool:
    """Whether the episode log of `run_dir` stays: always without `keep_logs_of`, else when the run's method
    is one of them. A run whose method cannot be read keeps its log and is named in `done.refused`."""
    if keep_logs_of is None:
        return True
    try:
        config = read_config(run_dir)
    except ValueError as error:  # damaged: the run cannot say what it is
        done.refused.append(f"{error}; its episode log is kept")
        return True
    method = config.get("method") if config else None
    if not isinstance(method, str):
        done.refused.append(f"{run_dir}: no config.json naming its method; its episode log is kept")
        return True
    return method in keep_logs_of


def delete_logs(run_dir: Path, done: Compressed) -> None:
    """Delete the run's episode log, compressed and plain."""
    for log in (run_dir / EPISODE_LOG, run_dir / PLAIN_EPISODE_LOG):
        if log.is_file():
            done.deleted.add(log.stat().st_size, 0)
            log.unlink()


def compress(directories: list[Path], keep_logs_of: frozenset[str] | None = None) -> Compressed:
    """Convert every plain episode log and every start_weights.npz not yet in the trainer's form under
    `directories`, in sorted order; with `keep_logs_of`, delete the episode logs of runs of other methods."""
    done = Compressed()
    for directory in directories:
        logs = {log.parent for name in (PLAIN_EPISODE_LOG, EPISODE_LOG) for log in directory.rglob(name) if log.is_file()}
        for run_dir in sorted(logs):
            if not keeps_log(run_dir, keep_logs_of, done):
                delete_logs(run_dir, done)
            elif (run_dir / PLAIN_EPISODE_LOG).is_file():
                compress_log(run_dir / PLAIN_EPISODE_LOG, done)
        for weights in sorted(directory.rglob(START_WEIGHTS)):
            if weights.is_file():
                compress_weights(weights, done)
    return done


def methods(text: str) -> frozenset[str]:
    """--keep-logs-of's value: known method names only, so that a misspelt one never deletes every log."""
    names = frozenset(text.split(","))
    unknown = sorted(names - set(METHODS))
    if unknown:
        raise argparse.ArgumentTypeError(f"unknown method(s) {', '.join(map(repr, unknown))}; expected some of "
                                         f"{', '.join(METHODS)}")
    return names


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lava_bridge_mj.eval.training.compress", description=__doc__.splitlines()[0],
                                     epilog="exits 1 when a file was refused, 2 on bad arguments")
    parser.add_argument("directories", nargs="+", type=Path, metavar="DIR",
                        help="a directory of run directories (any depth), e.g. results/study/LavaBridge-v0")
    parser.add_argument("--keep-logs-of", metavar="METHODS", type=methods,
                        help="comma-separated methods (e.g. reverse_ss): delete the episode logs of every other "
                             "method's runs")
    args = parser.parse_args(argv)
    for directory in args.directories:
        if not directory.is_dir():
            parser.error(f"DIR {str(directory)!r} is not a directory")
    try:
        done = compress(args.directories, args.keep_logs_of)
    except OSError as error:  # a full disk, a read-only tree: the file being converted is left as it was
        print(f"{parser.prog}: error: {error}", file=sys.stderr)
        return 1
    for refusal in done.refused:
        print(f"refused: {refusal}", file=sys.stderr)
    deleted = f"; deleted {done.deleted.files} episode logs ({done.deleted.bytes_before:,} bytes)" \
        if args.keep_logs_of is not None else ""
    print(f"compressed {done.logs.files} episode logs: {done.logs}; {done.weights.files} start weights: "
          f"{done.weights}{deleted}; {len(done.refused)} refused")
    return 1 if done.refused else 0


if __name__ == "__main__":
    sys.exit(main())
