"""CPU used by `toddlerbot hw emulate --hil` while nobody drives it.

Phases (CPU time of the emulator process / wall time, from /proc):
1. idle before any torque (the simulation waits for the first torque-enable);
2. a client runs the stand policy for a few seconds (physics in real time: this is the busy figure);
3. after the client closed the bus (torque off): the robot falls and settles (up to 2 simulated seconds),
   then the simulation pauses; measured from 8 s after the close (a loaded host simulates slower than real time).

Run: PYTHONPATH=src python benchmarks/bench_hw_idle.py [--seconds 5]
"""

from __future__ import annotations

import argparse
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from toddlerbot.hardware.calibration import load_calibration
from toddlerbot.hardware.real_robot import RealRobot
from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.runner import run_policy


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process, s."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def cpu_share(pid: int, seconds: float) -> float:
    """Average share of one core used by `pid` over the next `seconds`."""
    c0, t0 = cpu_seconds(pid), time.perf_counter()
    time.sleep(seconds)
    return (cpu_seconds(pid) - c0) / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="measuring window per phase, s")
    args = parser.parse_args()
    cal_file = Path(tempfile.mkdtemp(prefix="bench_hw_idle_")) / "emulated.yaml"
    proc = subprocess.Popen([sys.executable, "-m", "toddlerbot.cli.main", "hw", "emulate", "--hil",
                             "--write-calibration", str(cal_file)], stdout=subprocess.PIPE, text=True)
    port = proc.stdout.readline().strip()
    try:
        time.sleep(1.0)
        idle_before = cpu_share(proc.pid, args.seconds)
        description = RobotDescription.load()
        robot = RealRobot(description, port, load_calibration(cal_file, description), latency_ms=50,
                          reset_duration=0.5)
        c0, t0 = cpu_seconds(proc.pid), time.perf_counter()
        with robot:
            run_policy(robot, make_policy("stand", robot), CommandSchedule.parse("0:0,0,0"), args.seconds)
        busy = (cpu_seconds(proc.pid) - c0) / (time.perf_counter() - t0)
        time.sleep(8.0)
        idle_after = cpu_share(proc.pid, args.seconds)
    finally:
        proc.send_signal(signal.SIGINT)
        report = proc.communicate(timeout=30)[0].strip().splitlines()[-1]
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs (shared), Python {platform.python_version()}")
    print(f"hw emulate --hil CPU, share of one core: idle before torque {idle_before:.1%}; "
          f"driven (stand, torque on) {busy:.1%}; idle after torque off {idle_after:.1%}")
    print(f"emulator report: {report}")


if __name__ == "__main__":
    main()
