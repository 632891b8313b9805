"""Fan a benchmark out over worker processes of its own script: each runs with ``--worker K`` added to the same
arguments and prints one JSON line per result; the lines of all come back as dicts (nothing is pickled between
processes). A failed worker ends the benchmark."""

from __future__ import annotations

import json
import subprocess
import sys


def worker_rows(script: str, workers: int) -> list[dict]:
    procs = [subprocess.Popen([sys.executable, script, *sys.argv[1:], "--worker", str(w)], stdout=subprocess.PIPE,
                              text=True) for w in range(workers)]
    rows = [json.loads(line) for p in procs for line in p.stdout]
    if any(p.wait() != 0 for p in procs):
        sys.exit("a worker failed")
    return rows
