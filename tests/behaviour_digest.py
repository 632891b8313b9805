"""Digests of short seeded runs, to show that a change which only moves code changes no result: run as a script
under one source tree (PYTHONPATH) and print one JSON line of SHA-256 digests. Uses the command line only, which
both sides of such a change share. `tests/test_behaviour_unchanged.py` compares a baseline commit with the tree."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

VOLATILE = {"wall_seconds", "inference_ms", "walltime", "sps", "epoch_seconds", "compile_s", "device"}
"""Keys whose values are wall-clock measurements, not results."""


def _cli(*args: str) -> str:
    out = subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", *args], capture_output=True, text=True,
                         timeout=900)
    if out.returncode not in (0, 1):
        raise SystemExit(f"toddlerbot {' '.join(args)} failed ({out.returncode}): {out.stderr[-2000:]}")
    return out.stdout


def _digest_arrays(arrays: dict) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        value = np.asarray(arrays[name])
        h.update(name.encode())
        h.update(value.tobytes() if value.dtype.kind != "U" else "|".join(value.ravel().tolist()).encode())
    return h.hexdigest()


def _stable(value):
    if isinstance(value, dict):
        return {k: _stable(v) for k, v in value.items() if k not in VOLATILE}
    if isinstance(value, list):
        return [_stable(v) for v in value]
    return value


def _digest_json(value) -> str:
    return hashlib.sha256(json.dumps(_stable(value), sort_keys=True).encode()).hexdigest()


def main(folder: Path) -> dict:
    digests = {}
    for policy in ("walk-zmp", "walk-rl"):
        log = folder / f"{policy}.npz"
        _cli("sim", "run", "--policy", policy, "--seconds", "2", "--command", "0:0.1,0,0.1", "--log", str(log))
        with np.load(log, allow_pickle=False) as data:
            digests[f"sim run {policy}"] = _digest_arrays({k: data[k] for k in data.files
                                                           if k not in ("compute_time", "step_period")})
    digests["chain run pick"] = _digest_json(json.loads(_cli("chain", "run", "pick", "--seed", "3", "--json")))
    run = folder / "smoke"
    _cli("rl", "train", "--smoke", "--epochs", "1", "--imitation-iterations", "0", "--no-tensorboard", "--out",
         str(run))
    records = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines() if line]
    digests["rl train --smoke metrics"] = _digest_json(records)
    from flax import serialization

    checkpoint = sorted((run / "checkpoints").glob("*.msgpack"))[-1]
    state = serialization.msgpack_restore(checkpoint.read_bytes())["state"]
    leaves = {}

    def walk(prefix: str, node) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                walk(f"{prefix}/{k}", v)
        else:
            leaves[prefix] = node

    walk("", state)
    digests["rl train --smoke checkpoint"] = _digest_arrays(leaves)
    return digests


if __name__ == "__main__":
    print(json.dumps(main(Path(sys.argv[1]))))
