"""LavaBridge-v0: API conformance, exact physics facts, input validation, rendering, invariants.

Geometry of the default layout: bridge x in [-1.5, 1.5], |y| <= 0.15; lava elsewhere in that x
range; rooms either side; outer walls' inner faces at |x| = 5.5, |y| = 2. Ball radius 0.05, top
speed 4 m/s per axis, control period 0.1 s (10 physics steps of 0.01 s). The tests that need no
particular geometry run on every task of the suite (`TASK_IDS`).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys

import gymnasium
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import lava_bridge_mj
from lava_bridge_mj import TASKS, Layout, LavaBridgeEnv, start_distribution
from lava_bridge_mj.mjcf import build_mjcf, load_model, shipped_xml

LAYOUT = Layout()
R = LAYOUT.ball_radius
H = LAYOUT.timestep
DT = LAYOUT.control_dt
SAFE_STATE = np.array([-4.5, 0.0, 0.0, 0.0])  # at rest in the start room, far from everything
TASK_IDS = list(TASKS)


@pytest.fixture
def env():
    env = LavaBridgeEnv()
    yield env
    env.close()


def lava_distance(x: float, y: float) -> float:
    """Distance from a ball centre to the nearest lava pit (0 inside one)."""
    return min(pit.distance_to(x, y) for pit in LAYOUT.lava_pits.values())


def goal_distance(obs: np.ndarray) -> float:
    return math.hypot(obs[0] - LAYOUT.goal[0], obs[1] - LAYOUT.goal[1])


def renderer_unavailable() -> str | None:
    """Why off-screen rendering cannot work here, or None when it can.

    Probed in a child process: a missing GL backend can abort the interpreter rather than raise.
    """
    code = ("import lava_bridge_mj, mujoco; "
            "mujoco.Renderer(mujoco.MjModel.from_xml_string('<mujoco/>'), height=8, width=8).close()")
    probe = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    if probe.returncode != 0:
        tail = (probe.stderr.strip().splitlines() or ["(no output)"])[-1]
        return f"no off-screen OpenGL (MUJOCO_GL={os.environ.get('MUJOCO_GL')}): mujoco.Renderer failed: {tail}"
    return None


NO_GL = renderer_unavailable()
needs_gl = pytest.mark.skipif(NO_GL is not None, reason=str(NO_GL))


# --- gymnasium API ------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
@pytest.mark.parametrize("render_mode", [None, pytest.param("rgb_array", marks=needs_gl)])
def test_gymnasium_env_checker_passes(env_id, render_mode):
    env = gymnasium.make(env_id, render_mode=render_mode, width=240, height=100)
    try:
        check_env(env.unwrapped)
    finally:
        env.close()


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_make_has_500_step_time_limit_and_truncates_there(env_id):
    env = gymnasium.make(env_id)
    assert env.spec.max_episode_steps == 500 == lava_bridge_mj.MAX_EPISODE_STEPS
    blob = TASKS[env_id].p0_blobs[0]
    safe_state = np.array([blob.x, blob.y, 0.0, 0.0])  # at rest in the start room, far from everything
    env.reset(seed=0, options={"state": safe_state})
    for t in range(1, 501):
        obs, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        assert not terminated and reward == 0.0
        assert truncated == (t == 500), t
    np.testing.assert_array_equal(obs, safe_state)  # at rest with no force, nothing moves
    env.close()


def test_make_with_module_prefix_imports_and_registers_in_a_fresh_interpreter():
    code = ("import gymnasium; env = gymnasium.make('lava_bridge_mj:LavaBridge-v0'); "
            "obs, _ = env.reset(seed=0); print(type(env.unwrapped).__name__, obs.shape)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["LavaBridgeEnv", "(4,)"]
    env = gymnasium.make("lava_bridge_mj:LavaBridge-v0")  # and in this one, already imported
    assert env.spec.max_episode_steps == 500
    env.close()


def test_spaces():
    env = LavaBridgeEnv()
    assert env.action_space == gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)
    assert env.observation_space.dtype == np.float64 and env.observation_space.shape == (4,)
    np.testing.assert_array_equal(env.observation_space.high, [5.5, 2.0, 4.0, 4.0])
    np.testing.assert_array_equal(env.observation_space.low, [-5.5, -2.0, -4.0, -4.0])
    assert env.dt == pytest.approx(0.1) and env.frame_skip == 10


# --- seeding and determinism ------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_seeded_runs_are_identical_including_resets(env_id):
    actions = np.random.default_rng(7).uniform(-1, 1, size=(300, 2)).astype(np.float32)
    runs = []
    for _ in range(2):
        env = gymnasium.make(env_id)
        obs, _ = env.reset(seed=123, options={"start": "ood"})
        record, resets = [obs], 0
        for t, action in enumerate(actions):
            obs, reward, terminated, truncated, info = env.step(action)
            record += [obs, reward, terminated, truncated, info["is_success"], info["lava"]]
            if terminated or truncated or t % 60 == 59:  # also reset on a clock, so resets surely happen
                obs, _ = env.reset(options={"start": "ood"})
                record.append(obs)
                resets += 1
        env.close()
        assert resets >= 5
        runs.append(record)
    assert len(runs[0]) == len(runs[1])
    for a, b in zip(*runs):
        assert np.array_equal(a, b), (a, b)


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_seeded_reset_equals_start_distribution_sample(env_id):
    """gymnasium seeds np_random as default_rng(seed): the first reset is a known, exact draw."""
    layout = TASKS[env_id]
    env = LavaBridgeEnv(layout=layout)
    for name in ("p0", "ood"):
        for seed in (0, 1, 2024):
            obs, _ = env.reset(seed=seed, options={"start": name})
            expected = start_distribution(layout, name).sample(np.random.default_rng(seed))
            np.testing.assert_array_equal(obs, expected)
    default, _ = env.reset(seed=5)
    np.testing.assert_array_equal(default, start_distribution(layout, "p0").sample(np.random.default_rng(5)))


def test_different_seeds_give_different_starts():
    env = LavaBridgeEnv()
    starts = {tuple(env.reset(seed=seed)[0]) for seed in range(20)}
    assert len(starts) == 20


# --- exact state round trips -------------------------------------------------------------------------
@pytest.mark.parametrize("state", [
    [-4.5, 0.0, 0.0, 0.0],
    [-2.0, 1.3, 3.99, -2.5],
    [0.3, 0.0999999, 0.1, -0.2],  # on the bridge, footprint just short of the north pit
    [5.45, -1.95, -1.0, 4.0],     # pressed into the south-east corner, at top speed
    [1.0 / 3.0, -0.07, np.pi / 10, -np.e / 10],
])
def test_reset_state_round_trip_is_exact(env, state):
    state = np.array(state, dtype=np.float64)
    obs, info = env.reset(options={"state": state})
    assert obs.dtype == np.float64 and np.array_equal(obs, state)
    assert info == {"is_success": False, "lava": False}
    assert np.array_equal(env.get_state(), state)
    obs, _ = env.reset(options={"qpos": state[:2], "qvel": state[2:]})
    assert np.array_equal(obs, state)
    obs, _ = env.reset(options={"state": list(state)})  # any sequence of floats
    assert np.array_equal(obs, state)


def test_reset_qpos_alone_starts_at_rest(env):
    obs, _ = env.reset(options={"qpos": (-3.0, 0.5)})
    assert np.array_equal(obs, [-3.0, 0.5, 0.0, 0.0])


@pytest.mark.parametrize("start_state, push", [
    ([-4.5, 0.0, 0.0, 0.0], None),            # random flight in the start room
    # Pressed into a corner, two active wall contacts: bit-exact too, because the model disables
    # the solver's warm start (otherwise data.qacc_warmstart would be hidden state that reset clears).
    ([-5.3, 1.8, 0.0, 0.0], (-1.0, 1.0)),
])
def test_reset_to_a_visited_state_reproduces_the_continuation(start_state, push):
    """Resetting to a state reached by stepping gives the trajectory that continuing gives."""
    rng = np.random.default_rng(3)
    lead = [np.array(push)] * 8 if push else list(rng.uniform(-1, 1, (25, 2)))
    tail = rng.uniform(-1, 1, (40, 2))
    env = LavaBridgeEnv()
    env.reset(options={"state": start_state})
    for action in lead:
        assert not env.step(action)[2]
    state = env.get_state()
    if push:
        assert env.data.ncon == 2  # the round trip is tested with contacts in play
    continued = [env.step(a) for a in tail]
    env.reset(options={"state": state})
    replayed = [env.step(a) for a in tail]
    for (o1, r1, te1, tr1, i1), (o2, r2, te2, tr2, i2) in zip(continued, replayed):
        assert np.array_equal(o1, o2)
        assert (r1, te1, tr1, i1) == (r2, te2, tr2, i2)


# --- lava and goal --------------------------------------------------------------------------------
def first_step_beyond(distance: float, speed: float) -> int:
    """Physics steps, with no force, until a ball moving at `speed` has covered `distance`.

    MuJoCo's Euler integrator treats damping implicitly: v_n = v_0 / (1 + h b / m)^n and
    x_n = x_0 + h (v_1 + ... + v_n) = x_0 + v_0 m / b (1 - (1 + h b / m)^-n), here with b / m = 1.
    """
    return math.ceil(math.log(1 / (1 - distance / speed)) / math.log(1 + H))


@pytest.mark.parametrize("state", [
    (0.0, 0.0, 0.0, 2.0),     # the brief's example: off the bridge northwards, fast
    (0.0, 0.0, 0.0, 0.3),     # slowly: the ball coasts for several env steps first
    (0.0, 0.0, 0.0, -0.5),    # southwards
    (-1.0, 0.05, 0.0, 0.25),
    (-1.75, 1.0, 0.9, 0.0),   # from the start room straight into the pit's west face
    (1.8, -0.6, -0.4, 0.0),   # from the goal room back into the south pit
])
def test_lava_terminates_at_the_step_kinematics_predicts(env, state):
    x0, y0, vx, vy = state
    if vx == 0:  # heading along y on the bridge: footprint reaches the pit at |y| = 0.15 - r
        distance = LAYOUT.bridge_width / 2 - R - abs(y0)
        speed = abs(vy)
    else:        # heading along x at a pit's end face |x| = 1.5: footprint reaches it at 1.5 + r
        distance = abs(x0) - LAYOUT.bridge_length / 2 - R
        speed = abs(vx)
    physics_steps = first_step_beyond(distance, speed)
    expected_env_step = math.ceil(physics_steps / LAYOUT.frame_skip)
    # cross-check with the continuous-time bound t* = -ln(1 - d / v)
    t_star = -math.log(1 - distance / speed)
    assert abs(expected_env_step - math.ceil(t_star / DT)) <= 1

    previous, _ = env.reset(options={"state": state})
    assert lava_distance(*previous[:2]) > R
    for k in range(1, 100):
        obs, reward, terminated, truncated, info = env.step(np.zeros(2))
        if terminated:
            break
        assert lava_distance(*obs[:2]) > R and reward == 0.0
        previous = obs
    assert k == expected_env_step, (k, expected_env_step)
    assert reward == env.lava_reward == 0.0 and info == {"is_success": False, "lava": True} and not truncated
    # the moment: the terminal footprint overlaps a pit, the one before did not
    assert lava_distance(*obs[:2]) <= R + 1e-9
    assert abs(obs[1]) + R >= LAYOUT.bridge_width / 2 - 1e-9 or abs(obs[0]) + R >= 1.5 - 1e-9
    # and it is the very first physics step at which that happens (checked every physics step)
    data = mujoco.MjData(env.model)
    data.qpos[:], data.qvel[:] = state[:2], state[2:]
    for _ in range(physics_steps - 1):
        mujoco.mj_step(env.model, data)
        assert lava_distance(*data.qpos) > R
    mujoco.mj_step(env.model, data)
    assert lava_distance(*data.qpos) <= R
    np.testing.assert_allclose(obs, np.concatenate([data.qpos, data.qvel]), rtol=0, atol=1e-12)


def test_lava_at_full_speed_along_a_pit_corner_is_not_missed(env):
    """At 4 m/s the ball moves 4 cm per physics step: it cannot skip the 0.05 m footprint band."""
    env.reset(options={"state": [-1.7, 0.3, 4.0, 0.0]})
    obs, reward, terminated, _, info = env.step([1.0, 0.0])
    assert terminated and info["lava"] and reward == env.lava_reward
    assert R - 0.04 <= lava_distance(*obs[:2]) <= R


@pytest.mark.parametrize("state", [
    (4.1, 1.0, 1.0, 0.0),
    (4.5, 0.6, 0.0, 1.0),
    (4.9, 1.0, -1.0, 0.0),
    (4.75, 1.25, -0.5, -0.5),
    (4.5, 1.33, 0.0, -0.2),
])
def test_goal_terminates_with_success_within_the_goal_radius(env, state):
    previous, _ = env.reset(options={"state": state})
    assert goal_distance(previous) > LAYOUT.goal_radius
    for _ in range(50):
        obs, reward, terminated, truncated, info = env.step(np.zeros(2))
        if terminated:
            break
        previous = obs
    assert terminated and not truncated
    assert reward == 1.0 and info == {"is_success": True, "lava": False}
    assert goal_distance(obs) <= LAYOUT.goal_radius + 1e-9
    assert goal_distance(previous) > LAYOUT.goal_radius


def test_default_rewards_are_the_calibrated_ones():
    """+1 at the goal and 0 elsewhere, lava included: docs/calibration.md measured that a lava penalty
    of -1 or -0.1 made AuxSS's policies hide from the bridge; the termination is the penalty."""
    env = LavaBridgeEnv()
    assert (env.goal_reward, env.lava_reward, env.step_reward) == (1.0, 0.0, 0.0)


