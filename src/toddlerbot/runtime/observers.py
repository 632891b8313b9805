"""Run observers for a simulated robot a person watches: a video (and last-frame snapshot) from a scene camera,
and the interactive MuJoCo viewer kept in step with the run."""

from __future__ import annotations

from pathlib import Path

from toddlerbot.runtime.runner import RunObserver, Step
from toddlerbot.sim.mujoco_robot import MuJoCoRobot
from toddlerbot.sim.render import Recorder

VIDEO_FPS = 30.0


class VideoObserver(RunObserver):
    """Captures the robot's ``camera`` at about `VIDEO_FPS` (every whole number of control steps); `write` saves
    the MP4 and/or a PNG of the last frame. Raises `RenderError` when no renderer is available."""

    def __init__(self, robot: MuJoCoRobot, camera: str) -> None:
        self.recorder = Recorder(robot.model, robot.data, camera)
        self.every = max(1, round(1.0 / VIDEO_FPS / robot.control_dt))
        self.fps = 1.0 / (self.every * robot.control_dt)

    def on_step(self, step: Step) -> None:
        if step.index % self.every == 0:
            self.recorder.capture()

    def write(self, video: Path | None, snapshot: Path | None) -> list[Path]:
        """Write what was asked for and release the renderer; returns the files written."""
        written = []
        try:
            if video is not None:
                self.recorder.write_video(video, fps=self.fps)
                written.append(video)
            if snapshot is not None:
                self.recorder.write_png(snapshot)
                written.append(snapshot)
        finally:
            self.recorder.close()
        return written


class ViewerObserver(RunObserver):
    """The interactive MuJoCo viewer (needs a display) showing the robot as it looks, synced every step; close it
    after the run."""

    def __init__(self, robot: MuJoCoRobot) -> None:
        import mujoco.viewer

        from toddlerbot.sim.render import show_visuals

        self.handle = mujoco.viewer.launch_passive(robot.model, robot.data)
        show_visuals(self.handle.opt)  # the viewer's group toggles (2, 3) switch to the collision geometry

    def on_step(self, step: Step) -> None:
        self.handle.sync()

    def close(self) -> None:
        self.handle.close()
