"""Offscreen rendering (MP4 video, PNG snapshot) from a tracking camera, and the interactive viewer.

Headless by default: when no ``MUJOCO_GL`` is set, `configure_gl` picks EGL where a GPU driver is present and
OSMesa otherwise (``apt-get install libosmesa6``), and points MuJoCo's renderer at that backend even when MuJoCo
was imported first. An explicit ``MUJOCO_GL`` (set before starting Python) always wins.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from toddlerbot.errors import ToddlerbotError


class RenderError(ToddlerbotError):
    """No OpenGL backend could render offscreen."""


def configure_gl() -> str:
    """Choose a headless GL backend unless MUJOCO_GL is already set; returns the backend name."""
    if "MUJOCO_GL" in os.environ:
        return os.environ["MUJOCO_GL"]
    backend = "egl" if Path("/dev/nvidia0").exists() else "osmesa"
    os.environ["MUJOCO_GL"] = backend
    from mujoco.rendering.classic import gl_context

    if backend == "egl":
        from mujoco.egl import GLContext
    else:
        from mujoco.osmesa import GLContext
    gl_context.GLContext = GLContext
    return backend


def has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class Recorder:
    """Renders frames of a MuJoCo model/data pair from a named camera."""

    def __init__(self, model, data, camera: str = "perspective", width: int = 640, height: int = 360) -> None:
        import mujoco

        configure_gl()
        self.data = data
        self.camera = camera
        try:
            self.renderer = mujoco.Renderer(model, height, width)
        except Exception as exc:  # GL errors come in many types
            raise RenderError(
                f"cannot render offscreen with MUJOCO_GL={os.environ.get('MUJOCO_GL', '(unset)')}: {exc}. "
                "On CPU machines install OSMesa (apt-get install libosmesa6) and set MUJOCO_GL=osmesa"
            ) from None
        self.frames: list[np.ndarray] = []

    def capture(self) -> np.ndarray:
        self.renderer.update_scene(self.data, self.camera)
        frame = self.renderer.render().copy()
        self.frames.append(frame)
        return frame

    def write_video(self, path: str | Path, fps: float) -> Path:
        import imageio.v2 as imageio

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        imageio.mimwrite(path, self.frames, fps=fps, codec="libx264", macro_block_size=8)
        return path

    def write_png(self, path: str | Path, frame: np.ndarray | None = None) -> Path:
        import imageio.v2 as imageio

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        imageio.imwrite(path, self.frames[-1] if frame is None else frame)
        return path

    def close(self) -> None:
        self.renderer.close()