def test_custom_rewards():
    env = LavaBridgeEnv(goal_reward=10.0, lava_reward=-5.0, step_reward=-0.01)
    env.reset(options={"state": SAFE_STATE})
    assert env.step([0, 0])[1] == -0.01
    env.reset(options={"state": [0, 0, 0, 2.0]})
    assert env.step([0, 0])[1] == -5.0
    env.reset(options={"state": [4.1, 1.0, 1.0, 0.0]})
    assert [env.step([0, 0])[1] for _ in range(2)][-1] == 10.0


# --- inactive contacts: lava and goal never push --------------------------------------------------------
@pytest.mark.parametrize("position, geom", [
    ((0.0, 0.12), "lava_north"),
    ((0.7, -0.13), "lava_south"),
    ((0.0, 1.0), "lava_north"),
    ((4.5, 1.0), "goal"),
    ((4.5 + 0.2, 1.0 - 0.1), "goal"),
])
@pytest.mark.parametrize("ctrl", [(0.0, 0.0), (0.6, -1.0)])
def test_lava_and_goal_contacts_apply_no_force(position, geom, ctrl):
    env = LavaBridgeEnv()
    model, data = env.model, env.data
    mujoco.mj_resetData(model, data)
    data.qpos[:] = position
    data.qvel[:] = (0.7, -0.3)
    data.ctrl[:] = ctrl
    mujoco.mj_forward(model, data)
    geom_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    assert data.ncon >= 1 and geom_id in data.contact.geom  # detected ...
    assert data.nefc == 0 and np.all(data.contact.exclude == 1)  # ... but inactive
    expected = (LAYOUT.gear * np.asarray(ctrl) - LAYOUT.damping * data.qvel) / LAYOUT.ball_mass
    assert np.array_equal(data.qacc, expected), (data.qacc, expected)


