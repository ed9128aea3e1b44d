"""What lava-bridge-bench's commands share (training, sweep, report, video): argument types with
one-line usage errors (integers, seeds, seed lists, devices, thread counts), --config files and --set
values, output paths, and SIGINT / SIGTERM turned into one exception that says which signal came.
Light: no training code is imported."""

from __future__ import annotations

import argparse
import json
import os
import signal
import threading
from collections import Counter
from collections.abc import Sequence
from contextlib import contextmanager
from pathlib import Path

from lava_bridge_mj.eval.training.atomic import nearest_existing
from lava_bridge_mj.demos import MINARI_PREFIX
from lava_bridge_mj.eval.training.config import MAX_SEED


def int_at_least(minimum: int, what: str, maximum: int | None = None):
    """An argparse type: an integer >= minimum (and <= maximum), or a usage error naming the value."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if value < minimum or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"expected {what}, got {value}")
        return value
    return parse


positive_int = int_at_least(1, "a positive integer")


def two_looks(text: str) -> tuple[int, int]:
    """An argparse type: 'FIRST,SECOND', the seeds per group of a study's two readings, 0 < FIRST < SECOND."""
    parts = text.split(",")
    if len(parts) != 2 or not all(part.strip().isdigit() for part in parts):
        raise argparse.ArgumentTypeError(f"expected two seed counts FIRST,SECOND such as 20,49, got {text!r}")
    first, second = (int(part) for part in parts)
    if not 0 < first < second:
        raise argparse.ArgumentTypeError(f"expected 0 < FIRST < SECOND seeds per group, got {first},{second}")
    return first, second
seed = int_at_least(0, f"an integer seed in [0, {MAX_SEED}]", MAX_SEED)


def device(text: str) -> str:
    """An argparse type: the torch device to train on, "cpu" or a CUDA device this machine has ("cuda",
    "cuda:N"); anything else is a usage error naming what is available. torch is loaded only to
    check a CUDA device."""
    kind, colon, index = text.strip().partition(":")
    if kind == "cpu" and not colon:
        return "cpu"
    if kind != "cuda" or (colon and not index.isdigit()):
        raise argparse.ArgumentTypeError(f"expected cpu, cuda or cuda:N, got {text!r}")
    import torch

    if not torch.cuda.is_available():
        raise argparse.ArgumentTypeError(f"{text.strip()} requested but torch.cuda.is_available() is False; "
                                         "use --device cpu")
    count = torch.cuda.device_count()
    if colon and int(index) >= count:
        raise argparse.ArgumentTypeError(f"{text.strip()} requested but this machine has {count} CUDA device(s), "
                                         f"cuda:0 to cuda:{count - 1}")
    return text.strip()


MAX_SEEDS = 1000
"""Most seeds one --seeds list may name: a typo such as 0-99999999 is refused instead of planning for hours."""


def parse_seeds(text: str) -> list[int]:
    """'0-24', '3', '0,2,5-7' -> a list of distinct non-negative seeds, in the order given."""
    seeds: list[int] = []
    for part in text.split(","):
        low, dash, high = part.strip().partition("-")
        try:
            first, last = int(low), int(high if dash else low)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected seeds like 0-24 or 0,3,5-7, got {text!r}") from None
        if first < 0 or last < first or last > MAX_SEED:
            raise argparse.ArgumentTypeError(f"expected a range of seeds low-high in [0, {MAX_SEED}], got {part.strip()!r}")
        seeds.extend(range(first, last + 1))
    repeated = sorted(s for s, n in Counter(seeds).items() if n > 1)
    if repeated:
        raise argparse.ArgumentTypeError(f"seeds must be distinct; repeated: {repeated}")
    return seeds


def seed_list(text: str) -> list[int]:
    """An argparse type: parse_seeds' list ('0-24', '0,3,5-7'), refused beyond MAX_SEEDS seeds before
    it is built."""
    count = 0
    for part in text.split(","):
        low, dash, high = part.strip().partition("-")
        try:
            count += int(high) - int(low) + 1 if dash else 1
        except ValueError:
            break  # parse_seeds names the malformed part
    if count > MAX_SEEDS:
        raise argparse.ArgumentTypeError(f"expected at most {MAX_SEEDS:,} seeds, got {count:,} in {text!r}")
    return parse_seeds(text)


