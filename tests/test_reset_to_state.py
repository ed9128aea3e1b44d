"""ResetToState on MuJoCo envs this package does not define: Gymnasium's Hopper-v5 and Ant-v5,
Gymnasium-Robotics' PointMaze_Large-v3, OGBench's cube-single-singletask envs.

Trajectories are recorded with seeded random actions; a restore from one of their states and a
replay of the same actions must give back the recording bit for bit, except where the wrapper's
contract names the difference (Ant-v5's first forward reward and its restored contact forces)."""

from __future__ import annotations

import socket
import warnings

import gymnasium
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from lava_bridge_mj import ResetToState
from lava_bridge_mj.reset_to_state import PHYSICS_STATE, OGBenchCubeAdapter, PointMazeAdapter, TaskAdapter

pytestmark = pytest.mark.filterwarnings("ignore:.*precision lowered by casting to float32")  # OGBench's Box bounds

CUBE_TASK1 = "cube-single-singletask-task1-v0"
CUBE_TASK2 = "cube-single-singletask-task2-v0"


EXTRAS = {"PointMaze": ("gymnasium_robotics", "robotics"), "cube": ("ogbench", "ogbench")}
"""Env id prefix: (package that registers the envs, the extra that installs it; both are in `test`)."""


def make_env(env_id, **kwargs):
    """gymnasium.make(env_id), importing the package that registers it first."""
    for prefix, (package, extra) in EXTRAS.items():
        if env_id.startswith(prefix):
            gymnasium.register_envs(pytest.importorskip(package, reason=f"pip install -e '.[{extra}]' (or '.[test]')"))
    return gymnasium.make(env_id, **kwargs)


def make(env_id, **kwargs):
    return ResetToState(make_env(env_id, **kwargs))


def record(env, steps, seed=0, options=None):
    """(actions, [(observation, reward, terminated, truncated, info)]) from reset(seed) on, with random
    actions, until the episode ends; the first entry is the reset's (reward etc. None)."""
    observation, info = env.reset(seed=seed, options=options)
    env.action_space.seed(seed)
    actions, steps_seen = [], [(observation, None, None, None, info)]
    for _ in range(steps):
        actions.append(env.action_space.sample())
        steps_seen.append(env.step(actions[-1]))
        if steps_seen[-1][2] or steps_seen[-1][3]:
            break
    return actions, steps_seen


