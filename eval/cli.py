"""`lava-bridge-bench`: train one method on LavaBridge-v0 and evaluate it from p0 and ood.

    lava-bridge-bench --method auxss                      # the quick default run
    lava-bridge-bench --method sac --steps 300000         # the paper's protocol for plain SAC
    lava-bridge-bench --method auxss --seeds 0-24         # 25 seeds trained together in one process
    lava-bridge-bench --method auxss --config my.json     # any RunConfig field, e.g. SAC sizes
    lava-bridge-bench --method auxss --set sac.lr=1e-3 --set strategy.sigma=0.2   # one field at a time
    lava-bridge-bench sweep --methods auxss,sac --seeds 0-24 --demos 500,7500 --out runs/study
    lava-bridge-bench report ... / video ... / summary ... / export ...  # the commands: COMMANDS below

`train` is the command when none is named: `lava-bridge-bench --method auxss` is
`lava-bridge-bench train --method auxss`.
"""

from __future__ import annotations

import argparse
import difflib
import os
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

# OpenMP threads that sleep instead of spinning while they wait: with spinning threads, training fell
# from about 600 to 3 steps/s when another process used the CPUs. libgomp reads this once, when torch
# is loaded, so it is set before anything imports torch; a value the user set is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import lava_bridge_mj  # noqa: E402
from lava_bridge_mj.agents.methods import METHODS as METHOD_SPECS  # noqa: E402
from lava_bridge_mj.eval import arguments  # noqa: E402
from lava_bridge_mj.eval.training import tracking  # noqa: E402
from lava_bridge_mj.eval.training.config import METHODS, ConfigurationError, RunConfig, check_batch_fits  # noqa: E402
from lava_bridge_mj.eval.training.run_files import run_files  # noqa: E402

DEFAULTS = RunConfig()
TASK_IDS = tuple(lava_bridge_mj.TASKS)
COMMANDS = {"train": "lava_bridge_mj.eval.cli", "sweep": "lava_bridge_mj.eval.sweeps.sweep",
            "report": "lava_bridge_mj.eval.analysis.report", "video": "lava_bridge_mj.eval.video",
            "summary": "lava_bridge_mj.eval.analysis.summary", "export": "lava_bridge_mj.eval.sweeps.export"}
"""`lava-bridge-bench NAME ...` runs the module's main(rest of argv); without a name, `train`."""
COMMAND_HELP = {"train": "train one method, one seed or a batch of seeds (the default command)",
                "sweep": "every method x demo set x seed, as batched jobs on local worker processes or Ray",
                "report": "figures, tables and tests from a directory of runs",
                "video": "an mp4 of a run's policy from p0 and ood",
                "summary": "a markdown table of a directory of runs, with the start-room share of training",
                "export": "compact copies of finished runs (no checkpoints or policies), to commit to results/"}


