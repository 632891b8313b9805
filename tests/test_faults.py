"""Fault injection: the bus disappears mid-run, the head camera is unplugged, the leader arm's adapter dies, the
disk fills up. Each ends in a known state with one line, never a traceback or a lost log."""

from __future__ import annotations

import contextlib
import errno
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.log import RunLog

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)

DESC = RobotDescription.load()
SRC = Path(__file__).resolve().parents[1] / "src"


def _one_line(stderr: str) -> str:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def _hw_run(port: str, cal: Path, *args: str) -> subprocess.Popen:
    from test_hw_safety import _hw_run as run

    return run(port, cal, *args)


def _calibration(bus, path: Path) -> Path:
    from test_hw_safety import _calibration as write

    return write(bus, path)


def _wait_for_all_torque(bus, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    start = time.perf_counter()
    while not all(m.torque_on for m in bus.motors):
        assert proc.poll() is None, proc.communicate()
        assert time.perf_counter() - start < timeout
        time.sleep(0.01)


@pytest.mark.parametrize("named_log", [True, False], ids=["log", "no_log"])
def test_bus_lost_mid_run_reports_the_powered_motors_in_one_line_and_keeps_the_log(tmp_path, named_log):
    """The pty closes under `hw run` (a U2D2 unplugged): the run stops at once with exit 2 and one line naming
    every motor whose torque-off could not be confirmed; the steps so far are saved (in --log, or in a temporary
    file whose name is printed). The emulated motors stay powered, as real ones held by the Bus Watchdog would."""
    from hw_support import emulated_server

    log = tmp_path / "run.npz"
    with emulated_server(DESC) as server:
        proc = _hw_run(server.path, _calibration(server.bus, tmp_path / "cal.yaml"), "--policy", "stand",
                       "--seconds", "30", *(["--log", str(log)] if named_log else []))
        _wait_for_all_torque(server.bus, proc)
        time.sleep(3.0)  # the 2 s ramp to the home pose, then about 1 s of logged steps
        unplugged = time.perf_counter()
        server.stop()
        out, err = proc.communicate(timeout=60)
        stopped_in = time.perf_counter() - unplugged
        with server.bus.lock:
            powered = sum(m.torque_on for m in server.bus.motors)
    line = _one_line(err)
    assert proc.returncode == 2
    assert f"bus {server.path}: TORQUE MAY STILL BE ON for ids 0-29: no torque-off confirmation (bus lost: " in line
    assert "press the E-stop or cut the motor power" in line
    assert powered == 30
    assert stopped_in < 10.0  # not the 30 s run: detected on the first failed transaction (~15 ms in-process)
    saved = re.search(r"wrote the log of the (\d+) steps before the stop to (\S+) ?", out)
    assert saved, out
    path = Path(saved.group(2))
    try:
        assert (path == log) if named_log else path.name.startswith("toddlerbot-")
        partial = RunLog.load(path)
        assert partial.time.size == int(saved.group(1)) > 10
        assert np.isfinite(partial.motor_pos).all()
    finally:
        if not named_log:
            path.unlink()


def test_dying_leader_arm_stops_the_leader_and_the_follower_holds():
    """The leader arms' adapter is unplugged while streaming: the leader side publishes an error message and stops
    with `BusLostError` (no endless retries on a dead port); the follower holds its last safe targets."""
    pytest.importorskip("zmq")
    pytest.importorskip("msgpack")
    from hw_support import emulated_server
    from test_manip_leader_follower import _endpoint
    from toddlerbot.hardware.driver import BusLostError
    from toddlerbot.hardware.leader import LeaderArms
    from toddlerbot.teleop.follower import ArmFollower
    from toddlerbot.teleop.leader_follower import follow_leader, stream_leader
    from toddlerbot.teleop.link import LinkPublisher, LinkSubscriber

    gripper = RobotDescription.load(variant="gripper")
    endpoint = _endpoint()
    with emulated_server(gripper) as server:
        leader = LeaderArms(gripper, server.path, {m.name: m.mounting_offset for m in server.bus.motors}).open()
        publisher, subscriber = LinkPublisher(endpoint), LinkSubscriber(endpoint)
        follower = ArmFollower(gripper.motor_names, leader.names)
        outcome: dict[str, BaseException] = {}

        def stream() -> None:
            try:
                stream_leader(leader, publisher, threading.Event())
            except BaseException as exc:  # the test inspects it
                outcome["error"] = exc

        streamer = threading.Thread(target=stream, daemon=True)
        try:
            streamer.start()
            current = gripper.home_motor_pos.copy()
            deadline = time.monotonic() + 10
            while follower.status != "following leader" and time.monotonic() < deadline:
                current = follow_leader(subscriber, follower, current)
                time.sleep(0.02)
            assert follower.status == "following leader"
            server.stop()
            streamer.join(5)
            assert not streamer.is_alive()
            assert isinstance(outcome.get("error"), BusLostError)
            assert f"bus {server.path} lost" in str(outcome["error"])
            held = None
            deadline = time.monotonic() + 2
            while time.monotonic() < deadline and (held is None or not follower.holding):
                held = follow_leader(subscriber, follower, current)
            assert follower.holding and "leader lost (bus error on the leader side)" in follower.status
            np.testing.assert_array_equal(held, current)
        finally:
            publisher.close()
            subscriber.close()
            leader.close()


def test_unplugged_camera_makes_the_live_policy_hold_and_says_why(tmp_path, monkeypatch):
    """The head camera (a V4L2 device, here a video file) fails after 5 frames with ENODEV, as an unplugged USB
    camera does: the reader stops and records why, the policy holds its last safe targets, the 50 Hz run
    completes, and every target stays finite and inside its range."""
    pytest.importorskip("av")
    import av

    from dp_live_support import CONFIG, GRIPPER, SPACE, InstantRobot, write_video
    from test_dp_live import chunk
    from toddlerbot.dp.live import LiveDPPolicy
    from toddlerbot.runtime.commands import CommandSchedule
    from toddlerbot.runtime.runner import WallClock, run_policy
    from toddlerbot.tasks import video_camera

    real_open = av.open

    class Unplugged:
        def __init__(self, *args, **kwargs) -> None:
            self.inner = real_open(*args, **kwargs)
            self.streams = self.inner.streams

        def decode(self, **kwargs):
            for k, frame in enumerate(self.inner.decode(**kwargs)):
                if k == 5:
                    raise OSError(errno.ENODEV, "No such device")
                yield frame

        def close(self) -> None:
            self.inner.close()

    video = write_video(tmp_path / "head.mp4", frames=40, fps=50)
    monkeypatch.setattr(video_camera.av, "open", Unplugged)
    camera = video_camera.VideoCamera(str(video), max_age_s=0.1)
    robot = InstantRobot()
    policy = LiveDPPolicy(robot, lambda history: chunk(1), CONFIG, camera, synchronous=True)
    try:
        result = run_policy(robot, policy, CommandSchedule.parse("0:0,0,0"), 2.0, clock=WallClock())
    finally:
        camera.close()
    sent = np.array(robot.sent)
    low, high = GRIPPER.motor_range.T
    assert result.log.time.size == 100 and camera.frames == 5
    assert camera.error == "OSError: [Errno 19] No such device"
    assert policy.status.camera_misses > 0 and policy.status.last_error == "RuntimeError: no current camera frame"
    assert np.isfinite(sent).all() and np.all(sent >= low) and np.all(sent <= high)
    np.testing.assert_allclose(sent[-20:, SPACE.indices], np.tile(sent[-1, SPACE.indices], (20, 1)))  # holding


@contextlib.contextmanager
def _full_tmpfs(where: Path):
    """A 64 kB tmpfs at `where`, filled to the last byte (skips where mounting is impossible: not root)."""
    where.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(where)], capture_output=True
                      ).returncode:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        with contextlib.suppress(OSError), (where / "filler").open("wb") as f:
            while True:
                f.write(b"\0" * 4096)
                f.flush()
        yield where
    finally:
        subprocess.run(["umount", str(where)], check=True)


