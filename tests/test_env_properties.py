"""Every task of the suite fuzzed with hypothesis: random states, actions and interleaved reset sequences.

Every property below is checked on states, actions and episodes that hypothesis draws (and shrinks
to a minimal counterexample on failure), on LavaBridge-v0 with the example counts below and on each
other task of `lava_bridge_mj.TASKS` with NEW_TASK_SHARE of them; `tests/test_env.py` holds the
example-based tests.

- valid states: ball centres anywhere in the maze interior (|x| <= hx, |y| <= hy of the task's
  `Layout`) whose footprint (radius `ball_radius`) stays clear of every lava pit, with a bias towards
  the bridge, the lava strip's end faces and the goal; velocities within the top speed (gear / damping) on
  each axis. Hypothesis favours the bounds, so states on the wall faces and at top speed come up often.
  Centres within CORNER_BAND of an exact corner (|x| = hx and |y| = hy) are left out there: the
  corners have a test of their own.
- actions: shape (2,) float32 or float64 arrays in [-10, 10] (clipped to [-1, 1] by MuJoCo), often
  exactly -1, 0, 1 or the extremes.
- episodes: a reset (to `p0` or `ood` with a drawn seed, or to a drawn state), then up to
  `MAX_STEPS` steps with a reset after every termination and, at random, in between.

Properties and the number of hypothesis examples each one runs on LavaBridge-v0 (module constants):
1. observations are finite and inside `observation_space` after every reset and step (TRAJECTORY_EXAMPLES);
2. the ball's centre never leaves the interior, after any step or any physics step within one
   (TRAJECTORY_EXAMPLES), also not from an exact corner (CORNER_EXAMPLES; the walls overlap at the corners so the contact
   normal there is never ambiguous);
3. lava always terminates: lava contact <=> info["lava"], which comes with terminated and the lava
   reward, and happens exactly when the footprint overlaps a pit, checked at every physics step
   against the layout's geometry (TRAJECTORY_EXAMPLES);
4. after a termination the env resets and keeps working as if fresh; reset refuses exactly the
   lava-terminal states and accepts goal-terminal ones (TRAJECTORY_EXAMPLES);
5. reset round trips are bit-exact (reset "state", reset "qpos"/"qvel", set_state, get_state),
   two envs given the same state and actions agree bit for bit, and resetting to any visited state
   replays the continuation (ROUND_TRIP_EXAMPLES);
6. invalid states (centre past a wall, footprint on lava, non-finite, faster than top speed) raise
   ValueError through every entry point and change nothing (INVALID_EXAMPLES);
7. the goal: info["is_success"] comes with terminated, the goal reward and a centre within
   goal_radius of the goal, and happens exactly when the centre gets there (GOAL_EXAMPLES).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import mujoco
import numpy as np
import pytest
from hypothesis import event, example, given, settings
from hypothesis import strategies as st

from lava_bridge_mj import START_NAMES, TASKS, LavaBridgeEnv, start_distribution

TRAJECTORY_EXAMPLES = 150
"""Random episodes per trajectory property (1-4); each runs up to MAX_STEPS env steps."""
GOAL_EXAMPLES = 150
"""Random episodes started near the goal (property 7)."""
ROUND_TRIP_EXAMPLES = 200
"""Valid states (plus action sequences) for the reset round trips and determinism (property 5)."""
INVALID_EXAMPLES = 300
"""Invalid states (property 6)."""
CORNER_EXAMPLES = 50
"""States exactly in a corner (property 2)."""
MAX_STEPS = 60
"""Env steps per drawn episode, at most."""
RESET_ONE_IN = 15
"""Between terminations, a step is replaced by a reset with probability about 1 / RESET_ONE_IN."""
NEW_TASK_SHARE = 0.2
"""The other tasks run this share of each count (at least 10): they share LavaBridge-v0's code, so
what is new there is the geometry, and the suite stays fast."""
TASK_IDS = list(TASKS)

EDGE_TOL = 1e-9
"""Slack on the exact contact boundaries (footprint meets a pit, centre reaches the goal radius)."""
MARGIN = 1e-6
"""Drawn valid states keep their footprint this far off lava; drawn lava states overlap by this much."""
CORNER_BAND = 1e-6
"""Valid-state draws keep at least this far from an exact corner on one axis (see the corner test)."""


# --- strategies ------------------------------------------------------------------------------------
def floats(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


def examples(env_id: str, count: int) -> int:
    """Hypothesis examples of a property on a task: `count` on LavaBridge-v0, fewer on the others."""
    return count if env_id == TASK_IDS[0] else max(10, round(count * NEW_TASK_SHARE))


class Task:
    """One task's geometry, its envs and its hypothesis strategies."""

    def __init__(self, env_id: str):
        self.env_id = env_id
        self.layout = layout = TASKS[env_id]
        self.hx, self.hy = layout.half_extent
        self.top_speed = layout.top_speed
        self.r = layout.ball_radius
        self.goal_x, self.goal_y = layout.goal
        self.goal_radius = layout.goal_radius
        self.pits = tuple(layout.lava_pits.values())
        self.bridge = layout.bridge
        self.strip_end = layout.bridge_length / 2  # the lava strip's end faces, at |x| = strip_end
        self.high = np.array([self.hx, self.hy, self.top_speed, self.top_speed])
        # Created once: every example starts with a reset, and the env's state is all in (qpos, qvel).
        # A lava reward unlike the step reward: the reward itself names the event.
        self.env = LavaBridgeEnv(layout=layout, lava_reward=-1.0)
        self.twin = LavaBridgeEnv(layout=layout, lava_reward=-1.0)  # identical: replays must give the same bits
        self.shadow = mujoco.MjData(self.env.model)  # replays env steps physics step by physics step
        self.positions = self._positions()
        self.velocities = st.tuples(floats(-self.top_speed, self.top_speed), floats(-self.top_speed, self.top_speed))
        self.invalid_states = self._invalid_states()

    def lava_distance(self, x: float, y: float) -> float:
        """Distance from a ball centre to the nearest lava pit (0 inside one)."""
        return min(pit.distance_to(x, y) for pit in self.pits)

    def goal_distance(self, x: float, y: float) -> float:
        return math.hypot(x - self.goal_x, y - self.goal_y)

    def near_corner(self, x: float, y: float) -> bool:
        return self.hx - abs(x) < CORNER_BAND and self.hy - abs(y) < CORNER_BAND

    def inside(self, state: np.ndarray) -> bool:
        """The ball's centre is within the interior (on a wall face counts as inside)."""
        return abs(state[0]) <= self.hx and abs(state[1]) <= self.hy

    def wall_sink(self, state: np.ndarray) -> float:
        """How far the ball's footprint reaches into the nearest wall (negative: clear of the walls)."""
        return max(abs(state[0]) - self.hx, abs(state[1]) - self.hy) + self.r

    def _positions(self) -> dict[str, st.SearchStrategy[tuple[float, float]]]:
        hx, hy, r, bridge = self.hx, self.hy, self.r, self.bridge
        gx, gy, gr = self.goal_x, self.goal_y, self.goal_radius
        # in a room just past the lava strip's end face (approaching the bridge or the pit)
        face = self.strip_end + r + 2 * MARGIN
        beside = st.tuples(st.sampled_from([-1.0, 1.0]), floats(0.0, 0.6), floats(-hy, hy)).map(
            lambda t: (t[0] * min(face + t[1], hx), t[2]))
        return {
            "anywhere": st.tuples(floats(-hx, hx), floats(-hy, hy)),
            "bridge": st.tuples(floats(bridge.x - bridge.half_x - 2 * r, bridge.x + bridge.half_x + 2 * r),
                                floats(bridge.y - (bridge.half_y - r), bridge.y + bridge.half_y - r)),
            "beside a pit": beside,
            "near the goal": st.tuples(floats(gx - 3 * gr, min(gx + 3 * gr, hx)),
                                       floats(max(gy - 3 * gr, -hy), min(gy + 3 * gr, hy))),
        }

    def valid_states(self, *regions: str, corners: bool = False) -> st.SearchStrategy[np.ndarray]:
        """Valid physics states (x, y, vx, vy) with positions from the named regions (default: all)."""
        positions = st.one_of(*(self.positions[r] for r in regions or self.positions))
        positions = positions.filter(lambda p: self.lava_distance(*p) > self.r + MARGIN
                                     and (corners or not self.near_corner(*p)))
        return st.builds(lambda p, v: np.array([*p, *v], dtype=np.float64), positions, self.velocities)

    def _invalid_states(self) -> dict[str, st.SearchStrategy[np.ndarray]]:
        hx, hy, r = self.hx, self.hy, self.r
        lava_position = st.tuples(floats(-(self.strip_end + r), self.strip_end + r), floats(-hy, hy)).filter(
            lambda p: self.lava_distance(*p) < r - MARGIN)
        return {
            "outside": st.one_of(
                st.builds(_outside, self.valid_states(), st.just(0), st.sampled_from([-1.0, 1.0]),
                          st.floats(hx, 1e6, exclude_min=True)),
                st.builds(_outside, self.valid_states(), st.just(1), st.sampled_from([-1.0, 1.0]),
                          st.floats(hy, 1e6, exclude_min=True)),
            ),
            "lava": st.builds(lambda p, v: np.array([*p, *v]), lava_position, self.velocities),
            "non-finite": st.builds(lambda s, i, bad: np.array([*s[:i], bad, *s[i + 1:]]),
                                    self.valid_states(), st.integers(0, 3),
                                    st.sampled_from([np.nan, np.inf, -np.inf])),
            "too fast": st.builds(lambda s, i, sign, v: np.array([*s[:i], sign * v, *s[i + 1:]]),
                                  self.valid_states(), st.integers(2, 3), st.sampled_from([-1.0, 1.0]),
                                  st.floats(self.top_speed, 1e6, exclude_min=True)),
        }

