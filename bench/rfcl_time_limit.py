"""Is RFCL's shortened time limit reachable on each task? The scripted expert, sped up, from demo states.

RFCL gives an episode that starts t demonstration steps before the goal `8 + t // 3` steps
(`ReverseCurriculumSS.time_limit`), so a policy must finish about three times faster than the
demonstration. Per task and speed factor, the expert with `room_speed` and `bridge_speed` scaled by
that factor runs from every `--every`-th state of the task's goal-reaching 7,500-transition demos;
the table counts the starts it finishes within the limit, and those that end in lava.

Usage: python bench/rfcl_time_limit.py [--env ID] [--every 37] [--speeds 1,2,3,4]
"""

from __future__ import annotations

import argparse

import gymnasium
import numpy as np

import lava_bridge_mj
from lava_bridge_mj.agents import ReverseCurriculumSS, goal_reaching_demos


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", choices=sorted(lava_bridge_mj.TASKS), help="one task (default: every task)")
    parser.add_argument("--every", type=int, default=37, help="use every N-th demo state (default 37)")
    parser.add_argument("--speeds", default="1,2,3,4", help="expert speed factors (default 1,2,3,4)")
    args = parser.parse_args()
    speeds = [float(s) for s in args.speeds.split(",")]
    defaults = lava_bridge_mj.ScriptedExpert()
    print("| task | starts | " + " | ".join(f"expert x{s:g}: within limit (lava)" for s in speeds) + " |")
    print("|---|---|" + "---|" * len(speeds))
    for env_id in [args.env] if args.env else list(lava_bridge_mj.TASKS):
        states, ids = goal_reaching_demos(lava_bridge_mj.load_demos(7500, env_id=env_id))
        curriculum = ReverseCurriculumSS(states, ids)
        env = gymnasium.make(env_id)
        starts = np.arange(0, len(states), args.every)
        cells = []
        for speed in speeds:
            expert = lava_bridge_mj.ScriptedExpert(env, room_speed=defaults.room_speed * speed,
                                                   bridge_speed=defaults.bridge_speed * speed)
            within = lava = 0
            for index in starts:
                obs, _ = env.reset(options={"state": states[index]})
                for steps in range(1, lava_bridge_mj.MAX_EPISODE_STEPS + 1):
                    obs, _, terminated, truncated, info = env.step(expert.act(obs))
                    if terminated or truncated:
                        break
                lava += bool(terminated and not info["is_success"])
                within += bool(info["is_success"] and steps <= curriculum.time_limit(index))
            cells.append(f"{within} ({lava})")
        print(f"| {env_id} | {len(starts)} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
