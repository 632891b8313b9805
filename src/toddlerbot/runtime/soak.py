"""A soak in hardware-in-the-loop: `hw run` walks a policy against `hw emulate --hil` (each its own process, as on
the robot, the bus a pseudo-terminal) for a long time on a schedule across the policy's command reach, and what a
long run could lose is measured: status packets (the driver's counters, which `hw run` prints, and the emulator's
statistics), control deadlines (the log's step periods), memory (the resident set of the `hw run` process,
/proc/PID/status VmRSS, sampled while the run goes on), the log on disk, and falls.

A fall ends `hw run` (exit 1, torque off) with the robot on the floor; the soak counts it and walks on for the time
left against a fresh emulator (the robot standing again). There is no get-up yet: it would let one emulator run
through, and kicks could join the schedule. `benchmarks/bench_hil_soak.py` soaks 30 minutes, `tests/test_hw_soak.py`
60 s.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toddlerbot.locomotion.config import CommandReach
from toddlerbot.runtime.log import RunLog, parts_of
from toddlerbot.runtime.robustness import reach_commands

REACH_HOLD_S = 6.0
"""How long each command of the reach is held, s: the ten commands take a minute."""
MIN_SEGMENT_S = 5.0
"""Time left below which the soak starts no new `hw run` after a fall, s."""
CLI = (sys.executable, "-m", "toddlerbot.cli.main")
BUS_LINE = re.compile(r"^bus \S+: (\d+) retries, (\d+) CRC errors, (\d+) timeouts, (\d+) stale readings$", re.M)
"""The driver's counters as `hw run` prints them (`hardware.driver.BusCounters.describe`)."""
BUS_COUNTERS = ("retries", "crc_errors", "timeouts", "stale_readings")


def reach_schedule(reach: CommandReach, seconds: float, hold_s: float = REACH_HOLD_S) -> str:
    """`hw run --command` text: the ten commands of `reach_commands(reach)` in turn, each held `hold_s`, repeated
    for `seconds`."""
    commands = reach_commands(reach)
    return "; ".join(f"{k * hold_s:g}:{','.join(f'{v:g}' for v in commands[k % len(commands)])}"
                     for k in range(math.ceil(seconds / hold_s)))


def resident_kib(pid: int) -> int | None:
    """The resident set of process `pid`, KiB (VmRSS); None once it has ended."""
    try:
        found = re.search(r"^VmRSS:\s+(\d+) kB", Path(f"/proc/{pid}/status").read_text(), re.M)
    except OSError:
        return None
    return int(found.group(1)) if found else None


@dataclass(frozen=True)
class MemorySample:
    age_s: float
    """s since `hw run` started."""
    rss_kib: int
    chunk_bytes: int
    """The log's chunks on disk at that moment (`runtime.log.parts_of`)."""
    load: float
    """The machine's load average over the last minute."""


@dataclass(frozen=True)
class Segment:
    """One `hw run` against a fresh emulator, until its time ran out or the robot fell."""

    exit_code: int
    output: str
    """What `hw run` printed."""
    memory: tuple[MemorySample, ...]
    bus: dict[str, int] | None
    """The driver's counters (`BUS_COUNTERS`); None when `hw run` printed none (it failed)."""
    emulator: dict
    """The emulator's closing statistics (`hw emulate`'s JSON line)."""
    step_period: np.ndarray
    """s, one per logged step."""
    control_dt: float
    """s (NaN without a log)."""
    run_s: float
    """s of logged steps."""
    log_bytes: int
    """Size of the saved log."""

    @property
    def fell(self) -> bool:
        return self.exit_code == 1

    def rss_growth(self, after_s: float) -> float | None:
        """Largest resident set after the first sample at `after_s` s or later, relative to that sample; None
        without two such samples."""
        later = [s.rss_kib for s in self.memory if s.age_s >= after_s]
        return max(later) / later[0] - 1.0 if len(later) > 1 else None


@dataclass(frozen=True)
class SoakReport:
    policy: str
    segments: tuple[Segment, ...]
    wall_s: float

    @property
    def control_dt(self) -> float:
        return self.segments[0].control_dt

    @property
    def step_period(self) -> np.ndarray:
        return np.concatenate([s.step_period for s in self.segments])

    def late_steps(self, periods: float) -> int:
        """Steps whose period exceeded `periods` control periods."""
        return int(np.count_nonzero(self.step_period > periods * self.control_dt))

    def period_percentile_ms(self, q: float) -> float:
        return float(np.percentile(self.step_period, q) * 1e3)

    def bus(self, counter: str) -> int:
        """A driver counter summed over the segments (every segment that printed its counters)."""
        return sum(s.bus[counter] for s in self.segments if s.bus is not None)

    @property
    def emulator_crc_errors(self) -> int:
        """Instruction packets the emulator received with a bad CRC."""
        return sum(s.emulator.get("crc_errors", 0) for s in self.segments)

    @property
    def falls(self) -> int:
        return sum(s.fell for s in self.segments)

    def rss_growth(self, after_s: float) -> float | None:
        """The largest growth of any segment (`Segment.rss_growth`)."""
        growths = [g for s in self.segments if (g := s.rss_growth(after_s)) is not None]
        return max(growths) if growths else None


