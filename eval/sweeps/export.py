"""`lava-bridge-bench export RUNS RESULTS`: compact copies of finished runs, for committing to results/.

A compact copy holds what `report`, `summary` and the findings read (config.json, provenance.json,
metrics.csv with its checksum file metrics.csv.sha256, episodes.csv.gz, start_weights.npz) and none of the
checkpoints, policies or videos: a few hundred kB per run instead of several MB. A run's metrics.csv is
verified against its checksum file (eval/training/checksums.py) before it is copied. Every run directory under
RUNS, at any depth, lands at the same relative path under RESULTS, so
`runs/study/TASK/METHOD-d500/seed7` becomes `RESULTS/TASK/METHOD-d500/seed7`.

Only finished runs are exported (final.pt written and the last evaluation at config.json's `steps`):
a run still training or stopped part-way would put half a learning curve beside whole ones. The others
are listed with how far they got; `--unfinished` exports them too (a seed that diverged and stopped
is a result). A copy replaces an earlier copy of the same run at a smaller budget (the run was
extended since); a target holding another configuration, or the same run at a larger budget, is
refused and nothing of that run is written, and so is a run whose files are damaged or changed since
it wrote them. Each file is replaced atomically and config.json last, so an export killed part-way
leaves whole files that a rerun completes (a copy's old checksum file goes first and its new one after
its metrics.csv: in between, the copy reads as unverified, never as changed).

    lava-bridge-bench export runs/study results/study
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

from lava_bridge_mj.eval.training.atomic import atomic_write, nearest_existing
from lava_bridge_mj.eval.training.checksums import checksum_file
from lava_bridge_mj.eval.training.config import RunConfig
from lava_bridge_mj.eval.training.run_files import (EPISODE_LOG, PLAIN_EPISODE_LOG, DamagedFileError, episode_log_file,
                                                    gzip_bytes, read_config, read_metrics)

CHECKSUMS = checksum_file("metrics.csv").name
COMPACT_FILES = ("provenance.json", "metrics.csv", EPISODE_LOG, "start_weights.npz", CHECKSUMS, "config.json")
"""The files a compact copy holds, in the order they are written: metrics.csv's checksum file after it,
config.json last. The episode log always compressed, whichever form the run holds."""


@dataclass
class Export:
    """What an export did: run directories (relative to RUNS) per outcome, with the reason for the last two."""

    exported: list[str]
    unchanged: list[str]
    unfinished: list[str]
    refused: list[str]


def progress(source: Path, config: dict) -> tuple[bool, float]:
    """(finished, the step of the last evaluation) of the run in `source`."""
    rows = read_metrics(source)
    last = rows[-1]["step"] if rows else 0.0
    return (source / "final.pt").is_file() and last == config.get("steps"), last


def refusal(target: Path, config: dict, source: Path) -> str | None:
    """Why the copy in `target` must not be replaced by a copy of the run in `source` (its `config`);
    None if it may."""
    try:
        existing = read_config(target)
    except DamagedFileError as error:
        return f"{error}; move it aside"
    if existing is None:
        return None
    if not RunConfig.from_dict(config, source=str(source / "config.json")).continues(existing):
        return f"{target} holds a run of another configuration"
    if existing.get("steps", 0) > config["steps"]:
        return f"{target} holds this run at a larger budget ({existing['steps']:,} steps, here {config['steps']:,})"
    return None


def export(runs: Path, results: Path, unfinished: bool = False) -> Export:
    """Copy the compact files of every run under `runs` to the same place under `results` (module doc)."""
    done = Export([], [], [], [])
    for config_file in sorted(runs.rglob("config.json")):
        source = config_file.parent
        if not (source / "metrics.csv").is_file():
            continue
        name = str(source.relative_to(runs))
        try:
            config = read_config(source)
            finished, last = progress(source, config)  # metrics.csv verified against its checksum file
        except DamagedFileError as error:
            done.refused.append(f"{name}: {error}")
            continue
        if not finished:
            done.unfinished.append(f"{name} (last evaluation at step {last:,.0f} of {config.get('steps', 0):,})")
            if not unfinished:
                continue
        target = results / source.relative_to(runs)
        why = refusal(target, config, source)
        if why is not None:
            done.refused.append(f"{name}: {why}")
            continue
        contents = {f: (source / f).read_bytes() for f in COMPACT_FILES if (source / f).is_file()}
        log = episode_log_file(source)
        if log is not None and log.name == PLAIN_EPISODE_LOG:  # a run from before logs were compressed
            contents[EPISODE_LOG] = gzip_bytes(log.read_bytes())
            contents = {f: contents[f] for f in COMPACT_FILES if f in contents}  # the writing order
        changed = {f: data for f, data in contents.items()
                   if not ((target / f).is_file() and (target / f).read_bytes() == data)}
        stale = CHECKSUMS in changed or (CHECKSUMS not in contents and (target / CHECKSUMS).exists())
        plain = target / PLAIN_EPISODE_LOG  # an earlier copy's uncompressed log, replaced by the compressed one
        if not changed and not stale and not (EPISODE_LOG in contents and plain.exists()):
            done.unchanged.append(name)
            continue
        blocked = nearest_existing(target)
        if not blocked.is_dir():
            done.refused.append(f"{name}: cannot make the copy's directory {target}: {blocked} is a file; "
                                "move it aside")
            continue
        target.mkdir(parents=True, exist_ok=True)
        if stale:  # first: until the new one is written, the copy's metrics.csv reads as unverified
            (target / CHECKSUMS).unlink(missing_ok=True)
        for file, data in changed.items():  # in COMPACT_FILES order: config.json last
            atomic_write(target / file, lambda f, data=data: f.write(data))
        if EPISODE_LOG in contents:
            plain.unlink(missing_ok=True)
        done.exported.append(name)
    return done


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="lava-bridge-bench export", description=__doc__.splitlines()[0],
                                     epilog="exits 1 when a run was refused, 2 on bad arguments")
    parser.add_argument("runs", type=Path, help="a directory of run directories (any depth), e.g. runs/study")
    parser.add_argument("results", type=Path, help="where the compact copies go, e.g. results/study")
    parser.add_argument("--unfinished", action="store_true",
                        help="also export runs that have not finished (diverged or stopped seeds)")
    args = parser.parse_args(argv)
    if not args.runs.is_dir():
        parser.error(f"RUNS {str(args.runs)!r} is not a directory")
    if args.results.exists() and not args.results.is_dir():
        parser.error(f"RESULTS {str(args.results)!r} exists and is not a directory")
    runs, results = args.runs.resolve(), args.results.resolve()
    if results == runs or results.is_relative_to(runs):
        parser.error(f"RESULTS {str(args.results)!r} lies inside RUNS {str(args.runs)!r}: the copies would be "
                     "exported again; choose a directory outside it")
    try:
        done = export(args.runs, args.results, args.unfinished)
    except ValueError as error:  # an unreadable config.json or metrics.csv names its file
        print(f"{parser.prog}: error: {error}", file=sys.stderr)
        return 2
    except OSError as error:  # a full disk, a directory that turned read-only, ...
        print(f"{parser.prog}: error: {error.filename or args.results}: {error.strerror or error}; the files "
              "copied so far are whole: fix that and export again to complete the copies", file=sys.stderr)
        return 2
    print(f"exported {len(done.exported)} run(s) to {args.results}, {len(done.unchanged)} unchanged")
    for title, lines in (("not finished" + ("" if args.unfinished else ", not exported"), done.unfinished),
                         ("refused, nothing written", done.refused)):
        if lines:
            print(f"{title}:", *(f"  {line}" for line in lines), sep="\n")
    return 1 if done.refused else 0


if __name__ == "__main__":
    sys.exit(main())
