"""The task suite: registration, lookup, per-task layouts, the expert and the shipped demos of every task.

The env's own invariants (exact resets, lava at every physics step, check_env, determinism) are
parametrized over the tasks in tests/test_env.py, tests/test_env_properties.py and
tests/test_vector_env.py; this file holds what is specific to the suite.
"""

from __future__ import annotations

import json
import re
import types
from importlib import resources

import gymnasium
import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest

import lava_bridge_mj
from lava_bridge_mj import (TASKS, Layout, LavaBridgeEnv, LavaBridgeVectorEnv, ScriptedExpert, load_demos, pictures,
                            task_layout)
from lava_bridge_mj.demos import MANIFEST, SHIPPED_SEEDS, SHIPPED_SIZES, content_hash, demo_file, generate_demos
from lava_bridge_mj.external import EXTERNAL_TASKS
from lava_bridge_mj.eval.analysis import report_groups
from lava_bridge_mj.layout import Box2D, _uncovered
from lava_bridge_mj.mjcf import VIEW_ASPECT
from lava_bridge_mj.tasks import TASK_DOCS, placed_layout
from conftest import makefile_sweeps
from test_env import needs_gl

TASK_IDS = list(TASKS)
NEW_TASK_IDS = TASK_IDS[1:]
ASSETS = resources.files("lava_bridge_mj.assets")


def test_suite_starts_with_the_unchanged_reference_task():
    assert TASK_IDS[0] == lava_bridge_mj.ENV_ID == "LavaBridge-v0"
    assert TASKS["LavaBridge-v0"] == Layout() == placed_layout()
    assert len(TASK_IDS) >= 5 and len(set(TASKS.values())) == len(TASKS)  # every task differs
    assert set(TASK_DOCS) == set(TASKS)
    for env_id in TASK_IDS:
        assert env_id.startswith("LavaBridge") and env_id.endswith("-v0"), env_id


def test_the_study_trains_every_method_once_on_every_task_of_the_suite_and_on_no_other():
    # the Makefile's study targets (study, and study-rfcl for RFCL's two methods) are the one place their
    # commands live; SUITE names its tasks for Python
    cells = [(env, method, sweep["--steps"]) for target in ("study", "study-rfcl") for sweep in makefile_sweeps(target)
             for env in sweep["--envs"].split(",") for method in sweep["--methods"].split(",")]
    assert len(cells) == len(set(cells))
    methods = {method for _, method, _ in cells}
    assert methods == set(report_groups.START_STUDY) | {"sac", "hysac_auxss"}
    # every method on every task, at one budget per task: the paper's 300,000 steps on the two crossings only
    steps = {env: "300000" if env == "LavaBridgeTwoCrossings-v0" else "100000" for env in lava_bridge_mj.SUITE}
    assert sorted(cells) == sorted((env, method, steps[env]) for env in lava_bridge_mj.SUITE for method in methods)
    assert lava_bridge_mj.SUITE[0] == "LavaBridge-v0" and set(lava_bridge_mj.SUITE) <= set(TASKS)


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_every_task_is_registered_with_its_layout(env_id):
    spec = gymnasium.spec(env_id)
    assert spec.entry_point == "lava_bridge_mj.lava_bridge:LavaBridgeEnv"
    assert spec.vector_entry_point == "lava_bridge_mj.vector:LavaBridgeVectorEnv"
    assert spec.max_episode_steps == 500
    env = gymnasium.make(env_id)
    assert env.unwrapped.layout == task_layout(env_id) == TASKS[env_id]
    env.close()
    envs = gymnasium.make_vec(env_id, num_envs=2)
    assert isinstance(envs.unwrapped, LavaBridgeVectorEnv)
    assert envs.unwrapped.task.layout == TASKS[env_id] and envs.unwrapped.max_episode_steps == 500
    # the documented ways to build a task directly
    assert LavaBridgeEnv(layout=task_layout(env_id)).layout == TASKS[env_id]
    assert LavaBridgeVectorEnv(2, layout=task_layout(env_id)).task.layout == TASKS[env_id]


def test_reference_task_registers_without_keyword_arguments():
    assert gymnasium.spec("LavaBridge-v0").kwargs == {}


def test_make_keywords_override_single_fields_of_a_task():
    env = gymnasium.make("LavaBridgeNarrow-v0", damping=2.0).unwrapped
    assert env.layout.bridge_width == TASKS["LavaBridgeNarrow-v0"].bridge_width != Layout().bridge_width
    assert env.layout.damping == 2.0