def test_trajectory_over_lava_equals_one_without_lava_geoms():
    """Driving straight over both pits and the goal: same physics as a model with no lava or goal."""
    with_pads = load_model(LAYOUT)
    without = load_model(LAYOUT)
    for name in ("lava_north", "lava_south", "goal"):
        without.geom_conaffinity[mujoco.mj_name2id(without, mujoco.mjtObj.mjOBJ_GEOM, name)] = 0
    rng = np.random.default_rng(0)
    datas = [mujoco.MjData(with_pads), mujoco.MjData(without)]
    for d in datas:
        d.qpos[:], d.qvel[:] = (-2.0, 1.0), (2.0, 0.0)
    touched = set()
    # along y = 1: through the north pit, across the goal, into the east wall
    for ctrl in np.column_stack([np.full(60, 0.5), rng.uniform(-0.01, 0.01, 60)]):
        for model, d in zip((with_pads, without), datas):
            d.ctrl[:] = ctrl
            mujoco.mj_step(model, d, nstep=10)
        touched |= {mujoco.mj_id2name(with_pads, mujoco.mjtObj.mjOBJ_GEOM, g) for g in datas[0].contact.geom.ravel()}
        assert np.array_equal(datas[0].qpos, datas[1].qpos) and np.array_equal(datas[0].qvel, datas[1].qvel)
    assert {"lava_north", "goal", "wall_east"} <= touched  # the comparison did cross them


