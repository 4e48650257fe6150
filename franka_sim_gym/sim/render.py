"""Offscreen RGB frames of the world, on an EGL context (no display needed).

MuJoCo's Python ``Renderer`` takes its GL backend from MUJOCO_GL when mujoco is
first imported (GLFW by default, which needs a display and aborts without
one). The env must render in CI and on headless machines whatever was
imported before it, so it drives MuJoCo's low-level render calls on an EGL
context of its own.

The world has no skybox: where the camera sees past the floor (above its horizon)
nothing is drawn and MuJoCo leaves the pixels black. Those pixels (at the far plane of
the depth buffer) are painted ``BACKGROUND``.
"""

from __future__ import annotations

import mujoco
import numpy as np

#: The colour of the pixels nothing was drawn on (RGB): a pale sky.
BACKGROUND = (206, 218, 230)


class OffscreenRenderer:
    """Renders ``model``'s scene from a free camera into (height, width, 3) uint8 frames."""

    def __init__(self, model: mujoco.MjModel, width: int, height: int) -> None:
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise ValueError(
                f"frame {width}x{height} exceeds the model's offscreen buffer "
                f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}"
            )
        from mujoco.egl import GLContext  # EGL: offscreen, no display

        self.model = model
        self.width, self.height = width, height
        self._gl = GLContext(width, height)
        self._gl.make_current()
        self.scene = mujoco.MjvScene(model, maxgeom=2000)
        self._option = mujoco.MjvOption()
        self._perturb = mujoco.MjvPerturb()
        self._context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self.camera = mujoco.MjvCamera()

    def update_scene(self, data: mujoco.MjData) -> None:
        """Build the scene of ``data`` (add marker geoms to ``self.scene`` afterwards)."""
        mujoco.mjv_updateScene(
            self.model,
            data,
            self._option,
            self._perturb,
            self.camera,
            mujoco.mjtCatBit.mjCAT_ALL,
            self.scene,
        )

    def render(self) -> np.ndarray:
        """The current scene as an RGB frame."""
        self._gl.make_current()
        mujoco.mjr_render(self._rect, self.scene, self._context)
        frame = np.empty((self.height, self.width, 3), dtype=np.uint8)
        depth = np.empty((self.height, self.width), dtype=np.float32)
        mujoco.mjr_readPixels(frame, depth, self._rect, self._context)
        frame[depth >= 1.0] = BACKGROUND
        return np.flipud(frame)

    def close(self) -> None:
        self._context = None
        if self._gl is not None:
            self._gl.free()
            self._gl = None
