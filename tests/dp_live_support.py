"""Helpers of the live diffusion-policy tests: an instant robot, the pick task's motor names and a short video."""

from __future__ import annotations

from pathlib import Path

import av
import numpy as np

from toddlerbot.dp.config import DPConfig
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.interface import Observation, Robot
from toddlerbot.tasks.space import ManipulationSpace

GRIPPER = RobotDescription.load(variant="gripper")
SPACE = ManipulationSpace.of(GRIPPER)
CONFIG = DPConfig(state_dim=SPACE.dim, action_dim=SPACE.dim, state_names=SPACE.names, action_names=SPACE.names)
"""What a pick checkpoint's config says (16 arm and gripper motors, images); the network itself is not needed."""


class InstantRobot(Robot):
    """Every motor reaches its target within the step (no physics: the loop's own cost is only the policy's).
    Keeps every command it was sent, after the guard."""

    def __init__(self, description: RobotDescription = GRIPPER, control_dt: float = 0.02) -> None:
        super().__init__(description, control_dt)
        self.sent: list[np.ndarray] = []
        self._time = 0.0

    def reset(self) -> Observation:
        self._time = 0.0
        self.last_targets = self.description.home_motor_pos.copy()
        self._obs = self._observation(self.last_targets)
        return self._obs

    def observe(self) -> Observation:
        return self._obs

    def _apply(self, motor_targets, kp, kd) -> Observation:
        self.sent.append(motor_targets.copy())
        self._time += self.control_dt
        self._obs = self._observation(motor_targets)
        return self._obs

    def _observation(self, q: np.ndarray) -> Observation:
        zeros = np.zeros_like(q)
        return Observation(self._time, q.copy(), zeros, zeros, self.transmission.motor_to_joint(q), zeros,
                           np.array([1.0, 0, 0, 0]), np.zeros(3), np.array([0, 0, 9.81]), np.zeros(2, bool))


def write_video(path: Path, frames: int, fps: int = 20, size: tuple[int, int] = (160, 120)) -> Path:
    """An H.264 file of ``frames`` frames whose brightness rises frame by frame."""
    width, height = size
    with av.open(str(path), mode="w") as container:
        stream = container.add_stream("libx264", rate=fps)
        stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
        for k in range(frames):
            image = np.zeros((height, width, 3), np.uint8)
            image[..., 0] = np.linspace(0, 255, width, dtype=np.uint8)[None]  # a gradient: crops are visible
            image[..., 1] = 10 * k % 256
            container.mux(stream.encode(av.VideoFrame.from_ndarray(image, format="rgb24")))
        container.mux(stream.encode())
    return path