def format_seeds(seeds: Sequence[int]) -> str:
    """[0, 1, 2, 5] -> '0-2,5', the inverse of parse_seeds."""
    parts, start = [], 0
    for i in range(1, len(seeds) + 1):
        if i == len(seeds) or seeds[i] != seeds[i - 1] + 1:
            first, last = seeds[start], seeds[i - 1]
            parts.append(str(first) if first == last else f"{first}-{last}")
            start = i
    return ",".join(parts)


MAX_JSON_DEPTH = 32
"""Most levels of JSON arrays and objects a --config file or a --set value may nest: a RunConfig nests
four at most (the config, env, its decoys, each decoy), and far deeper JSON overflows Python's recursion
in the parser or later."""


def nesting_depth(value: object) -> int:
    """How many levels of lists and dicts `value` nests (0 for a number or a string), counted level by
    level without recursion, so any depth can be measured."""
    depth, level = 0, [value]
    while True:
        containers = [item for item in level if isinstance(item, (dict, list))]
        if not containers:
            return depth
        depth += 1
        level = [child for item in containers for child in (item.values() if isinstance(item, dict) else item)]


class NestedTooDeep(ValueError):
    """JSON that nests arrays and objects deeper than MAX_JSON_DEPTH levels."""

    def __init__(self):
        super().__init__(f"it nests arrays and objects more than {MAX_JSON_DEPTH} levels deep (a RunConfig "
                         "needs four at most)")


def load_json(text: str) -> object:
    """`text` parsed as JSON; ValueError if it is not JSON, NestedTooDeep if it nests deeper than
    MAX_JSON_DEPTH levels."""
    try:
        value = json.loads(text)
    except RecursionError:  # the parser's own limit, far beyond MAX_JSON_DEPTH
        raise NestedTooDeep from None
    if nesting_depth(value) > MAX_JSON_DEPTH:
        raise NestedTooDeep
    return value


def read_config_file(path: Path | None, parser: argparse.ArgumentParser) -> dict:
    """The RunConfig fields of a --config JSON file ({} without one); a usage error if it is unreadable."""
    if path is None:
        return {}
    try:
        values = load_json(path.read_text())
    except OSError as error:
        parser.error(f"--config {path} cannot be read: {error.strerror}")
    except NestedTooDeep as error:
        parser.error(f"--config {path}: {error}")
    except ValueError as error:
        parser.error(f"--config {path} is not valid JSON: {error}")
    if not isinstance(values, dict):
        parser.error(f"--config {path} must hold a JSON object of RunConfig fields")
    return values


def demo_set(text: str) -> int | str:
    """A demo set: a shipped set's size (500 or 7500), the path of a demo file that exists, or
    minari:DATASET_ID, a local Minari dataset (read, and refused when missing, with the configuration)."""
    if text.strip() in ("500", "7500"):
        return int(text)
    if text.startswith(MINARI_PREFIX) and text[len(MINARI_PREFIX):].strip():
        return text
    if not Path(text).expanduser().is_file():
        raise argparse.ArgumentTypeError(f"demos must be 500 or 7500 (a shipped set), {MINARI_PREFIX}DATASET_ID (a "
                                         f"local Minari dataset) or the path of a demo file "
                                         f"(lava_bridge_mj.save_demos); {text!r} is none of these")
    return text


def comma_list(text: str) -> tuple[str, ...]:
    """`a,b` -> ("a", "b"), blanks dropped."""
    return tuple(part.strip() for part in text.split(",") if part.strip())


def setting(text: str) -> tuple[list[str], object]:
    """A `--set KEY=VALUE` override: the dotted RunConfig field (`sac.lr`, `strategy.sigma`, `steps`)
    and its value, read as JSON where it is JSON (numbers, true/false, null, lists, quoted strings)
    and as a plain string otherwise (`strategy.schedule=budget`)."""
    key, equals, value = text.partition("=")
    path = key.strip().split(".")
    if not equals or not all(path):
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE with a dotted RunConfig field, such as sac.lr=1e-3 "
                                         f"or strategy.sigma=0.2, got {text!r}")
    if len(path) > MAX_JSON_DEPTH:
        raise argparse.ArgumentTypeError(f"expected a dotted RunConfig field of at most {MAX_JSON_DEPTH} names, got "
                                         f"{len(path)} ({key.strip()[:40]}...)")
    try:
        return path, load_json(value)
    except NestedTooDeep as error:
        raise argparse.ArgumentTypeError(f"the value of {key.strip()}: {error}") from None
    except ValueError:
        return path, value