@pytest.mark.parametrize("env_id", ["LavaBridge-v1", "lavabridge-v0", "", None])
def test_unknown_task_ids_are_refused_naming_the_known_ones(env_id):
    known = r"expected one of \['LavaBridge-v0', 'LavaBridgeLong-v0', 'LavaBridgeNarrow-v0'"
    with pytest.raises(ValueError, match=rf"unknown Lava Bridge task {env_id!r}; {known}"):
        task_layout(env_id)
    with pytest.raises(ValueError, match=rf"no shipped demo sets for {re.escape(repr(env_id))}; {known}"):
        load_demos(500, env_id=env_id)


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_the_top_camera_shows_the_whole_maze_in_a_default_frame(env_id):
    """Orthographic: the view is fovy high and fovy * aspect wide; the walls' outer edges fit in both."""
    env = LavaBridgeEnv(layout=TASKS[env_id])
    fovy = env.model.cam_fovy[mujoco.mj_name2id(env.model, mujoco.mjtObj.mjOBJ_CAMERA, "top")]
    hx, hy = env.layout.half_extent
    t = env.layout.wall_thickness
    assert fovy / 2 >= hy + t and fovy * VIEW_ASPECT / 2 >= hx + t
    assert VIEW_ASPECT == env.width / env.height


# --- the expert -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
@pytest.mark.parametrize("start", ["p0", "ood"])
def test_expert_succeeds_on_every_task(env_id, start):
    env = gymnasium.make(env_id)
    expert = ScriptedExpert(env)
    for episode in range(4):
        obs, _ = env.reset(seed=100 + episode, options={"start": start})
        for _ in range(500):
            obs, _, terminated, truncated, info = env.step(expert.act(obs))
            if terminated or truncated:
                break
        assert info["is_success"], (env_id, start, episode, obs, info)
    env.close()


# --- shipped demos --------------------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_every_task_ships_both_sets_recorded_in_the_manifest(env_id):
    manifest = json.loads(ASSETS.joinpath(MANIFEST).read_text())
    assert sorted(manifest) == sorted(TASK_IDS + list(EXTERNAL_TASKS))  # the suite's and the external tasks'
    for size in SHIPPED_SIZES:
        entry = manifest[env_id][str(size)]
        assert entry["file"] == demo_file(env_id, size) and entry["seed"] == SHIPPED_SEEDS[size]
        demos = load_demos(size, env_id=env_id)
        assert content_hash(demos) == entry["sha256"]
        assert len(demos["observations"]) == size
        assert int(demos["episode_ids"][-1]) + 1 == entry["episodes"]


@pytest.mark.parametrize("env_id", NEW_TASK_IDS)
def test_a_task_set_is_its_expert_in_its_layout_from_its_seed(env_id):
    """The 500 set regenerates bit for bit in the task's env, and its episodes replay exactly there."""
    demos = load_demos(500, env_id=env_id)
    env = LavaBridgeEnv(layout=TASKS[env_id])
    assert content_hash(generate_demos(500, SHIPPED_SEEDS[500], env)) == content_hash(demos)
    first, _ = env.reset(seed=SHIPPED_SEEDS[500])
    assert np.array_equal(demos["observations"][0], first)
    ends = np.flatnonzero(demos["terminations"] | demos["truncations"])
    starts = np.concatenate([[0], ends[:-1] + 1])
    for begin, end in zip(starts, ends):
        state = demos["observations"][begin]
        assert state[2:].tolist() == [0.0, 0.0]
        assert any(np.hypot(state[0] - b.x, state[1] - b.y) <= b.radius for b in env.layout.p0_blobs)
        env.reset(options={"state": state})
        for t in range(begin, end + 1):
            obs, reward, terminated, _, _ = env.step(demos["actions"][t])
            assert np.array_equal(obs, demos["next_observations"][t])
            assert reward == demos["rewards"][t] and terminated == demos["terminations"][t]
    assert demos["terminations"].sum() == len(ends) - 1  # whole successful episodes, the last one cut
    assert np.all(demos["rewards"][demos["terminations"]] == 1.0)


def test_a_task_without_a_recorded_set_is_refused(tmp_path, monkeypatch):
    manifest = json.loads(ASSETS.joinpath(MANIFEST).read_text())
    del manifest["LavaBridgeNarrow-v0"]
    (tmp_path / MANIFEST).write_text(json.dumps(manifest))
    import lava_bridge_mj.demos as demos_module
    monkeypatch.setattr(demos_module, "resources", types.SimpleNamespace(files=lambda package: tmp_path))
    with pytest.raises(ValueError, match="records no 500-transition demo set for LavaBridgeNarrow-v0"):
        load_demos(500, env_id="LavaBridgeNarrow-v0")


