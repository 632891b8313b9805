"""Offscreen rendering (MP4 video, PNG snapshot) from a tracking camera, and the interactive viewer.

Headless by default: when no ``MUJOCO_GL`` is set, `configure_gl` picks EGL where a GPU driver is present and
OSMesa otherwise (``apt-get install libosmesa6``), and points MuJoCo's renderer at that backend even when MuJoCo
was imported first. An explicit ``MUJOCO_GL`` (set before starting Python) always wins.

Scene renders draw the robot's visual geometry (motor housings, printed shells, camera lens, gripper jaws: see
`toddlerbot.robot.visuals`) instead of its collision primitives; ``visuals=False`` draws the primitives as the
physics sees them. The head camera (`toddlerbot.tasks.camera`) renders with MuJoCo's default groups, so it
sees the collision primitives it was trained on.

A machine without the backend's library still simulates: `configure_gl` and `Recorder` raise `RenderError` naming
the missing library and the package that provides it, and callers skip the video. `keep_mujoco_importable` covers
the one case where the missing library would break ``import mujoco`` itself (``MUJOCO_GL`` set to it).
"""

from __future__ import annotations

import ctypes
import os
import sys
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.files import atomic_write

GL_LIBRARY = {"osmesa": "OSMesa", "egl": "EGL"}
"""Shared library (``lib<name>.so*``) each headless MUJOCO_GL backend loads."""
INSTALL_HINT = {
    "osmesa": "install OSMesa: sudo apt-get install libosmesa6",
    "egl": "install EGL and a GPU driver (sudo apt-get install libegl1), or use MUJOCO_GL=osmesa with libosmesa6",
}

SOFTWARE_QUALITY = {"offsamples": 0, "shadowsize": 1024}
"""Render settings for OSMesa, which draws on the CPU: no multisampling and a 1024-pixel shadow map (the model asks
for 4x and 4096) render a 640x360 frame of the robot in about 200 ms instead of 750 ms on the 2-core VM, with no
visible difference. GPU backends keep the model's settings."""

_switched_off_because: str | None = None
"""Why `keep_mujoco_importable` switched MuJoCo's GL off (None: it did not)."""


class RenderError(ToddlerbotError):
    """No OpenGL backend could render offscreen."""


def _library_loads(name: str) -> bool:
    # the same file names PyOpenGL tries (lib<name>.so, then .so.9 ... .so.0)
    for filename in (f"lib{name}.so", *(f"lib{name}.so.{version}" for version in range(9, -1, -1))):
        try:
            ctypes.CDLL(filename)
        except OSError:
            continue
        return True
    return False


def missing_gl_library(backend: str) -> str | None:
    """One line naming the library `backend` (a MUJOCO_GL value) needs and how to install it, or None when it
    loads (or the backend needs no headless library)."""
    backend = backend.lower().strip()
    name = GL_LIBRARY.get(backend)
    if name is None or _library_loads(name):
        return None
    return f"MUJOCO_GL={backend} needs lib{name}, which cannot be loaded; to enable rendering, {INSTALL_HINT[backend]}"


def keep_mujoco_importable() -> None:
    """Switch MuJoCo's GL off (``MUJOCO_GL=disable``) when ``MUJOCO_GL`` names a backend whose library cannot
    load: ``import mujoco`` would otherwise end in an AttributeError inside PyOpenGL. Simulation keeps working and
    `configure_gl` reports the missing library. Call it before anything imports MuJoCo (the CLI does)."""
    global _switched_off_because
    if "mujoco" in sys.modules:
        return
    reason = missing_gl_library(os.environ.get("MUJOCO_GL", ""))
    if reason is not None:
        os.environ["MUJOCO_GL"] = "disable"
        _switched_off_because = reason


def configure_gl() -> str:
    """Choose a headless GL backend unless MUJOCO_GL is already set; returns the backend name.

    Raises `RenderError` (one line: the missing library and how to install it) when the backend cannot load."""
    if _switched_off_because is not None:
        raise RenderError(_switched_off_because)
    requested = os.environ.get("MUJOCO_GL")
    backend = requested or ("egl" if Path("/dev/nvidia0").exists() else "osmesa")
    reason = missing_gl_library(backend)
    if reason is not None:
        raise RenderError(reason)
    if requested:
        return requested
    os.environ["MUJOCO_GL"] = backend
    from mujoco.rendering.classic import gl_context

    if backend == "egl":
        from mujoco.egl import GLContext
    else:
        from mujoco.osmesa import GLContext
    gl_context.GLContext = GLContext
    return backend


