"""Off-screen rollout videos: the maze from above, the ball, its trail and its start marked.

    lava-bridge-bench video runs/auxss/seed0                     # the final policy -> RUN_DIR/rollouts.mp4
    lava-bridge-bench video runs/auxss/seed0 --policy step_20000 --episodes 3 --out early.mp4
    python -m lava_bridge_mj.eval.video --expert --out runs/expert.mp4   # the scripted expert

A run's policy is rebuilt from its config.json (the method's actor and its sizes) and its weights:
`--policy final` reads final.pt, or the latest checkpoint.pt of a run still training; `--policy
step_N` reads the snapshot policies/step_N.pt. It acts deterministically (the Gaussian's mean, as in
evaluation), in the run's own env settings, from p0 and then from ood, `--episodes` episodes each,
episode i starting from `reset(seed=SEED + i)`. A run directory that is missing, lacks config.json or
lacks the chosen policy is refused with one error line and exit code 2, before anything is written;
so are an --out or --still that cannot be written (wrong suffix, a file where a directory must be,
a read-only directory), before anything is rendered. The video is written to a temporary name and
renamed when complete (the still with it): a failure while writing (a full disk) or an interruption
leaves nothing behind and replaces nothing.

Rendering goes through the env's `render_mode="rgb_array"` (mujoco.Renderer, EGL or OSMesa);
on Lava Bridge the trail and the start marker are extra geoms added to the scene before each frame
is drawn. An external task (`lava_bridge_mj.external.EXTERNAL_TASKS`) renders through its own env's
camera, without trail (`video_env`); another env is refused.
"""

from __future__ import annotations

import argparse
import errno
import io
import os
import re
import signal
import struct
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable

import imageio.v2 as imageio
import mujoco
import numpy as np

from lava_bridge_mj.eval.training.atomic import nearest_existing

VIDEO_SUFFIXES = (".mp4",)
STILL_SUFFIXES = (".png", ".jpg", ".jpeg")
MAX_EPISODES = 100
"""Most episodes per start distribution: 100 x 2 starts x up to 501 frames is hours of video already."""
TRAIL_RGBA = np.array([0.1, 0.2, 0.9, 0.9], dtype=np.float32)
START_RGBA = np.array([1.0, 0.85, 0.0, 1.0], dtype=np.float32)


def _add_sphere(scene: mujoco.MjvScene, position, radius: float, rgba: np.ndarray) -> None:
    if scene.ngeom >= scene.maxgeom:
        return  # a full scene drops the oldest extras silently rather than failing a long video
    mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE,
                        np.array([radius, 0, 0]), np.array([position[0], position[1], 0.06]),
                        np.eye(3).ravel(), rgba)
    scene.ngeom += 1


def render_frame(env, trail: list[np.ndarray]) -> np.ndarray:
    """One frame of `env` (made with render_mode="rgb_array") with the path so far drawn on it."""
    base = env.unwrapped
    renderer = base.renderer
    renderer.update_scene(base.data, camera="top")
    for point in trail[1:]:
        _add_sphere(renderer.scene, point, 0.025, TRAIL_RGBA)
    if trail:
        _add_sphere(renderer.scene, trail[0], 0.08, START_RGBA)
    return renderer.render()


def own_frame(env, trail: list[np.ndarray]) -> np.ndarray:
    """One frame of `env` (made with render_mode="rgb_array") as the env renders it (no trail)."""
    return env.render()


def video_env(env_id: str, env_kwargs: dict[str, Any], max_episode_steps: int | None = None):
    """(the env that renders the rollouts of a run of `env_id`, its frame function): Lava Bridge's
    env with `render_frame`; an external task's `make_task_env` with `own_frame`, seen as the learners
    see it (flattened observations, actions in [-1, 1] rescaled to its bounds, as
    `ResetToStateVectorEnv` does). ValueError for any other env."""
    import gymnasium

    import lava_bridge_mj

    limit = {} if max_episode_steps is None else {"max_episode_steps": max_episode_steps}
    if env_id in lava_bridge_mj.TASKS:
        return gymnasium.make(env_id, render_mode="rgb_array", **limit, **env_kwargs), render_frame
    if env_id in lava_bridge_mj.EXTERNAL_TASKS:
        env = lava_bridge_mj.make_task_env(env_id, render_mode="rgb_array", **limit, **env_kwargs)
        flat = gymnasium.wrappers.FlattenObservation(env)
        return gymnasium.wrappers.RescaleAction(flat, -1.0, 1.0), own_frame
    raise ValueError(f"videos draw the rollouts of a Lava Bridge task or an external task "
                     f"({list(lava_bridge_mj.EXTERNAL_TASKS)}); {env_id} is another env")