# --- layouts with other shapes: bent bridges, islands, decoys -------------------------------------------
def floor_boxes(layout: Layout):
    """Every floor rectangle over the strip between the rooms: bridge segments, decoys and islands."""
    half_w = layout.room_width / 2
    islands = [Box2D((w + e) / 2, 0.0, (e - w) / 2, half_w) for w, e in layout.islands]
    return [*layout.bridge_segments, *layout.decoys, *islands]


def inside(box, x, y):
    return abs(x - box.x) < box.half_x and abs(y - box.y) < box.half_y


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_lava_and_floor_tile_the_strip_between_the_rooms(env_id):
    """Every point of the strip is lava or floor, never both; lava rectangles never overlap."""
    layout = TASKS[env_id]
    pits, floor = list(layout.lava_pits.values()), floor_boxes(layout)
    rng = np.random.default_rng(0)
    half_l, half_w = layout.bridge_length / 2, layout.room_width / 2
    for x, y in rng.uniform([-half_l, -half_w], [half_l, half_w], (4000, 2)):
        in_lava = sum(inside(pit, x, y) for pit in pits)
        assert in_lava + any(inside(box, x, y) for box in floor) == 1, (x, y)
    area = sum(4 * pit.half_x * pit.half_y for pit in pits)
    uncovered = np.mean([not any(inside(box, x, y) for box in floor)
                         for x, y in rng.uniform([-half_l, -half_w], [half_l, half_w], (20000, 2))])
    assert area == pytest.approx(uncovered * 4 * half_l * half_w, rel=0.03)


def test_general_lava_cutting_reproduces_the_straight_bridge_pits():
    """The rectangle cutting used for other shapes gives LavaBridge-v0's two pits for its shape."""
    layout = Layout()
    cut = _uncovered((-1.5, 1.5), (-2.0, 2.0), layout.bridge_segments)
    expected = sorted(layout.lava_pits.values())
    assert len(cut) == 2
    for box, pit in zip(sorted(cut), expected):
        assert box == pytest.approx(pit)


def test_the_bend_is_floor_and_its_inside_corner_is_lava():
    env = LavaBridgeEnv(layout=TASKS["LavaBridgeBend-v0"])
    for state in ([-1.0, -0.8, 0.0, 0.0], [0.0, -0.8, 0.0, 0.0], [0.0, 0.0, 0.0, 0.4], [0.1, 0.85, 0.0, 0.0],
                  [1.5, 0.8, 0.3, 0.0]):
        assert np.array_equal(env.reset(options={"state": state})[0], state)
    for position in ([-0.5, 0.0], [0.5, -0.8], [-1.0, -0.6], [0.0, 1.0], [-1.4, 0.8]):
        with pytest.raises(ValueError, match="touches lava"):
            env.reset(options={"qpos": position})
    # heading north up the middle segment without turning: lava at the far corner's outer edge
    env.reset(options={"state": [0.0, 0.5, 0.0, 1.0]})
    for _ in range(20):
        obs, reward, terminated, _, info = env.step([0.0, 0.5])
        if terminated:
            break
    assert info["lava"] and abs(obs[1] - 0.95) <= 0.05


def test_a_decoy_is_floor_that_ends_in_lava():
    env = LavaBridgeEnv(layout=TASKS["LavaBridgeDecoy-v0"])
    env.reset(options={"state": [-1.4, 1.0, 0.0, 0.0]})  # on the decoy, at its start
    for _ in range(60):
        obs, _, terminated, _, info = env.step([1.0, 0.0])
        if terminated:
            break
    assert info["lava"] and 0.95 <= obs[0] <= 1.0  # at its east end, 0.5 m short of the goal room


