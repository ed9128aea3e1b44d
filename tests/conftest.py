"""Shared test set-up.

The package picks EGL for off-screen rendering on headless machines, but only if it is imported
before mujoco: mujoco reads MUJOCO_GL once, at import, and falls back to GLFW, which aborts the
whole process (not an exception) when there is no display. Test modules import mujoco in any
order, so the choice is made here, before any of them is collected.
"""

import os

if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"