def video_horizon(env_id: str) -> int:
    """The longest episode a video of `env_id` shows: the task's step limit."""
    import lava_bridge_mj

    if env_id in lava_bridge_mj.EXTERNAL_TASKS:
        return lava_bridge_mj.EXTERNAL_TASKS[env_id].max_episode_steps
    return lava_bridge_mj.MAX_EPISODE_STEPS


def record_rollouts(env, policy: Callable[[np.ndarray], np.ndarray], path: str | Path, *,
                    starts: list[str] | tuple[str, ...] = ("p0", "ood"), episodes_per_start: int = 2,
                    seed: int = 0, fps: int | None = None, still: str | Path | None = None,
                    frame: Callable[[Any, list[np.ndarray]], np.ndarray] = render_frame) -> dict:
    """Roll `policy` out from each named start distribution and write one mp4 to `path`; `frame`
    draws each frame from the env and the positions so far (`video_env` gives the env's).

    Returns per-start success counts. `still`, if given, receives the last frame as an image (PNG or
    JPEG by its suffix). The video is written to a temporary name and renamed when complete, the
    still just before, so an interrupted or failed call never leaves a truncated video under `path`,
    nor a still without its video. A failure while writing (a full disk) is an OSError naming the
    file, with ffmpeg's own reason where it gave one.
    """
    from lava_bridge_mj.eval.training.atomic import atomic_write

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if still is not None:
        Path(still).parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.partial{os.getpid()}{path.suffix}")
    fps = fps or env.metadata.get("render_fps") or 10
    successes = {start: 0 for start in starts}
    try:
        with tempfile.TemporaryFile() as ffmpeg_log:
            # log level "error": ffmpeg prints only when something went wrong, and into ffmpeg_log
            with imageio.get_writer(tmp, fps=fps, ffmpeg_log_level="error") as writer:
                started = False

                def append(frame: np.ndarray) -> None:
                    nonlocal started
                    try:
                        if started:
                            writer.append_data(frame)
                            return
                        with _stderr_into(ffmpeg_log):  # the first frame starts ffmpeg, which inherits it
                            writer.append_data(frame)
                        started = True
                    except (OSError, RuntimeError) as error:  # ffmpeg stopped reading: its log says why
                        code, reason = _ffmpeg_failure(ffmpeg_log)
                        reason = reason or f"ffmpeg stopped writing it ({error})".splitlines()[0]
                        raise OSError(code or getattr(error, "errno", None), reason, str(path)) from None

                for start in starts:
                    for episode in range(episodes_per_start):
                        obs, _ = env.reset(seed=seed + episode, options={"start": start})
                        trail = [obs[:2].copy()]
                        append(frame(env, trail))
                        done = False
                        while not done:
                            obs, _, terminated, truncated, info = env.step(policy(obs))
                            trail.append(obs[:2].copy())
                            append(frame(env, trail))
                            done = terminated or truncated
                        successes[start] += bool(info.get("success", info.get("is_success")))
            code, reason = _ffmpeg_failure(ffmpeg_log)  # imageio does not check how ffmpeg ended
            if reason:
                raise OSError(code, reason, str(path))
        if not whole_mp4(tmp):  # ffmpeg can end without a word, e.g. stopped by the file size limit
            raise OSError(*_truncation_reason(tmp), str(path))
        if still is not None:
            image = io.BytesIO()
            imageio.imwrite(image, frame(env, trail), format=Path(still).suffix.lstrip(".").lower())
            atomic_write(still, lambda f: f.write(image.getvalue()))
        tmp.replace(path)
    finally:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:  # not ours to remove (a directory of that name)
            pass
    return successes


def whole_mp4(path: str | Path) -> bool:
    """Whether `path` holds a whole MP4 file: its top-level boxes (ISO/IEC 14496-12: a 32-bit size, or 1
    and a 64-bit size, then the type) end exactly at the end of the file, the index (`moov`), which
    ffmpeg writes last, among them. A file cut short anywhere fails."""
    size, offset, types = os.path.getsize(path), 0, set()
    with open(path, "rb") as f:
        while offset < size:
            f.seek(offset)
            header = f.read(16)
            if len(header) < 8:
                return False
            box_size, box_type = struct.unpack(">I4s", header[:8])
            if box_size == 1 and len(header) == 16:
                box_size = struct.unpack(">Q", header[8:])[0]
            elif box_size == 0:  # the box runs to the end of the file
                box_size = size - offset
            if box_size < 8:
                return False
            types.add(box_type)
            offset += box_size
    return offset == size and b"moov" in types


