"""The Lava Bridge task suite: LavaBridge-v0 and registered variants, each one `Layout`.

Every task is the same MDP family (a point mass, a sparse goal reward, lava that ends the episode,
p0 and ood start distributions, a 500-step horizon) with one thing changed that makes learning from
start states harder in its own way. Starts and goal are placed relative to the geometry as in
LavaBridge-v0: p0 blobs 1 m from the start room's west wall, two ood spots 0.7 m before the lava
beside the bridge's mouth and two in far parts of the start room, the goal 3 m past the bridge.

`TASKS` maps each gymnasium id to its layout (LavaBridge-v0 first); `TASK_DOCS` says in a sentence
what makes each one hard; `SUITE` names the ones the study runs on; `task_layout(env_id)` looks one up.
"""

from __future__ import annotations

from lava_bridge_mj.layout import Disc, Layout


def placed_layout(bridge_length: float = 3.0, room_length: float = 4.0, **fields) -> Layout:
    """A Layout whose starts and goal sit where LavaBridge-v0's sit relative to its walls and bridge.

    `placed_layout()` is `Layout()`; other geometry moves the p0 blobs with the west wall and the
    ood spots and goal with the bridge's ends, so every task has the same kind of starts.
    """
    west = -(bridge_length / 2 + room_length)
    mouth = -bridge_length / 2
    return Layout(
        bridge_length=bridge_length,
        room_length=room_length,
        goal=(-mouth + 3.0, 1.0),
        p0_blobs=(Disc(west + 1.0, 0.0, 0.2), Disc(west + 1.0, 1.2, 0.2), Disc(west + 1.0, -1.2, 0.2)),
        ood_spots=(Disc(mouth - 0.7, 1.6, 0.15), Disc(mouth - 0.7, -1.6, 0.15),
                   Disc(west + 0.3, 1.7, 0.15), Disc(mouth - 2.0, -1.7, 0.15)),
        **fields,
    )


DEFAULT_ENV_ID = "LavaBridge-v0"
"""The reference task, the package's default wherever an env id may be given."""

TASKS: dict[str, Layout] = {
    DEFAULT_ENV_ID: Layout(),
    "LavaBridgeLong-v0": placed_layout(bridge_length=5.0),
    "LavaBridgeNarrow-v0": placed_layout(bridge_width=0.2),
    # Half the damping doubles the top speed (gear / damping = 8 m/s); the physics step halves with
    # it so that a ball at top speed still moves less than its radius per step (see Layout.timestep),
    # and frame_skip doubles to keep 0.1 s per env step.
    "LavaBridgeLowDamping-v0": placed_layout(damping=0.5, timestep=0.005, frame_skip=20),
    "LavaBridgeFarStart-v0": placed_layout(room_length=8.0),
    "LavaBridgeBend-v0": placed_layout(bridge_path=((-1.5, -0.8), (0.0, -0.8), (0.0, 0.8), (1.5, 0.8))),
    "LavaBridgeTwoCrossings-v0": placed_layout(bridge_length=6.0, islands=((-1.0, 1.0),),
                                               bridge_path=((-3.0, 1.2), (0.0, 1.2), (0.0, -1.2), (3.0, -1.2))),
    "LavaBridgeDecoy-v0": placed_layout(decoys=((-0.25, 1.0, 1.25, 0.3),)),
}
"""Every task's layout by gymnasium id, in suite order: LavaBridge-v0 first."""

TASK_DOCS: dict[str, str] = {
    "LavaBridge-v0": "The reference task: a 3 m long, 0.3 m wide bridge, damping 1 (top speed 4 m/s).",
    "LavaBridgeLong-v0": "A 5 m bridge: the unsafe stretch, where one bad action ends the episode, is 5/3 as "
                         "long, so a policy must stay accurate for longer and more demo states sit on it.",
    "LavaBridgeNarrow-v0": "A 0.2 m bridge: the ball's centre must stay within 5 cm of the axis (10 cm on "
                           "LavaBridge-v0), so random actions from bridge states reach lava sooner and the "
                           "demo states' safety varies more.",
    "LavaBridgeLowDamping-v0": "Damping 0.5 (top speed 8 m/s): the ball keeps its speed twice as long, so it "
                               "must brake early and random actions carry it into lava from further away.",
    "LavaBridgeFarStart-v0": "8 m rooms: p0 lies 9 m from the bridge, a long approach without reward that "
                             "puts most demo states far from both lava and goal.",
    "LavaBridgeBend-v0": "A Z-shaped bridge (1.5 m east at y = -0.8, 1.6 m north, 1.5 m east at y = 0.8): the "
                         "ball must brake and turn twice on a 0.3 m bridge, where momentum carries it towards lava.",
    "LavaBridgeTwoCrossings-v0": "Two 2 m crossings with a 2 m room between them, entered at opposite sides "
                                 "(y = 1.2, then y = -1.2): two stretches where one bad action ends the episode, "
                                 "and demo states in the middle room that are safe yet far from p0 and the goal.",
    "LavaBridgeDecoy-v0": "Beside the bridge, a 0.6 m wide floor strip (y = 0.7 to 1.3) points straight at the goal "
                          "and ends in lava 0.5 m short of the goal room: the direct way from p0 is a dead end.",
}
"""What makes each task hard, in a sentence."""

SUITE: tuple[str, ...] = ("LavaBridge-v0", "LavaBridgeDecoy-v0", "LavaBridgeFarStart-v0", "LavaBridgeNarrow-v0",
                          "LavaBridgeTwoCrossings-v0")
"""The tasks the start-distribution study runs on, easy to hard: the reference; the decoy, where the
screening put AuxSS ahead of the other three start distributions; the far start, where it put
GoalDist-SS ahead; the narrow bridge, the one maze where Omega-SS's weights are not near uniform; the
two crossings, where nothing succeeds from p0 within 100,000 steps and AuxSS pulled away from U-SS by
300,000. docs/design.md, section 7, gives the measurements behind each variant kept or left out; the
others stay registered."""


def task_layout(env_id: str) -> Layout:
    """The layout of the registered task `env_id`; ValueError naming it and the known ids otherwise."""
    try:
        return TASKS[env_id]
    except (KeyError, TypeError):
        raise ValueError(f"unknown Lava Bridge task {env_id!r}; expected one of {list(TASKS)}") from None