# --- walls --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("start, push, axis, face", [
    ((-4.5, 0.0), (-1.0, 0.0), 0, -5.5),  # west
    ((3.0, -1.5), (1.0, 0.0), 0, 5.5),    # east (away from the goal)
    ((-3.0, 0.0), (0.0, 1.0), 1, 2.0),    # north
    ((-3.0, 0.0), (0.0, -1.0), 1, -2.0),  # south
    ((-4.0, 1.0), (-1.0, 1.0), 0, -5.5),  # diagonally into the north-west corner
])
def test_walls_stop_the_ball(env, start, push, axis, face):
    env.reset(options={"state": [*start, 0.0, 0.0]})
    for _ in range(30):
        obs, reward, terminated, truncated, _ = env.step(push)
        assert not terminated and reward == 0.0
        assert abs(obs[0]) <= 5.5 and abs(obs[1]) <= 2.0  # the centre never passes a wall face
        assert env.observation_space.contains(obs)
    # pressed against the face: about one radius from it, at rest
    assert abs(face - obs[axis]) == pytest.approx(R, abs=0.005)
    assert abs(obs[2 + axis]) < 1e-6


def test_wall_push_never_reaches_into_the_wall_by_more_than_a_few_mm(env):
    env.reset(options={"state": [-4.0, 0.0, 0.0, 0.0]})
    deepest = 0.0
    for _ in range(30):
        obs, *_ = env.step([-1.0, 0.0])
        deepest = max(deepest, R - (obs[0] + 5.5))
    assert 0 < deepest < 0.01


# --- input validation -------------------------------------------------------------------------------
BAD_RESET_OPTIONS = [
    ({"state": [np.nan, 0.0, 0.0, 0.0]}, "finite"),
    ({"state": [-3.0, 0.0, np.inf, 0.0]}, "finite"),
    ({"state": [-3.0, 0.0, 0.0]}, r"shape \(4,\).*\(3,\)"),
    ({"state": [[-3.0, 0.0], [0.0, 0.0]]}, r"shape \(4,\).*\(2, 2\)"),
    ({"state": ["a", "b", "c", "d"]}, "'a'"),
    ({"state": None}, "shape"),
    ({"qpos": "ab"}, "qpos must be finite real numbers of shape \\(2,\\), got 'ab'"),
    ({"qpos": [-3.0 + 1j, 0.0]}, r"qpos must be finite real numbers.*1j"),  # not its real part
    ({"state": [[-3.0, 0.0], [0.0]]}, "state must be finite real numbers"),  # ragged
    ({"qpos": [-3.0, 0.0, 1.0]}, r"qpos must have shape \(2,\)"),
    ({"qpos": [-3.0, 0.0], "qvel": [0.0, np.nan]}, "qvel must be finite"),
    ({"state": [5.55, 0.0, 0.0, 0.0]}, r"outside the maze"),     # centre inside the east wall
    ({"state": [-3.0, -2.04, 0.0, 0.0]}, r"outside the maze"),   # centre inside the south wall
    ({"state": [9.0, 0.0, 0.0, 0.0]}, r"outside the maze"),
    ({"state": [0.0, 0.12, 0.0, 0.0]}, r"\(0, 0.12\) touches lava"),
    ({"state": [-1.52, 1.0, 0.0, 0.0]}, "touches lava"),
    ({"state": [0.0, 1.0, 0.0, 0.0]}, "touches lava"),
    ({"state": [-3.0, 0.0, 0.0, 4.5]}, "exceeds the top speed 4"),
    ({"state": [-3.0, 0.0, -4.01, 0.0]}, "exceeds the top speed 4"),
    ({"start": "uniform"}, "unknown start distribution 'uniform'"),
    ({"seed": 3}, r"unknown reset options \['seed'\]"),
    ({"state": SAFE_STATE, "start": "p0"}, "conflict"),
    ({"qpos": SAFE_STATE[:2], "state": SAFE_STATE}, "conflict"),
    ({"qvel": [0.0, 0.0]}, "'qvel' needs 'qpos'"),
]