def _truncation_reason(path: Path) -> tuple[int | None, str]:
    """(errno, reason) for a video that ffmpeg left unfinished: the file size limit where it reached it."""
    import resource

    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if limit != resource.RLIM_INFINITY and os.path.getsize(path) >= limit:
        return errno.EFBIG, f"{os.strerror(errno.EFBIG)} (the file size limit, {limit} bytes, cut it short)"
    return None, "ffmpeg ended without finishing it"


@contextmanager
def _stderr_into(file):
    """File descriptor 2 points to `file` for the block: a child process started in it (ffmpeg) keeps
    writing its messages there."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        os.dup2(file.fileno(), 2)
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)


SYSTEM_ERRORS = {os.strerror(code): code for code in sorted(errno.errorcode, reverse=True)}
"""The system's error messages (as ffmpeg prints them after a failed write) and their errno."""


def _ffmpeg_failure(log) -> tuple[int | None, str]:
    """(errno, reason) of ffmpeg's failure as its `log` tells it (at level "error": it has lines only
    if it failed): the first system error it names (a full disk: ENOSPC, "No space left on device"),
    else (None, its last message); (None, "") for an empty log."""
    log.seek(0)
    lines = [line.strip() for line in log.read().decode(errors="replace").splitlines() if line.strip()]
    for line in lines:
        for message, code in SYSTEM_ERRORS.items():
            if line.endswith((f": {message}", f"({message})")):
                return code, message
    return None, lines[-1] if lines else ""


def output_problem(path: Path, option: str, suffixes: tuple[str, ...]) -> str | None:
    """Why `path` cannot be written as `option`'s file (wrong suffix, a directory, under a file, in a
    read-only directory), or None. Missing directories are fine: they are made."""
    if path.suffix.lower() not in suffixes:
        names = " or ".join([", ".join(suffixes[:-1]), suffixes[-1]] if len(suffixes) > 1 else suffixes)
        return f"{option} {path}: expected a file name ending in {names}"
    if path.is_dir():
        return f"{option} {path} is a directory"
    existing = nearest_existing(path.parent)
    if not existing.is_dir():
        return f"{option} {path}: {existing} is a file, not a directory"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"{option} {path}: {existing} is not a writable directory"
    return None


POLICY_SPEC = re.compile(r"final|step_(\d+)")


Policy = Callable[[np.ndarray], np.ndarray]
"""An observation (4,) -> an action (2,)."""


def load_policy(run_dir: str | Path, policy: str = "final") -> tuple[Policy, Any, str]:
    """The deterministic policy of the run in `run_dir`: `policy` is "final" or "step_N".

    Returns (the policy, the run's RunConfig, a description of what was loaded). ValueError with a
    one-line reason when the directory, its config or the policy is missing or unreadable."""
    from lava_bridge_mj.eval.training.config import RunConfig
    from lava_bridge_mj.eval.training.run_files import load_torch, read_config
    from lava_bridge_mj.eval.training.runner import make_agent

    run_dir = Path(run_dir)
    spec = POLICY_SPEC.fullmatch(policy)
    if spec is None:
        raise ValueError(f"--policy must be final or step_N (e.g. step_5000), got {policy!r}")
    if not run_dir.is_dir():
        raise ValueError(f"{run_dir} is not a directory")
    config_file = run_dir / "config.json"
    if not config_file.is_file():
        raise ValueError(f"{run_dir} holds no config.json: not a run directory")
    try:
        config = RunConfig.from_dict(read_config(run_dir), source=str(config_file))
    except ValueError as error:  # invalid JSON, unknown or bad fields
        raise ValueError(f"{config_file} is not a usable run configuration: {error}") from None
    snapshot = spec.group(1) is not None  # policies/step_N.pt holds the actor's weights alone
    if snapshot:
        path = run_dir / "policies" / f"{policy}.pt"
        if not path.is_file():
            found = sorted(int(m.group(1)) for f in (run_dir / "policies").glob("step_*.pt")
                           if (m := POLICY_SPEC.fullmatch(f.stem)) and m.group(1))
            raise ValueError(f"{run_dir} has no policy snapshot {path.name}; available steps: "
                             f"{', '.join(map(str, found)) or 'none'}")
    else:
        path = next((run_dir / name for name in ("final.pt", "checkpoint.pt") if (run_dir / name).is_file()), None)
        if path is None:
            raise ValueError(f"{run_dir} holds neither final.pt nor checkpoint.pt: the run has not checkpointed yet")
    try:
        state = load_torch(path, weights_only=snapshot)  # CRC-checked; a checkpoint also holds RNG states
        actor = state if snapshot else state["agent"]["actor"]
        agent = make_agent(config, [config.seed])
        agent.actor.load_state_dict(actor)
    except Exception as error:  # a foreign or damaged file fails in many ways
        raise ValueError(f"cannot load the actor from {path} ({type(error).__name__}: {error})") from None
    step = spec.group(1) if snapshot else state.get("step")
    described = f"{config.method} seed {config.seed}, {path.name}" + (f" (step {step})" if step is not None else "")
    return agent.policy(0), config, described


