"""Wrist-camera rendering tuned for software (CPU) OpenGL, with the same picture as robosuite's.

robosuite's default camera observable renders with 4x multisampling, planar reflections and the
whole robot in the scene. On Mesa's llvmpipe at 64x64 almost all of that cost is vertex work on
meshes the wrist camera never sees (the arm's links behind it) and the reflection pass. The tuned
path keeps everything that shows: it turns multisampling and reflections off and moves the visual
geoms of bodies that are never in the wrist camera's view (arm links, mount, table legs) into a
geom group the wrist render leaves out. Collision geoms stay hidden, as in robosuite's renderer.
"""

from __future__ import annotations

import mujoco
import numpy as np

WRIST_CAMERA = "robot0_eye_in_hand"
#: Bodies whose geoms the wrist camera cannot see (checked by segmentation in the tests).
UNSEEN_BODY_PREFIXES = ("robot0_link", "robot0_base", "mount0_", "fixed_mount0_")
UNSEEN_GEOM_PREFIXES = ("table_leg",)
HIDDEN_GROUP = 5


def unseen_geom_ids(model: mujoco.MjModel) -> np.ndarray:
    """Visual geoms the wrist camera never sees (arm links, mount, table legs)."""
    ids = []
    for g in range(model.ngeom):
        body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g])) or ""
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        if body.startswith(UNSEEN_BODY_PREFIXES) or name.startswith(UNSEEN_GEOM_PREFIXES):
            ids.append(g)
    return np.asarray(ids, dtype=np.int64)


class WristRenderer:
    """Render the wrist camera at ``size x size`` with the tuned settings.

    Args:
        model, data: the simulation's ``MjModel``/``MjData``.
        size: image side in pixels.
        cull_unseen: leave the unseen geoms out (the picture is unchanged; ~10x faster on CPU).
        multisample: keep MuJoCo's multisampling (off: faster, edges differ by a few levels).
        reflection: keep planar reflections (the table and hole have none to show).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, size: int, *,
                 cull_unseen: bool = True, multisample: bool = False,
                 reflection: bool = False) -> None:
        self.model, self.data, self.size = model, data, size
        if not multisample:
            model.vis.quality.offsamples = 0  # read when the GL context is created
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, size)
        model.vis.global_.offheight = max(model.vis.global_.offheight, size)
        self.renderer = mujoco.Renderer(model, size, size)
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = int(reflection)
        self.option = mujoco.MjvOption()
        self.option.geomgroup[0] = 0  # collision geoms, hidden as in robosuite's renderer
        if cull_unseen:
            ids = unseen_geom_ids(model)
            visual = ids[model.geom_group[ids] != 0]
            model.geom_group[visual] = HIDDEN_GROUP
            self.option.geomgroup[HIDDEN_GROUP] = 0
        self.camera_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, WRIST_CAMERA)

    def render(self) -> np.ndarray:
        """The current wrist image, uint8 [size, size, 3], upright (row 0 at the top)."""
        self.renderer.update_scene(self.data, camera=self.camera_id, scene_option=self.option)
        return self.renderer.render()

    def render_segmentation(self) -> np.ndarray:
        """Geom ids seen per pixel (-1 for background), for tests of what the camera sees."""
        self.renderer.enable_segmentation_rendering()
        try:
            opt = mujoco.MjvOption()
            opt.geomgroup[0] = 0
            opt.geomgroup[HIDDEN_GROUP] = 1  # include culled geoms: show what *would* be seen
            self.renderer.update_scene(self.data, camera=self.camera_id, scene_option=opt)
            seg = self.renderer.render()
        finally:
            self.renderer.disable_segmentation_rendering()
        ids = np.where(seg[..., 1] == mujoco.mjtObj.mjOBJ_GEOM, seg[..., 0], -1)
        return ids

    def close(self) -> None:
        """Release the GL context."""
        self.renderer.close()
