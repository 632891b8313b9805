"""Leader-follower: the leader side streams its arm angles (a loop reading the leader arms, torque off), the
follower side turns them into targets (`follow_leader`; `FollowerPolicy`, run by `runtime.run_policy`).

Both run at the control rate (50 Hz). The leader side reports a bus error (a message of kind ``"error"``) so the
follower learns why it holds, and keeps trying, unless the leader's serial port itself is gone (unplugged): then
it stops with `BusLostError` after that last message.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from toddlerbot.hardware.driver import BusLostError, HardwareError
from toddlerbot.hardware.leader import LeaderArms
from toddlerbot.policies.base import Action, Policy
from toddlerbot.robot.interface import CONTROL_HZ, Observation, Robot
from toddlerbot.teleop.follower import ArmFollower
from toddlerbot.teleop.link import LinkPublisher, LinkSubscriber


def stream_leader(leader: LeaderArms, publisher: LinkPublisher, stop: threading.Event, rate_hz: float = CONTROL_HZ,
                  on_error=None) -> int:
    """Read the leader and publish its angles at `rate_hz` until `stop` is set; returns the messages sent. Raises
    `BusLostError` (after publishing an error message) when the leader's port is gone."""
    period = 1.0 / rate_hz
    next_tick = time.monotonic()
    sent = 0
    while not stop.is_set():
        try:
            reading = leader.read()
            publisher.send(leader.names, reading.positions)
        except HardwareError as exc:
            publisher.send((), np.zeros(0), kind="error")
            if isinstance(exc, BusLostError):  # no retry can reach an unplugged adapter
                raise
            if on_error:
                on_error(str(exc))
        sent += 1
        next_tick += period
        stop.wait(max(0.0, next_tick - time.monotonic()))
    return sent


def follow_leader(subscriber: LinkSubscriber, follower: ArmFollower, current: np.ndarray) -> np.ndarray:
    """The follower's next motor targets from the newest leader message (held when stale or failed)."""
    message = subscriber.poll()
    if message is not None and message.kind == "error":
        follower.lost("bus error on the leader side")
        return current
    if message is None:
        return follower.targets(current, None, None, subscriber.age())
    return follower.targets(current, message.names, message.values, subscriber.age())


class FollowerPolicy(Policy):
    """The follower's arms as a `Policy`: each control step the newest leader message -> rate-limited targets (the
    motors the follower does not follow hold where they started), at firmware gains `kp` (None: the spec's)."""

    name = "follower"

    def __init__(self, robot: Robot, subscriber: LinkSubscriber, follower: ArmFollower,
                 kp: np.ndarray | None = None) -> None:
        super().__init__(robot)
        self.subscriber, self.follower, self.kp = subscriber, follower, kp
        self.targets: np.ndarray | None = None

    def reset(self, obs: Observation) -> None:
        self.targets = obs.motor_pos.copy()

    def act(self, obs: Observation, command: np.ndarray) -> Action:
        if self.targets is None:
            raise RuntimeError("call reset() with the robot's first observation")
        self.targets = follow_leader(self.subscriber, self.follower, self.targets)
        return Action(self.targets.copy(), self.transmission.motor_to_joint(self.targets), self.kp)
