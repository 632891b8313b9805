"""The video of docs/tools.md "Getting up": walk-rl walking, kicked forwards with 1.5 m/s at 2 s, falls on its front,
the get-up policy stands it up (`sim run --on-fall get-up`), and it walks on; rendered headless (OSMesa on a CPU).

Run: MUJOCO_GL=osmesa PYTHONPATH=src python benchmarks/video_get_up.py [--out docs/figures/get_up_front.mp4]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from toddlerbot.runtime.robustness import DirectedKick
from toddlerbot.sessions.sim import sim_session


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/figures/get_up_front.mp4"))
    args = parser.parse_args()
    session = sim_session("walk-rl", "0:0.05,0,0", seconds=16.0, camera="perspective", on_fall="get-up")
    if session.render_skipped:
        raise SystemExit(session.render_skipped)
    result = session.run(DirectedKick(session.robot, 1.5, 0.0, 2.0))
    print(f"falls {result.falls}, got up from {result.recoveries}; {session.recovery.status.describe()}")
    for path in session.write_video(args.out, None):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