def same_bits(a: np.ndarray, b: Any) -> bool:
    """Bit-for-bit equality of float64 vectors (tells -0.0 from 0.0)."""
    return a.dtype == np.float64 and a.tobytes() == np.asarray(b, dtype=np.float64).tobytes()


TASK_CASES: dict[str, Task] = {}


def task(env_id: str) -> Task:
    """The task's geometry, envs and strategies, built on first use."""
    if env_id not in TASK_CASES:
        TASK_CASES[env_id] = Task(env_id)
    return TASK_CASES[env_id]


ACTION_COMPONENTS = st.one_of(floats(-10.0, 10.0), st.sampled_from([-1.0, 0.0, 1.0, -10.0, 10.0]))
ACTION_DTYPES = st.sampled_from([np.float64, np.float32])
ACTIONS = st.builds(lambda a, b, dtype: np.array([a, b], dtype=dtype),
                    ACTION_COMPONENTS, ACTION_COMPONENTS, ACTION_DTYPES)
SEEDS = st.integers(0, 2**32 - 1)


def reset_requests(states: st.SearchStrategy[np.ndarray], named: bool = True
                   ) -> st.SearchStrategy[tuple[int | None, dict]]:
    """(seed, options) for env.reset: a state, or (`named`) a start distribution with a seed."""
    to_state = st.tuples(st.none(), states.map(lambda s: {"state": s}))
    if not named:
        return to_state
    return st.one_of(st.tuples(SEEDS, st.sampled_from(START_NAMES).map(lambda name: {"start": name})), to_state)


