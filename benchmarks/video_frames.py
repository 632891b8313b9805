"""Frames of a side-by-side manipulation video (`manip demo --video`, `dp eval --video`, `chain run --video`: the
scene camera, 320 px wide, then the head camera) as one PNG: the frames picked by index or by time, tiled left to
right, each whole or cropped to its scene-camera half. Not a benchmark: it makes the README's video figures.

Run: PYTHONPATH=src python benchmarks/video_frames.py VIDEO -o OUT.png (--frame I ... | --time S ...) [--scene-only]

The README figures made with it:

    toddlerbot dp eval --task pick --episodes 1 --seed 1000 --video eval.mp4
    python benchmarks/video_frames.py eval.mp4 --frame 40 -o docs/figures/dp_pick_eval.png
    toddlerbot chain run wagon --seed 0 --video wagon.mp4       # prints the grasp -> settle switch time (4.06 s)
    python benchmarks/video_frames.py wagon.mp4 --frame 0 101 200 -1 --scene-only -o docs/figures/chain_wagon.png

(`chain run` records every 2nd 50 Hz control step at 25 fps, so frame j shows the simulation at (2j + 1) * 0.02 s:
frame 101 is the switch at 4.06 s, the last of 312 frames 12.46 s.)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import av
import numpy as np

from toddlerbot.sim.render import write_png
from toddlerbot.tasks.video import SCENE_SIZE


def read_frames(path: str | Path) -> tuple[list[np.ndarray], float]:
    """Every frame of the video as (H, W, 3) uint8 RGB, and its frame rate."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        fps = float(stream.average_rate or stream.base_rate)
        return [f.to_ndarray(format="rgb24") for f in container.decode(stream)], fps


def pick(count: int, fps: float, frames: list[int] | None, times: list[float] | None) -> list[int]:
    """Frame indices: `frames` as given, or the frame nearest each time (s); negative values count from the end."""
    if frames is not None:
        picked = [i if i >= 0 else count + i for i in frames]
    else:
        picked = [count + round(t) if t < 0 else round(t * fps) for t in times or []]
    bad = [i for i in picked if not 0 <= i < count]
    if bad:
        raise SystemExit(f"frames {bad} outside the video's 0..{count - 1}")
    return picked


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("video", type=Path)
    parser.add_argument("-o", "--out", type=Path, required=True, help="PNG to write")
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--frame", type=int, nargs="+", help="frame indices (from 0; -1: the last)")
    which.add_argument("--time", type=float, nargs="+", help="times, s (the nearest frame; -1: the last frame)")
    parser.add_argument("--scene-only", action="store_true", help="keep only the scene-camera half of each frame")
    args = parser.parse_args()
    video, fps = read_frames(args.video)
    indices = pick(len(video), fps, args.frame, args.time)
    tiles = [video[i][:, : SCENE_SIZE[0]] if args.scene_only else video[i] for i in indices]
    write_png(args.out, np.ascontiguousarray(np.concatenate(tiles, axis=1)))
    print(f"wrote {args.out}: frames {indices} of {len(video)} at {fps:g} fps "
          f"({', '.join(f'{i / fps:.2f}' for i in indices)} s)")


if __name__ == "__main__":
    main()
