"""Generate the Lava Bridge MJCF model from a `Layout`, and load compiled models.

The default layout's model is also shipped as `assets/lava_bridge.xml` (a test checks the two agree);
`python -m lava_bridge_mj model` rewrites it after a change to the defaults.

Collision design (why the bits are what they are):
- The ball collides with walls (physical contacts) and with lava (detected, never pushed back).
- Lava pits are thin boxes just below the ball's lowest point. Their contacts with the ball are
  *inactive*: with margin 0 and a positive `gap`, MuJoCo lists contacts closer than the gap in
  `data.contact` (with `exclude` = 1) for the env to read, and the solver ignores them (measured with
  mujoco 3.17: contacts inside the margin, by contrast, do push). The gap is set so that a contact
  exists exactly when the ball's footprint (a disc of `ball_radius`) overlaps a pit, which is what
  "touching lava" means here.
- The goal is detected the same way: a disc just below the surface, of radius goal_radius - ball_radius,
  so that its (inactive) contact exists exactly when the ball's centre is within goal_radius of it.
- Walls, lava and goal never collide with each other (contype 0), so every contact involves the ball.
- The floor is drawn below the lava and goal so that they show; the ball has no vertical joint,
  so nothing rests on anything and gravity is off.
"""

from __future__ import annotations

import functools
import math
from importlib import resources

import mujoco

from lava_bridge_mj.layout import Layout

ASSET_NAME = "lava_bridge.xml"
WALL_CONAFFINITY = 1
LAVA_CONAFFINITY = 2
GOAL_CONAFFINITY = 4
BALL_CONTYPE = WALL_CONAFFINITY | LAVA_CONAFFINITY | GOAL_CONAFFINITY
LAVA_DEPTH = 0.005
"""Height of the ball's lowest point above the lava and goal tops; any small value works."""
PAD_THICKNESS = 0.001
FLOOR_Z = -0.02
WALL_HEIGHT = 0.2
VIEW_ASPECT = 960 / 400
"""Width / height of the env's default frame: the top camera's view is sized for it."""


def top_camera_fovy(layout: Layout) -> float:
    """Height (m) of the orthographic top camera's view: the maze with its walls and 0.2 m to spare
    above and below, made taller where a long maze would otherwise overflow a default-sized frame's
    width (then 0.05 m spare at each end). The default maze fits by height alone."""
    hx, hy = layout.half_extent
    t = layout.wall_thickness
    return max(2 * hy + 2 * t + 0.4, (2 * hx + 2 * t + 0.1) / VIEW_ASPECT)


def pad_gap(layout: Layout) -> float:
    """Contact gap at which a lava (or goal) contact appears exactly when the ball's footprint meets it.

    The ball's lowest point is LAVA_DEPTH above the lava top; with its centre a horizontal distance
    d from the pit edge, MuJoCo's sphere-box distance is sqrt(d^2 + (r + LAVA_DEPTH)^2) - r. Setting
    the gap to that value at d = r makes contacts exist for d < r.
    """
    r = layout.ball_radius
    return math.hypot(r, r + LAVA_DEPTH) - r