def _outside(base: np.ndarray, axis: int, sign: float, value: float) -> np.ndarray:
    state = base.copy()
    state[axis] = sign * value
    return state


# --- episodes ----------------------------------------------------------------------------------------
class Reset(NamedTuple):
    seed: int | None
    options: dict
    obs: np.ndarray
    info: dict
    after_termination: bool


class Step(NamedTuple):
    before: np.ndarray
    action: np.ndarray
    obs: np.ndarray
    reward: float
    terminated: bool
    truncated: bool
    info: dict
    lava_contact: bool
    goal_contact: bool


def run_episodes(data: st.DataObject, t: Task, states: st.SearchStrategy[np.ndarray], named: bool = True
                 ) -> list[Reset | Step]:
    """Draw and play a reset, then up to MAX_STEPS steps, resetting after every termination and now and then."""
    env = t.env
    resets = reset_requests(states, named)
    record: list[Reset | Step] = []

    def reset(after_termination: bool) -> np.ndarray:
        seed, options = data.draw(resets, label="reset")
        obs, info = env.reset(seed=seed, options=options)
        record.append(Reset(seed, options, obs, info, after_termination))
        return obs

    obs = reset(False)
    dtype = data.draw(ACTION_DTYPES, label="action dtype")  # per episode: fewer draws per step
    actions = st.builds(lambda a, b: np.array([a, b], dtype=dtype), ACTION_COMPONENTS, ACTION_COMPONENTS)
    for _ in range(data.draw(st.integers(1, MAX_STEPS), label="steps")):
        if data.draw(st.integers(0, RESET_ONE_IN - 1), label="reset now?") == 0:
            obs = reset(False)
            continue
        action = data.draw(actions, label="action")
        new_obs, reward, terminated, truncated, info = env.step(action)
        record.append(Step(obs, action, new_obs, reward, terminated, truncated, info,
                           env.lava_contact(), env.goal_contact()))
        obs = new_obs
        if terminated:
            event("lava" if info["lava"] else "goal" if info["is_success"] else "terminated?")
            obs = reset(True)
    return record