def build_parser(prog: str = "lava-bridge-bench") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Train a method on a Lava Bridge task (SAC from a start-state distribution, a hybrid "
                    "or an offline baseline), evaluating the deterministic policy's success rate from "
                    "p0 (the MDP's starts) and ood (unseen starts) as it learns. Writes a run "
                    "directory with config.json, "
                    "metrics.csv, start_weights.npz, checkpoints and policy snapshots. "
                    "Ctrl-C (or SIGTERM) stops after writing a checkpoint; --resume continues.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="commands (lava-bridge-bench COMMAND --help describes each; without one, train):\n" + "\n".join(
            f"  {name:<8} {text}" for name, text in COMMAND_HELP.items()))
    parser.add_argument("--method", required=True, choices=METHODS,
                        help="; ".join(f"{m.name}: {m.description}" + ("" if m.online else " (offline: --steps counts "
                                  "gradient steps on the demos)") for m in METHOD_SPECS.values()))
    seeds = parser.add_mutually_exclusive_group()
    seeds.add_argument("--seed", type=arguments.seed, help=f"random seed of the run (default: {DEFAULTS.seed})")
    seeds.add_argument("--seeds", type=arguments.parse_seeds, metavar="LIST",
                       help="train several seeds together in one process (stacked networks, one batched "
                            "update for all), e.g. 0-24 or 0,3,5-7; each seed writes the run directory it "
                            "would write alone, OUT/seedS")
    parser.add_argument("--env", dest="env_id", metavar="ID",
                        help=f"the task, one of {', '.join(TASK_IDS)} (default: {DEFAULTS.env_id}), an "
                             f"external task, one of {', '.join(lava_bridge_mj.EXTERNAL_TASKS)} "
                             f"(docs/external-tasks.md), or any gymnasium id of a MuJoCo env that "
                             f"lava_bridge_mj.ResetToState serves (e.g. Hopper-v5), with --demos PATH (docs/any-env.md)")
    parser.add_argument("--steps", type=arguments.positive_int,
                        help=f"online env steps (default: {DEFAULTS.steps}; the paper's protocol: 300000)")
    parser.add_argument("--demos", type=arguments.demo_set, metavar="500|7500|PATH|minari:ID",
                        help=f"demo set the candidate start states come from: a shipped set, 500 or 7500 (default: "
                             f"{DEFAULTS.demos}), a demo file (lava_bridge_mj.save_demos), or minari:DATASET_ID, a "
                             f"local Minari dataset with its states (python -m lava_bridge_mj demos --minari "
                             f"writes the shipped sets; nothing is downloaded); config.json records its path or "
                             f"id and content hash")
    parser.add_argument("--eval-every", type=arguments.positive_int,
                        help=f"evaluate, snapshot the policy and checkpoint every this many steps "
                             f"(default: {DEFAULTS.eval_every})")
    parser.add_argument("--eval-episodes", type=arguments.positive_int,
                        help=f"evaluation episodes per start distribution, fixed seeds (default: {DEFAULTS.eval_episodes})")
    parser.add_argument("--config", type=Path,
                        help="JSON file of RunConfig fields, e.g. {\"sac\": {\"hidden_sizes\": [256, 256]}, "
                             "\"strategy\": {\"sigma\": 0.2}}; options given here override it")
    parser.add_argument("--set", dest="settings", type=arguments.setting, action="append", metavar="KEY=VALUE",
                        help="one RunConfig field by its dotted name, over --config: --set sac.lr=1e-3 "
                             "--set strategy.sigma=0.2 --set sac.hidden_sizes=[256,256] (values read as "
                             "JSON, else as text); checked like a config file")
    parser.add_argument("--out", type=arguments.directory, default=None,
                        help="run directory (default: runs/METHOD/seedSEED); with --seeds, the directory "
                             "that holds one seedS directory per seed (default: runs/METHOD)")
    written = parser.add_mutually_exclusive_group()
    written.add_argument("--resume", action="store_true",
                         help="continue the run in --out from its last checkpoint (same configuration; a larger "
                              "--steps extends a finished run, equal to training to it in one go)")
    written.add_argument("--overwrite", action="store_true",
                         help="replace the run already in --out instead of refusing")
    parser.add_argument("--video", action="store_true",
                        help="after training, write rollouts.mp4 of the policy from p0 and ood")
    parser.add_argument("--threads", type=arguments.positive_int, default=1,
                        help="torch CPU threads, at most the CPUs this process may use (default: 1). 1 avoids "
                             "oversubscription when runs share cores and keeps a seed's numbers independent of "
                             "the seeds batched with it; 2 speeds up a large --seeds batch on an otherwise idle "
                             "2-core machine")
    parser.add_argument("--device", type=arguments.device, default="cpu",
                        help="torch device the networks train on: cpu (default) or cuda / cuda:N where this "
                             "machine has one; the envs, buffers and start strategies stay on the CPU. A run "
                             "option, not part of the configuration: provenance.json records it, and a run "
                             "continues on the device type it started on")
    parser.add_argument("--log", type=arguments.comma_list, default=(), metavar="SINKS",
                        help="also log training and evaluations live to tensorboard and/or wandb "
                             "(comma-separated; each an optional extra): training scalars every --log-every "
                             "steps, each evaluation's success and return, the start strategy's "
                             "probabilities as a histogram, the videos of --log-videos; metrics.csv stays "
                             "the record")
    parser.add_argument("--log-videos", action="store_true",
                        help="render the policy's rollouts from p0 and ood at every evaluation to "
                             "videos/step_N.mp4 (and to the --log sinks)")
    parser.add_argument("--log-every", type=arguments.positive_int, default=tracking.TRAIN_LOG_EVERY, metavar="N",
                        help="write the training scalars (train/, rollout/, time/) to the --log sinks every N "
                             f"steps (default: {tracking.TRAIN_LOG_EVERY}); evaluations go to eval/")
    wandb = parser.add_argument_group("W&B, with --log wandb (each option beats its WANDB_* environment variable)")
    wandb.add_argument("--wandb-project", metavar="PROJECT",
                       help=f"the W&B project (default: $WANDB_PROJECT, else {tracking.WANDB_PROJECT})")
    wandb.add_argument("--wandb-entity", metavar="ENTITY", help="the W&B entity (default: $WANDB_ENTITY, else "
                                                                  "W&B's default entity)")
    wandb.add_argument("--wandb-group", metavar="GROUP",
                       help="the W&B group of the seeds' runs (default: $WANDB_RUN_GROUP, else 'METHOD on ENV')")
    wandb.add_argument("--wandb-name", metavar="NAME", help="each seed's W&B run is named 'NAME seed S' (default: "
                                                            "$WANDB_NAME, else 'METHOD on ENV')")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def _config_from(args: argparse.Namespace, parser: argparse.ArgumentParser) -> RunConfig:
    values = arguments.apply_settings(arguments.read_config_file(args.config, parser), args.settings, parser)
    values["method"] = args.method
    for name in ("env_id", "seed", "steps", "demos", "eval_every", "eval_episodes"):
        if getattr(args, name) is not None:
            values[name] = getattr(args, name)
    try:
        return RunConfig.from_dict(values, source=arguments.config_source(args))
    except ValueError as error:
        parser.error(str(error))


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    prog = "lava-bridge-bench"
    if argv and argv[0] == "train":
        argv, prog = argv[1:], "lava-bridge-bench train"
    elif argv and argv[0] in COMMANDS:
        import importlib

        command = importlib.import_module(COMMANDS[argv[0]])
        with arguments.stopping_on_signals():
            try:  # a signal held while the package loaded stops the command before it starts
                arguments.release_held_signals()
            except KeyboardInterrupt as stop:
                return _stopped_during_start_up(f"lava-bridge-bench {argv[0]}", stop)
        return command.main(argv[1:]) or 0
    elif argv and not argv[0].startswith("-"):
        arguments.release_held_signals()
        return unknown_command(argv[0])
    with arguments.stopping_on_signals():  # before any start-up work: a signal then stops it too
        try:
            arguments.release_held_signals()  # a signal that came while the package loaded: raised here
            return _train_command(argv, prog)
        except KeyboardInterrupt as stop:  # while loading, before training touched any run directory
            return _stopped_during_start_up("lava-bridge-bench", stop)


