"""LavaBridgeTask: the one piece of physics and rules that LavaBridgeEnv and LavaBridgeVectorEnv share."""

import ast
from pathlib import Path

import gymnasium
import mujoco
import numpy as np
import pytest

import lava_bridge_mj
from lava_bridge_mj import ENV_ID, TASKS, LavaBridgeTask, LavaBridgeVectorEnv, Layout
from lava_bridge_mj.expert import ScriptedExpert

PACKAGE = Path(lava_bridge_mj.__file__).parent


def test_both_envs_are_built_on_the_task():
    env = gymnasium.make(ENV_ID, goal_reward=2.0, bridge_width=0.4).unwrapped
    envs = LavaBridgeVectorEnv(2, goal_reward=2.0, bridge_width=0.4)
    for task in (env.task, envs.task):
        assert isinstance(task, LavaBridgeTask)
        assert task.goal_reward == 2.0 and task.layout.bridge_width == 0.4
    # the env's public attributes are the task's
    assert env.model is env.task.model and env.layout is env.task.layout
    assert (env.frame_skip, env.dt, env.lava_reward) == (env.task.frame_skip, env.task.dt, env.task.lava_reward)
    assert env.observation_space == env.task.observation_space and env.action_space == env.task.action_space


@pytest.mark.parametrize("env_id", list(TASKS))
def test_a_task_on_its_own_mjdata_steps_as_the_env_does(env_id):
    """Driving an MjData with the task's own methods gives the env's observations, rewards and ends
    bit for bit, on every task of the suite."""
    env = gymnasium.make(env_id).unwrapped
    task = LavaBridgeTask(TASKS[env_id], goal_reward=1.0, lava_reward=0.0, step_reward=0.0)
    data = mujoco.MjData(task.model)
    rng, task_rng = np.random.default_rng(3), np.random.default_rng(4)
    obs, _ = env.reset(seed=5)
    env_rng = np.random.default_rng(5)
    task.set_state(data, *task.sample_start("p0", env_rng))
    np.testing.assert_array_equal(task.observation(data), obs)
    ends = 0
    for _ in range(300):
        action = rng.uniform(-0.5, 0.5, 2) + (0.6, 0.0)  # eastwards, into lava or across: episodes end
        obs, reward, terminated, _, info = env.step(action)
        task_reward, lava, success = task.step(data, task.check_action(action))
        np.testing.assert_array_equal(task.observation(data), obs)
        assert (task_reward, lava, success, lava or success) == (reward, info["lava"], info["is_success"], terminated)
        assert task.lava_contact(data) == env.lava_contact() and task.goal_contact(data) == env.goal_contact()
        if terminated:
            ends += 1
            state = task.sample_start("ood", task_rng)
            env.set_state(*state)
            task.set_state(data, *task.check_state(*state))
    assert ends > 0, "no episode ended: the resets from a checked state went untested"


def test_check_state_refuses_lava_and_leaves_the_callers_data_alone():
    task = LavaBridgeTask(Layout())
    data = mujoco.MjData(task.model)
    task.set_state(data, *task.check_state((-4.5, 0.0)))
    before = task.observation(data)
    with pytest.raises(ValueError, match=r"state position \(0, 1\) touches lava"):
        task.check_state((0.0, 1.0), (0.0, 0.0))
    with pytest.raises(ValueError, match="qvel must be finite"):
        task.check_state((-4.5, 0.0), (np.nan, 0.0))
    np.testing.assert_array_equal(task.observation(data), before)
    qpos, qvel = task.check_state([-4, 0], [1, 0])
    assert qpos.dtype == qvel.dtype == np.float64 and list(qpos) == [-4.0, 0.0]


@pytest.mark.parametrize("kwargs, message", [
    ({"layout": "wide"}, "layout must be a Layout, got 'wide'"),
    ({"goal_reward": "x"}, "goal_reward must be a finite number, got 'x'"),
])
def test_bad_task_arguments_raise_naming_them(kwargs, message):
    with pytest.raises(ValueError, match=message):
        LavaBridgeTask(**{"layout": Layout(), **kwargs})


