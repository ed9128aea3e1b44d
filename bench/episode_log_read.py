"""How long does the report's reader take on episode logs stored plain, gzip-compressed or as Parquet?

Copies the committed episode logs of RUNS (default: the reverse curriculum's runs on LavaBridge-v0 in
results/study, the logs the study report reads) into a scratch directory three ways: plain CSV,
gzip CSV as the trainer writes it (`run_files.gzip_bytes`) and, where pyarrow is installed, Parquet
(pandas). It then reads every log with the report's reader (`run_files.read_csv` through
`run_files.read_episode_log`, as `summary.curriculum_stall` does), and with pandas, timing the best
of `--repeats` passes, and prints bytes and seconds side by side.

Usage: python bench/episode_log_read.py [--runs DIR] [--repeats 3]
"""

from __future__ import annotations

import argparse
import importlib.util
import shlex
import sys
import tempfile
import time
from pathlib import Path

from lava_bridge_mj.eval.training import run_files
from lava_bridge_mj.eval.analysis.summary import EPISODE_COLUMNS
from lava_bridge_mj.eval.training.run_files import read_csv

ROOT = Path(__file__).resolve().parent.parent


def read_as_report(path: Path) -> list[dict[str, float]]:
    """An episode log as `summary.curriculum_stall` reads it (the report's only reader of episode logs)."""
    return read_csv(path, EPISODE_COLUMNS + ("start_index", "length"), run_files.read_episode_log)


def best_time(read, paths: list[Path], repeats: int) -> float:
    """The fastest of `repeats` passes reading every path."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for path in paths:
            read(path)
        best = min(best, time.perf_counter() - start)
    return best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=Path, default=ROOT / "results/study/LavaBridge-v0/reverse_ss-d500",
                        help="a directory of run directories whose episode logs are read")
    parser.add_argument("--repeats", type=int, default=3, help="passes per form; the fastest counts (default: 3)")
    args = parser.parse_args(argv)
    logs = sorted(log for log in (run_files.episode_log_file(run.parent) for run in args.runs.rglob("config.json"))
                  if log is not None)
    if not logs or args.repeats < 1:
        parser.error(f"--runs {str(args.runs)!r} holds no episode log, or --repeats {args.repeats} is below 1")
    import pandas

    parquet = importlib.util.find_spec("pyarrow") is not None
    print(f"$ python bench/episode_log_read.py {shlex.join(argv if argv is not None else sys.argv[1:])}")
    print(f"{len(logs)} episode logs under {args.runs}; best of {args.repeats} passes")
    with tempfile.TemporaryDirectory(prefix="episode-log-read-") as scratch:
        forms = {name: [] for name in ("plain", "gzip", "parquet")}
        for i, log in enumerate(logs):
            data = run_files.read_episode_log(log)
            for name, file, payload in (("plain", run_files.PLAIN_EPISODE_LOG, data),
                                        ("gzip", run_files.EPISODE_LOG, run_files.gzip_bytes(data))):
                path = Path(scratch) / str(i) / file
                path.parent.mkdir(exist_ok=True)
                path.write_bytes(payload)
                forms[name].append(path)
            if parquet:
                path = Path(scratch) / str(i) / "episodes.parquet"
                pandas.read_csv(forms["plain"][-1]).to_parquet(path, compression="zstd", index=False)
                forms["parquet"].append(path)
        print(f"{'form':<8} {'bytes':>12} {'report reader s':>16} {'pandas s':>9}")
        for name, paths in forms.items():
            if not paths:
                print(f"{name:<8} {'-':>12} {'-':>16} {'-':>9}  (pyarrow is not installed)")
                continue
            size = sum(p.stat().st_size for p in paths)
            pandas_read = pandas.read_parquet if name == "parquet" else pandas.read_csv
            report = "-" if name == "parquet" else f"{best_time(read_as_report, paths, args.repeats):.3f}"
            print(f"{name:<8} {size:>12,} {report:>16} {best_time(pandas_read, paths, args.repeats):>9.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