def _stopped_during_start_up(prog: str, stop: KeyboardInterrupt) -> int:
    signum = arguments.signal_of(stop)
    print(f"{prog}: {arguments.stop_reason(signum)} during start-up, before anything was written; run the same "
          "command again to start", file=sys.stderr)
    return 128 + signum


def _train_command(argv: list[str], prog: str) -> int:
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    config = _config_from(args, parser)
    if (args.video or args.log_videos) and not (config.lava_bridge or config.external):
        parser.error(f"--video and --log-videos draw the p0 and ood rollouts of a Lava Bridge task or an external "
                     f"task; {config.env_id} is another env")
    try:
        tracking.check_sinks(args.log)
    except ValueError as error:
        parser.error(f"--log: {error}")
    wandb = {key: getattr(args, f"wandb_{key}") for key in tracking.WANDB_SETTINGS
             if getattr(args, f"wandb_{key}") is not None}
    if wandb and "wandb" not in args.log:
        parser.error(f"--wandb-{next(iter(wandb))} needs --log wandb")
    if "wandb" in args.log:
        try:
            tracking.wandb_settings(wandb)
        except ValueError as error:
            parser.error(f"--log wandb: {error}")
    if args.threads > arguments.usable_cpus():  # more threads than CPUs only compete (and may exhaust the machine's)
        parser.error(f"--threads {args.threads}: this machine lets the run use {arguments.usable_cpus()} CPUs")
    seeds = args.seeds or [config.seed]
    try:  # before anything per seed: a million seeds' directories take minutes to check
        check_batch_fits(config, len(seeds))
    except ValueError as error:
        parser.error(str(error))
    if args.seeds:
        root = args.out or Path("runs") / config.method
        outs = [root / f"seed{seed}" for seed in seeds]
    else:
        outs = [args.out or Path("runs") / config.method / f"seed{config.seed}"]
    if args.out is not None:
        arguments.check_writable(args.out, parser)
    for out in outs:
        arguments.check_writable(out, parser)
        found = run_files(out)
        if found and not (args.resume or args.overwrite):
            parser.error(f"--out {out} already holds a run ({', '.join(found)}); pass --resume to continue it, "
                         "--overwrite to replace it, or choose another --out")

    import torch  # after argument checks, so --help and usage errors are instant

    from lava_bridge_mj.eval.training.runner import RunInterrupted, train

    torch.set_num_threads(args.threads)

    try:
        run = train(config, outs, seeds=seeds, resume=args.resume, overwrite=args.overwrite,
                    progress=not args.no_progress, log=args.log, log_videos=args.log_videos, log_every=args.log_every,
                    wandb=wandb or None, device=args.device)
    except RunInterrupted as stop:
        print(f"lava-bridge-bench: {stop}; continue with: {resume_command(argv)}", file=sys.stderr)
        return 128 + stop.signum
    except KeyboardInterrupt as stop:  # before the loop's first checkpoint, or a second signal in it
        print(f"lava-bridge-bench: {arguments.stop_reason(arguments.signal_of(stop))}; files already written are "
              f"intact; continue with: {resume_command(argv)}", file=sys.stderr)
        return 128 + arguments.signal_of(stop)
    except ConfigurationError as error:  # a start strategy's parameter out of range: the user's input
        parser.error(f"{arguments.config_source(args)}: {error}")
    except ValueError as error:  # a directory is in use or holds another run, a foreign checkpoint, ...
        print(f"lava-bridge-bench: error: {error}", file=sys.stderr)
        return 2
    except OSError as error:  # a full disk, a directory made read-only mid-run, ...
        print(f"lava-bridge-bench: error: cannot write {error.filename or 'a run file'}: "
              f"{error.strerror or error}; files already written are intact: fix that, then continue with: "
              f"{resume_command(argv)}", file=sys.stderr)
        return 1
    for seed_run in run.seed_runs:
        seed = seed_run.config.seed
        if seed in run.diverged:
            print(f"{config.method} seed {seed}: stopped at step {run.diverged[seed]} (diverged) -> {seed_run.dir}")
            continue
        last = seed_run.rows[-1]
        print(f"{config.method} seed {seed}: {last['step']} steps, success p0 "
              f"{last['success_p0']:.2f}, ood {last['success_ood']:.2f} -> {seed_run.dir}")
    if args.video:
        try:
            write_videos(run, config)
        except KeyboardInterrupt as stop:
            print(f"lava-bridge-bench: {arguments.stop_reason(arguments.signal_of(stop))} while writing the videos; "
                  "the runs are finished", file=sys.stderr)
            return 128 + arguments.signal_of(stop)
    return 1 if run.diverged else 0


