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

Why these defaults (docs/design.md section 3; docs/environment.md measures them): with 4 N of force, damping 1
(top speed 4 m/s) and 0.1 s per env step, momentum makes bridge states unsafe for a random policy,
so the start-state safety signal is informative, while a uniformly random policy from p0 practically
never crosses the 3 m long, 0.3 m wide bridge.

Three optional fields give the strip between the rooms other shapes (all empty by default, which is
the straight bridge above): `bridge_path` bends the bridge, `islands` put rooms between several
crossings of lava, and `decoys` add floor over the lava that leads nowhere. The lava is then the
strip minus that floor, cut into rectangles (`lava_pits`).
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
    """MuJoCo integration step (s). At 0.01 s a ball at top speed moves 4 cm per step along an axis, less
    than its radius, so it never ends a step with its centre inside a wall (every wall and lava pit is
    axis-aligned). A timestep of ball_radius / top_speed or more is refused: the ball could then pass
    through walls, lava and goal within one step."""
    frame_skip: int = 10
    """Physics steps per env step; the control period is timestep * frame_skip."""
    bridge_path: tuple[tuple[float, float], ...] = ()
    """The bridge's centre line as points (x, y) from its west end (x = -bridge_length / 2) to its east
    end (x = bridge_length / 2), each segment along x (eastwards) or along y, the first and last along x;
    the bridge is bridge_width wide around it, corners filled. Empty: straight along y = 0."""
    islands: tuple[tuple[float, float], ...] = ()
    """Stretches (x_west, x_east) of the strip between the rooms that are floor across its whole width:
    rooms between crossings of lava. The bridge path runs on through them; a segment along y must lie
    inside an island or clear of the islands' edges."""
    decoys: tuple[Box2D, ...] = ()
    """Extra floor over the lava, as rectangles (x, y, half_x, half_y): paths that lead nowhere."""

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
        for field, size, what in (("bridge_path", 2, "(x, y) points"), ("islands", 2, "(x_west, x_east) stretches"),
                                  ("decoys", 4, "(x, y, half_x, half_y) rectangles")):
            try:
                items = tuple(tuple(float(v) for v in item) for item in getattr(self, field))
            except (TypeError, ValueError):
                items = None
            if items is None or any(len(item) != size or not all(map(math.isfinite, item)) for item in items):
                raise ValueError(f"Layout.{field} must be a sequence of finite {what}, got {getattr(self, field)!r}")
            object.__setattr__(self, field, tuple(map(Box2D._make, items)) if field == "decoys" else items)
        positive = ("room_length", "room_width", "bridge_length", "bridge_width", "wall_thickness",
                    "goal_radius", "ball_radius", "ball_mass", "damping", "gear", "timestep")
        for name in positive:
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"Layout.{name} must be a positive finite number, got {value!r}")
        if isinstance(self.frame_skip, bool) or not (isinstance(self.frame_skip, int) and self.frame_skip >= 1):
            raise ValueError(f"Layout.frame_skip must be an integer >= 1, got {self.frame_skip!r}")
        # MuJoCo's Euler step damps implicitly, v' = (m v + h F) / (m + h c): from any speed up to F / c it
        # stays at most F / c, whatever the mass, so one physics step moves the ball at most h F / c per axis
        limit = self.ball_radius / self.top_speed
        if self.timestep >= limit:
            raise ValueError(
                f"Layout.timestep={self.timestep:g} lets the ball move {self.timestep * self.top_speed:g} m in one "
                f"physics step at its top speed gear / damping = {self.top_speed:g} m/s, not less than its radius "
                f"{self.ball_radius:g} m, so it could pass through walls and lava: timestep must be below "
                f"ball_radius * damping / gear = {limit:g} s")
        if self.bridge_width <= 2 * self.ball_radius:
            raise ValueError(
                f"Layout.bridge_width={self.bridge_width} leaves no room for a ball of radius "
                f"{self.ball_radius}: it must exceed {2 * self.ball_radius}")
        if self.goal_radius <= self.ball_radius:
            raise ValueError(f"Layout.goal_radius={self.goal_radius} must exceed ball_radius={self.ball_radius}")
        if self.bridge_width >= self.room_width:
            raise ValueError(f"Layout.bridge_width={self.bridge_width} must be below room_width={self.room_width}")
        self._check_strip()
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
    def straight(self) -> bool:
        """True for LavaBridge-v0's shape: one straight bridge along y = 0, no islands, no decoys."""
        return not (self.bridge_path or self.islands or self.decoys)

    @property
    def bridge(self) -> Box2D:
        """The rectangle the bridge spans (the bridge itself when it is straight)."""
        if self.straight:
            return Box2D(0.0, 0.0, self.bridge_length / 2, self.bridge_width / 2)
        segments = self.bridge_segments
        west, east = min(b.x - b.half_x for b in segments), max(b.x + b.half_x for b in segments)
        south, north = min(b.y - b.half_y for b in segments), max(b.y + b.half_y for b in segments)
        return Box2D((west + east) / 2, (south + north) / 2, (east - west) / 2, (north - south) / 2)

    @property
    def path(self) -> tuple[tuple[float, float], ...]:
        """The bridge's centre line: `bridge_path`, or the straight one from end to end along y = 0."""
        return self.bridge_path or ((-self.bridge_length / 2, 0.0), (self.bridge_length / 2, 0.0))

    @property
    def lava_stretches(self) -> tuple[tuple[float, float], ...]:
        """The x ranges (west, east) of the strip between the rooms that are lava but for the bridge:
        the whole strip, cut by the islands."""
        edges = [-self.bridge_length / 2, *(x for island in sorted(self.islands) for x in island),
                 self.bridge_length / 2]
        return tuple(zip(edges[::2], edges[1::2]))

    @property
    def crossings(self) -> tuple[tuple[tuple[float, float], ...], ...]:
        """The bridge path over each lava stretch, west to east: the centre lines of the crossings."""
        return tuple(_clip_path(self.path, west, east) for west, east in self.lava_stretches)

    @property
    def bridge_segments(self) -> tuple[Box2D, ...]:
        """The bridge's floor over the lava: one rectangle per segment of each crossing, bridge_width
        wide and reaching bridge_width / 2 past the segment's ends (filling the corners), cut at the
        ends of its lava stretch."""
        half = self.bridge_width / 2
        boxes = []
        for (west, east), crossing in zip(self.lava_stretches, self.crossings):
            for (x0, y0), (x1, y1) in zip(crossing, crossing[1:]):
                lo_x, hi_x = max(min(x0, x1) - half, west), min(max(x0, x1) + half, east)
                lo_y, hi_y = min(y0, y1) - half, max(y0, y1) + half
                boxes.append(Box2D((lo_x + hi_x) / 2, (lo_y + hi_y) / 2, (hi_x - lo_x) / 2, (hi_y - lo_y) / 2))
        return tuple(boxes)

    @property
    def lava_pits(self) -> dict[str, Box2D]:
        """The lava as rectangles, by MJCF geom name: the two pits either side of a straight bridge
        (`lava_north`, `lava_south`), otherwise `lava_0`, `lava_1`, ... covering each lava stretch
        but for the bridge's and decoys' floor."""
        if self.straight:
            half_y = (self.room_width - self.bridge_width) / 4
            y = self.bridge_width / 2 + half_y
            return {
                "lava_north": Box2D(0.0, y, self.bridge_length / 2, half_y),
                "lava_south": Box2D(0.0, -y, self.bridge_length / 2, half_y),
            }
        floor = self.bridge_segments + self.decoys
        boxes = [box for west, east in self.lava_stretches
                 for box in _uncovered((west, east), (-self.room_width / 2, self.room_width / 2), floor)]
        return {f"lava_{i}": box for i, box in enumerate(boxes)}

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

    def _check_strip(self) -> None:
        """ValueError unless the bridge path, islands and decoys describe floor inside the strip."""
        half_l, half_w = self.bridge_length / 2, self.room_width / 2
        previous_east = -half_l
        for west, east in sorted(self.islands):
            if not previous_east < west < east < half_l:
                raise ValueError(f"Layout.islands: ({west:g}, {east:g}) must lie strictly inside the strip "
                                 f"(-{half_l:g}, {half_l:g}) between the rooms, clear of the other islands")
            previous_east = east
        path = self.path
        if len(path) < 2 or path[0][0] != -half_l or path[-1][0] != half_l:
            raise ValueError(f"Layout.bridge_path must run from x = {-half_l:g} to x = {half_l:g}, got {path!r}")
        for (x0, y0), (x1, y1) in zip(path, path[1:]):
            along_x, along_y = y0 == y1 and x1 > x0, x0 == x1 and y0 != y1
            if not (along_x or along_y):
                raise ValueError(f"Layout.bridge_path: the segment {(x0, y0)} -> {(x1, y1)} must run eastwards "
                                 "along x or along y")
            if max(abs(y0), abs(y1)) + self.bridge_width / 2 > half_w:
                raise ValueError(f"Layout.bridge_path: the segment {(x0, y0)} -> {(x1, y1)} takes the bridge "
                                 f"past the walls at |y| = {half_w:g}")
            if along_y and any(abs(x0 - edge) < self.bridge_width / 2 for edge in self._stretch_edges()):
                raise ValueError(f"Layout.bridge_path: the segment {(x0, y0)} -> {(x1, y1)} along y must lie "
                                 "inside an island or at least bridge_width / 2 from the rooms' and islands' edges")
        if path[0][1] != path[1][1] or path[-2][1] != path[-1][1]:
            raise ValueError("Layout.bridge_path must leave the start room and enter the goal room along x")
        for decoy in self.decoys:
            if (decoy.half_x <= 0 or decoy.half_y <= 0 or abs(decoy.x) + decoy.half_x > half_l
                    or abs(decoy.y) + decoy.half_y > half_w):
                raise ValueError(f"Layout.decoys: {tuple(decoy)} must be a rectangle of positive size inside the "
                                 "strip between the rooms")

    def _stretch_edges(self) -> list[float]:
        return [x for stretch in self.lava_stretches for x in stretch]

    def disc_is_clear(self, disc: Disc) -> bool:
        """True when every ball centre in `disc` is inside the start room, off the walls and lava."""
        room = self.start_room
        margin = disc.radius + self.ball_radius
        return (abs(disc.x - room.x) + margin <= room.half_x
                and abs(disc.y - room.y) + margin <= room.half_y)