def test_minari_reset_option_is_accepted_and_ignored(env):
    """minari.DataCollector passes its `minari_autoseed` switch on to the env's reset."""
    plain, _ = env.reset(seed=5)
    for options in ({"minari_autoseed": False}, {"minari_autoseed": True, "start": "p0"}):
        obs, _ = env.reset(seed=5, options=options)
        np.testing.assert_array_equal(obs, plain)
    with pytest.raises(ValueError, match=r"unknown reset options \['minari_autoseedd'\]"):
        env.reset(options={"minari_autoseedd": False})


@pytest.mark.parametrize("options, message", BAD_RESET_OPTIONS)
def test_bad_reset_raises_and_leaves_the_state_untouched(env, options, message):
    env.reset(options={"state": [-2.5, 0.7, 1.5, -0.5]})
    env.step([0.3, 0.2])
    before = env.get_state()
    qacc = env.data.qacc.copy()
    with pytest.raises(ValueError, match=message):
        env.reset(options=options)
    assert np.array_equal(env.get_state(), before)
    assert np.array_equal(env.data.qacc, qacc)
    env.step([0.0, 0.0])  # and the env still works


@pytest.mark.parametrize("state", [[object()] * 4, {"x": 1.0}])
def test_non_numeric_state_object_raises_value_error(env, state):
    with pytest.raises(ValueError):
        env.reset(options={"state": state})


def test_states_overlapping_a_wall_by_less_than_a_radius_are_accepted(env):
    """Wall contacts push the ball a few mm into the wall; every visited state must reset cleanly."""
    obs, _ = env.reset(options={"state": [5.48, 1.97, 0.0, 0.0]})
    assert np.array_equal(obs, [5.48, 1.97, 0.0, 0.0])


@pytest.mark.parametrize("action, message", [
    ([np.nan, 0.0], "finite"),
    ([0.0, np.inf], "finite"),
    ([0.0, 0.0, 0.0], r"shape \(2,\)"),
    ([[0.0, 0.0]], r"shape \(2,\)"),
    (0.5, r"shape \(2,\)"),
    (["a", "b"], "'a'"),
    ([0.5 + 1j, 0.0], r"action must be finite real numbers of shape \(2,\), got \[\(0\.5\+1j\), 0\.0\]"),
    (np.array([0.5, 0.2], dtype=np.complex64), "action must be finite real numbers"),
    (object(), "action must be finite real numbers of shape \\(2,\\), got <object object"),
    ([object(), 0.0], "action must be finite real numbers"),
    (None, "action must be finite real numbers"),
])
def test_bad_actions_raise(env, action, message):
    env.reset(options={"state": SAFE_STATE})
    with pytest.raises(ValueError, match=message):
        env.step(action)
    assert np.array_equal(env.get_state(), SAFE_STATE)


@pytest.mark.parametrize("big, clipped", [
    ((5.0, 0.0), (1.0, 0.0)),
    ((-7.0, 2.0), (-1.0, 1.0)),
    ((1e9, -1e9), (1.0, -1.0)),
])
def test_out_of_range_actions_are_clipped(env, big, clipped):
    results = []
    for action in (big, clipped):
        env.reset(options={"state": [-3.0, 0.5, 0.5, -0.5]})
        results.append([env.step(action)[0] for _ in range(3)])
    assert np.array_equal(results[0], results[1])


@pytest.mark.parametrize("kwargs, field", [
    ({"bridge_width": -0.3}, "bridge_width"),
    ({"bridge_width": 0.0}, "bridge_width"),
    ({"bridge_width": 0.08}, "bridge_width"),   # narrower than the ball
    ({"bridge_width": 0.1}, "bridge_width"),    # exactly the ball's diameter: no room either
    ({"bridge_width": float("nan")}, "bridge_width"),
    ({"goal": (0.0, 0.0)}, "goal"),             # on the bridge
    ({"goal": (-3.0, 0.0)}, "goal"),            # in the start room
    ({"goal": (4.5, 2.5)}, "goal"),             # beyond the north wall
    ({"goal_radius": 0.04}, "goal_radius"),
    ({"ball_mass": -1.0}, "ball_mass"),
    ({"frame_skip": 0}, "frame_skip"),
    ({"p0_blobs": ()}, "p0_blobs"),
])
def test_bad_layout_fields_raise_naming_the_field(kwargs, field):
    with pytest.raises(ValueError, match=rf"Layout\.{field}"):
        Layout(**kwargs)
    with pytest.raises(ValueError, match=rf"Layout\.{field}"):
        gymnasium.make("LavaBridge-v0", **kwargs)


def test_non_finite_goal_is_rejected():
    with pytest.raises(ValueError, match=r"Layout\.goal"):
        Layout(goal=(float("nan"), float("nan")))