def build_mjcf(layout: Layout) -> str:
    """Return the MJCF XML text of the maze described by `layout`."""
    from dm_control import mjcf  # imported here: only custom layouts need it at run time

    root = mjcf.RootElement(model="lava_bridge")
    root.compiler.angle = "radian"
    # A planar point mass: no gravity needed; soft contacts stiff enough to keep the ball out of walls.
    root.option.timestep = layout.timestep
    root.option.gravity = (0, 0, 0)
    # No solver warm start: then (qpos, qvel) is the whole state, and a reset to a visited state
    # replays the original continuation bit for bit, also while the ball presses on a wall.
    root.option.flag.warmstart = "disable"
    root.default.geom.solref = (2 * layout.timestep, 1)
    root.default.geom.condim = 1  # frictionless: the ball slides along walls

    root.visual.__getattr__("global").offwidth = 1920
    root.visual.__getattr__("global").offheight = 1080
    root.visual.headlight.ambient = (0.5, 0.5, 0.5)
    root.visual.headlight.diffuse = (0.5, 0.5, 0.5)

    root.asset.add("texture", name="grid", type="2d", builtin="checker", width=256, height=256,
                   rgb1=(0.82, 0.84, 0.86), rgb2=(0.76, 0.78, 0.8))
    root.asset.add("material", name="floor", texture="grid", texrepeat=(1, 1), texuniform=True)
    root.asset.add("material", name="wall", rgba=(0.25, 0.3, 0.4, 1))
    root.asset.add("material", name="lava", rgba=(0.8, 0.08, 0.02, 1), emission=0.1, specular=0)
    root.asset.add("material", name="ball", rgba=(0.1, 0.1, 0.12, 1))

    hx, hy = layout.half_extent
    world = root.worldbody
    world.add("light", name="top", pos=(0, 0, 8), dir=(0, 0, -1), directional=True)
    fovy = top_camera_fovy(layout)
    world.add("camera", name="top", pos=(0, 0, 10), projection="orthographic", fovy=fovy)
    # the floor reaches 1 m past the walls, and fills the top camera's view of a long maze
    world.add("geom", name="floor", type="plane", pos=(0, 0, FLOOR_Z),
              size=(max(hx + 1, fovy * VIEW_ASPECT / 2), max(hy + 1, fovy / 2), 0.1),
              material="floor", contype=0, conaffinity=0)
    for name, box in layout.walls.items():
        world.add("geom", name=name, type="box", material="wall",
                  pos=(box.x, box.y, WALL_HEIGHT / 2), size=(box.half_x, box.half_y, WALL_HEIGHT / 2),
                  contype=0, conaffinity=WALL_CONAFFINITY)
    gap = pad_gap(layout)
    pad_z = -LAVA_DEPTH - PAD_THICKNESS / 2
    for name, box in layout.lava_pits.items():
        world.add("geom", name=name, type="box", material="lava",
                  pos=(box.x, box.y, pad_z), size=(box.half_x, box.half_y, PAD_THICKNESS / 2),
                  contype=0, conaffinity=LAVA_CONAFFINITY, margin=0, gap=gap)
    world.add("geom", name="goal", type="cylinder", rgba=(0.1, 0.75, 0.2, 1), pos=(*layout.goal, pad_z),
              size=(layout.goal_radius - layout.ball_radius, PAD_THICKNESS / 2),
              contype=0, conaffinity=GOAL_CONAFFINITY, margin=0, gap=gap)
    # Markers only (no collision): where episodes start.
    for name, color, discs in (("p0", (0.2, 0.8, 0.3, 0.5), layout.p0_blobs),
                               ("ood", (0.2, 0.4, 0.95, 0.5), layout.ood_spots)):
        for i, disc in enumerate(discs):
            world.add("site", name=f"{name}_{i}", type="cylinder", pos=(disc.x, disc.y, FLOOR_Z / 2),
                      size=(disc.radius, PAD_THICKNESS / 2), rgba=color)

    ball = world.add("body", name="ball", pos=(0, 0, layout.ball_radius))
    ball.add("joint", name="x", type="slide", axis=(1, 0, 0), damping=layout.damping)
    ball.add("joint", name="y", type="slide", axis=(0, 1, 0), damping=layout.damping)
    ball.add("geom", name="ball", type="sphere", size=(layout.ball_radius,), mass=layout.ball_mass,
             material="ball", contype=BALL_CONTYPE, conaffinity=0)

    for axis in ("x", "y"):
        root.actuator.add("motor", name=axis, joint=axis, gear=(layout.gear,),
                          ctrllimited=True, ctrlrange=(-1, 1))
    return root.to_xml_string(precision=10)


def shipped_xml() -> str:
    """The XML text of the shipped default model."""
    return resources.files("lava_bridge_mj.assets").joinpath(ASSET_NAME).read_text()


@functools.lru_cache(maxsize=8)
def model_xml(layout: Layout) -> str:
    """The XML for `layout`: the shipped file for the default layout (no dm_control import needed)."""
    return shipped_xml() if layout == Layout() else build_mjcf(layout)


def load_model(layout: Layout) -> mujoco.MjModel:
    """A freshly compiled model for `layout` (each env owns its model, so it may change it)."""
    return mujoco.MjModel.from_xml_string(model_xml(layout))


def regenerate_model(check: bool = False) -> bool:
    """Rewrite the shipped XML from the default Layout, or with `check` report whether it is current."""
    xml = build_mjcf(Layout())
    path = resources.files("lava_bridge_mj.assets").joinpath(ASSET_NAME)
    if check:
        current = path.read_text() == xml
        print(f"{ASSET_NAME}: {'up to date' if current else 'OUT OF DATE'}")
        return current
    with open(str(path), "w") as f:
        f.write(xml)
    print(f"wrote {path}")
    return True