def apply_settings(values: dict, settings: Sequence[tuple[list[str], object]] | None,
                   parser: argparse.ArgumentParser) -> dict:
    """`values` (a config file's fields) with each `--set` override written into it, later ones winning;
    RunConfig.from_dict then checks the result like a config file."""
    values = json.loads(json.dumps(values))  # a copy: the caller's dict stays as read
    for path, value in settings or ():
        section = values
        for depth, name in enumerate(path[:-1]):
            section = section.setdefault(name, {})
            if not isinstance(section, dict):
                parser.error(f"--set {'.'.join(path)}: {'.'.join(path[:depth + 1])} is a value, not a section "
                             f"of fields")
        section[path[-1]] = value
    return values


def config_source(args: argparse.Namespace) -> str:
    """How error messages name where a configuration came from: its --config file and/or --set."""
    sources = [f"--config {args.config}"] * bool(args.config) + ["--set"] * bool(args.settings)
    return " / ".join(sources) or "options"


def directory(text: str) -> Path:
    """An argparse type: a directory path; an empty one (which would mean the current directory) is refused."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a directory, got {text!r}")
    return Path(text)


def check_writable(out: Path, parser: argparse.ArgumentParser) -> None:
    """A usage error unless directory `out` exists or can be made, and can be written."""
    try:
        if out.exists() and not out.is_dir():
            parser.error(f"--out {out} exists and is not a directory")
        existing = nearest_existing(out)
    except OSError as error:  # a name longer than the filesystem allows, a path too long, ...
        parser.error(f"--out {out} cannot be used: {error.strerror or error}")
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        parser.error(f"--out {out} cannot be written: {existing} is not a writable directory")


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity mask on Linux, else the machine's)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


class Interrupted(KeyboardInterrupt):
    """What `raise_keyboard_interrupt` raises: a KeyboardInterrupt that says which signal it was."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def signal_of(stop: KeyboardInterrupt) -> int:
    """The signal behind a KeyboardInterrupt: Interrupted's, else SIGINT (Python's own Ctrl-C handler)."""
    return getattr(stop, "signum", signal.SIGINT)


def stop_reason(signum: int) -> str:
    """How messages say what stopped a command: SIGINT is the user's Ctrl-C (or `kill -INT`), any other
    signal is named."""
    return "interrupted by the user (SIGINT)" if signum == signal.SIGINT else f"stopped by {signal.Signals(signum).name}"


def raise_keyboard_interrupt(signum, frame):
    """A signal handler: SIGTERM stops a command the way Ctrl-C does (its cleanup runs, nothing half-written)."""
    raise Interrupted(signum)


@contextmanager
def stopping_on_signals():
    """While the block runs, SIGINT and SIGTERM raise Interrupted (main thread only; the handlers
    before it are restored after). SIGINT is set explicitly too: a process a script starts in the
    background inherits SIGINT ignored, Python then leaves it ignored, and Ctrl-C or `kill -INT` would
    be lost. Commands enter it first thing, so a signal during their start-up stops them too."""
    with handling_signals(raise_keyboard_interrupt):
        yield


@contextmanager
def handling_signals(handler):
    """While the block runs, SIGINT and SIGTERM call `handler(signum, frame)` (main thread only: elsewhere
    signals cannot be handled and the block runs as it is); the handlers before it are restored after."""
    if not in_main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def release_held_signals() -> None:
    """Unblock SIGINT and SIGTERM, which the program's entry point (lava_bridge_bench.py) blocks while the
    package loads: a signal that came meanwhile is delivered now, to the handlers in place. Commands call
    it once their handlers are installed (`stopping_on_signals`); without the entry point (`python -m`)
    nothing is blocked and it changes nothing."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})


def in_main_thread() -> bool:
    """Signal handlers can only be set from the main thread (not where a test or Ray calls main)."""
    return threading.current_thread() is threading.main_thread()