@pytest.mark.parametrize("fields, message", [
    ({"bridge_path": ((-1.5, 0.0), (1.5, 0.3))}, "must run eastwards along x or along y"),
    ({"bridge_path": ((-1.5, 0.0), (0.5, 0.0), (0.0, 0.0), (1.5, 0.0))}, "must run eastwards"),
    ({"bridge_path": ((-1.0, 0.0), (1.5, 0.0))}, "must run from x = -1.5 to x = 1.5"),
    ({"bridge_path": ((-1.5, 0.0),)}, "must run from x = -1.5"),
    ({"bridge_path": ((-1.5, 1.9), (1.5, 1.9))}, "past the walls"),
    ({"bridge_path": ((-1.5, 0.0), (-1.5, 1.0), (1.5, 1.0))}, "along y must lie inside an island"),
    ({"bridge_path": ((-1.5, 0.0), (0.0, 0.0), (0.0, 1.0))}, "must run from x = -1.5 to x = 1.5"),
    ({"bridge_path": ((-1.5, 0.0), (1.5, 0.0), (1.5, 1.0))}, "Layout.bridge_path"),
    ({"bridge_path": "abc"}, "Layout.bridge_path must be a sequence of finite"),
    ({"bridge_path": ((0.0, float("nan")),)}, "Layout.bridge_path must be a sequence of finite"),
    ({"islands": ((-2.0, 0.0),)}, r"Layout.islands: \(-2, 0\) must lie strictly inside the strip"),
    ({"islands": ((-1.0, 0.0), (-0.5, 0.5))}, "clear of the other islands"),
    ({"islands": ((0.5, -0.5),)}, "Layout.islands"),
    ({"islands": ((1.0,),)}, "Layout.islands must be a sequence of finite"),
    ({"decoys": ((0.0, 1.0, 2.0, 0.3),)}, "Layout.decoys"),
    ({"decoys": ((0.0, 1.0, 0.5, -0.3),)}, "Layout.decoys"),
    ({"decoys": ((0.0, 1.0, 0.5),)}, "Layout.decoys must be a sequence of finite"),
])
def test_bad_shapes_are_refused_naming_the_field(fields, message):
    with pytest.raises(ValueError, match=message):
        Layout(**fields)
    with pytest.raises(ValueError, match=message):
        gymnasium.make("LavaBridge-v0", **fields)


def test_shapes_given_as_json_lists_make_the_same_layout():
    """A run's config.json holds plain lists; they build the task's layout exactly."""
    layout = TASKS["LavaBridgeTwoCrossings-v0"]
    fields = json.loads(json.dumps({name: getattr(layout, name) for name in ("bridge_path", "islands", "decoys")}))
    rebuilt = placed_layout(bridge_length=layout.bridge_length, **fields)
    assert rebuilt == layout and hash(rebuilt) == hash(layout)
    decoy = TASKS["LavaBridgeDecoy-v0"]
    assert Layout(decoys=json.loads(json.dumps(decoy.decoys))).decoys == decoy.decoys
    assert isinstance(decoy.decoys[0], Box2D)


@needs_gl
@pytest.mark.parametrize("env_id", TASK_IDS)
def test_rendering_shows_each_task_as_its_layout_says(env_id):
    """From the top camera: lava red at every pit's centre, floor along the bridge's centre line and in
    the frame's corners, the goal green."""
    env = gymnasium.make(env_id, render_mode="rgb_array", width=480, height=200)
    try:
        base = env.unwrapped
        layout = base.layout
        env.reset(seed=0)  # the ball in a p0 blob, clear of everything checked below
        rgb = env.render().astype(int)
        camera = mujoco.mj_name2id(base.model, mujoco.mjtObj.mjOBJ_CAMERA, "top")
        scale = base.height / base.model.cam_fovy[camera]  # orthographic, centred on the origin

        def pixel(x, y):
            return rgb[int(round(base.height / 2 - y * scale)), int(round(base.width / 2 + x * scale))]

        for pit in layout.lava_pits.values():
            r, g, b = pixel(pit.x, pit.y)
            assert r > 150 and r > 2 * g and r > 2 * b, (env_id, pit, (r, g, b))
        for crossing in layout.crossings:
            for (x0, y0), (x1, y1) in zip(crossing, crossing[1:]):
                r, g, b = pixel((x0 + x1) / 2, (y0 + y1) / 2)
                assert abs(r - g) < 30 and r > 150, (env_id, (x0, y0, x1, y1), (r, g, b))
        r, g, b = pixel(*layout.goal)
        assert g > 150 and g > r + 50 and g > b + 50, (env_id, (r, g, b))
        for corner in (rgb[0, 0], rgb[0, -1], rgb[-1, 0], rgb[-1, -1]):  # the floor fills the view
            assert corner.min() > 100, (env_id, corner)
    finally:
        env.close()


@needs_gl
def test_the_task_picture_shows_every_task(tmp_path):
    out = tmp_path / "tasks.png"
    assert pictures.main(["--out", str(out), "--width", "240", "--height", "100"]) == 0
    image = imageio.imread(out)
    assert image.ndim == 3 and image.shape[0] > 4 * 100 and image.shape[1] > 2 * 240  # 2 columns, 4+ rows
    assert not list(tmp_path.glob("*.tmp.png"))


def test_the_task_picture_refuses_a_non_png_path(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        pictures.main(["--out", str(tmp_path / "tasks.jpg")])
    assert exit_info.value.code == 2 and "must name a .png file" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