def soak(policy: str, reach: CommandReach, seconds: float, workdir: Path, sample_every: float = 60.0,
         weights: str | None = None, latency_ms: float | None = None,
         on_segment: Callable[[Segment], object] = lambda _: None) -> SoakReport:
    """Walk `policy` over `reach` for `seconds` of `hw run` against `hw emulate --hil`, starting again after each fall
    for the time left; the resident set sampled every `sample_every` s. Each segment's files (calibration, log,
    output) go in `workdir/segmentK`."""
    start, left, segments = time.perf_counter(), seconds, []
    while left >= MIN_SEGMENT_S:
        segment = run_segment(policy, reach_schedule(reach, left), left, workdir / f"segment{len(segments)}",
                              sample_every, weights, latency_ms)
        segments.append(segment)
        on_segment(segment)
        if not segment.fell:
            break
        left -= max(segment.run_s, 1.0)
    return SoakReport(policy, tuple(segments), time.perf_counter() - start)


def run_segment(policy: str, schedule: str, seconds: float, folder: Path, sample_every: float,
                weights: str | None = None, latency_ms: float | None = None) -> Segment:
    """One `hw run --log` of `seconds` against a new `hw emulate --hil`, its memory sampled meanwhile."""
    folder.mkdir(parents=True)
    cal, log, out = folder / "emulated.yaml", folder / "run.npz", folder / "hw_run.txt"
    emulator = subprocess.Popen([*CLI, "hw", "emulate", "--hil", "--write-calibration", str(cal)],
                                stdout=subprocess.PIPE, text=True)
    try:
        port = emulator.stdout.readline().strip()
        with out.open("w") as sink:
            run = subprocess.Popen([*CLI, "hw", "run", "--port", port, "--calibration", str(cal), "--imu", "emulator",
                                    "--policy", policy, "--command", schedule, "--seconds", f"{seconds:g}", "--log",
                                    str(log), *(["--weights", weights] if weights else []),
                                    *(["--latency-ms", f"{latency_ms:g}"] if latency_ms else [])],
                                   stdout=sink, stderr=subprocess.STDOUT)
            memory = _sample_memory(run, seconds, sample_every, parts_of(log))
    finally:
        emulator.send_signal(signal.SIGINT)
        closing, _ = emulator.communicate(timeout=60)
    text = out.read_text()
    counters = BUS_LINE.search(text)
    steps = RunLog.load(log) if log.is_file() else None
    return Segment(run.returncode, text, memory,
                   None if counters is None else dict(zip(BUS_COUNTERS, map(int, counters.groups()), strict=True)),
                   json.loads(closing.strip().splitlines()[-1]) if closing.strip() else {},
                   np.zeros(0) if steps is None else steps.step_period,
                   float("nan") if steps is None else steps.control_dt,
                   0.0 if steps is None or not steps.time.size else float(steps.time[-1]),
                   log.stat().st_size if log.is_file() else 0)


def _sample_memory(run: subprocess.Popen, seconds: float, every: float, chunks: Path) -> tuple[MemorySample, ...]:
    """Sample `run`'s resident set every `every` s until it ends; only samples within its first `seconds` are kept
    (after them it joins and saves its log, which a run's memory is not). It is killed after a further 300 s."""
    start, samples = time.perf_counter(), []
    while True:
        age = time.perf_counter() - start
        try:
            run.wait(timeout=max(0.0, (math.floor(age / every) + 1) * every - age))
            return tuple(samples)
        except subprocess.TimeoutExpired:
            age = time.perf_counter() - start
            rss = resident_kib(run.pid)
            if rss is not None and age <= seconds:
                samples.append(MemorySample(age, rss, _folder_bytes(chunks), os.getloadavg()[0]))
            if age > seconds + 300:
                run.kill()


def _folder_bytes(folder: Path) -> int:
    """Bytes of the files in `folder` (0 if there is none; a file renamed meanwhile is skipped)."""
    total = 0
    with contextlib.suppress(FileNotFoundError), os.scandir(folder) as entries:
        for entry in entries:
            with contextlib.suppress(FileNotFoundError):
                total += entry.stat().st_size
    return total
