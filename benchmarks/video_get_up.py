"""The videos of docs/tools.md "Getting up": walk-rl walking, kicked with 1.5 m/s at 2 s towards its front or its
back, falls, the get-up policy stands it up (`sim run --on-fall get-up`), and it walks on; rendered headless (OSMesa
on a CPU), with a strip of frames from the video beside it (``--frames``).

Run: MUJOCO_GL=osmesa PYTHONPATH=src python benchmarks/video_get_up.py --side back [--out DIR]
     [--frames 2.8,4.4,5.6,7.6,9.6,11.6,16.4]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import av
import numpy as np
from PIL import Image

from toddlerbot.policies.get_up_trials import KICK_DIRECTION
from toddlerbot.runtime.robustness import DirectedKick
from toddlerbot.sessions.sim import sim_session
from toddlerbot.sim.render import write_png


def frame_strip(video: Path, times: list[float], out: Path) -> None:
    """The video's first frames at or after ``times`` (s) side by side, at half size, in one PNG."""
    picked: dict[float, np.ndarray] = {}
    with av.open(str(video)) as container:
        for frame in container.decode(video=0):
            for t in times:
                if t not in picked and frame.time >= t:
                    picked[t] = frame.to_ndarray(format="rgb24")
    strip = np.concatenate([picked[t] for t in times if t in picked], axis=1)
    write_png(out, np.asarray(Image.fromarray(strip).reduce(2)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", choices=tuple(KICK_DIRECTION), default="front")
    parser.add_argument("--out", type=Path, default=Path("docs/figures"), help="folder for get_up_<side>.mp4/.png")
    parser.add_argument("--seconds", type=float, default=17.0)
    parser.add_argument("--frames", default="2.8,4.4,5.6,7.6,9.6,11.6,16.4", help="s of the frames in the strip")
    args = parser.parse_args()
    session = sim_session("walk-rl", "0:0.05,0,0", seconds=args.seconds, camera="perspective", on_fall="get-up")
    if session.render_skipped:
        raise SystemExit(session.render_skipped)
    result = session.run(DirectedKick(session.robot, 1.5, KICK_DIRECTION[args.side], 2.0))
    print(f"falls {result.falls}, got up from {result.recoveries}; {session.recovery.status.describe()}")
    video = args.out / f"get_up_{args.side}.mp4"
    for path in session.write_video(video, None):
        print(f"wrote {path}")
    strip = video.with_suffix(".png")
    frame_strip(video, [float(t) for t in args.frames.split(",")], strip)
    print(f"wrote {strip}")


if __name__ == "__main__":
    main()
