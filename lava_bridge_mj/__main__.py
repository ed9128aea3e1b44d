"""Maintenance commands for the shipped assets, and the demo sets' Minari export.

    python -m lava_bridge_mj model [--check]   rewrite (or check) assets/lava_bridge.xml from Layout()
    python -m lava_bridge_mj demos [--check] [--env ID]
                                               regenerate (or check bit for bit) every task's shipped demo
                                               sets (--env: one task's, a Lava Bridge or an external task)
    python -m lava_bridge_mj demos --minari [--size 500|7500] [--env ID]
                                               write a task's shipped sets (both sizes unless --size) as
                                               local Minari datasets, under MINARI_DATASETS_PATH
"""

import argparse
import sys

from lava_bridge_mj.demos import (SHIPPED_SIZES, check_shipped_task, minari_dataset_path, regenerate_demos,
                                  to_minari)
from lava_bridge_mj.mjcf import regenerate_model
from lava_bridge_mj.tasks import DEFAULT_ENV_ID


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lava_bridge_mj", description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n".join(__doc__.splitlines()[2:]))
    parser.add_argument("asset", choices=("model", "demos"), help="which shipped asset")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 unless the shipped files equal their regeneration")
    parser.add_argument("--minari", action="store_true",
                        help="demos: write the shipped sets as local Minari datasets (needs the minari extra)")
    parser.add_argument("--size", type=int, choices=SHIPPED_SIZES, help="with --minari: this set only")
    parser.add_argument("--env", help=f"demos: this task's sets only (with --minari, default {DEFAULT_ENV_ID})")
    args = parser.parse_args(argv)
    if args.minari:
        if args.asset != "demos" or args.check:
            parser.error("--minari exports the demo sets: use it as `demos --minari`, without --check")
        return export_minari(args.env or DEFAULT_ENV_ID, (args.size,) if args.size else SHIPPED_SIZES)
    if args.size is not None:
        parser.error("--size goes with `demos --minari`")
    if args.asset == "model":
        if args.env is not None:
            parser.error("--env goes with `demos`")
        return 0 if regenerate_model(check=args.check) else 1
    if args.env is not None:
        try:
            check_shipped_task(args.env)
        except ValueError as error:
            parser.error(str(error))
    return 0 if regenerate_demos(check=args.check, env_ids=None if args.env is None else [args.env]) else 1


def export_minari(env_id: str, sizes: tuple[int, ...]) -> int:
    """Write each size's set of `env_id` to Minari; 2 with one line on stderr, writing nothing, for bad input."""
    try:
        check_shipped_task(env_id)
        existing = [str(path) for path in (minari_dataset_path(size, env_id) for size in sizes) if path.exists()]
        if existing:
            raise ValueError(f"Minari datasets already exist at {', '.join(existing)}; delete them "
                             "(minari.delete_dataset(id)) to write them again")
        for size in sizes:
            dataset = to_minari(size, env_id)
            print(f"wrote Minari dataset {dataset.spec.dataset_id}: {dataset.total_episodes} episodes, "
                  f"{dataset.total_steps} steps")
    except (ImportError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:  # Minari's root cannot be made or written
        print(f"error: cannot write the Minari datasets: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
