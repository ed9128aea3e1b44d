"""A scripted expert: a velocity-tracking feedback controller that follows waypoints derived from the layout.

For each crossing of lava (`Layout.crossings`: one on LavaBridge-v0), west to east:
1. Line up in front of the crossing (its *mouth*), slowing down as it gets there.
2. Cross at a walking pace while steering back to the bridge's centre line; on a bent bridge, slow
   down before each corner and turn onto the next segment there.
Past the last crossing, head for the goal. Between two crossings (on an island), phase 1 of the next
one leads across the island to its mouth.

The controller is stateless (the phase is read off the observation), so `act` is a pure function
of the state and the demonstrations it produces are reproducible from a seed alone.
"""

from __future__ import annotations

import numpy as np

from lava_bridge_mj.layout import Layout


class _Crossing:
    """The waypoints of one crossing: its mouth, its segments (each with its floor rectangle), its exit."""

    def __init__(self, points: tuple[tuple[float, float], ...], layout: Layout, mouth_offset: float):
        (x0, y0) = points[0]
        self.mouth = np.array([x0 - mouth_offset, y0])
        self.entry_y = y0
        self.exit_x = points[-1][0] + layout.ball_radius
        half = layout.bridge_width / 2
        self.segments = []  # (start, end, axis along which it runs, its floor's bounds (x_lo, x_hi, y_lo, y_hi))
        for start, end in zip(points, points[1:]):
            axis = 0 if start[1] == end[1] else 1
            bounds = (min(start[0], end[0]) - half, max(start[0], end[0]) + half,
                      min(start[1], end[1]) - half, max(start[1], end[1]) + half)
            self.segments.append((np.array(start), np.array(end), axis, bounds))


class ScriptedExpert:
    """`act(obs) -> action` for Lava Bridge observations (x, y, vx, vy), on any task of the suite.

    Speeds are chosen for a careful expert: fast enough to finish LavaBridge-v0 in about 170 steps
    from p0 (so 3 trajectories make the paper's 500 transitions), slow enough on the bridge that its
    own small tracking errors never reach the lava; `turn_speed` is its pace through a corner.
    """

    def __init__(self, env=None, *, room_speed: float = 0.7, bridge_speed: float = 0.42,
                 position_gain: float = 1.5, velocity_gain: float = 4.0, mouth_offset: float = 0.3,
                 lineup_tolerance: float = 0.04, turn_speed: float = 0.1):
        layout = env.unwrapped.layout if env is not None else Layout()
        self.layout = layout
        self.room_speed, self.bridge_speed, self.turn_speed = room_speed, bridge_speed, turn_speed
        self.position_gain, self.velocity_gain = position_gain, velocity_gain
        self.lineup_tolerance = lineup_tolerance
        self.crossings = [_Crossing(points, layout, mouth_offset) for points in layout.crossings]
        self.goal = np.asarray(layout.goal, dtype=np.float64)

    def desired_velocity(self, obs: np.ndarray) -> np.ndarray:
        position = obs[:2]
        x, y = position
        for crossing in self.crossings:
            if x > crossing.exit_x:  # across this one
                continue
            # on a later segment of a bent bridge: follow it
            for index in range(len(crossing.segments) - 1, 0, -1):
                x_lo, x_hi, y_lo, y_hi = crossing.segments[index][3]
                if x_lo <= x <= x_hi and y_lo <= y <= y_hi:
                    return self._follow(crossing, index, position)
            lined_up = (x >= crossing.mouth[0] - self.lineup_tolerance
                        and abs(y - crossing.entry_y) <= self.lineup_tolerance)
            if lined_up:  # phase 2: on (or at the mouth of) the bridge, keep to its centre line
                return self._follow(crossing, 0, position)
            return self._towards(crossing.mouth, position, self.room_speed)  # phase 1
        return self._towards(self.goal, position, self.room_speed)  # across every crossing: the goal

    def _follow(self, crossing: _Crossing, index: int, position: np.ndarray) -> np.ndarray:
        """Along segment `index` at the bridge pace (slowing into a corner), steering to its line."""
        start, end, axis, _ = crossing.segments[index]
        speed = self.bridge_speed
        if index + 1 < len(crossing.segments):  # a corner ahead: arrive there at turn_speed
            remaining = abs(end[axis] - position[axis])
            speed = min(speed, max(self.turn_speed, self.position_gain * remaining))
        along = speed if end[axis] > start[axis] else -speed
        across = -self.position_gain * 2 * (position[1 - axis] - start[1 - axis])
        return np.array([along, across]) if axis == 0 else np.array([across, along])

    def _towards(self, target: np.ndarray, position: np.ndarray, speed: float) -> np.ndarray:
        velocity = self.position_gain * (target - position)
        norm = np.linalg.norm(velocity)
        return velocity if norm <= speed else velocity * (speed / norm)

    def act(self, obs) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float64)
        v_desired = self.desired_velocity(obs)
        # feed-forward against damping, plus feedback on the velocity error, in units of gear
        force = self.layout.damping * v_desired + self.velocity_gain * (v_desired - obs[2:])
        return np.clip(force / self.layout.gear, -1.0, 1.0).astype(np.float32)

    __call__ = act