BAD_ENV_ARGUMENTS = [
    ({"lava_reward": "x"}, "lava_reward must be a finite number, got 'x'"),
    ({"goal_reward": float("nan")}, "goal_reward must be a finite number, got nan"),
    ({"step_reward": float("inf")}, "step_reward must be a finite number, got inf"),
    ({"goal_reward": None}, "goal_reward must be a finite number, got None"),
    ({"lava_reward": True}, "lava_reward must be a finite number, got True"),
    ({"lava_reward": 1 + 0j}, r"lava_reward must be a finite number, got \(1\+0j\)"),
    ({"width": -5}, r"width must be an integer in \[1, 1920\], got -5"),
    ({"width": 0}, r"width must be an integer in \[1, 1920\], got 0"),
    ({"width": 1921}, r"width must be an integer in \[1, 1920\], got 1921"),  # beyond MuJoCo's framebuffer
    ({"width": 640.0}, r"width must be an integer in \[1, 1920\], got 640\.0"),
    ({"height": -5}, r"height must be an integer in \[1, 1080\], got -5"),
    ({"height": "400"}, r"height must be an integer in \[1, 1080\], got '400'"),
    ({"render_quality": "ultra"}, "render_quality='ultra'; expected 'fast' or 'high'"),
    ({"render_quality": ["fast"]}, r"render_quality=\['fast'\]; expected 'fast' or 'high'"),
    ({"layout": "wide"}, "layout must be a Layout, got 'wide'"),
]


@pytest.mark.parametrize("kwargs, message", BAD_ENV_ARGUMENTS)
def test_bad_env_arguments_raise_naming_the_argument(kwargs, message):
    with pytest.raises(ValueError, match=message):
        gymnasium.make("LavaBridge-v0", **kwargs)


def test_rewards_may_be_any_finite_real_number():
    env = LavaBridgeEnv(goal_reward=np.float32(2.5), lava_reward=-1, step_reward=np.int64(0))
    assert (env.goal_reward, env.lava_reward, env.step_reward) == (2.5, -1.0, 0.0)
    assert all(type(r) is float for r in (env.goal_reward, env.lava_reward, env.step_reward))
    env.reset(options={"state": [0, 0, 0, 2.0]})  # on the bridge, heading off its side
    _, reward, terminated, _, info = env.step([0, 0])
    assert info["lava"] and terminated and reward == -1.0 and type(reward) is float


def test_unknown_make_kwargs_raise_type_error():
    with pytest.raises(TypeError, match="bridge_widht"):
        gymnasium.make("LavaBridge-v0", bridge_widht=0.4)
    with pytest.raises(ValueError, match="render_mode"):
        LavaBridgeEnv(render_mode="human")


# --- random policy and start distributions -------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_random_policy_from_p0_never_succeeds(env_id):
    env = LavaBridgeEnv(layout=TASKS[env_id])
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    outcomes = {"success": 0, "lava": 0, "timeout": 0}
    for _ in range(100):
        actions = rng.uniform(-1, 1, size=(500, 2))
        for action in actions:
            _, _, terminated, _, info = env.step(action)
            if terminated:
                break
        outcomes["success" if info["is_success"] else "lava" if info["lava"] else "timeout"] += 1
        env.reset()
    assert outcomes["success"] == 0, outcomes


@pytest.mark.parametrize("env_id", TASK_IDS)
@pytest.mark.parametrize("name", ["p0", "ood"])
def test_start_distributions_sample_their_discs_at_rest(env_id, name):
    layout = TASKS[env_id]
    discs = layout.p0_blobs if name == "p0" else layout.ood_spots
    hx, hy = layout.half_extent
    env = LavaBridgeEnv(layout=layout)
    env.reset(seed=11)
    hits = np.zeros(len(discs), dtype=int)
    for _ in range(400):
        obs, info = env.reset(options={"start": name})
        assert obs[2] == 0.0 and obs[3] == 0.0 and info == {"is_success": False, "lava": False}
        inside = [math.hypot(obs[0] - d.x, obs[1] - d.y) <= d.radius + 1e-12 for d in discs]
        assert sum(inside) == 1, (obs, discs)
        hits[inside.index(True)] += 1
        pits = layout.lava_pits.values()
        assert min(pit.distance_to(*obs[:2]) for pit in pits) > R and abs(obs[0]) + R <= hx and abs(obs[1]) + R <= hy
    assert hits.min() > 400 / len(discs) / 2, hits  # every disc is used, roughly uniformly
    # seeded: the same seed gives the same sample stream
    a, b = LavaBridgeEnv(layout=layout), LavaBridgeEnv(layout=layout)
    sa = [a.reset(seed=4, options={"start": name})[0]] + [a.reset(options={"start": name})[0] for _ in range(5)]
    sb = [b.reset(seed=4, options={"start": name})[0]] + [b.reset(options={"start": name})[0] for _ in range(5)]
    assert np.array_equal(sa, sb)


def test_start_positions_fill_the_discs_uniformly():
    """Uniform over a disc's area: the mean squared radius fraction is 1/2 (not 1/3 as for uniform r)."""
    dist = start_distribution(LAYOUT, "p0")
    rng = np.random.default_rng(0)
    samples = np.array([dist.sample(rng) for _ in range(3000)])
    centres = np.array([[d.x, d.y] for d in LAYOUT.p0_blobs])
    nearest = np.linalg.norm(samples[:, None, :2] - centres[None], axis=-1).min(axis=1)
    assert np.mean((nearest / 0.2) ** 2) == pytest.approx(0.5, abs=0.02)


