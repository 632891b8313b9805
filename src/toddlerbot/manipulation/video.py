"""Demonstration videos: the scene camera and the head camera's 96x96 policy image, side by side."""

from __future__ import annotations

from pathlib import Path

import av
import numpy as np
from PIL import Image

from toddlerbot.manipulation.camera import fast_scene
from toddlerbot.sim.render import Recorder
from toddlerbot.sim.scenes import WORKSPACE_CAMERA

SCENE_SIZE = (320, 240)
"""(width, height) of the scene-camera half, px; the head image is scaled up to the same height."""


class SideBySideVideo:
    """Collects side-by-side frames from a task; `write` encodes them as H.264 MP4 with PyAV."""

    def __init__(self, task, camera: str = WORKSPACE_CAMERA) -> None:  # task: PickTask (layer-local duck type)
        self._recorder = Recorder(task.model, task.robot.data, camera, *SCENE_SIZE)
        self.frames: list[np.ndarray] = []

    def add(self, task, head_image: np.ndarray) -> np.ndarray:
        renderer = self._recorder.renderer
        renderer.update_scene(self._recorder.data, self._recorder.camera)
        fast_scene(renderer.scene)
        scene = renderer.render().copy()
        height = scene.shape[0]
        head = np.asarray(Image.fromarray(head_image).resize((height, height), Image.Resampling.NEAREST))
        frame = np.concatenate([scene, head], axis=1)
        self.frames.append(frame)
        return frame

    def write(self, path: str | Path, fps: int) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with av.open(str(path), mode="w") as container:
            stream = container.add_stream("libx264", rate=fps, options={"crf": "20"})
            stream.height, stream.width = self.frames[0].shape[:2]
            stream.width -= stream.width % 2
            stream.pix_fmt = "yuv420p"
            for frame in self.frames:
                container.mux(stream.encode(av.VideoFrame.from_ndarray(frame[:, : stream.width], format="rgb24")))
            container.mux(stream.encode())
        return path

    def write_png(self, path: str | Path, index: int = -1) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(self.frames[index]).save(path)
        return path