def main(argv: list[str] | None = None) -> int:
    import lava_bridge_mj
    from lava_bridge_mj.eval import arguments

    parser = argparse.ArgumentParser(
        prog="lava-bridge-bench video",
        description="Render a trained run's policy (or the scripted expert) from p0 and from ood into one mp4, "
                    "off screen, with the ball's trail and its start marked.")
    parser.add_argument("run_dir", nargs="?", type=Path, help="run directory (holding config.json and final.pt, "
                        "checkpoint.pt or policies/)")
    parser.add_argument("--expert", action="store_true", help="record the scripted expert instead of a run")
    parser.add_argument("--env", dest="env_id", metavar="ID", choices=tuple(lava_bridge_mj.TASKS), default=None,
                        help="with --expert: the task (default: LavaBridge-v0); a run's task is its own")
    parser.add_argument("--policy", default="final", help="final (final.pt, or the latest checkpoint.pt of an "
                        "unfinished run) or step_N (policies/step_N.pt) (default: %(default)s)")
    parser.add_argument("--episodes", type=int, default=2,
                        help=f"episodes per start distribution, 1-{MAX_EPISODES} (default: %(default)s)")
    parser.add_argument("--max-steps", type=int, default=None,
                        help=f"cut each episode after this many steps (default: the task's limit, "
                             f"{lava_bridge_mj.MAX_EPISODE_STEPS} on Lava Bridge)")
    parser.add_argument("--seed", type=arguments.seed, default=0, help="episode i starts from reset(seed=SEED + i)")
    parser.add_argument("--out", type=Path, default=None, help="video file to write, .mp4 (default: "
                        "RUN_DIR/rollouts.mp4, RUN_DIR/rollouts_step_N.mp4 for --policy step_N, runs/expert.mp4 "
                        "with --expert)")
    parser.add_argument("--still", type=Path, default=None, help="also write the last frame here, .png or .jpg")
    args = parser.parse_args(argv)
    if args.expert == (args.run_dir is not None):
        parser.error("give either RUN_DIR or --expert")
    if args.env_id is not None and not args.expert:
        parser.error("--env goes with --expert; a run is rendered on its own task")
    if not 1 <= args.episodes <= MAX_EPISODES:
        parser.error(f"--episodes must be in 1-{MAX_EPISODES}, got {args.episodes}")

    def error(message: str, code: int = 2) -> int:
        print(f"lava-bridge-bench video: error: {message}", file=sys.stderr)
        return code

    env_id, env_kwargs = args.env_id or lava_bridge_mj.ENV_ID, {}
    if args.expert:
        out = args.out or Path("runs/expert.mp4")
    else:
        name = "rollouts.mp4" if args.policy == "final" else f"rollouts_{args.policy}.mp4"
        out = args.out or args.run_dir / name
    problems = [output_problem(out, "--out", VIDEO_SUFFIXES),
                output_problem(args.still, "--still", STILL_SUFFIXES) if args.still is not None else None]
    if any(problems):
        return error(next(problem for problem in problems if problem))
    if args.expert:
        policy, what = None, "expert"
    else:
        try:
            policy, config, what = load_policy(args.run_dir, args.policy)
        except ValueError as problem:
            return error(str(problem))
        env_id, env_kwargs = config.env_id, config.env
    most = video_horizon(env_id)
    max_steps = most if args.max_steps is None else args.max_steps
    if not 1 <= max_steps <= most:
        parser.error(f"--max-steps must be in 1-{most}, got {max_steps} ({env_id}'s step limit is {most})")
    try:
        env, frame = video_env(env_id, env_kwargs, max_steps)
    except ValueError as problem:
        return error(str(problem))
    previous = signal.signal(signal.SIGTERM, arguments.raise_keyboard_interrupt) if arguments.in_main_thread() else None
    try:
        policy = policy or lava_bridge_mj.ScriptedExpert(env).act
        successes = record_rollouts(env, policy, out, episodes_per_start=args.episodes, seed=args.seed,
                                    still=args.still, frame=frame)
    except OSError as problem:  # a full disk, a directory that turned read-only, ...
        return error(f"cannot write {problem.filename or out}: {problem.strerror or problem}; nothing written")
    except KeyboardInterrupt:
        return error("interrupted; nothing written", code=130)
    finally:
        env.close()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    summary = ", ".join(f"{start} {n}/{args.episodes}" for start, n in successes.items())
    print(f"wrote {out}: {what}" + (f" and {args.still}" if args.still is not None else "") + f"; successes {summary}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