# --- the model file -----------------------------------------------------------------------------------
def test_shipped_model_file_matches_the_default_layout():
    assert shipped_xml() == build_mjcf(Layout())


def test_custom_layout_changes_the_compiled_model():
    default, wide = LavaBridgeEnv(), gymnasium.make("LavaBridge-v0", bridge_width=0.4).unwrapped
    assert wide.layout.bridge_width == 0.4
    for name, env, half_y, centre_y in (("lava_north", default, 0.925, 1.075), ("lava_north", wide, 0.9, 1.1),
                                        ("lava_south", wide, 0.9, -1.1)):
        gid = mujoco.mj_name2id(env.model, mujoco.mjtObj.mjOBJ_GEOM, name)
        assert env.model.geom_size[gid][:2] == pytest.approx([1.5, half_y])
        assert env.model.geom_pos[gid][:2] == pytest.approx([0.0, centre_y])
    # and the behaviour follows: (0, 0.12) is lava on the default bridge, safe on the wide one
    assert np.array_equal(wide.reset(options={"state": [0.0, 0.12, 0.0, 0.0]})[0], [0.0, 0.12, 0.0, 0.0])
    with pytest.raises(ValueError, match="lava"):
        wide.reset(options={"state": [0.0, 0.16, 0.0, 0.0]})
    with pytest.raises(ValueError, match="lava"):
        default.reset(options={"state": [0.0, 0.12, 0.0, 0.0]})


def test_layout_physics_fields_reach_the_model():
    env = gymnasium.make("LavaBridge-v0", gear=2.0, damping=0.5, timestep=0.005, frame_skip=20).unwrapped
    assert env.model.opt.timestep == 0.005 and env.frame_skip == 20 and env.dt == pytest.approx(0.1)
    assert env.model.actuator_gear[0, 0] == 2.0 and env.model.dof_damping.tolist() == [0.5, 0.5]
    assert env.observation_space.high[2] == 4.0


@pytest.mark.parametrize("physics", [{"timestep": 10.0}, {"timestep": 1.0}, {"timestep": 0.0125}, {"gear": 5.0},
                                     {"damping": 0.79}, {"ball_radius": 0.04}])
def test_physics_that_let_one_step_move_the_ball_its_radius_are_refused(physics):
    """At timestep=10 one step with action [1, 0] put the ball at x = 391.6 m, through walls, lava and
    goal. A physics step may move the ball less than its radius at its top speed gear / damping:
    0.0125 s is the limit of the default gear 4, damping 1 and radius 0.05."""
    message = r"^Layout\.timestep=[0-9.]+ lets the ball move .* timestep must be below ball_radius \* damping / gear = "
    with pytest.raises(ValueError, match=message):
        gymnasium.make("LavaBridge-v0", **physics)
    with pytest.raises(ValueError, match=message):
        lava_bridge_mj.LavaBridgeVectorEnv(2, **physics)
    gymnasium.make("LavaBridge-v0", **{**physics, "timestep": 0.99 * physics.get("ball_radius", 0.05)
                                       * physics.get("damping", 1.0) / physics.get("gear", 4.0)}).close()


@pytest.mark.parametrize("mass", [0.01, 1.0, 100.0])
def test_one_physics_step_moves_the_ball_at_most_timestep_times_the_top_speed_whatever_its_mass(mass):
    """The fact the timestep limit rests on: MuJoCo's Euler step damps implicitly, v' = (m v + h F) / (m + h c),
    so from the top speed F / c under full force the speed stays F / c for any mass, and a step moves
    the ball h F / c per axis: just under its radius at a timestep just under the limit."""
    env = gymnasium.make("LavaBridge-v0", ball_mass=mass, timestep=0.0124, frame_skip=8).unwrapped
    env.reset(options={"state": [-3.0, 0.0, 4.0, -4.0]})
    env.data.ctrl[:] = [1.0, -1.0]
    mujoco.mj_step(env.model, env.data)
    assert env.data.qpos - [-3.0, 0.0] == pytest.approx([0.0124 * 4.0, -0.0124 * 4.0], rel=1e-12)
    assert np.abs(env.data.qvel).tolist() == pytest.approx([4.0, 4.0], rel=1e-12)
    assert (np.abs(env.data.qpos - [-3.0, 0.0]) < env.layout.ball_radius).all()


# --- rendering ---------------------------------------------------------------------------------------
def world_to_pixel(env: LavaBridgeEnv, x: float, y: float) -> tuple[int, int]:
    """The top camera is orthographic at the origin: pixels per metre = height / fovy on both axes."""
    cam = mujoco.mj_name2id(env.model, mujoco.mjtObj.mjOBJ_CAMERA, "top")
    assert env.model.cam_projection[cam] == mujoco.mjtProjection.mjPROJ_ORTHOGRAPHIC
    assert np.array_equal(env.model.cam_pos[cam][:2], [0.0, 0.0])
    scale = env.height / env.model.cam_fovy[cam]
    return int(round(env.height / 2 - y * scale)), int(round(env.width / 2 + x * scale))


