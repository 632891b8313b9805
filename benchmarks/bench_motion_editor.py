"""Motion editor figures, measured as a user meets them in headless Chromium: page load (navigation until the joint
sliders are on screen), Play on the 5 s `wave` (until the result line, then until the real-time animation ends),
and a screenshot of the page for the docs.

    python benchmarks/bench_motion_editor.py [--screenshot docs/figures/motion_editor.png]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from browser_support import browser_page, labelled, running_editor, slider, wait_for_text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--screenshot", type=Path, default=None, help="PNG of the page to write")
    parser.add_argument("--runs", type=int, default=3, help="page loads to time")
    args = parser.parse_args()
    loads = []
    with running_editor("wave") as (url, _proc):
        for run in range(args.runs):
            with browser_page(1400, 1450) as page:
                started = time.perf_counter()
                page.goto(url)
                slider(page, "right_shoulder_roll").wait_for(timeout=120_000)
                loads.append(time.perf_counter() - started)
                if run < args.runs - 1:
                    continue
                started = time.perf_counter()
                # dispatched, not clicked: Playwright's wait for a stable element costs tens of seconds when the
                # page renders WebGL in software on a busy machine, which is not what a user waits for
                page.get_by_role("button", name="Play in simulator").dispatch_event("click")
                result = wait_for_text(page, r"stayed upright|FELL|stopped:", timeout_s=300)
                simulated = time.perf_counter() - started
                page.wait_for_function("() => [...document.querySelectorAll('button')].some(b => "
                                       "b.innerText.includes('Play in simulator') && !b.disabled)", timeout=300_000)
                played = time.perf_counter() - started
                if args.screenshot:
                    _screenshot(page, args.screenshot)
    print(f"page load: {', '.join(f'{s:.1f}' for s in loads)} s (first, then warm)")
    print(f"play wave (5 s): result after {simulated:.1f} s, animation done after {played:.1f} s")
    print(f"result line: {result}")


def _screenshot(page, path: Path) -> None:
    """Keyframe 2 of wave (arm raised, forearm bent)."""
    for close in page.locator(".mantine-Notification-closeButton").all():
        close.click()
    labelled(page, "Keyframe", "input").click()
    page.get_by_role("option", name="2: t = 1.50 s").click()
    wait_for_text(page, r"Keyframe 2: CoM")
    page.mouse.move(10, 10)  # no tooltip in the picture
    time.sleep(2.0)
    path.parent.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(path))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