def steps_of(record: list[Reset | Step]) -> list[Step]:
    return [r for r in record if isinstance(r, Step)]


def physics_steps(t: Task, state: np.ndarray, action: np.ndarray) -> list[np.ndarray]:
    """One env step replayed with plain mj_step from `state`: the state after each physics step."""
    model, data = t.env.model, t.shadow
    mujoco.mj_resetData(model, data)
    data.qpos[:], data.qvel[:] = state[:2], state[2:]
    data.ctrl[:] = action
    states = []
    for _ in range(t.env.frame_skip):
        mujoco.mj_step(model, data)
        states.append(np.concatenate([data.qpos, data.qvel]))
    return states


# --- 1. observations ----------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_observations_are_finite_and_in_the_observation_space(env_id):
    t = task(env_id)

    @settings(max_examples=examples(env_id, TRAJECTORY_EXAMPLES), deadline=None)
    @given(data=st.data())
    def check(data):
        space = t.env.observation_space
        np.testing.assert_array_equal(space.high, t.high)
        np.testing.assert_array_equal(space.low, -t.high)
        for item in run_episodes(data, t, t.valid_states()):
            obs = item.obs
            assert isinstance(obs, np.ndarray) and obs.shape == (4,) and obs.dtype == np.float64, obs
            assert np.isfinite(obs).all(), item
            assert np.all(np.abs(obs) <= t.high), item
            assert space.contains(obs), item
            assert not np.shares_memory(obs, t.env.data.qpos) and not np.shares_memory(obs, t.env.data.qvel)

    check()


# --- 2. walls -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_the_ball_centre_never_leaves_the_interior(env_id):
    t = task(env_id)

    @settings(max_examples=examples(env_id, TRAJECTORY_EXAMPLES), deadline=None)
    @given(data=st.data())
    def check(data):
        for step in steps_of(run_episodes(data, t, t.valid_states())):
            assert t.inside(step.obs), step
            # nor between observations: replay the step physics step by physics step. The footprint
            # sinks into a wall by at most one physics step of travel at top speed (less than a radius,
            # as Layout.timestep promises), or by no more than it already did at the start.
            allowed = max(t.wall_sink(step.before), t.top_speed * t.layout.timestep) + EDGE_TOL
            for k, state in enumerate(physics_steps(t, step.before, step.action), 1):
                assert t.inside(state), (k, state, step)
                assert t.wall_sink(state) <= allowed, (k, state, step)

    check()


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_a_ball_started_exactly_in_a_corner_stays_inside_the_maze(env_id):
    """Either reset refuses a corner state or the ball stays inside from it (walls span the corners)."""
    t = task(env_id)

    @settings(max_examples=examples(env_id, CORNER_EXAMPLES), deadline=None)
    @given(signs=st.tuples(st.sampled_from([-1.0, 1.0]), st.sampled_from([-1.0, 1.0])),
           velocity=t.velocities, actions=st.lists(ACTIONS, min_size=1, max_size=10))
    @example(signs=(1.0, 1.0), velocity=(0.0, 0.0), actions=[np.array([1.0, 0.0])])  # once escaped the maze
    def check(signs, velocity, actions):
        state = np.array([signs[0] * t.hx, signs[1] * t.hy, *velocity])
        try:
            obs, _ = t.env.reset(options={"state": state})
        except ValueError:
            return  # a fix may refuse corner states ...
        assert same_bits(obs, state)  # ... or keep the ball inside from them
        for action in actions:
            obs, *_ = t.env.step(action)
            assert t.inside(obs) and t.env.observation_space.contains(obs), (state, action, obs)

    check()