def test_check_start_name_names_the_known_ones():
    task = LavaBridgeTask(Layout())
    assert task.check_start_name("ood") == "ood"
    with pytest.raises(ValueError, match=r"unknown start distribution 'far'; expected one of \('p0', 'ood'\)"):
        task.check_start_name("far")


def private_calls_on_other_objects(tree: ast.AST) -> list[str]:
    """`x._name(...)` calls where x is not self or cls: a private method used from outside its class."""
    found = []
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr.startswith("_") and not node.func.attr.startswith("__")
                and not (isinstance(node.func.value, ast.Name) and node.func.value.id in ("self", "cls"))):
            found.append(f"line {node.lineno}: {ast.unparse(node.func)}")
    return found


FOREIGN_ADAPTERS = {"reset_to_state.py": {"_get_obs", "_get_reset_info"}}
"""ResetToState's adapters compute other projects' envs' observations for a restored state: those envs
offer no public way to, so the adapters call the envs' own observation functions, and only those."""


def test_no_module_of_the_env_calls_private_methods_of_another_object():
    """The envs share the task through its public methods only."""
    offenders = {path.name: calls for path in sorted(PACKAGE.glob("*.py"))
                 if (calls := private_calls_on_other_objects(ast.parse(path.read_text())))}
    adapters = {name: offenders.pop(name) for name in FOREIGN_ADAPTERS if name in offenders}
    assert offenders == {}
    for name, calls in adapters.items():
        assert {call.rsplit(".", 1)[-1] for call in calls} <= FOREIGN_ADAPTERS[name], calls


def same_steps(a, b):
    for x, y, name in zip(a, b, ("obs", "reward", "terminated", "truncated")):
        np.testing.assert_array_equal(x, y, err_msg=name)
    for key in ("is_success", "lava"):
        np.testing.assert_array_equal(a[4][key], b[4][key], err_msg=key)


@pytest.mark.parametrize("env_id", list(TASKS))
def test_free_motion_steps_equal_the_checked_loop_bit_for_bit(env_id):
    """The vector env and the single env with free-motion steps (the default) against the same envs
    checking every physics step, under the same seeded actions: an expert with noise (goal reaches and
    lava deaths on the bridge) and uniform random actions (walls, truncations), with their resets."""
    k, horizon = 6, 400
    fast, checked = (LavaBridgeVectorEnv(k, max_episode_steps=horizon, layout=TASKS[env_id]) for _ in range(2))
    single_fast, single_checked = (gymnasium.make(env_id, max_episode_steps=horizon) for _ in range(2))
    checked.task.skip_free_contacts = single_checked.unwrapped.task.skip_free_contacts = False
    expert = ScriptedExpert(single_fast)
    rng = np.random.default_rng(0)
    obs, _ = fast.reset(seed=3)
    np.testing.assert_array_equal(obs, checked.reset(seed=3)[0])
    single_obs, _ = single_fast.reset(seed=3)
    np.testing.assert_array_equal(single_obs, single_checked.reset(seed=3)[0])
    follows_expert = (np.arange(k) < 3)[:, None]
    free = walls_only = success = lava = truncated = 0
    for _ in range(900):
        noisy_expert = np.array([expert.act(o) for o in obs]) + rng.normal(0.0, 0.15, (k, 2))
        actions = np.where(follows_expert, noisy_expert, rng.uniform(-1, 1, (k, 2))).astype(np.float32)
        free += sum(fast.task.free_motion(data) for data in fast.datas)
        walls_only += sum(fast.task.clear_of_hazards(data) and not fast.task.free_motion(data) for data in fast.datas)
        step = fast.step(actions)
        same_steps(step, checked.step(actions))
        obs = step[0]
        success += step[4]["is_success"].sum()
        lava += step[4]["lava"].sum()
        truncated += step[3].sum()
        single_action = expert.act(single_obs) + rng.normal(0.0, 0.4, 2).astype(np.float32)
        single_step = single_fast.step(single_action)
        same_steps(single_step, single_checked.step(single_action))
        single_obs = single_step[0]
        if single_step[2] or single_step[3]:
            start = "ood" if rng.random() < 0.5 else "p0"
            single_obs, _ = single_fast.reset(options={"start": start})
            np.testing.assert_array_equal(single_obs, single_checked.reset(options={"start": start})[0])
    assert success and lava and truncated, (success, lava, truncated)  # every ending was compared
    assert 0 < free < 900 * k and walls_only, (free, walls_only)  # the three paths ran


