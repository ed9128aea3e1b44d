"""The `lava-bridge-bench` program's entry point: `lava_bridge_mj.eval.cli.main` once the package has loaded.

It lives outside the package so that it runs before the package's imports (gymnasium, MuJoCo: a few
tenths of a second). Meanwhile SIGINT and SIGTERM are blocked, not lost: a process a script starts in
the background inherits SIGINT ignored, and an ignored signal that is not blocked is discarded, so a
Ctrl-C or `kill -INT` in that time used to leave the run training to the end. The command unblocks them
once its own handlers are in place (`arguments.release_held_signals`), and a signal held until then
stops it there, before it has written anything.
"""

import signal
import sys

HELD_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def main() -> int:
    if hasattr(signal, "pthread_sigmask"):  # POSIX; elsewhere the package loads as before
        signal.pthread_sigmask(signal.SIG_BLOCK, HELD_SIGNALS)
    from lava_bridge_mj.eval.cli import main as cli_main

    return cli_main()


if __name__ == "__main__":
    sys.exit(main())
