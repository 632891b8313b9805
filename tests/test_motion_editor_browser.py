"""The motion editor in a real headless browser, as a user drives it: load the page, move a slider, add a
keyframe, play it in the simulator, save; the saved file replays with `toddlerbot sim run --policy replay`."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("viser")
pytest.importorskip("playwright")

from browser_support import browser_page, chromium_available, labelled, running_editor, slider, wait_for_text
from toddlerbot.policies.motions import load_motion
from toddlerbot.robot.description import RobotDescription

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)

if not chromium_available():
    if os.environ.get("CI"):
        raise RuntimeError("CI needs Debian's chromium (.ci/run installs it) for the motion editor's browser test")
    pytest.skip("Debian's chromium is not installed: apt-get install chromium", allow_module_level=True)


SHORT = """name: raise
joints: [right_shoulder_roll, right_elbow_roll]
keyframes:
  - {t: 0.0, right_shoulder_roll: -15, right_elbow_roll: 30}
  - {t: 1.0, right_shoulder_roll: -60, right_elbow_roll: 60}
"""


def test_edit_in_the_browser_then_replay_the_saved_file(tmp_path):
    opened, saved = tmp_path / "raise.yaml", tmp_path / "my_motion.yaml"
    opened.write_text(SHORT)
    with running_editor(str(opened)) as (url, proc), browser_page(800, 700) as page:
        started = time.perf_counter()
        page.goto(url)
        thumb = slider(page, "right_shoulder_roll")
        thumb.wait_for(timeout=120_000)
        load_s = time.perf_counter() - started
        assert thumb.get_attribute("aria-valuenow") == "-15"  # keyframe 0
        assert [thumb.get_attribute("aria-valuemin"), thumb.get_attribute("aria-valuemax")] == ["-90", "20"]
        assert labelled(page, "Save to", "input").input_value() == str(opened)  # Save writes the opened file

        thumb.focus()
        for _ in range(10):  # 0.5 deg a step
            page.keyboard.press("ArrowLeft")
        page.wait_for_function("() => document.body.innerText.includes('CoM')")
        assert slider(page, "right_shoulder_roll").get_attribute("aria-valuenow") == "-20"

        page.get_by_role("button", name="Add", exact=True).click()
        wait_for_text(page, r"add: keyframe 1 selected, 3 keyframes, 2\.00 s")

        labelled(page, "Save to", "input").fill(str(saved))
        page.get_by_role("button", name="Save", exact=True).click()
        status = wait_for_text(page, r"saved .*my_motion\.yaml|error:")
        assert status.startswith("saved") and "3 keyframes, 2.00 s, 2 joints" in status, status

        play_started = time.perf_counter()
        page.get_by_role("button", name="Play in simulator").click()
        result = wait_for_text(page, r"stayed upright|FELL|stopped:", timeout_s=300)
        play_s = time.perf_counter() - play_started
        assert result.startswith("stayed upright: 2.0"), result
        assert page.external == [], f"the page fetched from outside: {page.external[:3]}"
    assert proc.returncode == 0
    assert opened.read_text() == SHORT  # saved elsewhere: the opened file is untouched
    print(f"page load {load_s:.1f} s, play {play_s:.1f} s")

    description = RobotDescription.load()
    motion = load_motion(str(saved), description)
    np.testing.assert_allclose(motion.times, [0, 1, 2])
    np.testing.assert_allclose(np.rad2deg(motion.poses), [[-20, 30], [-20, 30], [-60, 60]], atol=1e-9)

    run = subprocess.run([sys.executable, "-m", "toddlerbot.cli.main", "sim", "run", "--policy", "replay",
                          "--motion", str(saved)], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "no fall" in run.stdout and "replay 2.0" in run.stdout
