"""Off-screen rollout videos: the maze from above, the ball, its trail and its start marked.

Rendering goes through the env's `render_mode="rgb_array"` (mujoco.Renderer, EGL or OSMesa);
the trail and the start marker are extra geoms added to the scene before each frame is drawn.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import imageio.v2 as imageio
import mujoco
import numpy as np

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


def record_rollouts(env, policy: Callable[[np.ndarray], np.ndarray], path: str | Path, *,
                    starts: list[str] | tuple[str, ...] = ("p0", "ood"), episodes_per_start: int = 2,
                    seed: int = 0, fps: int | None = None, still: str | Path | None = None) -> dict:
    """Roll `policy` out from each named start distribution and write one mp4 to `path`.

    Returns per-start success counts. `still`, if given, receives the last frame as an image.
    The file is written to a temporary name and renamed when
    complete, so an interrupted call never leaves a truncated video under `path`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".partial" + path.suffix)
    fps = fps or env.metadata.get("render_fps", 10)
    successes = {start: 0 for start in starts}
    with imageio.get_writer(tmp, fps=fps) as writer:
        for start in starts:
            for episode in range(episodes_per_start):
                obs, _ = env.reset(seed=seed + episode, options={"start": start})
                trail = [obs[:2].copy()]
                writer.append_data(render_frame(env, trail))
                done = False
                while not done:
                    obs, _, terminated, truncated, info = env.step(policy(obs))
                    trail.append(obs[:2].copy())
                    writer.append_data(render_frame(env, trail))
                    done = terminated or truncated
                successes[start] += bool(info["is_success"])
    tmp.replace(path)
    if still is not None:
        imageio.imwrite(still, render_frame(env, trail))
    return successes


def main(argv: list[str] | None = None) -> None:
    import argparse

    import gymnasium

    import lava_bridge_mj

    parser = argparse.ArgumentParser(description="Write an mp4 of scripted-expert rollouts from p0 and ood.")
    parser.add_argument("--out", default="runs/expert.mp4", help="video file to write (default: %(default)s)")
    parser.add_argument("--episodes", type=int, default=2, help="episodes per start distribution")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--still", default=None, help="also write the last frame as a PNG here")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    env = gymnasium.make(lava_bridge_mj.ENV_ID, render_mode="rgb_array")
    expert = lava_bridge_mj.ScriptedExpert(env)
    try:
        successes = record_rollouts(env, expert.act, args.out, episodes_per_start=args.episodes,
                                    seed=args.seed, still=args.still)
    finally:
        env.close()
    summary = ", ".join(f"{start} {n}/{args.episodes}" for start, n in successes.items())
    print(f"wrote {args.out}: expert successes {summary}")


if __name__ == "__main__":
    main()
