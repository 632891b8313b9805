"""The diffusion policy in the runtime loop: does the 50 Hz loop keep its period while the model runs?

The `hw run` path end to end: the runner drives `RealRobot` (driver, Protocol 2.0 over a pty) against the bus
emulator in its own process (`toddlerbot hw emulate --variant gripper`), with the shipped pick checkpoint as
`LiveDPPolicy` and a fixed head-camera image. Run with inference on the worker thread (as `hw run` does), inline
(synchronous), and with a model that answers at once (the loop's own jitter on this machine); print the loop's
step periods, the time `policy.act` takes per step and the inference time.

    PYTHONPATH=src python benchmarks/bench_dp_live.py [--seconds 10] [--threads 1]
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

import numpy as np
import torch

from toddlerbot.dp.inference import PolicyInference
from toddlerbot.dp.live import LiveDPPolicy
from toddlerbot.dp.shipped import shipped_checkpoint
from toddlerbot.hardware.calibration import load_calibration
from toddlerbot.hardware.real_robot import RealRobot
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.commands import CommandSchedule
from toddlerbot.runtime.runner import run_policy

SRC = Path(__file__).resolve().parents[1] / "src"


def run_once(port: str, calibration: Path, seconds: float, mode: str) -> dict:
    """``mode``: worker, inline, or baseline (the same loop and runner with a model that answers at once)."""
    description = RobotDescription.load(variant="gripper")
    robot = RealRobot(description, port, load_calibration(calibration, description), reset_duration=0.5,
                      latency_ms=20)
    image = np.full((96, 96, 3), 120, np.uint8)
    inference = PolicyInference.from_checkpoint(shipped_checkpoint("pick"))
    config = inference.policy.config
    if mode == "baseline":
        home = description.home_motor_pos[[description.motor_names.index(n) for n in config.action_names]]
        policy = LiveDPPolicy(robot, lambda history: np.tile(home, (config.horizon, 1)), config, lambda: image)
    else:
        policy = LiveDPPolicy(robot, inference, config, lambda: image, synchronous=mode == "inline")
    act, act_ms = policy.act, []

    def timed_act(obs, command):  # the policy's own share of a step (the step also waits for the bus)
        start = time.perf_counter()
        action = act(obs, command)
        act_ms.append(1e3 * (time.perf_counter() - start))
        return action

    policy.act = timed_act
    try:
        with robot:
            log = run_policy(robot, policy, CommandSchedule.parse("0:0,0,0"), seconds).log
    finally:
        policy.close()
    period = 1e3 * log.step_period
    return {"period": period, "compute": np.array(act_ms), "status": policy.status,
            "late": int(np.sum(period > 25.0))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--threads", type=int, default=1, help="torch threads for inference")
    parser.add_argument("--switch-interval-ms", type=float, default=None,
                        help="Python's GIL switch interval (default: the interpreter's, 5 ms)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    if args.switch_interval_ms is not None:
        sys.setswitchinterval(args.switch_interval_ms / 1e3)
    env = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    with tempfile.TemporaryDirectory() as tmp:
        calibration = Path(tmp) / "cal.yaml"
        emulator = subprocess.Popen([sys.executable, "-m", "toddlerbot.cli.main", "hw", "emulate", "--variant",
                                     "gripper", "--write-calibration", str(calibration)],
                                    stdout=subprocess.PIPE, text=True, env=env)
        try:
            port = emulator.stdout.readline().strip()
            results = {mode: run_once(port, calibration, args.seconds, mode)
                       for mode in ("baseline", "worker", "inline")}
        finally:
            emulator.send_signal(signal.SIGINT)
            emulator.communicate(timeout=20)
    print(f"{platform.machine()}, {os.cpu_count()} CPUs, torch {torch.__version__} ({args.threads} thread(s)), "
          f"GIL switch interval {1e3 * sys.getswitchinterval():g} ms, {args.seconds:g} s per mode, 50 Hz")
    for mode, r in results.items():
        p, c, s = r["period"], r["compute"], r["status"]
        print(f"{mode:>8}: step period p50 {np.median(p):.1f} ms, p99 {np.percentile(p, 99):.1f} ms, max "
              f"{p.max():.1f} ms, {r['late']} of {len(p)} steps > 25 ms; policy.act p50 {np.median(c):.2f} ms, "
              f"p99 {np.percentile(c, 99):.1f} ms, max {c.max():.1f} ms; inference {s.inference_ms:.1f} ms mean; "
              f"{s.chunks_used} chunks used, {s.holding_steps} steps held, {s.failures} failures")


if __name__ == "__main__":
    main()