def write_videos(run, config: RunConfig) -> None:
    """rollouts.mp4 of each seed's policy from p0 and ood, in its run directory (not for diverged seeds)."""
    from lava_bridge_mj.eval import video

    env, frame = video.video_env(config.env_id, config.env)
    try:
        for i, seed_run in enumerate(run.seed_runs):
            if seed_run.config.seed in run.diverged:
                continue
            video.record_rollouts(env, run.policy(i), seed_run.dir / "rollouts.mp4", frame=frame)
            print(f"wrote {seed_run.dir / 'rollouts.mp4'}")
    finally:
        env.close()


def unknown_command(name: str) -> int:
    """A usage error for `lava-bridge-bench NAME` with no command NAME, suggesting the nearest ones."""
    close = difflib.get_close_matches(name, COMMANDS, n=2, cutoff=0.6)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    print(f"usage: lava-bridge-bench [COMMAND] ...\nlava-bridge-bench: error: unknown command {name!r}{hint} "
          f"(commands: {', '.join(COMMANDS)}; without one, train: lava-bridge-bench --method ...)", file=sys.stderr)
    return 2


def resume_command(argv: Sequence[str]) -> str:
    """The command that continues this run: the same arguments with --resume (and without --overwrite)."""
    kept = [arg for arg in argv if arg not in ("--resume", "--overwrite")]
    return shlex.join(["lava-bridge-bench", *kept, "--resume"])


if __name__ == "__main__":
    sys.exit(main())
