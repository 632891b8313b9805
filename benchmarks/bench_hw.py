"""Benchmark of one full control cycle for the 30 motors of ToddlerBot v1 (read present current, velocity and
position of all motors; write all goal positions), through the real driver on the official dynamixel_sdk.

Figures:
* host CPU time per cycle: the driver (packet building, CRC, parsing, unit conversions) against a port that
  replays the emulator's recorded answers instantly, so only host work is timed;
* bytes on the wire per cycle (instruction + status packets) and their transmission time at the baud rate
  (10 bits per byte: start, 8 data, stop; return delay time 0);
* maximum loop rate = 1 / (wire time + host CPU time);
* the measured loop rate through the CLI emulator (separate process, pseudo-terminal without baud-rate limit).

Run: PYTHONPATH=src python benchmarks/bench_hw.py [--cycles 2000]
"""

from __future__ import annotations

import argparse
import os
import platform
import signal
import subprocess
import sys
import time

import numpy as np

from toddlerbot.hardware import driver as drv
from toddlerbot.hardware import protocol as p
from toddlerbot.hardware.driver import DynamixelBus, motors_of
from toddlerbot.hardware.emulator import EmulatedBus
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import load_spec


class ReplayPort:
    """Stands in for dynamixel_sdk.PortHandler (same method names): answers each instruction with the
    emulator's answer to the first packet of that instruction (recorded once), instantly, and counts the bytes
    each way."""

    def __init__(self, emulator: EmulatedBus, baudrate: int) -> None:
        self.emulator = emulator
        self.baudrate = baudrate
        self.tx_time_per_byte = 1000.0 / baudrate * 10.0
        self.is_using = False
        self.is_open = True
        self.packet_start_time = self.packet_timeout = 0.0
        self.recorded: dict[int, bytes] = {}
        self.pending = bytearray()
        self.tx_bytes = self.rx_bytes = 0

    def openPort(self) -> bool:
        return True

    def setBaudRate(self, baudrate: int) -> bool:
        return True

    def closePort(self) -> None:
        pass

    def clearPort(self) -> None:
        self.pending.clear()

    def writePort(self, packet) -> int:
        data = bytes(packet)
        self.tx_bytes += len(data)
        instruction = data[7]
        if instruction not in self.recorded:
            self.recorded[instruction] = b"".join(self.emulator.handle(pk) for pk in p.PacketParser().feed(data))
        answer = self.recorded[instruction]
        self.pending += answer
        self.rx_bytes += len(answer)
        return len(data)

    def readPort(self, length: int) -> bytes:
        out = bytes(self.pending[:length])
        del self.pending[:length]
        return out

    def setPacketTimeout(self, packet_length: int) -> None:
        self.packet_start_time = time.time() * 1000
        self.packet_timeout = self.tx_time_per_byte * packet_length + 34.0

    def setPacketTimeoutMillis(self, msec: float) -> None:
        self.packet_start_time, self.packet_timeout = time.time() * 1000, msec

    def isPacketTimeout(self) -> bool:
        return time.time() * 1000 - self.packet_start_time > self.packet_timeout


def host_cycle(cycles: int, baudrate: int, fast: bool) -> dict[str, float]:
    spec = load_spec()
    emulator = EmulatedBus(RobotDescription(spec))
    replay = ReplayPort(emulator, baudrate)
    real_port_handler = drv.sdk.PortHandler
    drv.sdk.PortHandler = lambda name: replay
    try:
        bus = DynamixelBus("replay", motors_of(RobotDescription(spec)), baudrate=baudrate).open()
    finally:
        drv.sdk.PortHandler = real_port_handler
    bus.fast_sync_read = fast
    goal = bus.read_state().position
    for _ in range(50):  # warm-up
        bus.write_goal_positions(goal)
        bus.read_state()
    replay.tx_bytes = replay.rx_bytes = 0
    cpu, wall = time.process_time(), time.perf_counter()
    for k in range(cycles):
        bus.write_goal_positions(goal + (k % 7))
        state = bus.read_state()
    cpu, wall = (time.process_time() - cpu) / cycles, (time.perf_counter() - wall) / cycles
    assert state.position.shape == (30,)
    wire_bytes = (replay.tx_bytes + replay.rx_bytes) / cycles
    wire_time = wire_bytes * 10 / baudrate
    return {"cpu_ms": cpu * 1e3, "wall_ms": wall * 1e3, "tx_bytes": replay.tx_bytes / cycles,
            "rx_bytes": replay.rx_bytes / cycles, "wire_ms": wire_time * 1e3, "max_hz": 1.0 / (wire_time + cpu)}


def emulator_loop(cycles: int) -> float:
    """Cycles per second through the CLI emulator (own process) over a pseudo-terminal."""
    env = dict(os.environ)
    proc = subprocess.Popen([sys.executable, "-m", "toddlerbot.cli.main", "hw", "emulate"], stdout=subprocess.PIPE,
                            text=True, env=env)
    path = proc.stdout.readline().strip()
    try:
        with DynamixelBus(path, motors_of(RobotDescription.load())) as bus:
            bus.scan()
            bus.configure()
            goal = bus.read_state().position
            start = time.perf_counter()
            for _ in range(cycles):
                bus.write_goal_positions(goal)
                bus.read_state()
            return cycles / (time.perf_counter() - start)
    finally:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=20)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=2000)
    parser.add_argument("--baud", type=int, default=2_000_000)
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPU(s), Python {platform.python_version()}, "
          f"numpy {np.__version__}")
    for fast in (True, False):
        r = host_cycle(args.cycles, args.baud, fast)
        name = "Fast Sync Read" if fast else "Sync Read (fallback)"
        print(f"{name:22s} host CPU {r['cpu_ms']:.3f} ms/cycle | wire {r['tx_bytes']:.0f} B out + "
              f"{r['rx_bytes']:.0f} B in = {r['wire_ms']:.3f} ms at {args.baud / 1e6:g} Mbps | "
              f"max loop rate {r['max_hz']:.0f} Hz")
    rate = emulator_loop(min(args.cycles, 500))
    print(f"through the CLI emulator (pty, separate process): {rate:.0f} cycles/s")


if __name__ == "__main__":
    main()