STRONGEST_PUSHES = [np.array([dx, dy], dtype=np.float32) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy]
"""Full force in each of eight directions."""


def checked_loop_task(env_id):
    """A task with its free-motion shortcut off (`skip_free_contacts = False`), and an MjData of it."""
    task = LavaBridgeTask(TASKS[env_id])
    task.skip_free_contacts = False
    return task, mujoco.MjData(task.model)


@pytest.mark.parametrize("env_id", ["LavaBridge-v0", "LavaBridgeLowDamping-v0", "LavaBridgeBend-v0"])
def test_free_motion_is_only_claimed_where_no_contact_can_occur(env_id):
    """From random states (any position, speeds up to the top speed) that free_motion accepts, the
    strongest pushes in eight directions find no contact at any physics step of the checked loop."""
    task, data = checked_loop_task(env_id)
    rng = np.random.default_rng(1)
    hx, hy = task.layout.half_extent
    v = task.layout.top_speed
    accepted = refused = 0
    for _ in range(400):
        state = rng.uniform([-hx, -hy, -v, -v], [hx, hy, v, v])
        task.set_state(data, state[:2], state[2:])
        if not task.free_motion(data):
            refused += 1
            continue
        accepted += 1
        push = STRONGEST_PUSHES[rng.integers(len(STRONGEST_PUSHES))]
        data.ctrl[:] = push
        for _ in range(task.frame_skip):
            mujoco.mj_step2(task.model, data)
            mujoco.mj_step1(task.model, data)
            assert data.ncon == 0, (state, push)
    assert accepted and refused, (accepted, refused)


@pytest.mark.parametrize("env_id", ["LavaBridge-v0", "LavaBridgeLowDamping-v0", "LavaBridgeBend-v0",
                                    "LavaBridgeDecoy-v0"])
def test_clear_of_hazards_is_only_claimed_where_no_lava_or_goal_contact_can_occur(env_id):
    """From random states that clear_of_hazards accepts, many against a wall (ball centres up to the
    maze's edge, speeds up to the top speed), the strongest pushes find no lava or goal contact at any
    physics step of the checked loop; and the walls-only steps it allows do touch walls."""
    task, data = checked_loop_task(env_id)
    rng = np.random.default_rng(2)
    hx, hy = task.layout.half_extent
    v = task.layout.top_speed
    accepted = refused = wall_contacts = 0
    for i in range(600):
        state = rng.uniform([-hx, -hy, -v, -v], [hx, hy, v, v])
        if i % 2:  # against a wall: pressed onto one axis's edge, moving into it
            axis = rng.integers(2)
            side = rng.choice([-1.0, 1.0])
            state[axis] = side * (hx, hy)[axis]
            state[2 + axis] = side * v
        task.set_state(data, state[:2], state[2:])
        if not task.clear_of_hazards(data):
            refused += 1
            continue
        accepted += 1
        data.ctrl[:] = STRONGEST_PUSHES[rng.integers(len(STRONGEST_PUSHES))]
        for _ in range(task.frame_skip):
            mujoco.mj_step2(task.model, data)
            mujoco.mj_step1(task.model, data)
            assert not task.lava_contact(data) and not task.goal_contact(data), state
            wall_contacts += data.ncon > 0
    assert accepted and refused and wall_contacts, (accepted, refused, wall_contacts)


def test_observations_of_several_datas_are_their_observations():
    task = LavaBridgeTask(Layout())
    datas = [mujoco.MjData(task.model) for _ in range(3)]
    for data, x in zip(datas, (-4.0, -3.0, 4.0)):
        task.set_state(data, np.array([x, 0.1 / 3]), np.array([0.7, -1 / 3]))
    observations = task.observations(datas)
    assert observations.shape == (3, 4) and observations.dtype == np.float64
    np.testing.assert_array_equal(observations, np.stack([task.observation(d) for d in datas]))
