"""Maintenance commands for the shipped assets.

    python -m lava_bridge_mj model [--check]   rewrite (or check) assets/lava_bridge.xml from Layout()
    python -m lava_bridge_mj demos [--check]   regenerate (or check bit for bit) every task's shipped demo sets
"""

import argparse
import sys

from lava_bridge_mj.demos import regenerate_demos
from lava_bridge_mj.mjcf import regenerate_model


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lava_bridge_mj", description=__doc__.splitlines()[0])
    parser.add_argument("asset", choices=("model", "demos"), help="which shipped asset")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 unless the shipped files equal their regeneration")
    args = parser.parse_args(argv)
    regenerate = regenerate_model if args.asset == "model" else regenerate_demos
    return 0 if regenerate(check=args.check) else 1


if __name__ == "__main__":
    sys.exit(main())
