"""`lava-bridge-bench`: train one method on LavaBridge-v0 and evaluate it from p0 and ood.

    lava-bridge-bench --method auxss                      # the quick default run
    lava-bridge-bench --method sac --steps 300000         # the paper's protocol for plain SAC
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from lava_bridge_mj.eval.runner import METHODS, RunConfig

DEFAULTS = RunConfig()


def _int_at_least(minimum: int, what: str):
    """An argparse type: an integer >= minimum, or a usage error naming the value."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected {what}, got {value}")
        return value
    return parse


_positive_int = _int_at_least(1, "a positive integer")
_seed = _int_at_least(0, "a non-negative integer seed")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="lava-bridge-bench",
        description="Train SAC on LavaBridge-v0 from a start-state distribution, evaluating the "
                    "deterministic policy's success rate from p0 (the MDP's starts) and ood "
                    "(unseen starts) as it learns. Writes a run directory with config.json, "
                    "metrics.csv, start_weights.npz, checkpoints and policy snapshots.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--method", required=True, choices=METHODS,
                        help="sac: plain SAC from p0; auxss: the paper's episode-length start-state "
                             "safety; omega_ss: random-policy Monte-Carlo safety; uniform_ss: uniform "
                             "over demo states; goaldist_ss: goal-distance weighted, flattening over time")
    parser.add_argument("--seed", type=_seed, default=DEFAULTS.seed, help="random seed of the run")
    parser.add_argument("--steps", type=_positive_int, default=DEFAULTS.steps,
                        help="online env steps (the paper's protocol: 300000)")
    parser.add_argument("--demos", type=int, choices=(500, 7500), default=DEFAULTS.demos,
                        help="shipped demo set the candidate start states come from")
    parser.add_argument("--eval-every", type=_positive_int, default=DEFAULTS.eval_every,
                        help="evaluate, snapshot the policy and checkpoint every this many steps")
    parser.add_argument("--eval-episodes", type=_positive_int, default=DEFAULTS.eval_episodes,
                        help="evaluation episodes per start distribution (fixed seeds)")
    parser.add_argument("--out", type=Path, default=None,
                        help="run directory (default: runs/METHOD/seedSEED)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the run in --out from its last checkpoint")
    parser.add_argument("--video", action="store_true",
                        help="after training, write rollouts.mp4 of the policy from p0 and ood")
    parser.add_argument("--threads", type=_positive_int, default=1,
                        help="torch CPU threads (1 avoids oversubscription when runs share cores)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    out = args.out or Path("runs") / args.method / f"seed{args.seed}"
    if out.exists() and not out.is_dir():
        parser.error(f"--out {out} exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        parser.error(f"--out {out} cannot be created: {error.strerror}")
    if not os.access(out, os.W_OK):
        parser.error(f"--out {out} is not writable")
    if (out / "config.json").exists() and not args.resume:
        parser.error(f"--out {out} already holds a run; pass --resume to continue it or choose another --out")

    import torch  # after argument checks, so --help and usage errors are instant

    torch.set_num_threads(args.threads)
    from lava_bridge_mj.eval.runner import train

    config = RunConfig(method=args.method, seed=args.seed, steps=args.steps, demos=args.demos,
                       eval_every=args.eval_every, eval_episodes=args.eval_episodes)
    try:
        run = train(config, out, resume=args.resume, progress=not args.no_progress)
    except ValueError as error:  # e.g. a checkpoint from another configuration
        print(f"lava-bridge-bench: error: {error}", file=sys.stderr)
        return 2
    last = run.rows[-1]
    print(f"{args.method} seed {args.seed}: {last['step']} steps, success p0 {last['success_p0']:.2f}, "
          f"ood {last['success_ood']:.2f} -> {out}")
    if args.video:
        import gymnasium

        import lava_bridge_mj
        from lava_bridge_mj.eval.video import record_rollouts

        env = gymnasium.make(lava_bridge_mj.ENV_ID, render_mode="rgb_array")
        try:
            record_rollouts(env, lambda obs: run.agent.act(obs, deterministic=True), out / "rollouts.mp4")
        finally:
            env.close()
        print(f"wrote {out / 'rollouts.mp4'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
