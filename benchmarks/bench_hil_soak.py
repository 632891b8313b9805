"""A long soak in hardware-in-the-loop (`toddlerbot.runtime.soak`): `hw run` walks a policy over its command reach (ten
commands, 6 s each, in turn) against `hw emulate --hil` for the given minutes, starting again against a fresh emulator
after a fall. Printed: the machine and its load; status packets (the driver's retries, CRC errors, timeouts and stale
readings, the emulator's CRC errors); control deadlines (step periods beyond 1.1, 1.5 and 2 control periods, their
50th, 99th and 99.9th percentiles); the `hw run` process's resident memory every `--sample-every` s and its growth
after the first sample; the log's chunks on disk and the saved log's size; falls. Goal (issue 39): memory growth under
5 % after the first minute, no lost packet, every deadline within 2 periods. `tests/test_hw_soak.py` soaks one minute.

Run: PYTHONPATH=src python benchmarks/bench_hil_soak.py [--minutes 30] [--policy walk-rl] [--weights FILE]
     [--sample-every 60] [--latency-ms MS] [--keep FOLDER]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import tempfile
from pathlib import Path

from toddlerbot.locomotion.config import WALK_REACH
from toddlerbot.runtime.soak import BUS_COUNTERS, REACH_HOLD_S, Segment, SoakReport, soak

MB = 1e6


def machine() -> str:
    """CPU model and cores (lscpu)."""
    lscpu = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
    model = re.search(r"^Model name:\s*(.+)$", lscpu, re.M)
    return f"{model.group(1).strip() if model else 'unknown CPU'}, {os.cpu_count()} cores"


def load() -> str:
    return "load average " + " ".join(f"{v:.2f}" for v in os.getloadavg())


def print_segment(segment: Segment) -> None:
    last = segment.output.strip().splitlines()[-1] if segment.output.strip() else ""
    print(f"segment: exit {segment.exit_code}, {segment.run_s:.0f} s of steps, min uprightness "
          f"{segment.emulator.get('powered_min_torso_upright')}, real-time factor "
          f"{segment.emulator.get('realtime_factor')}; {load()}; hw run: {last}", flush=True)


def print_report(report: SoakReport, sample_every: float) -> None:
    dt_ms = report.control_dt * 1e3
    steps = report.step_period.size
    if not steps:
        print(f"no step logged; hw run printed:\n{report.segments[-1].output}")
        return
    counters = ", ".join(f"{report.bus(c)} {c.replace('_', ' ')}" for c in BUS_COUNTERS)
    print(f"packets: {counters} (driver); "
          f"{report.emulator_crc_errors} CRC errors, "
          f"{sum(s.emulator.get('packets', 0) for s in report.segments)} instruction packets (emulator)")
    late = ", ".join(f"{report.late_steps(k)} beyond {k:g}" for k in (1.1, 1.5, 2.0))
    print(f"deadlines: {steps} steps of {dt_ms:g} ms: {late} periods; step period p50 "
          f"{report.period_percentile_ms(50):.1f} ms, p99 {report.period_percentile_ms(99):.1f} ms, p99.9 "
          f"{report.period_percentile_ms(99.9):.1f} ms, max {report.step_period.max() * 1e3:.1f} ms")
    for k, segment in enumerate(report.segments):
        rss = " ".join(f"{s.rss_kib / 1024:.1f}" for s in segment.memory)
        loads = " ".join(f"{s.load:.1f}" for s in segment.memory)
        growth = segment.rss_growth(sample_every)
        print(f"segment {k}: resident MiB every {sample_every:g} s: {rss}")
        print(f"segment {k}: load average (1 min) at those samples: {loads}")
        print(f"segment {k}: growth after the first {sample_every:g} s: "
              f"{'n/a' if growth is None else f'{growth * 100:+.2f} %'}; chunks on disk at the last sample "
              f"{segment.memory[-1].chunk_bytes / MB if segment.memory else 0:.1f} MB; saved log "
              f"{segment.log_bytes / MB:.1f} MB ({segment.log_bytes / MB / max(segment.run_s / 60, 1e-9):.2f} "
              "MB/min)")
    falls = ", ".join(f"{s.run_s:.1f} s" for s in report.segments if s.fell)
    print(f"falls: {report.falls}{f' (after {falls} of their segments)' if falls else ''}; "
          f"wall {report.wall_s:.0f} s; {load()}")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--policy", default="walk-rl")
    parser.add_argument("--weights", default=None)
    parser.add_argument("--sample-every", type=float, default=60.0, help="s between memory samples")
    parser.add_argument("--latency-ms", type=float, default=None, help="hw run --latency-ms (default: hw run's)")
    parser.add_argument("--keep", type=Path, default=None, help="keep the logs and outputs in this new folder")
    args = parser.parse_args()
    print(f"{args.policy} ({args.weights or 'default weights'}) over {WALK_REACH.describe()}, each command "
          f"{REACH_HOLD_S:g} s, {args.minutes:g} min; {machine()}; {load()}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        workdir = args.keep or Path(tmp)
        report = soak(args.policy, WALK_REACH, args.minutes * 60, workdir, args.sample_every, args.weights,
                      args.latency_ms, on_segment=print_segment)
    print_report(report, args.sample_every)


if __name__ == "__main__":
    main()
