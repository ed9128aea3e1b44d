"""The Lava Bridge layout: one dataclass that every other part is derived from.

Coordinates are metres in the floor plane. The bridge is centred on the origin and runs along x;
the start room lies to its left (x < 0), the goal room to its right. Between the rooms, everything
that is not bridge is lava, bounded by the outer walls::

    +-----------------+===============+-----------------+
    |                 |   lava pit    |            (G)  |
    |  p0 blobs       |---------------|                 |
    |   o             =    bridge     =    goal room    |
    |  start room     |---------------|                 |
    |                 |   lava pit    |                 |
    +-----------------+===============+-----------------+

Why these defaults (DESIGN.md section 2, measured in the README): with 4 N of force, damping 1
(top speed 4 m/s) and 0.1 s per env step, momentum makes bridge states unsafe for a random policy,
so the start-state safety signal is informative, while a uniformly random policy from p0 practically
never crosses the 3 m long, 0.3 m wide bridge.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple


class Disc(NamedTuple):
    """A round patch of floor: a p0 blob or an ood spot."""

    x: float
    y: float
    radius: float


class Box2D(NamedTuple):
    """An axis-aligned rectangle by centre and half-sizes (MuJoCo's box convention)."""

    x: float
    y: float
    half_x: float
    half_y: float

    def distance_to(self, x: float, y: float) -> float:
        """Euclidean distance from a point to the rectangle (0 inside)."""
        dx = max(abs(x - self.x) - self.half_x, 0.0)
        dy = max(abs(y - self.y) - self.half_y, 0.0)
        return math.hypot(dx, dy)


@dataclasses.dataclass(frozen=True)
class Layout:
    """Geometry and physics of one Lava Bridge maze. Every field is a `gymnasium.make` keyword."""

    room_length: float = 4.0
    """Extent of each room along x (m)."""
    room_width: float = 4.0
    """Extent of the rooms and of the lava strip along y (m)."""
    bridge_length: float = 3.0
    """Length of the bridge, i.e. of the lava strip between the rooms (m)."""
    bridge_width: float = 0.3
    """Width of the bridge (m). The ball's centre must stay within (width / 2 - ball_radius) of its axis."""
    wall_thickness: float = 0.2
    """Thickness of the outer walls (m)."""
    goal: tuple[float, float] = (4.5, 1.0)
    """Centre of the goal disc (m); must lie in the goal room."""
    goal_radius: float = 0.3
    """The episode succeeds when the ball's centre comes within this distance of the goal (m)."""
    p0_blobs: tuple[Disc, ...] = (
        Disc(-4.5, 0.0, 0.2),
        Disc(-4.5, 1.2, 0.2),
        Disc(-4.5, -1.2, 0.2),
    )
    """The MDP's start distribution: a blob uniformly, then a point uniformly in it, at rest."""
    ood_spots: tuple[Disc, ...] = (
        Disc(-2.2, 1.6, 0.15),
        Disc(-2.2, -1.6, 0.15),
        Disc(-5.2, 1.7, 0.15),
        Disc(-3.5, -1.7, 0.15),
    )
    """The robustness benchmark's starts: near the lava edge beside the bridge (reached along the
    pit, not head-on) and in far corners of the start room."""
    ball_radius: float = 0.05
    """Radius of the point mass (m)."""
    ball_mass: float = 1.0
    """Mass of the point mass (kg)."""
    damping: float = 1.0
    """Viscous damping on each slide joint (N s/m); top speed per axis is gear / damping."""
    gear: float = 4.0
    """Force (N) per unit of action on each axis."""
    timestep: float = 0.01
    """MuJoCo integration step (s). At 0.01 s a ball at top speed moves 4 cm per step, less than its
    radius, so it never ends a step with its centre inside a wall."""
    frame_skip: int = 10
    """Physics steps per env step; the control period is timestep * frame_skip."""

    def __post_init__(self) -> None:
        # accept plain tuples for discs (e.g. from a JSON config); frozen, hence object.__setattr__
        for field in ("p0_blobs", "ood_spots"):
            try:
                discs = tuple(Disc(*map(float, disc)) for disc in getattr(self, field))
            except (TypeError, ValueError):
                raise ValueError(f"Layout.{field} must be a sequence of (x, y, radius) discs, "
                                 f"got {getattr(self, field)!r}") from None
            object.__setattr__(self, field, discs)
        try:
            goal = tuple(float(v) for v in self.goal)
        except (TypeError, ValueError):
            goal = ()
        if len(goal) != 2 or not all(map(math.isfinite, goal)):
            raise ValueError(f"Layout.goal must be two finite numbers (x, y), got {self.goal!r}")
        object.__setattr__(self, "goal", goal)
        positive = ("room_length", "room_width", "bridge_length", "bridge_width", "wall_thickness",
                    "goal_radius", "ball_radius", "ball_mass", "damping", "gear", "timestep")
        for name in positive:
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"Layout.{name} must be a positive finite number, got {value!r}")
        if isinstance(self.frame_skip, bool) or not (isinstance(self.frame_skip, int) and self.frame_skip >= 1):
            raise ValueError(f"Layout.frame_skip must be an integer >= 1, got {self.frame_skip!r}")
        if self.bridge_width <= 2 * self.ball_radius:
            raise ValueError(
                f"Layout.bridge_width={self.bridge_width} leaves no room for a ball of radius "
                f"{self.ball_radius}: it must exceed {2 * self.ball_radius}")
        if self.goal_radius <= self.ball_radius:
            raise ValueError(f"Layout.goal_radius={self.goal_radius} must exceed ball_radius={self.ball_radius}")
        if self.bridge_width >= self.room_width:
            raise ValueError(f"Layout.bridge_width={self.bridge_width} must be below room_width={self.room_width}")
        if not self.p0_blobs or not self.ood_spots:
            raise ValueError("Layout.p0_blobs and Layout.ood_spots must each name at least one disc")
        room = self.goal_room
        if (abs(self.goal[0] - room.x) + self.goal_radius > room.half_x
                or abs(self.goal[1] - room.y) + self.goal_radius > room.half_y):
            raise ValueError(f"Layout.goal={self.goal} with goal_radius={self.goal_radius} must lie "
                             f"inside the goal room {room}")
        for field in ("p0_blobs", "ood_spots"):
            for disc in getattr(self, field):
                if not all(map(math.isfinite, disc)) or disc.radius < 0:
                    raise ValueError(f"Layout.{field} disc {disc} must be finite with radius >= 0")
                if not self.disc_is_clear(disc):
                    raise ValueError(f"Layout.{field} disc {disc} overlaps a wall or lava, or leaves the start room")

    # --- derived geometry -------------------------------------------------------------------
    @property
    def half_extent(self) -> tuple[float, float]:
        """Half-size (x, y) of the free interior enclosed by the outer walls."""
        return self.bridge_length / 2 + self.room_length, self.room_width / 2

    @property
    def start_room(self) -> Box2D:
        hx, hy = self.half_extent
        return Box2D(-(hx + self.bridge_length / 2) / 2, 0.0, self.room_length / 2, hy)

    @property
    def goal_room(self) -> Box2D:
        hx, hy = self.half_extent
        return Box2D((hx + self.bridge_length / 2) / 2, 0.0, self.room_length / 2, hy)

    @property
    def bridge(self) -> Box2D:
        return Box2D(0.0, 0.0, self.bridge_length / 2, self.bridge_width / 2)

    @property
    def lava_pits(self) -> dict[str, Box2D]:
        """The two pits either side of the bridge, by MJCF geom name."""
        half_y = (self.room_width - self.bridge_width) / 4
        y = self.bridge_width / 2 + half_y
        return {
            "lava_north": Box2D(0.0, y, self.bridge_length / 2, half_y),
            "lava_south": Box2D(0.0, -y, self.bridge_length / 2, half_y),
        }

    @property
    def walls(self) -> dict[str, Box2D]:
        """The four outer walls, by MJCF geom name.

        Each spans the corners (the boxes overlap there): a wall ending exactly at a corner would put
        a ball centred in that corner on the edge of its box, where MuJoCo's contact normal is
        ambiguous and a push along the wall escapes through it.
        """
        hx, hy = self.half_extent
        t = self.wall_thickness / 2
        return {
            "wall_north": Box2D(0.0, hy + t, hx + 2 * t, t),
            "wall_south": Box2D(0.0, -hy - t, hx + 2 * t, t),
            "wall_east": Box2D(hx + t, 0.0, t, hy + 2 * t),
            "wall_west": Box2D(-hx - t, 0.0, t, hy + 2 * t),
        }

    @property
    def control_dt(self) -> float:
        """Seconds of simulated time per env step."""
        return self.timestep * self.frame_skip

    @property
    def top_speed(self) -> float:
        """Terminal speed along one axis under full force (m/s)."""
        return self.gear / self.damping

    def disc_is_clear(self, disc: Disc) -> bool:
        """True when every ball centre in `disc` is inside the start room, off the walls and lava."""
        room = self.start_room
        margin = disc.radius + self.ball_radius
        return (abs(disc.x - room.x) + margin <= room.half_x
                and abs(disc.y - room.y) + margin <= room.half_y)
