"""`python -m lava_bridge_mj.eval.training.compress DIR [DIR ...]`: plain episode logs compressed in place.

Every episodes.csv under each DIR (at any depth) becomes episodes.csv.gz, the form the trainer now
writes (`run_files.write_episode_log`: deterministic gzip, so a log converted here has the same bytes
as one the trainer wrote with the same rows). Nothing is lost: the compressed file is checked to
decompress to exactly the bytes it replaces, once in memory and once as written to disk, before the
plain one is deleted; a log that fails a check is left as it was, named, and the command exits 1.
Running it again converts nothing more (a log killed between the two steps, compressed but with its
plain file still there, is finished: the plain file goes once the compressed one is checked against it).

    python -m lava_bridge_mj.eval.training.compress results/study/LavaBridge-v0     # or: make compress-results
"""

from __future__ import annotations

import argparse
import gzip
import sys
from dataclasses import dataclass, field
from pathlib import Path

from lava_bridge_mj.eval.training.atomic import atomic_write
from lava_bridge_mj.eval.training.run_files import EPISODE_LOG, PLAIN_EPISODE_LOG, gzip_bytes, read_episode_log


@dataclass
class Compressed:
    """What `compress` did: the logs converted, their bytes before and after, and those it refused."""
    converted: int = 0
    plain_bytes: int = 0
    compressed_bytes: int = 0
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
    done.converted += 1
    done.plain_bytes += len(data)
    done.compressed_bytes += target.stat().st_size
    plain.unlink()


def compress(directories: list[Path]) -> Compressed:
    """Convert every plain episode log under `directories`, in sorted order."""
    done = Compressed()
    for directory in directories:
        for plain in sorted(directory.rglob(PLAIN_EPISODE_LOG)):
            if plain.is_file():
                compress_log(plain, done)
    return done


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lava_bridge_mj.eval.training.compress", description=__doc__.splitlines()[0],
                                     epilog="exits 1 when a log was refused, 2 on bad arguments")
    parser.add_argument("directories", nargs="+", type=Path, metavar="DIR",
                        help="a directory of run directories (any depth), e.g. results/study/LavaBridge-v0")
    args = parser.parse_args(argv)
    for directory in args.directories:
        if not directory.is_dir():
            parser.error(f"DIR {str(directory)!r} is not a directory")
    try:
        done = compress(args.directories)
    except OSError as error:  # a full disk, a read-only tree: the log being converted is left plain
        print(f"{parser.prog}: error: {error}", file=sys.stderr)
        return 1
    for refusal in done.refused:
        print(f"refused: {refusal}", file=sys.stderr)
    ratio = f" ({done.compressed_bytes / done.plain_bytes:.1%})" if done.plain_bytes else ""
    print(f"compressed {done.converted} episode logs: {done.plain_bytes:,} bytes -> {done.compressed_bytes:,}{ratio}; "
          f"{len(done.refused)} refused")
    return 1 if done.refused else 0


if __name__ == "__main__":
    sys.exit(main())