def same(a, b):
    """Bit-for-bit equality of two observations (arrays or dicts of arrays)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(np.array_equal(a[key], b[key]) for key in a)
    return np.array_equal(a, b)


def physics_state(env):
    unwrapped = env.unwrapped
    state = np.empty(mujoco.mj_stateSize(unwrapped.model, PHYSICS_STATE))
    mujoco.mj_getState(unwrapped.model, unwrapped.data, state, PHYSICS_STATE)
    return state


# --- exact round trips -------------------------------------------------------------------------
@pytest.mark.parametrize("env_id, steps", [("Hopper-v5", 40), ("PointMaze_Large-v3", 40), (CUBE_TASK1, 24)])
def test_replay_from_a_recorded_state_is_bit_exact(env_id, steps):
    env = make(env_id)
    actions, recording = record(env, steps)
    assert len(recording) > 8
    for k in (1, len(recording) // 2):
        observation, info = env.reset(seed=123, options={"state": recording[k][4]["state"]})
        assert same(observation, recording[k][0])
        assert np.array_equal(info["state"], recording[k][4]["state"])
        # the reset info is the env's for the restored state ("previous" ones are the state's own, as after a reset)
        for key in info.keys() & recording[k][4].keys() - {"state", "prev_qpos", "prev_qvel"}:
            assert np.array_equal(info[key], recording[k][4][key]), key
        if "prev_qpos" in info:
            assert np.array_equal(info["prev_qpos"], info["qpos"])
        for action, (rec_observation, rec_reward, rec_terminated, rec_truncated, rec_info) in zip(
                actions[k:], recording[k + 1:]):
            observation, reward, terminated, truncated, info = env.step(action)
            assert np.array_equal(info["state"], rec_info["state"])
            assert same(observation, rec_observation)
            assert (reward, terminated, truncated) == (rec_reward, rec_terminated, rec_truncated)


def test_state_is_mujoco_integration_state_then_task_state():
    hopper, maze, cube = make("Hopper-v5"), make("PointMaze_Large-v3"), make(CUBE_TASK1)
    for env, task_size in ((hopper, 0), (maze, 2), (cube, 18)):
        _, info = env.reset(seed=0)
        model = env.unwrapped.model
        assert info["state"].dtype == np.float64
        assert info["state"].shape == (mujoco.mj_stateSize(model, PHYSICS_STATE) + task_size,) == (env.state_size,)
        assert np.array_equal(info["state"][:env.physics_state_size], physics_state(env))
    assert np.array_equal(maze.get_state()[-2:], maze.unwrapped.goal)
    info["state"][:] = 0.0  # a copy: the env keeps its state
    assert not np.array_equal(cube.get_state(), info["state"])


def test_ant_replay_matches_except_the_first_forward_reward():
    """Ant-v5's forward reward starts from the torso position that MuJoCo's step left from before its
    last integration; a restore recomputes it for the restored state, so the first reward differs by
    its forward part alone, and everything from then on is the recording's."""
    env = make("Ant-v5")
    actions, recording = record(env, 40)
    assert len(recording) > 20
    for k in (5, len(recording) // 2):
        env.reset(options={"state": recording[k][4]["state"]})
        for i, (action, (rec_observation, rec_reward, rec_terminated, _, rec_info)) in enumerate(
                zip(actions[k:], recording[k + 1:])):
            observation, reward, terminated, _, info = env.step(action)
            assert np.array_equal(info["state"], rec_info["state"])
            assert np.array_equal(observation, rec_observation)
            assert terminated == rec_terminated
            for part in ("reward_ctrl", "reward_contact", "reward_survive"):
                assert info[part] == rec_info[part]
            if i == 0:
                assert info["reward_forward"] != rec_info["reward_forward"]
                assert reward != rec_reward
            else:
                assert (reward, info["reward_forward"]) == (rec_reward, rec_info["reward_forward"])


def test_ant_restored_observation_holds_the_contact_forces_of_the_restored_state():
    env = make("Ant-v5")
    _, recording = record(env, 40)
    unwrapped = env.unwrapped
    for _, _, _, _, rec_info in recording[1:]:
        observation, _ = env.reset(options={"state": rec_info["state"]})
        if unwrapped.data.ncon:
            break
    assert unwrapped.data.ncon > 0, "no recorded state touches the floor"
    positions_velocities = unwrapped.model.nq - 2 + unwrapped.model.nv
    assert np.array_equal(observation[:positions_velocities],
                          np.concatenate([unwrapped.data.qpos[2:], unwrapped.data.qvel]))
    fresh = mujoco.MjData(unwrapped.model)
    mujoco.mj_setState(unwrapped.model, fresh, rec_info["state"], PHYSICS_STATE)
    mujoco.mj_forward(unwrapped.model, fresh)
    mujoco.mj_rnePostConstraint(unwrapped.model, fresh)
    forces = np.clip(fresh.cfrc_ext[1:], *unwrapped._contact_force_range).ravel()
    assert np.any(forces != 0.0)
    assert np.array_equal(observation[positions_velocities:], forces)


def test_warm_start_is_needed_for_an_exact_replay():
    """A physics fact behind mjSTATE_INTEGRATION: Ant-v5 restored without its solver warm start drifts."""
    env = make("Ant-v5")
    actions, recording = record(env, 40)
    k = len(recording) // 2
    env.reset(options={"state": recording[k][4]["state"]})
    env.unwrapped.data.qacc_warmstart[:] = 0.0
    drifted = [not np.array_equal(env.step(action)[4]["state"], rec_info["state"])
               for action, (_, _, _, _, rec_info) in zip(actions[k:], recording[k + 1:])]
    assert any(drifted)


# --- task state ----------------------------------------------------------------------------------
def drive_to_goal(env, steps=300):
    """PD control of the point towards its goal until PointMaze reports success; the step's info."""
    for _ in range(steps):
        position, velocity = env.unwrapped.data.qpos.copy(), env.unwrapped.data.qvel.copy()
        action = np.clip(5.0 * (env.unwrapped.goal - position) - 1.0 * velocity, -1.0, 1.0)
        _, _, _, _, info = env.step(action.astype(np.float32))
        if info["success"]:
            return info
    raise AssertionError("the PD controller did not reach the goal")


def test_pointmaze_goal_is_restored_with_the_state():
    env = make("PointMaze_Large-v3", reward_type="sparse")
    env.reset(seed=0, options={"goal_cell": np.array([1, 1]), "reset_cell": np.array([1, 2])})
    at_goal = drive_to_goal(env)["state"]
    goal = env.unwrapped.goal.copy()
    rec_step = env.step(np.zeros(2, dtype=np.float32))
    assert rec_step[1] == 1.0

    far_goal_cell = np.array([7, 10])
    env.reset(seed=1, options={"goal_cell": far_goal_cell, "reset_cell": np.array([1, 2])})
    assert np.linalg.norm(env.unwrapped.goal - goal) > 5.0
    observation, info = env.reset(options={"state": at_goal, "goal_cell": far_goal_cell})  # the state's goal wins
    assert np.array_equal(observation["desired_goal"], goal) and np.array_equal(env.unwrapped.goal, goal)
    assert info["success"] is True
    site = env.unwrapped.model.site_pos[env.unwrapped.target_site_id]
    assert np.array_equal(site[:2], goal)  # the marker renders draw moved with it
    observation, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
    assert same(observation, rec_step[0]) and (reward, info["success"]) == (1.0, True)
    assert np.array_equal(info["state"], rec_step[4]["state"])


def test_ogbench_target_and_success_are_restored_with_the_state():
    """A state recorded in the task-2 env, with the cube on task 2's target, restored into the task-1
    env: reward, success and termination follow task 2's target (a mocap pose), and the replay is the
    task-2 env's."""
    task2 = make(CUBE_TASK2)
    task2.reset(seed=0)
    unwrapped = task2.unwrapped
    unwrapped.data.joint("object_joint_0").qpos[:3] = unwrapped.data.mocap_pos[unwrapped._cube_target_mocap_ids[0]]
    mujoco.mj_forward(unwrapped.model, unwrapped.data)
    hold = np.zeros(5, dtype=np.float32)
    on_target = task2.step(hold)[4]["state"]
    rec_observation, rec_reward, rec_terminated, _, rec_info = task2.step(hold)

    task1 = make(CUBE_TASK1)
    task1.reset(seed=0)
    assert task1.step(hold)[1:3] == (-1.0, False)  # its own target: the cube is not on it
    observation, info = task1.reset(seed=0, options={"state": on_target})
    observation, reward, terminated, _, info = task1.step(hold)
    assert (reward, terminated, info["success"]) == (0.0, True, True)
    assert (reward, terminated) == (rec_reward, rec_terminated)
    assert np.array_equal(observation, rec_observation) and np.array_equal(info["state"], rec_info["state"])


# --- bad states, refused envs ------------------------------------------------------------------
def hopper_state_size():
    return make("Hopper-v5").state_size


BAD_STATES = {
    "one short": (lambda s: s[:-1], r"shape \(\d+,\).*got shape \(\d+,\)"),
    "one long": (lambda s: np.append(s, 0.0), r"got shape"),
    "2-D": (lambda s: s[None], r"got shape \(1, \d+\)"),
    "NaN": (lambda s: np.where(np.arange(s.size) == 3, np.nan, s), r"must be finite, got \[nan\] at indices \[3\]"),
    "inf": (lambda s: np.where(np.arange(s.size) == 0, np.inf, s), r"must be finite, got \[inf\] at indices \[0\]"),
    "strings": (lambda s: s.astype(str), r"must be real numbers"),
    "None": (lambda s: None, r"must be real numbers"),
    "ragged": (lambda s: [s, [1.0]], r"must be real numbers"),
    "Walker2d's": (lambda s: make("Walker2d-v5").reset(seed=0)[1]["state"], r"another model"),
    "Ant's": (lambda s: make("Ant-v5").reset(seed=0)[1]["state"], r"another model"),
}


@pytest.mark.parametrize("bad", list(BAD_STATES))
def test_bad_state_raises_and_leaves_the_env_as_it_was(bad):
    """A refused restore changes nothing: the episode goes on as in an env that was never asked,
    physics, random generator and time limit included."""
    to_bad_state, message = BAD_STATES[bad]
    asked, untouched = make("Hopper-v5", max_episode_steps=8), make("Hopper-v5", max_episode_steps=8)
    hold = np.zeros(3, dtype=np.float32)
    for env in (asked, untouched):
        env.reset(seed=0)
        for _ in range(5):
            _, _, _, _, info = env.step(hold)
    before = physics_state(asked)
    generator = asked.unwrapped.np_random.bit_generator.state
    with pytest.raises(ValueError, match=message):
        asked.reset(seed=9, options={"state": to_bad_state(info["state"].copy())})
    assert np.array_equal(physics_state(asked), before)
    assert asked.unwrapped.np_random.bit_generator.state == generator
    for _ in range(3):
        step, expected = asked.step(hold), untouched.step(hold)
        assert np.array_equal(step[0], expected[0]) and step[1:4] == expected[1:4]
        assert np.array_equal(step[4]["state"], expected[4]["state"])
    assert step[3] is True  # truncated at the 8th step: the time limit kept counting


def test_state_error_names_the_expected_layout():
    env = make("PointMaze_Large-v3")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"state must have shape \(25,\), 25 numbers: 23 of MuJoCo's state of "
                                         r"PointMazeEnv's model, then the task state \('goal_x', 'goal_y'\); "
                                         r"got shape \(23,\)"):
        env.reset(options={"state": physics_state(env)})