# --- 3. lava ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_lava_always_terminates_and_only_lava_does(env_id):
    t = task(env_id)

    @settings(max_examples=examples(env_id, TRAJECTORY_EXAMPLES), deadline=None)
    @given(data=st.data())
    def check(data):
        record = run_episodes(data, t, t.valid_states())
        for step in steps_of(record):
            obs, info = step.obs, step.info
            assert step.lava_contact == info["lava"], step
            footprint_gap = t.lava_distance(*obs[:2]) - t.r  # < 0: the footprint overlaps a pit
            if info["lava"]:
                assert step.terminated and not step.truncated and not info["is_success"], step
                assert step.reward == t.env.lava_reward == -1.0, step
                assert footprint_gap <= EDGE_TOL, step
            else:
                assert footprint_gap >= -EDGE_TOL, step  # a footprint on lava never goes unpunished
                assert step.reward in (t.env.step_reward, t.env.goal_reward), step
            # checked at every physics step: the step ends at the first one whose footprint meets a pit
            states = physics_steps(t, step.before, step.action)
            gaps = [t.lava_distance(*s[:2]) - t.r for s in states]
            first_touch = next((k for k, gap in enumerate(gaps) if gap < -EDGE_TOL), None)
            if first_touch is not None:
                assert step.terminated, (first_touch, states[first_touch], step)
            if info["lava"]:
                k = next(k for k, s in enumerate(states) if same_bits(s, obs))  # where the env stopped
                assert all(gap >= -EDGE_TOL for gap in gaps[:k]), (k, gaps, step)  # nothing touched before
            if not step.terminated:
                assert same_bits(states[-1], obs), (states[-1], step)  # the replay is the env's step

    check()


# --- 4. termination, then reset ---------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_after_a_termination_the_env_resets_and_keeps_working(env_id):
    t = task(env_id)
    env, twin = t.env, t.twin

    @settings(max_examples=examples(env_id, TRAJECTORY_EXAMPLES), deadline=None)
    @given(data=st.data())
    def check(data):
        record = run_episodes(data, t, t.valid_states("bridge", "beside a pit", "near the goal"))
        for before, item, after in zip(record, record[1:], record[2:] + [None]):
            if not isinstance(item, Reset):
                continue
            assert item.info == {"is_success": False, "lava": False}, item
            if "state" in item.options:
                assert same_bits(item.obs, item.options["state"]), item
            else:  # a named start distribution, seeded: a known draw from it
                expected = start_distribution(t.layout, item.options["start"]).sample(np.random.default_rng(item.seed))
                assert same_bits(item.obs, expected), item
            assert t.lava_distance(*item.obs[:2]) > t.r and t.inside(item.obs), item
            if not item.after_termination:
                continue
            # the terminal state: refused by reset if on lava, a valid state to start from if at the goal
            if before.info["lava"]:
                with pytest.raises(ValueError, match="lava"):
                    twin.reset(options={"state": before.obs})
            else:
                assert same_bits(twin.reset(options={"state": before.obs})[0], before.obs), before
            # and the episode after it is the one a fresh env plays from the reset state
            if isinstance(after, Step):
                twin.reset(options={"state": item.obs})
                fresh = twin.step(after.action)
                assert same_bits(fresh[0], after.obs), (fresh, after)
                assert fresh[1:] == (after.reward, after.terminated, after.truncated, after.info), (fresh, after)
        # the env still runs from wherever the episodes left it
        last = record[-1]
        obs, _, terminated, _, _ = env.step(np.zeros(2))
        assert np.isfinite(obs).all()
        if not terminated:
            assert same_bits(obs, physics_steps(t, last.obs, np.zeros(2))[-1]), (last, obs)

    check()


