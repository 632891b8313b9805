"""A real head camera (V4L2 device) or a video file as the policy's camera, read with PyAV on a reader thread.

Every decoded frame goes through `camera.resize_and_crop`, the same path the simulated head camera's images (and
so the datasets') take, to the 96x96 policy image. Calling the camera returns the latest image, or None when no
frame has arrived for ``max_age_s`` (a stalled or unplugged camera, the end of a file): the policy then holds
rather than act on an old picture. A file plays at its own frame rate (frame timestamps), as a live camera would
deliver it; a device is read as fast as it delivers.
"""

from __future__ import annotations

import threading
import time

import av
import numpy as np

from toddlerbot.errors import ToddlerbotError
from toddlerbot.tasks.camera import IMAGE_SIZE, resize_and_crop

MAX_AGE_S = 0.3
"""Default age after which a frame no longer counts as current, s (3 policy periods at 10 Hz)."""


class CameraError(ToddlerbotError):
    """A camera device or video file cannot be opened or holds no video."""


def is_device(source: str) -> bool:
    """Video4Linux devices are ``/dev/video*``; anything else is read as a file."""
    return source.startswith("/dev/")


class VideoCamera:
    """Latest-frame camera over PyAV. Use as a context manager, or call `close`."""

    def __init__(self, source: str, max_age_s: float = MAX_AGE_S, size: int = IMAGE_SIZE) -> None:
        self.source, self.max_age_s, self.size = source, max_age_s, size
        self.live = is_device(source)
        try:
            self._container = av.open(source, format="v4l2" if self.live else None)
        except (av.error.FFmpegError, OSError) as exc:
            raise CameraError(f"camera {source}: cannot open ({exc})") from None
        if not self._container.streams.video:
            self._container.close()
            raise CameraError(f"camera {source}: holds no video stream")
        self.frames = 0
        """Frames decoded so far."""
        self.error: str | None = None
        """Why the reader stopped early (a decoding or device error), if it did."""
        self._latest: tuple[float, np.ndarray] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, name="camera-reader", daemon=True)
        self._thread.start()

    def __call__(self) -> np.ndarray | None:
        """The newest (size, size, 3) uint8 image, or None when there is none younger than ``max_age_s``."""
        latest = self._latest  # one read: the reader may replace it meanwhile
        if latest is None or time.monotonic() - latest[0] > self.max_age_s:
            return None
        return latest[1]

    @property
    def finished(self) -> bool:
        """True once the reader has stopped (end of file, error or `close`)."""
        return not self._thread.is_alive()

    def _read(self) -> None:
        start = time.monotonic()
        try:
            for frame in self._container.decode(video=0):
                if self._stop.is_set():
                    break
                if not self.live and frame.time is not None:  # play a file at its own rate
                    wait = start + frame.time - time.monotonic()
                    if self._stop.wait(max(0.0, wait)):
                        break
                image = resize_and_crop(frame.to_ndarray(format="rgb24"), self.size)
                self._latest = (time.monotonic(), image)
                self.frames += 1
        except (av.error.FFmpegError, OSError) as exc:
            self.error = f"{type(exc).__name__}: {exc}"
        finally:
            self._container.close()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)  # a device blocked in a read ends with the process (daemon thread)

    def __enter__(self) -> VideoCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
