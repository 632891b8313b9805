"""SIGINT at random moments against `toddlerbot hw run` on the emulator: does torque always end off, and does every
goal register stay inside its joint range?

The emulator runs as `toddlerbot hw emulate` in its own process. Each trial forks a fresh `hw run` process from
this (pre-imported, thread-free) one, so a trial costs the run itself rather than Python's start-up; the child
runs the real CLI entry point. After a random delay (uniform over start-up, torque-on, the reset ramp and the
run) it gets SIGINT; once it has exited, this process reads Torque Enable and Goal Position of every motor back
over the bus with the official SDK. Odd trials use ``--control-hz 1000`` so that nearly all the time is spent inside bus
transactions (the case where an interrupt used to leave the SDK port marked busy and every motor powered).
``--spawn`` starts every trial as a fresh interpreter instead, so the signals also land in Python's start-up and the
CLI's imports (where third-party code once swallowed one).

Prints: trials, exit codes, trials with any motor still powered, trials with a goal outside its joint range.

Run: PYTHONPATH=src python benchmarks/bench_hw_signals.py [--trials 200] [--max-delay 3.0] [--spawn]
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import os
import platform
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import toddlerbot.cli.main as cli_main
from toddlerbot.hardware import control_table as ct
from toddlerbot.hardware.calibration import load_calibration
from toddlerbot.hardware.driver import BusError, DynamixelBus, motors_of
from toddlerbot.robot.description import RobotDescription


def _hw_run(argv: list[str], output: Path) -> int:
    """Fork a child that runs `toddlerbot <argv>` (stdout and stderr to `output`) and return its pid."""
    pid = os.fork()
    if pid == 0:  # child: the real CLI, then exit without running the parent's cleanup
        code = 1
        try:
            sys.argv = ["toddlerbot", *argv]
            sys.stdout = sys.stderr = output.open("w")
            cli_main.main()
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        except BaseException as exc:  # escaped the CLI: record it
            print(f"escaped: {type(exc).__name__}: {exc}", file=sys.stderr)
            code = 99
        finally:
            sys.stderr.flush()
            os._exit(code)
    return pid


def _read_back_retrying(bus: DynamixelBus, offsets: np.ndarray, mid: np.ndarray) -> tuple[list[int], np.ndarray]:
    """`_read_back`, tolerating an emulator that a loaded machine starves for a while."""
    for attempt in range(5):
        try:
            with bus:  # closing it afterwards sends torque-off again, after the read-back
                return _read_back(bus, offsets, mid)
        except BusError:
            if attempt == 4:
                raise
            time.sleep(1.0)
    raise AssertionError("unreachable")


def _read_back(bus: DynamixelBus, offsets: np.ndarray, mid: np.ndarray) -> tuple[list[int], np.ndarray]:
    """(ids with torque on, goal angles in rad) as the motors report them."""
    powered, goals, present = [], [], []
    for m in bus.motors:
        if bus.read(m, "torque_enable", allow_alert=True):
            powered.append(m.id)
        goals.append(bus.read(m, "goal_position", allow_alert=True))
        present.append(bus.read(m, "present_position", allow_alert=True))
    # whole turns as RealRobot resolves them: within half a turn of each joint range's middle
    turns = np.rint((ct.pulses_to_rad(np.array(present) - offsets) - mid) / (2 * np.pi)).astype(np.int64)
    return powered, ct.pulses_to_rad(np.array(goals) - offsets - turns * ct.PULSES_PER_REV)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=200)
    parser.add_argument("--max-delay", type=float, default=3.0, help="largest delay before SIGINT, s")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--spawn", action="store_true", help="a fresh interpreter per trial (start-up included)")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    signal.signal(signal.SIGINT, signal.default_int_handler)  # a background shell job starts with SIGINT ignored
    description = RobotDescription.load()
    low, high = description.motor_range.T
    mid = np.where(np.isfinite(low + high), (low + high) / 2, 0.0)
    work = Path(tempfile.mkdtemp(prefix="bench_hw_signals_"))
    cal_file = work / "emulated.yaml"
    emulator = subprocess.Popen([sys.executable, "-m", "toddlerbot.cli.main", "hw", "emulate", "--write-calibration",
                                 str(cal_file)], stdout=subprocess.PIPE, text=True)
    port = emulator.stdout.readline().strip()
    offsets = load_calibration(cal_file, description).offsets_for(description)
    checker = DynamixelBus(port, motors_of(description), latency_ms=50, watchdog_s=0)
    exit_codes: collections.Counter[int] = collections.Counter()
    powered_trials, out_of_range_trials, unusual = [], [], []
    start = time.perf_counter()
    try:
        with checker:  # goals where the motors are, so that every register starts inside its range
            checker.write_goal_positions(checker.read_state().position)
        for trial in range(args.trials):
            argv = ["hw", "run", "--port", port, "--calibration", str(cal_file), "--imu", "none", "--policy", "stand",
                    "--seconds", "2", "--latency-ms", "50"] + (["--control-hz", "1000"] if trial % 2 else [])
            if args.spawn:
                with (work / "trial.log").open("w") as log:
                    proc = subprocess.Popen([sys.executable, "-m", "toddlerbot.cli.main", *argv], stdout=log,
                                            stderr=log, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
                pid = proc.pid
            else:
                pid = _hw_run(argv, work / "trial.log")
            time.sleep(rng.uniform(0.0, args.max_delay))
            with contextlib.suppress(ProcessLookupError):  # the run may have finished already
                os.kill(pid, signal.SIGINT)
            code = proc.wait() if args.spawn else os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
            exit_codes[code] += 1
            if code != 130:
                unusual.append((trial, code, (work / "trial.log").read_text().strip().splitlines()[-1:]))
            powered, goals = _read_back_retrying(checker, offsets, mid)
            if powered:
                powered_trials.append((trial, powered))
            if np.any(goals < low - ct.RAD_PER_PULSE) or np.any(goals > high + ct.RAD_PER_PULSE):
                out_of_range_trials.append(trial)
            print(f"trial {trial:3d}: exit {code:4d}, powered {powered or 'none'}",
                  flush=True)
    finally:
        emulator.send_signal(signal.SIGINT)
        emulator.communicate(timeout=30)
    elapsed = time.perf_counter() - start
    print(f"\nmachine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}")
    print(f"{args.trials} SIGINTs at random moments (0..{args.max_delay:g} s after start) in {elapsed:.0f} s")
    print(f"exit codes: {dict(sorted(exit_codes.items()))}")
    for trial, code, last_line in unusual:
        print(f"  trial {trial}: exit {code}: {last_line}")
    print(f"trials ending with any motor powered: {len(powered_trials)} {powered_trials or ''}")
    print(f"trials with a goal register outside its joint range: {len(out_of_range_trials)} "
          f"{out_of_range_trials or ''}")


if __name__ == "__main__":
    main()
