"""A scripted expert: a velocity-tracking feedback controller that follows three waypoints.

1. Line up in front of the bridge (the *mouth*), slowing down as it gets there.
2. Cross the bridge at a walking pace while steering back to its axis.
3. Head for the goal.

The controller is stateless (the phase is read off the observation), so `act` is a pure function
of the state and the demonstrations it produces are reproducible from a seed alone.
"""

from __future__ import annotations

import numpy as np

from lava_bridge_mj.layout import Layout


class ScriptedExpert:
    """`act(obs) -> action` for LavaBridge-v0 observations (x, y, vx, vy).

    Speeds are chosen for a careful expert: fast enough to finish in about 170 steps from p0
    (so 3 trajectories make the paper's 500 transitions), slow enough on the bridge that its own
    small tracking errors never reach the lava.
    """

    def __init__(self, env=None, *, room_speed: float = 0.7, bridge_speed: float = 0.42,
                 position_gain: float = 1.5, velocity_gain: float = 4.0, mouth_offset: float = 0.3,
                 lineup_tolerance: float = 0.04):
        layout = env.unwrapped.layout if env is not None else Layout()
        self.layout = layout
        self.room_speed, self.bridge_speed = room_speed, bridge_speed
        self.position_gain, self.velocity_gain = position_gain, velocity_gain
        self.lineup_tolerance = lineup_tolerance
        half_bridge = layout.bridge_length / 2
        self.mouth = np.array([-half_bridge - mouth_offset, 0.0])
        self.bridge_end_x = half_bridge + layout.ball_radius
        self.goal = np.asarray(layout.goal, dtype=np.float64)

    def desired_velocity(self, obs: np.ndarray) -> np.ndarray:
        position = obs[:2]
        x, y = position
        lined_up = x >= self.mouth[0] - self.lineup_tolerance and abs(y) <= self.lineup_tolerance
        if x > self.bridge_end_x:  # phase 3: across, go to the goal
            return self._towards(self.goal, position, self.room_speed)
        if lined_up:  # phase 2: on (or at the mouth of) the bridge, keep to its axis
            return np.array([self.bridge_speed, -self.position_gain * 2 * y])
        return self._towards(self.mouth, position, self.room_speed)  # phase 1

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
