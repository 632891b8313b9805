"""What loading tensorboardX costs a process that has not loaded PyTorch: tensorboardX's own `import tensorboardX`
(its writer imports PyTorch whenever it is installed) against `toddlerbot.metrics.import_tensorboardx` (PyTorch
hidden while it loads, as RL training loads it). Each trial is a fresh process; the figures are medians.

Run: PYTHONPATH=src python benchmarks/bench_tensorboardx_import.py [--trials 5]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import subprocess
import sys
from importlib.metadata import version

PROBE = """
import resource, sys, time
from toddlerbot.metrics import import_tensorboardx  # loaded before the clock starts, in both modes
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.perf_counter()
if sys.argv[1] == "plain":
    import tensorboardX
else:
    import_tensorboardx()
seconds = time.perf_counter() - start
print(seconds, (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024, "torch" in sys.modules)
"""


def trial(mode: str) -> tuple[float, float, bool]:
    out = subprocess.run([sys.executable, "-c", PROBE, mode], capture_output=True, text=True, check=True)
    seconds, megabytes, torch = out.stdout.split()
    return float(seconds), float(megabytes), torch == "True"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--trials", type=int, default=5)
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, tensorboardX "
          f"{version('tensorboardX')}, torch {version('torch')}, {args.trials} trials")
    for mode, label in (("plain", "import tensorboardX"), ("hidden", "metrics.import_tensorboardx()")):
        runs = [trial(mode) for _ in range(args.trials)]
        seconds = statistics.median(r[0] for r in runs)
        megabytes = statistics.median(r[1] for r in runs)
        print(f"{label:32s} {seconds:6.3f} s  +{megabytes:5.0f} MB peak RSS  torch loaded: {runs[0][2]}")


if __name__ == "__main__":
    main()
