"""The head camera's policy image: render larger than needed, resize, then centre-crop to 96x96 (appendix 8.12)."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from PIL import Image

from toddlerbot.sim.render import Recorder

IMAGE_SIZE = 96
"""Side of the square policy image, px."""
CAMERA_EVERY = 3
"""Recorded episodes (scripted demonstrations, teleoperation) take a head-camera image every this many control
steps: 16.7 Hz at 50 Hz control, above the 10 Hz dataset, which takes the nearest frame."""


def blank_image() -> np.ndarray:
    """The image an episode recorded without a camera carries (black, IMAGE_SIZE square, RGB uint8), so every
    episode has at least one frame."""
    return np.zeros((IMAGE_SIZE, IMAGE_SIZE, 3), np.uint8)


@dataclass(frozen=True)
class CameraGeometry:
    render_size: tuple[int, int] = (160, 120)
    """(width, height) rendered by MuJoCo, px (the camera's 4:3 frame)."""
    resized_height: int = IMAGE_SIZE
    """Height after resizing, px (width keeps the aspect ratio); then the centre IMAGE_SIZE columns are kept."""


def fast_scene(scene: mujoco.MjvScene) -> None:
    """Skip shadows and reflections: software (OSMesa) rendering is 10x faster without them, and the policy
    image does not need them."""
    scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
    scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False


def resize_and_crop(frame: np.ndarray, size: int = IMAGE_SIZE) -> np.ndarray:
    """Resize an (H, W, 3) uint8 frame so its height is `size` (area filter), then keep the centre `size` columns."""
    h, w = frame.shape[:2]
    new_w = max(size, round(w * size / h))
    resized = np.asarray(Image.fromarray(frame).resize((new_w, size), Image.Resampling.BOX))
    left = (new_w - size) // 2
    return np.ascontiguousarray(resized[:, left : left + size])


class HeadCamera:
    """Renders the robot's head camera and returns the 96x96 policy image. The renderer is created on first use
    (it needs an OpenGL backend; see `toddlerbot.sim.render.configure_gl`)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, camera: str,
                 geometry: CameraGeometry | None = None) -> None:
        self.model, self.data, self.camera = model, data, camera
        self.geometry = geometry or CameraGeometry()
        self._recorder: Recorder | None = None

    def raw(self) -> np.ndarray:
        """The rendered (height, width, 3) frame before resizing."""
        if self._recorder is None:
            w, h = self.geometry.render_size
            self._recorder = Recorder(self.model, self.data, self.camera, w, h)
        renderer = self._recorder.renderer
        renderer.update_scene(self.data, self.camera)
        fast_scene(renderer.scene)
        return renderer.render().copy()

    def image(self) -> np.ndarray:
        return resize_and_crop(self.raw(), self.geometry.resized_height)

    def close(self) -> None:
        if self._recorder is not None:
            self._recorder.close()
            self._recorder = None
