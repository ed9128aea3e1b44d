"""External tasks (lava_bridge_mj/external.py): Gymnasium-Robotics' PointMaze_Large-v3 and
PointMaze_Medium-v3, OGBench's cube-single-singletask-task1-v0, with their named starts, their
declared states and their experts."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import mujoco
import numpy as np
import pytest

from lava_bridge_mj import ResetToState
from lava_bridge_mj.external import (EXTERNAL_TASKS, START_NAMES, MazeExpert, NamedStarts, make_task_env,
                                     MazePlanner, run_episode, state_offset)

pytestmark = pytest.mark.filterwarnings("ignore:.*precision lowered by casting to float32")  # OGBench's Box bounds

MAZES = ("PointMaze_Large-v3", "PointMaze_Medium-v3")
CUBE = "cube-single-singletask-task1-v0"
ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True)
def offline(monkeypatch):
    """Every test here runs with the network refused: the tasks need none."""
    def refuse(*args, **kwargs):
        raise OSError("network refused by the test")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)


def cell_of(env, xy):
    return tuple(int(x) for x in env.unwrapped.maze.cell_xy_to_rowcol(xy))


def cube_xy(env):
    return env.unwrapped.data.joint("object_joint_0").qpos[:2].copy()


def same(a, b):
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(np.array_equal(a[key], b[key]) for key in a)
    return np.array_equal(a, b)


# --- experts -------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id, episodes", [(MAZES[0], 5), (MAZES[1], 5), (CUBE, 4)])
@pytest.mark.parametrize("start", START_NAMES)
def test_expert_succeeds_from_p0_and_ood_and_random_actions_do_not(env_id, episodes, start):
    env = make_task_env(env_id)
    expert = EXTERNAL_TASKS[env_id].expert(env, seed=0)
    limit = env.spec.max_episode_steps
    for seed in range(episodes):
        success, length = run_episode(env, expert, seed=seed, options={"start": start})
        assert success and length < limit, (seed, length)
    if start == "p0":  # the task is no free lunch: random actions time out from its start
        assert run_episode(env, None, seed=0, options={"start": "p0"}) == (False, limit)


@pytest.mark.parametrize("env_id", MAZES)
def test_maze_expert_reaches_the_goal_from_every_free_cell(env_id):
    task = EXTERNAL_TASKS[env_id]
    env = task.make_env()  # the env's own reset options place the ball in any cell
    expert = MazeExpert(env.unwrapped.maze, env.action_space)
    cells = [cell for cell in expert.planner.free_cells() if cell != task.goal_cell]
    assert len(cells) == sum(row.count(0) for row in env.unwrapped.maze.maze_map) - 1
    for seed, cell in enumerate(cells):
        observation, info = env.reset(seed=seed, options={"reset_cell": np.array(cell),
                                                          "goal_cell": np.array(task.goal_cell)})
        assert cell_of(env, observation["achieved_goal"]) == cell
        expert.reset(observation, info)
        for _ in range(env.spec.max_episode_steps):
            observation, reward, terminated, truncated, info = env.step(expert(observation))
            if terminated or truncated:
                break
        assert terminated and info["success"] and reward == 1.0, cell


def test_maze_plan_is_a_shortest_path_through_free_cells():
    task = EXTERNAL_TASKS[MAZES[0]]
    planner = MazePlanner(make_task_env(MAZES[0]).unwrapped.maze)
    cell, path = task.start_cell, [task.start_cell]
    while cell != task.goal_cell:
        cell = planner.next_cell(cell, task.goal_cell)
        path.append(cell)
    free = set(planner.free_cells())
    assert all(c in free for c in path)
    assert all(abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1 for a, b in zip(path, path[1:]))
    # LARGE_MAZE by hand: down column 1 to row 3, east along row 3 to column 6, down column 6 to row 5,
    # east along row 5 to column 8, down to row 7, east to column 10: 15 steps, the Manhattan distance
    # 6 + 9 (no detour)
    assert len(path) - 1 == 15 == planner.steps_to_goal(task.goal_cell)[task.start_cell]
    with pytest.raises(ValueError, match=r"cell \(0, 0\) is a wall"):
        planner.next_cell((0, 0), task.goal_cell)


def test_cube_expert_reads_the_oracles_inputs_from_the_observation():
    env = make_task_env(CUBE)
    expert = EXTERNAL_TASKS[CUBE].expert(env, seed=0)
    with pytest.raises(ValueError, match="expert.reset"):
        expert(env.reset(seed=0)[0])
    for start in START_NAMES:
        observation, info = env.reset(seed=3, options={"start": start})
        expert.reset(observation, info)
        for _ in range(3):
            observation, *_ = env.step(expert(observation))
        decoded, truth = expert.decode(observation), env.unwrapped.compute_ob_info()
        for key in ("proprio/effector_pos", "proprio/effector_yaw", "proprio/gripper_opening",
                    "proprio/gripper_contact", "privileged/block_0_pos", "privileged/block_0_quat",
                    "privileged/block_0_yaw"):
            np.testing.assert_allclose(decoded[key], truth[key], atol=1e-12, err_msg=key)
        np.testing.assert_array_equal(decoded["privileged/target_block_pos"], [0.425, -0.1, 0.02])


def test_cube_expert_leaves_numpys_global_generator_alone():
    env = make_task_env(CUBE)
    expert = EXTERNAL_TASKS[CUBE].expert(env, seed=0)
    np.random.seed(11)
    expected = np.random.random(3)
    np.random.seed(11)
    expert.reset(*env.reset(seed=0))
    np.testing.assert_array_equal(np.random.random(3), expected)


# --- starts --------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", MAZES)
def test_maze_p0_starts_in_its_start_cell_and_ood_in_other_free_cells(env_id):
    task, env = EXTERNAL_TASKS[env_id], make_task_env(env_id)
    ood_cells = set()
    for seed in range(30):
        observation, _ = env.reset(seed=seed)  # no options: p0
        assert cell_of(env, observation["achieved_goal"]) == task.start_cell
        assert cell_of(env, observation["desired_goal"]) == task.goal_cell
        observation, info = env.reset(seed=seed, options={"start": "ood"})
        ood_cells.add(cell_of(env, observation["achieved_goal"]))
        assert cell_of(env, observation["desired_goal"]) == task.goal_cell and not info["success"]
    free = set(MazePlanner(env.unwrapped.maze).free_cells())
    assert ood_cells <= free - {task.start_cell, task.goal_cell} and len(ood_cells) >= 10


def test_cube_p0_is_ogbenchs_start_and_ood_places_the_cube_wider():
    task, env = EXTERNAL_TASKS[CUBE], make_task_env(CUBE)
    start, target = np.array([0.425, 0.1]), np.array([0.425, -0.1])
    p0, ood = [], []
    for seed in range(30):
        env.reset(seed=seed, options={"start": "p0"})
        p0.append(cube_xy(env))
        _, info = env.reset(seed=seed, options={"start": "ood"})
        ood.append(cube_xy(env))
        assert env.unwrapped.data.joint("object_joint_0").qpos[2] == 0.02  # on the floor
        assert not env.unwrapped._success  # OGBench's success flag for the restored start
    p0, ood = np.array(p0), np.array(ood)
    assert np.abs(p0 - start).max() <= 0.01  # OGBench's noise: +-1 cm
    low, high = np.array(task.ood_bounds)
    assert (ood >= low).all() and (ood <= high).all()
    assert (np.linalg.norm(ood - target, axis=1) >= task.ood_clearance).all()
    assert (np.linalg.norm(ood - start, axis=1) > 0.05).mean() > 0.8  # mostly far from p0's cube
    assert (ood.max(axis=0) - ood.min(axis=0) > 0.15).all()  # spread over the area


@pytest.mark.parametrize("env_id", [*MAZES, CUBE])
@pytest.mark.parametrize("start", START_NAMES)
def test_seeded_resets_reproduce(env_id, start):
    env = make_task_env(env_id)
    observation, info = env.reset(seed=4, options={"start": start})
    env.step(env.action_space.sample())
    other, other_info = env.reset(seed=5, options={"start": start})
    again, again_info = env.reset(seed=4, options={"start": start})
    assert same(observation, again) and np.array_equal(info["state"], again_info["state"])
    assert not np.array_equal(info["state"], other_info["state"])


def test_ogbench_cube_reset_alone_reports_a_different_state_per_reset():
    """The physics fact behind SeededCubeReset: OGBench's own seeded reset leaves the warm start and
    controls of its unseeded goal-preview steps in the state."""
    env = ResetToState(EXTERNAL_TASKS[CUBE].make_env())
    states = [env.reset(seed=4)[1]["state"] for _ in range(2)]
    size = env.unwrapped.model
    warm = state_offset(size, mujoco.mjtState.mjSTATE_WARMSTART)
    ctrl = state_offset(size, mujoco.mjtState.mjSTATE_CTRL)
    differ = np.flatnonzero(states[0] != states[1])
    assert differ.size and set(differ) <= set(range(warm, warm + size.nv)) | set(range(ctrl, ctrl + size.nu))


@pytest.mark.parametrize("options", [{"start": "p1"}, {"start": None}, {"start": "p0", "state": [0.0]},
                                     {"reset_cell": [1, 1]}, ["p0"]])
def test_bad_start_options_raise_naming_the_choices(options):
    env = make_task_env(MAZES[1])
    with pytest.raises(ValueError, match=r"'p0', 'ood'"):
        env.reset(seed=0, options=options)


def test_make_task_env_refuses_unknown_ids_and_named_starts_needs_reset_to_state():
    with pytest.raises(ValueError, match=r"'PointMaze_Huge-v3' is not an external task; expected one of .*"
                                         r"PointMaze_Large-v3"):
        make_task_env("PointMaze_Huge-v3")
    task = EXTERNAL_TASKS[MAZES[1]]
    with pytest.raises(ValueError, match="NamedStarts wraps a ResetToState"):
        NamedStarts(task.make_env(), task)


def test_a_missing_extra_is_named(monkeypatch):
    monkeypatch.setitem(sys.modules, "ogbench", None)  # import ogbench now raises ImportError
    with pytest.raises(ImportError, match=r"pip install 'lava-bridge-mj\[ogbench\]'"):
        make_task_env(CUBE)


@pytest.mark.parametrize("env_id", [MAZES[1], "gymnasium_robotics:PointMaze_UMaze-v3"])
def test_making_a_maze_env_leaves_no_file_in_the_temp_directory(env_id, tmp_path, monkeypatch):
    # Gymnasium-Robotics writes each maze's model to a new file beside tempfile's directories: the
    # task's env and any maze env made by id remove it, once the model is loaded
    from lava_bridge_mj.state_vector import make_state_env

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    env = make_state_env(env_id)
    assert Path(env.unwrapped.tmp_xml_file_path).parent == tmp_path  # where the env wrote it
    assert list(tmp_path.iterdir()) == []
    env.reset(seed=0)
    _, _, terminated, truncated, _ = env.step(env.action_space.sample())  # the loaded model runs
    assert not (terminated or truncated)
    env.close()


def test_importing_the_module_imports_neither_project():
    code = ("import sys, lava_bridge_mj.external; "
            "print(sorted(m for m in ('gymnasium_robotics', 'ogbench') if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


# --- states --------------------------------------------------------------------------------------
def test_state_offsets_follow_mujocos_layout():
    env = make_task_env(CUBE)
    _, info = env.reset(seed=0)
    model, data = env.unwrapped.model, env.unwrapped.data
    state = info["state"]
    assert state_offset(model, mujoco.mjtState.mjSTATE_QPOS) == 1 and state[0] == data.time
    qpos = state_offset(model, mujoco.mjtState.mjSTATE_QPOS)
    np.testing.assert_array_equal(state[qpos:qpos + model.nq], data.qpos)
    mocap = state_offset(model, mujoco.mjtState.mjSTATE_MOCAP_POS)
    np.testing.assert_array_equal(state[mocap:mocap + 3 * model.nmocap], data.mocap_pos.ravel())
    quat = state_offset(model, mujoco.mjtState.mjSTATE_MOCAP_QUAT)
    np.testing.assert_array_equal(state[quat:quat + 4 * model.nmocap], data.mocap_quat.ravel())


@pytest.mark.parametrize("env_id", MAZES)
def test_maze_task_states_point_to_the_ball_and_measure_the_path_to_the_goal(env_id):
    env = make_task_env(env_id)
    task_states, expert = env.get_wrapper_attr("task_states"), EXTERNAL_TASKS[env_id].expert(env)
    observation, info = env.reset(seed=2, options={"start": "ood"})
    expert.reset(observation, info)
    states = [info["state"]]
    for _ in range(40):
        observation, _, _, _, info = env.step(expert(observation))
        states.append(info["state"])
    data = env.unwrapped.data
    position = list(task_states.position)
    np.testing.assert_array_equal(states[-1][position], data.qpos[:2])
    np.testing.assert_array_equal(states[-1][position], observation["achieved_goal"])
    mujoco.mj_forward(env.unwrapped.model, data)
    np.testing.assert_allclose(states[-1][position], data.body("particle").xpos[:2], atol=1e-12)

    # the path length by hand from a state in the start cell, and the straight distance in the goal cell
    task = EXTERNAL_TASKS[env_id]
    maze, goal = env.unwrapped.maze, observation["desired_goal"]
    start_state, goal_state = states[0].copy(), states[0].copy()
    start_state[position] = maze.cell_rowcol_to_xy(task.start_cell) + [0.1, -0.2]
    goal_state[position] = goal + [0.3, 0.0]
    steps = expert.planner.steps_to_goal(task.goal_cell)[task.start_cell]
    following = maze.cell_rowcol_to_xy(expert.planner.next_cell(task.start_cell, task.goal_cell))
    by_hand = (np.linalg.norm(following - start_state[position]) + (steps - 1)
               + np.linalg.norm(goal - maze.cell_rowcol_to_xy(task.goal_cell)))
    np.testing.assert_allclose(task_states.goal_distance(np.array([start_state, goal_state])), [by_hand, 0.3])
    distances = task_states.goal_distance(np.array(states))
    assert distances[-1] < distances[0] - 1.0  # the expert's 40 steps bring it nearer along the path


def test_cube_task_states_point_to_the_cube_and_measure_its_distance_to_the_target():
    env = make_task_env(CUBE)
    task_states, expert = env.get_wrapper_attr("task_states"), EXTERNAL_TASKS[CUBE].expert(env, seed=0)
    observation, info = env.reset(seed=1, options={"start": "ood"})
    expert.reset(observation, info)
    states, successes = [info["state"]], [None]  # OGBench's reset info has no success
    terminated = truncated = False
    while not (terminated or truncated):
        observation, _, terminated, truncated, info = env.step(expert(observation))
        states.append(info["state"])
        successes.append(info["success"])
    data = env.unwrapped.data
    position = list(task_states.position)
    np.testing.assert_array_equal(states[-1][position], data.joint("object_joint_0").qpos[:3])
    mujoco.mj_forward(env.unwrapped.model, data)
    np.testing.assert_allclose(states[-1][position], data.body("object_0").xpos, atol=1e-12)
    distances = task_states.goal_distance(np.array(states))
    np.testing.assert_allclose(distances[-1], np.linalg.norm(data.joint("object_joint_0").qpos[:3]
                                                             - data.mocap_pos[0]))
    assert terminated and distances[-2] <= 0.04 < distances[0]
    # OGBench's success after a step is its state's (success_timing "pre": reported one step later)
    assert [d <= 0.04 for d in distances[:-1]] == successes[1:]


# --- exact resets --------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", [*MAZES, CUBE])
def test_reset_to_a_recorded_state_and_replay_reproduces_the_trajectory(env_id):
    env = make_task_env(env_id)
    expert = EXTERNAL_TASKS[env_id].expert(env, seed=0)
    observation, info = env.reset(seed=7, options={"start": "ood"})
    expert.reset(observation, info)
    actions, recording = [], [(observation, None, None, None, info)]
    for _ in range(60):
        actions.append(expert(observation))
        recording.append(env.step(actions[-1]))
        observation = recording[-1][0]
        if recording[-1][2] or recording[-1][3]:
            break
    assert len(recording) > 20
    for k in (1, len(recording) // 2):
        observation, info = env.reset(seed=123, options={"state": recording[k][4]["state"]})
        np.testing.assert_array_equal(info["state"], recording[k][4]["state"])
        for step, action in enumerate(actions[k:], start=k + 1):
            replayed = env.step(action)
            assert same(replayed[0], recording[step][0]), (k, step)
            assert replayed[1:4] == recording[step][1:4], (k, step)
            np.testing.assert_array_equal(replayed[4]["state"], recording[step][4]["state"])


def test_bench_script_runs_and_writes_its_table(tmp_path):
    out = tmp_path / "external_tasks.txt"
    result = subprocess.run([sys.executable, str(ROOT / "bench" / "external_tasks.py"), "--quick", "--out", str(out)],
                            capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    text = out.read_text()
    assert "python bench/external_tasks.py --quick" in text
    for env_id in EXTERNAL_TASKS:
        assert text.count(f"| {env_id} |") == 4  # expert and random, from p0 and ood
    assert "steps/s" in text


def test_the_documentation_example_runs_and_does_what_it_says(tmp_path):
    page = (ROOT / "docs" / "external-tasks.md").read_text().split("\n## Use a task\n", 1)[1]
    script = tmp_path / "example.py"
    script.write_text(re.search(r"```python\n(.*?)```", page, re.S).group(1))
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.splitlines() == ["positions at (1, 2)", "expert success: True", "back at the start: True"]