# --- 5. reset round trips and determinism ------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_reset_round_trips_are_exact_and_runs_are_deterministic(env_id):
    t = task(env_id)
    env, twin = t.env, t.twin

    @settings(max_examples=examples(env_id, ROUND_TRIP_EXAMPLES), deadline=None)
    @given(state=t.valid_states(corners=True), actions=st.lists(ACTIONS, max_size=MAX_STEPS),
           replay_from=st.integers(0, MAX_STEPS))
    def check(state, actions, replay_from):
        env.step(np.ones(2))  # move away first: the round trip must not depend on where the env was
        obs, info = env.reset(options={"state": state.copy()})
        assert same_bits(obs, state) and same_bits(env.get_state(), state)
        assert info == {"is_success": False, "lava": False}
        obs, _ = env.reset(options={"qpos": tuple(state[:2]), "qvel": list(state[2:])})
        assert same_bits(obs, state) and same_bits(env.get_state(), state)
        env.step(-np.ones(2))
        env.set_state(state[:2], state[2:])
        assert same_bits(env.get_state(), state)

        # two envs from the same state, given the same actions, agree bit for bit
        env.reset(options={"state": state})
        twin.reset(options={"state": state})
        trajectory = []
        for step, action in enumerate(actions):
            a = env.step(action)
            b = twin.step(action.copy())
            assert same_bits(a[0], b[0]) and a[1:] == b[1:], (step, a, b)
            trajectory.append(a)
            if a[2]:
                break
        # and a reset to any visited, non-terminal state replays the rest (the state is (qpos, qvel))
        k = min(replay_from, len(trajectory))
        if k < len(trajectory) and k > 0:
            visited = trajectory[k - 1][0]
            obs, _ = twin.reset(options={"state": visited})
            assert same_bits(obs, visited)
            for step in range(k, len(trajectory)):
                replayed = twin.step(actions[step])
                assert same_bits(replayed[0], trajectory[step][0]) and replayed[1:] == trajectory[step][1:], step

    check()


# --- 6. invalid states --------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_invalid_states_raise_and_change_nothing(env_id):
    t = task(env_id)
    env, twin = t.env, t.twin

    @settings(max_examples=examples(env_id, INVALID_EXAMPLES), deadline=None)
    @given(kind_and_state=st.one_of(*(st.tuples(st.just(k), s) for k, s in t.invalid_states.items())),
           start=t.valid_states(), action=ACTIONS, probe=ACTIONS)
    def check(kind_and_state, start, action, probe):
        kind, bad = kind_and_state
        event(kind)
        env.reset(options={"state": start})
        _, _, terminated, _, _ = env.step(action)
        if terminated:  # a terminal lava state is itself invalid: begin from a valid one
            env.reset(options={"state": start})
        before = env.get_state()
        attempts = [
            lambda: env.reset(options={"state": bad}),
            lambda: env.reset(options={"state": list(bad)}),
            lambda: env.reset(seed=0, options={"qpos": bad[:2], "qvel": bad[2:]}),
            lambda: env.set_state(bad[:2], bad[2:]),
        ]
        if kind in ("outside", "lava", "non-finite") and np.all(bad[2:] == 0):
            attempts.append(lambda: env.reset(options={"qpos": bad[:2]}))
        for attempt in attempts:
            with pytest.raises(ValueError):
                attempt()
            assert same_bits(env.get_state(), before), (kind, bad)
        # nothing hidden changed either: the next step is the one a fresh env takes from `before`
        twin.reset(options={"state": before})
        a, b = env.step(probe), twin.step(probe)
        assert same_bits(a[0], b[0]) and a[1:] == b[1:], (a, b)

    check()


# --- 7. the goal --------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_success_exactly_when_the_centre_reaches_the_goal(env_id):
    t = task(env_id)

    @settings(max_examples=examples(env_id, GOAL_EXAMPLES), deadline=None)
    @given(data=st.data())
    def check(data):
        for step in steps_of(run_episodes(data, t, t.valid_states("near the goal"), named=False)):
            obs, info = step.obs, step.info
            assert step.goal_contact == info["is_success"], step
            distance = t.goal_distance(*obs[:2])
            if info["is_success"]:
                assert step.terminated and not step.truncated and not info["lava"], step
                assert step.reward == t.env.goal_reward == 1.0, step
                assert distance <= t.goal_radius + EDGE_TOL, step
            else:
                assert distance >= t.goal_radius - EDGE_TOL, step  # reaching the goal never goes unnoticed
            states = physics_steps(t, step.before, step.action)
            first_in = next((k for k, s in enumerate(states)
                             if t.goal_distance(*s[:2]) < t.goal_radius - EDGE_TOL), None)
            if first_in is not None:
                assert step.terminated, (first_in, states[first_in], step)
            if info["is_success"]:
                k = next(k for k, s in enumerate(states) if same_bits(s, obs))
                assert all(t.goal_distance(*s[:2]) >= t.goal_radius - EDGE_TOL for s in states[:k]), (k, step)

    check()