def render_views(model, data, cameras: list[str], width: int, height: int, visuals: bool = True) -> np.ndarray:
    """The current state seen from each of `cameras`, side by side: one (height, width * len(cameras), 3) uint8
    image. Raises as `Recorder` does (an unknown camera, no OpenGL backend)."""
    recorder = Recorder(model, data, cameras[0], width, height, visuals)
    try:
        frames = []
        for camera in cameras:
            if camera not in {model.camera(i).name for i in range(model.ncam)}:
                raise ToddlerbotError(f"camera {camera!r} is not in the model; expected one of "
                                      f"{', '.join(model.camera(i).name for i in range(model.ncam))}")
            recorder.camera = camera
            frames.append(recorder.capture())
    finally:
        recorder.close()
    return np.concatenate(frames, axis=1)


def write_png(path: str | Path, image: np.ndarray) -> Path:
    """Write an (H, W, 3) uint8 image as a PNG (atomically)."""
    import imageio.v2 as imageio

    return atomic_write(path, lambda tmp: imageio.imwrite(tmp, image, format="png"))


def has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def show_visuals(option, visuals: bool = True) -> None:
    """Set which robot geoms an ``mujoco.MjvOption`` draws: the visual geometry (``visuals=True``) or the collision
    primitives and the skeleton of thin links (``False``). Scene geoms (group 0: floor, table, cube) always show."""
    from toddlerbot.robot.builder import COLLISION_GROUP, SKELETON_GROUP
    from toddlerbot.robot.visuals import VISUAL_GROUP

    option.geomgroup[COLLISION_GROUP] = option.geomgroup[SKELETON_GROUP] = not visuals
    option.geomgroup[VISUAL_GROUP] = visuals


def scene_option(model, visuals: bool = True):
    """A ``mujoco.MjvOption`` for scene renders of `model`; a model built without visual geometry is drawn with its
    collision primitives either way."""
    import mujoco

    from toddlerbot.robot.visuals import VISUAL_GROUP

    option = mujoco.MjvOption()
    show_visuals(option, visuals and bool(np.any(model.geom_group == VISUAL_GROUP)))
    return option


class Recorder:
    """Renders frames of a MuJoCo model/data pair from a named camera (``width`` x ``height`` pixels)."""

    def __init__(self, model, data, camera: str = "perspective", width: int = 640, height: int = 360,
                 visuals: bool = True) -> None:
        """`visuals`: draw the visual geometry (default) or the collision primitives.

        Raises `ToddlerbotError` for a camera the model lacks (before any rendering set-up), `RenderError` when no
        OpenGL backend can render."""
        import mujoco

        cameras = [model.camera(i).name for i in range(model.ncam)]
        if camera not in cameras:
            raise ToddlerbotError(f"camera {camera!r} is not in the model; expected one of {', '.join(cameras)}")
        backend = configure_gl()
        self.data = data
        self.camera = camera
        self.option = scene_option(model, visuals)
        quality = model.vis.quality
        saved = quality.offsamples, quality.shadowsize
        if backend.lower() == "osmesa":  # read once, when the render context is made; restored below
            quality.offsamples, quality.shadowsize = SOFTWARE_QUALITY["offsamples"], min(
                quality.shadowsize, SOFTWARE_QUALITY["shadowsize"])
        try:
            self.renderer = mujoco.Renderer(model, height, width)
        except Exception as exc:  # GL errors come in many types
            hint = INSTALL_HINT.get(backend.lower(), INSTALL_HINT["osmesa"] + " and set MUJOCO_GL=osmesa")
            raise RenderError(f"cannot render offscreen with MUJOCO_GL={backend}: {exc}; {hint}") from None
        finally:
            quality.offsamples, quality.shadowsize = saved
        self.frames: list[np.ndarray] = []

    def capture(self) -> np.ndarray:
        """Render the current state; returns the (height, width, 3) uint8 RGB frame and keeps it for the video."""
        self.renderer.update_scene(self.data, self.camera, self.option)
        frame = self.renderer.render().copy()
        self.frames.append(frame)
        return frame

    def write_video(self, path: str | Path, fps: float) -> Path:
        """Write the captured frames as an H.264 MP4 at ``fps`` frames per second."""
        import imageio.v2 as imageio

        return atomic_write(path, lambda tmp: imageio.mimwrite(tmp, self.frames, fps=fps, codec="libx264",
                                                               macro_block_size=8))

    def write_png(self, path: str | Path, frame: np.ndarray | None = None) -> Path:
        """Write ``frame`` (default: the last captured one) as a PNG."""
        return write_png(path, self.frames[-1] if frame is None else frame)

    def close(self) -> None:
        self.renderer.close()