def _clip_path(path: tuple[tuple[float, float], ...], west: float, east: float) -> tuple[tuple[float, float], ...]:
    """The part of an eastward path within west <= x <= east (cut where segments along x cross them)."""
    points = []
    for (x0, y0), (x1, y1) in zip(path, path[1:]):
        if x1 < west or x0 > east:
            continue
        start, end = (max(x0, west), y0), (min(x1, east), y1)
        if not points or points[-1] != start:
            points.append(start)
        points.append(end)
    return tuple(p for i, p in enumerate(points) if i == 0 or p != points[i - 1])


def _uncovered(xs: tuple[float, float], ys: tuple[float, float], floor: tuple[Box2D, ...]) -> list[Box2D]:
    """The part of the rectangle xs x ys that no `floor` rectangle covers, as few rectangles: cut it
    on every floor edge, keep the uncovered cells, join them along y within a column, then join
    neighbouring columns with the same y ranges."""
    def edges(axis: int, bounds: tuple[float, float]) -> list[float]:
        cuts = {bounds[0], bounds[1]}
        for box in floor:
            centre, half = (box.x, box.half_x) if axis == 0 else (box.y, box.half_y)
            cuts |= {c for c in (centre - half, centre + half) if bounds[0] < c < bounds[1]}
        return sorted(cuts)

    def covered(x: float, y: float) -> bool:
        return any(abs(x - box.x) < box.half_x and abs(y - box.y) < box.half_y for box in floor)

    x_edges, y_edges = edges(0, xs), edges(1, ys)
    columns = []  # (x_lo, x_hi, [(y_lo, y_hi), ...])
    for x_lo, x_hi in zip(x_edges, x_edges[1:]):
        runs: list[list[float]] = []
        for y_lo, y_hi in zip(y_edges, y_edges[1:]):
            if covered((x_lo + x_hi) / 2, (y_lo + y_hi) / 2):
                continue
            if runs and runs[-1][1] == y_lo:
                runs[-1][1] = y_hi
            else:
                runs.append([y_lo, y_hi])
        runs_t = [tuple(run) for run in runs]
        if columns and columns[-1][1] == x_lo and columns[-1][2] == runs_t:
            columns[-1] = (columns[-1][0], x_hi, runs_t)
        else:
            columns.append((x_lo, x_hi, runs_t))
    return [Box2D((x_lo + x_hi) / 2, (y_lo + y_hi) / 2, (x_hi - x_lo) / 2, (y_hi - y_lo) / 2)
            for x_lo, x_hi, runs in columns for y_lo, y_hi in runs]
