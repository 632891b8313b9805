"""Dataset viewer figures: time and recording size of `manip dataset view --save` for one episode and for the whole
dataset, and (optionally) a screenshot of Rerun's web viewer in headless Chromium for the docs.

    toddlerbot manip demo --task pick --episodes 2 --seed 0 -o /tmp/ds
    python benchmarks/bench_dataset_view.py /tmp/ds [--screenshot docs/figures/dataset_view.png]
"""

from __future__ import annotations

import argparse
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from browser_support import browser_page

COMMAND = [sys.executable, "-m", "toddlerbot.cli.main", "manip", "dataset", "view"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--screenshot", type=Path, default=None, help="PNG of the web viewer to write")
    parser.add_argument("--port", type=int, default=9190)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for label, extra in (("episode 0", ["--episode", "0"]), ("all episodes", [])):
            rrd = Path(tmp) / "view.rrd"
            started = time.perf_counter()
            out = subprocess.run([*COMMAND, str(args.dataset), *extra, "--save", str(rrd)], check=True,
                                 capture_output=True, text=True).stdout
            seconds = time.perf_counter() - started
            print(f"{label}: {out.splitlines()[0]}; {rrd.stat().st_size / 1e6:.2f} MB in {seconds:.1f} s (command, "
                  "imports included)")
    if args.screenshot:
        _screenshot(args.dataset, args.port, args.screenshot)


def _screenshot(dataset: Path, port: int, path: Path) -> None:
    proc = subprocess.Popen([*COMMAND, str(dataset), "--web", "--port", str(port)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        url = None
        while url is None:
            line = proc.stdout.readline()
            if not line:
                raise RuntimeError("the viewer did not start")
            match = re.search(rf"(http://localhost:{port}/\S+)", line)
            url = match.group(1) if match else None
        with browser_page(1600, 1000) as page:
            page.goto(url)
            time.sleep(60)  # the viewer is a canvas (nothing in the page to wait for); it draws in software here
            path.parent.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(path))
            hosts = sorted({re.sub(r"^(https?://[^/]+).*", r"\1", u) for u in page.external})
            print(f"wrote {path}; the web viewer asked for {len(page.external)} outside address(es): {hosts}")
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
