"""Demonstration videos: the scene camera and the head camera's 96x96 policy image, side by side.

Frames are encoded as they come (H.264 with PyAV) into a temporary file that replaces the target on `close`,
so long recordings do not pile up in memory and a crash leaves no half-written video.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import av
import numpy as np
from PIL import Image

from toddlerbot.sim.render import Recorder
from toddlerbot.tasks.camera import fast_scene
from toddlerbot.tasks.scenes import WORKSPACE_CAMERA

SCENE_SIZE = (320, 240)
"""(width, height) of the scene-camera half, px; the head image is scaled up to the same height (560x240 in all)."""


class SideBySideVideo:
    """Encodes side-by-side frames of a task's scene to `path` at `fps`; frames whose index is in `keep` stay in
    memory (`kept`) for snapshots."""

    def __init__(self, task, path: str | Path, fps: int, keep: set[int] | None = None,
                 camera: str = WORKSPACE_CAMERA) -> None:  # task: PickTask (model, robot.data)
        self._recorder = Recorder(task.model, task.robot.data, camera, *SCENE_SIZE)
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, self._tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".mp4", dir=self.path.parent)
        os.close(fd)
        self._container = av.open(self._tmp, mode="w")
        self._stream = self._container.add_stream("libx264", rate=fps, options={"crf": "20"})
        self._stream.width, self._stream.height = SCENE_SIZE[0] + SCENE_SIZE[1], SCENE_SIZE[1]
        self._stream.pix_fmt = "yuv420p"
        self.keep = keep or set()
        self.kept: dict[int, np.ndarray] = {}
        self.count = 0

    def add(self, head_image: np.ndarray) -> np.ndarray:
        """Render the scene camera now, put the head image (scaled up) beside it, encode; returns the frame."""
        renderer = self._recorder.renderer
        renderer.update_scene(self._recorder.data, self._recorder.camera, self._recorder.option)
        fast_scene(renderer.scene)
        scene = renderer.render().copy()
        height = scene.shape[0]
        head = np.asarray(Image.fromarray(head_image).resize((height, height), Image.Resampling.NEAREST))
        frame = np.concatenate([scene, head], axis=1)
        self._container.mux(self._stream.encode(av.VideoFrame.from_ndarray(frame, format="rgb24")))
        if self.count in self.keep:
            self.kept[self.count] = frame
        self.count += 1
        return frame

    def close(self) -> Path:
        """Flush the encoder and move the file into place."""
        self._container.mux(self._stream.encode())
        self._container.close()
        self._recorder.close()
        os.replace(self._tmp, self.path)
        return self.path

    def abort(self) -> None:
        self._container.close()
        self._recorder.close()
        if os.path.exists(self._tmp):
            os.unlink(self._tmp)


def write_png(path: str | Path, frame: np.ndarray) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(frame).save(path)
    return path
