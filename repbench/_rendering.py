"""Choose MuJoCo's rendering backend before mujoco is imported anywhere.

On a machine with no display (a CI runner, a cluster node) and no user choice, MuJoCo's default
GLFW backend fails; EGL (hardware or Mesa's software llvmpipe) works headless. PyOpenGL reads
``PYOPENGL_PLATFORM`` at import, so both variables are set together.
"""

from __future__ import annotations

import os
import sys


def configure_headless_rendering() -> str | None:
    """Set ``MUJOCO_GL=egl`` when the user set nothing and no display exists.

    Returns the backend now in effect (or None when left to MuJoCo's default).
    Does nothing once mujoco has been imported: the backend is fixed at that point.
    """
    if "MUJOCO_GL" in os.environ:
        backend = os.environ["MUJOCO_GL"]
        if backend in ("egl", "osmesa"):
            os.environ.setdefault("PYOPENGL_PLATFORM", backend)
        return backend
    if "mujoco" in sys.modules:
        return None
    has_display = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if sys.platform.startswith("linux") and not has_display:
        os.environ["MUJOCO_GL"] = "egl"
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        return "egl"
    return None