def test_env_without_mujoco_is_refused():
    with pytest.raises(ValueError, match=r"needs an env whose unwrapped env holds a MuJoCo model and data; "
                                         r"CartPoleEnv.model is not available"):
        ResetToState(gymnasium.make("CartPole-v1"))


def test_env_of_no_known_family_is_refused_unless_given_an_adapter():
    class Pendulum(gymnasium.Env):
        observation_space = gymnasium.spaces.Box(-np.inf, np.inf, (2,), np.float64)
        action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,), np.float32)

        def __init__(self):
            self.model = mujoco.MjModel.from_xml_string(
                "<mujoco><worldbody><body><joint name='hinge' axis='0 1 0'/><geom size='.1' pos='0.5 0 0'/></body>"
                "</worldbody><actuator><motor joint='hinge'/></actuator></mujoco>")
            self.data = mujoco.MjData(self.model)

        def _get_obs(self):
            return np.concatenate([self.data.qpos, self.data.qvel])

        def _get_reset_info(self):
            return {}

        def reset(self, *, seed=None, options=None):
            super().reset(seed=seed)
            mujoco.mj_resetData(self.model, self.data)
            return self._get_obs(), {}

        def step(self, action):
            self.data.ctrl[:] = action
            mujoco.mj_step(self.model, self.data)
            return self._get_obs(), 0.0, False, False, {}

    with pytest.raises(ValueError, match=r"no TaskAdapter knows .*Pendulum .*pass ResetToState\(env, adapter=...\)"):
        ResetToState(Pendulum())
    env = ResetToState(Pendulum(), adapter=TaskAdapter())
    env.reset(seed=0)
    recorded = [env.step(np.array([0.5]))[4]["state"] for _ in range(3)]
    observation, _ = env.reset(options={"state": recorded[0]})
    assert observation[1] != 0.0  # it moves
    assert np.array_equal(env.step(np.array([0.5]))[4]["state"], recorded[1])


