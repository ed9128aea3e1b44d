"""A picture of every task of the suite, from each env's own top camera: `docs/tasks.png`.

    python -m lava_bridge_mj.pictures [--out docs/tasks.png] [--width 960] [--height 400]

Each panel is a frame of `render_mode="rgb_array"` with the scripted expert's path from a p0 start
(blue) and from an ood start (orange) drawn in as small spheres, its start as a larger one; the
green and blue discs on the floor are the p0 blobs and ood spots, the green disc on the right the
goal. Needs matplotlib (the `plots` extra) for the panel titles.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium
import mujoco
import numpy as np

import lava_bridge_mj

PATH_RGBA = {"p0": np.array([0.1, 0.2, 0.9, 0.9], np.float32), "ood": np.array([1.0, 0.55, 0.0, 0.9], np.float32)}


def expert_path(env, start: str, seed: int = 0) -> np.ndarray:
    """The (x, y) positions of one scripted-expert episode from the named start distribution."""
    expert = lava_bridge_mj.ScriptedExpert(env)
    obs, _ = env.reset(seed=seed, options={"start": start})
    positions = [obs[:2]]
    for _ in range(lava_bridge_mj.MAX_EPISODE_STEPS):
        obs, _, terminated, truncated, _ = env.step(expert.act(obs))
        positions.append(obs[:2])
        if terminated or truncated:
            break
    return np.array(positions)


def _add_sphere(scene: mujoco.MjvScene, position, radius: float, rgba: np.ndarray) -> None:
    if scene.ngeom < scene.maxgeom:
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE, np.array([radius, 0, 0]),
                            np.array([position[0], position[1], 0.06]), np.eye(3).ravel(), rgba)
        scene.ngeom += 1


def task_frame(env_id: str, width: int, height: int) -> np.ndarray:
    """The task from its top camera, the ball at its goal, with the expert's paths from p0 and ood."""
    env = gymnasium.make(env_id, render_mode="rgb_array", width=width, height=height)
    paths = {start: expert_path(env, start) for start in PATH_RGBA}
    base = env.unwrapped
    base.set_state(base.layout.goal)  # park the ball out of the way, on the goal
    renderer = base.renderer
    renderer.update_scene(base.data, camera="top")
    for start, path in paths.items():
        for point in path[1:]:
            _add_sphere(renderer.scene, point, 0.025, PATH_RGBA[start])
        _add_sphere(renderer.scene, path[0], 0.08, PATH_RGBA[start])
    frame = renderer.render().copy()
    env.close()
    return frame


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lava_bridge_mj.pictures", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/tasks.png"))
    parser.add_argument("--width", type=int, default=960)
    parser.add_argument("--height", type=int, default=400)
    parser.add_argument("--columns", type=int, default=2)
    args = parser.parse_args(argv)
    if min(args.width, args.height, args.columns) < 1:
        parser.error("--width, --height and --columns must be positive")
    if args.out.suffix.lower() != ".png":
        parser.error(f"--out {args.out} must name a .png file")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env_ids = list(lava_bridge_mj.TASKS)
    rows = -(-len(env_ids) // args.columns)
    panel_w, panel_h = 6.0, 6.0 * args.height / args.width + 0.35
    fig, axes = plt.subplots(rows, args.columns, figsize=(panel_w * args.columns, panel_h * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, env_id in zip(axes.ravel(), env_ids):
        ax.imshow(task_frame(env_id, args.width, args.height))
        ax.set_title(env_id, fontsize=12)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_name(args.out.stem + ".tmp.png")
    fig.savefig(tmp, dpi=100)
    tmp.replace(args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