@needs_gl
@pytest.mark.parametrize("width, height", [(960, 400), (480, 200)])
def test_rgb_array_rendering_shows_lava_goal_and_ball(width, height):
    env = gymnasium.make("LavaBridge-v0", render_mode="rgb_array", width=width, height=height)
    try:
        base = env.unwrapped
        assert base.model.cam_fovy[0] == pytest.approx(2 * 2.0 + 2 * 0.2 + 0.4)
        env.reset(options={"state": [-3.0, 1.0, 0.0, 0.0]})
        frame = env.render()
        assert frame.shape == (height, width, 3) and frame.dtype == np.uint8
        rgb = frame.astype(int)

        def pixel(x, y):
            return rgb[world_to_pixel(base, x, y)]

        for x, y in [(0.0, 1.0), (-1.3, -1.8), (1.3, 0.3), (0.0, -0.5)]:  # lava
            r, g, b = pixel(x, y)
            assert r > 150 and r > 2 * g and r > 2 * b, (x, y, (r, g, b))
        for x, y in [(4.5, 1.0), (4.6, 0.85)]:  # goal
            r, g, b = pixel(x, y)
            assert g > 150 and g > r + 50 and g > b + 50, (x, y, (r, g, b))
        for x, y in [(0.0, 0.0), (1.0, -0.05)]:  # the bridge is floor, not lava
            r, g, b = pixel(x, y)
            assert abs(r - g) < 30 and r > 150, (x, y, (r, g, b))
        ball = pixel(-3.0, 1.0)
        assert ball.max() < 128, ball  # the dark ball, where the camera model puts it

        env.reset(options={"state": [-3.0, -1.0, 0.0, 0.0]})
        moved = env.render().astype(int)
        assert moved[world_to_pixel(base, -3.0, 1.0)].min() > 150  # floor where the ball was
        assert moved[world_to_pixel(base, -3.0, -1.0)].max() < 128  # ball where it went
    finally:
        env.close()


def test_render_without_render_mode_returns_none(env):
    env.reset(seed=0)
    assert env.render() is None


@needs_gl
def test_render_frames_do_not_alias_each_other():
    env = LavaBridgeEnv(render_mode="rgb_array", width=240, height=100)
    try:
        env.reset(options={"state": [-3.0, 1.0, 0.0, 0.0]})
        first = env.render()
        snapshot = first.copy()
        env.reset(options={"state": [-3.0, -1.0, 0.0, 0.0]})
        env.render()
        assert np.array_equal(first, snapshot)
    finally:
        env.close()


@needs_gl
def test_renderers_left_open_close_quietly_at_exit():
    """A script that renders and exits without env.close() prints nothing on stderr (no EGL tracebacks
    from the renderers' destructors), with the GL backend the tests use."""
    code = ("import gymnasium, lava_bridge_mj\n"
            "wrapped = gymnasium.make('LavaBridge-v0', render_mode='rgb_array', width=64, height=48)\n"
            "bare = lava_bridge_mj.LavaBridgeEnv(render_mode='rgb_array', width=32, height=24)\n"
            "for env in (wrapped, bare):\n"
            "    env.reset(seed=0)\n"
            "    print(env.render().shape)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0
    assert out.stdout.split("\n")[:2] == ["(48, 64, 3)", "(24, 32, 3)"]
    assert out.stderr == ""


@needs_gl
def test_an_env_rendering_again_after_close_still_works():
    env = LavaBridgeEnv(render_mode="rgb_array", width=32, height=24)
    env.reset(seed=0)
    first = env.render()
    env.close()
    env.close()  # closing twice is harmless
    assert np.array_equal(env.render(), first)  # a new renderer, made on demand
    env.close()


# --- suite-style invariants ------------------------------------------------------------------------------
@pytest.mark.parametrize("wrapped", [False, True])
def test_observations_never_share_memory_with_physics(wrapped):
    env = gymnasium.make("LavaBridge-v0") if wrapped else LavaBridgeEnv()
    data = env.unwrapped.data
    obs, _ = env.reset(seed=0)
    outputs = [obs, env.step(np.array([0.5, 0.5], dtype=np.float32))[0], env.unwrapped.get_state()]
    for out in outputs:
        for buffer in (data.qpos, data.qvel):
            assert not np.shares_memory(out, buffer)
        qpos, qvel = data.qpos.copy(), data.qvel.copy()
        out[:] = 123.0
        assert np.array_equal(data.qpos, qpos) and np.array_equal(data.qvel, qvel)
    env.close()


def test_reset_options_arrays_are_copied(env):
    state = np.array([-3.0, 0.5, 0.1, 0.2])
    obs, _ = env.reset(options={"state": state})
    state[:] = 0.0
    assert np.array_equal(env.get_state(), [-3.0, 0.5, 0.1, 0.2]) and obs[0] == -3.0


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_observations_stay_in_the_observation_space_under_random_actions(env_id):
    env = LavaBridgeEnv(layout=TASKS[env_id])
    rng = np.random.default_rng(1)
    env.reset(seed=1, options={"start": "ood"})
    for action in rng.uniform(-1, 1, (2000, 2)) * 1.0:
        obs, _, terminated, _, _ = env.step(np.sign(action))  # bang-bang: reaches top speed and walls
        assert env.observation_space.contains(obs), obs
        if terminated:
            env.reset(options={"start": "ood"})