def test_full_disk_fails_sim_run_in_one_line_without_a_partial_file(tmp_path, monkeypatch, capsys):
    from toddlerbot.cli import main as cli_main

    with _full_tmpfs(tmp_path / "full") as full:
        log = full / "run.npz"
        monkeypatch.setattr(sys, "argv", ["toddlerbot", "sim", "run", "--policy", "stand", "--seconds", "0.5",
                                          "--log", str(log)])
        with pytest.raises(SystemExit) as exit_:
            cli_main.main()
        assert exit_.value.code == 2
        assert _one_line(capsys.readouterr().err) == f"error: {log}: No space left on device"
        assert sorted(p.name for p in full.iterdir()) == ["filler"]  # no half-written log, no temporary file


def test_full_disk_keeps_the_log_of_a_completed_hw_run_in_a_temporary_file(tmp_path):
    from hw_support import emulated

    with _full_tmpfs(tmp_path / "full") as full, emulated(DESC) as (bus, port):
        proc = _hw_run(port, _calibration(bus, tmp_path / "cal.yaml"), "--policy", "stand", "--seconds", "1",
                       "--log", str(full / "run.npz"))
        out, err = proc.communicate(timeout=240)
    assert proc.returncode == 0, err
    saved = re.search(r"wrote the run log to (\S+) \(cannot write (\S+): No space left on device\)", out)
    assert saved and saved.group(2) == str(full / "run.npz"), out
    path = Path(saved.group(1))
    try:
        assert RunLog.load(path).time.size == 50
    finally:
        path.unlink()