def test_observation_wrapper_inside_is_refused():
    env = gymnasium.wrappers.FlattenObservation(make_env("PointMaze_Large-v3"))
    with pytest.raises(ValueError, match=r"FlattenObservation inside ResetToState changes observations"):
        ResetToState(env)
    outside = gymnasium.wrappers.FlattenObservation(make("PointMaze_Large-v3"))
    _, info = outside.reset(seed=0)
    observation, _ = outside.reset(options={"state": info["state"]})
    assert observation.shape == outside.observation_space.shape


def test_adapters_by_family():
    assert type(make("Hopper-v5").adapter) is TaskAdapter
    assert type(make("PointMaze_Large-v3").adapter) is PointMazeAdapter
    assert type(make(CUBE_TASK1).adapter) is OGBenchCubeAdapter


# --- the env's own reset ---------------------------------------------------------------------------
def test_plain_reset_is_the_envs_own():
    wrapped, plain = make("Hopper-v5"), gymnasium.make("Hopper-v5")
    observation, info = wrapped.reset(seed=3)
    expected_observation, expected_info = plain.reset(seed=3)
    assert np.array_equal(observation, expected_observation)
    assert info.keys() - {"state"} == expected_info.keys()
    assert all(info[key] == expected_info[key] for key in expected_info)
    assert np.array_equal(info["state"], wrapped.get_state())


def test_restore_seeds_the_env_and_passes_its_other_options_on():
    """The reset beneath a restore gets the seed and the env's own options: the random generator is
    where a plain reset with them leaves it, and the caller's options are not changed."""
    env, plain = make("PointMaze_Large-v3"), make("PointMaze_Large-v3")
    _, info = env.reset(seed=0)
    options = {"state": info["state"], "goal_cell": np.array([7, 10])}
    env.reset(seed=7, options=options)
    plain.reset(seed=7, options={"goal_cell": np.array([7, 10])})
    assert env.unwrapped.np_random.bit_generator.state == plain.unwrapped.np_random.bit_generator.state
    assert set(options) == {"state", "goal_cell"}


@pytest.mark.parametrize("env_id", ["Hopper-v5", "Ant-v5", "PointMaze_Large-v3", CUBE_TASK1])
def test_wrapped_env_passes_gymnasiums_env_checker(env_id):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the envs' own warnings (infinite Box bounds, float32 casts)
        check_env(make(env_id), skip_render_check=True)


def test_envs_run_without_network(monkeypatch):
    """Nothing downloads at run time: OGBench's single-task env and PointMaze make, reset, restore and step
    with every connection refused."""
    def refuse(*args, **kwargs):
        raise OSError("network refused by the test")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    for env_id in (CUBE_TASK1, "PointMaze_Large-v3"):
        env = make(env_id)
        _, info = env.reset(seed=0)
        env.step(env.action_space.sample())
        env.reset(options={"state": info["state"]})
