"""Leader-follower arms on two emulated Dynamixel buses, over the msgpack/ZeroMQ link."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

pytest.importorskip("zmq")
pytest.importorskip("msgpack")

from hw_support import emulated
from toddlerbot.hardware.calibration import Calibration, spec_label
from toddlerbot.hardware.leader import LeaderArms
from toddlerbot.hardware.real_robot import RealRobot
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.runner import RunObserver, run_policy
from toddlerbot.tasks.space import follower_gains
from toddlerbot.teleop.follower import ArmFollower, FollowerConfig
from toddlerbot.teleop.leader_follower import FollowerPolicy, stream_leader
from toddlerbot.teleop.link import LinkError, LinkMessage, LinkPublisher, LinkSubscriber

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)

DESCRIPTION = RobotDescription.load(variant="gripper")
SPEC = DESCRIPTION.spec


def _endpoint() -> str:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp://127.0.0.1:{s.getsockname()[1]}"


def test_messages_round_trip_and_malformed_ones_are_rejected():
    message = LinkMessage(7, 123.5, ("a", "b"), np.array([0.1, -0.2]))
    back = LinkMessage.decode(message.encode())
    assert (back.seq, back.sent_at, back.names) == (7, 123.5, ("a", "b"))
    np.testing.assert_allclose(back.values, [0.1, -0.2])
    with pytest.raises(LinkError, match="malformed"):
        LinkMessage.decode(b"\x93\x01")
    with pytest.raises(LinkError, match="non-finite"):
        LinkMessage.decode(LinkMessage(1, 0.0, ("a",), np.array([np.nan])).encode())


def test_subscriber_keeps_only_the_newest_message():
    endpoint = _endpoint()
    pub, sub = LinkPublisher(endpoint), LinkSubscriber(endpoint)
    try:
        deadline = time.monotonic() + 3
        while sub.poll() is None and time.monotonic() < deadline:  # PUB/SUB joins asynchronously
            pub.send(("a",), np.array([0.0]))
            time.sleep(0.01)
        for i in range(20):
            pub.send(("a",), np.array([float(i)]))
        time.sleep(0.1)
        newest = sub.poll()
        assert newest is not None and newest.values[0] == 19.0 and newest.seq == pub.seq - 1
        assert sub.age() < 0.2
    finally:
        pub.close()
        sub.close()


def test_follower_rate_limits_and_holds_when_the_leader_goes_stale():
    names = ("a", "b", "c")
    follower = ArmFollower(names, ("a", "b"), FollowerConfig(max_step=0.05, stale_after=0.2))
    current = np.zeros(3)
    out = follower.targets(current, ("a", "b"), np.array([1.0, -0.02]), age=0.01)
    np.testing.assert_allclose(out, [0.05, -0.02, 0.0])
    held = follower.targets(out, ("a", "b"), np.array([1.0, -0.02]), age=0.25)
    np.testing.assert_allclose(held, out)
    assert follower.holding and "leader stale" in follower.status
    assert follower.events == ["following leader", "leader stale (0.25 s): holding last safe targets"]


def _calibration(emu) -> tuple[Calibration, dict[str, int]]:
    offsets = {m.name: m.mounting_offset for m in emu.motors}
    return Calibration("tb", spec_label(DESCRIPTION), offsets), offsets


class _Operator(RunObserver):
    """Watches the follower: until it follows (3 s at most), then 60 steps more; then stops the leader's stream and
    ends the run 0.35 s later."""

    def __init__(self, policy, follow, stop, streamer) -> None:
        self.policy, self.follow, self.stop, self.streamer = policy, follow, stop, streamer
        self.first_step = self.followed_steps = None
        self.stopped_at = None

    def on_start(self, robot, policy, obs) -> None:
        self.start, self.began = policy.targets.copy(), time.monotonic()

    def on_step(self, step) -> None:
        if self.first_step is None:
            if self.follow.status == "following leader" or time.monotonic() - self.began > 3:
                self.first_step, self.followed_steps = np.abs(self.policy.targets - self.start).max(), 0
        elif self.followed_steps < 60:
            self.followed_steps += 1
            if self.followed_steps == 60:
                self.followed, self.obs = self.policy.targets.copy(), step.next_obs
                self.stop.set()  # the leader stops sending
                self.streamer.join(2)
                self.held, self.stopped_at = self.policy.targets.copy(), time.monotonic()

    @property
    def stopped_by_leader(self) -> bool:
        return self.stopped_at is not None

    @property
    def stop_requested(self) -> bool:
        return self.stopped_at is not None and time.monotonic() - self.stopped_at >= 0.35


def test_leader_follower_on_two_emulated_buses():
    endpoint = _endpoint()
    with emulated(SPEC, offsets_seed=1) as (leader_emu, leader_path), \
            emulated(SPEC, offsets_seed=2) as (follower_emu, follower_path):
        _, leader_offsets = _calibration(leader_emu)
        follower_cal, _ = _calibration(follower_emu)
        names = DESCRIPTION.motor_names
        pose = DESCRIPTION.home_motor_pos.copy()
        moved = {"right_shoulder_pitch": -0.5, "right_elbow_roll": 0.9, "right_gripper_drive": 1.2}
        for name, value in moved.items():
            pose[names.index(name)] = value
        with leader_emu.lock:  # the operator holds the leader arms in `pose` (torque is off)
            for i, motor in enumerate(leader_emu.motors):
                leader_emu.plant.q[i] = pose[names.index(motor.name)]
                leader_emu.plant.qd[i] = 0.0

        leader = LeaderArms(DESCRIPTION, leader_path, leader_offsets).open()
        assert not any(m.torque_on for m in leader_emu.motors)
        reading = leader.read()
        np.testing.assert_allclose(reading.positions, [pose[names.index(n)] for n in leader.names], atol=2e-3)

        publisher, subscriber = LinkPublisher(endpoint), LinkSubscriber(endpoint)
        stop = threading.Event()
        streamer = threading.Thread(target=stream_leader, args=(leader, publisher, stop), daemon=True)
        streamer.start()
        follow = ArmFollower(names, leader.names, FollowerConfig(max_step=0.05))
        try:
            with RealRobot(DESCRIPTION, follower_path, follower_cal, control_dt=0.02, reset_duration=0.2) as robot:
                policy = FollowerPolicy(robot, subscriber, follow, kp=follower_gains(DESCRIPTION, 0.5))
                operator = _Operator(policy, follow, stop, streamer)
                run_policy(robot, policy, seconds=10.0, observers=[operator], stop_on_fall=False)
                arm = follow.indices
                # targets reached the leader; the follower's motors moved most of the way (emulated plant)
                np.testing.assert_allclose(operator.followed[arm], pose[arm], atol=5e-3)
                assert np.abs(operator.obs.motor_pos[names.index("right_elbow_roll")] - 0.9) < 0.15
                assert operator.first_step <= 0.05 + 1e-9
                legs = DESCRIPTION.groups["leg"]
                np.testing.assert_allclose(operator.followed[legs], operator.start[legs])
                # the leader stopped sending: 0.2 s later the follower holds
                assert operator.stopped_by_leader and follow.holding and "leader stale" in follow.status
                np.testing.assert_allclose(policy.targets, operator.held)
        finally:
            stop.set()
            publisher.close()
            subscriber.close()
            leader.close()
