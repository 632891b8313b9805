"""`toddlerbot sysid record` against the Protocol 2.0 emulator: the runs it writes are logs `sysid fit` reads,
with the torque-off segment, the supply voltage and the motion of the emulated motor."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hw_support import emulated
from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.cli.main import app
from toddlerbot.hardware.plant import LOAD_INERTIA
from toddlerbot.sysid.evaluate import evaluate
from toddlerbot.sysid.manifest import load_manifest

pytestmark = pytest.mark.realtime  # emulator or browser in wall-clock time: runs alone (conftest.py)


def test_record_on_the_emulator_writes_fit_ready_logs(tmp_path: Path) -> None:
    out = tmp_path / "runs"
    rig = f'{{"type": "testbed", "load_inertia": {LOAD_INERTIA}}}'  # the emulator's plant: an inertia, no gravity
    with emulated() as (emu, path):
        result = CliRunner().invoke(app, [
            "sysid", "record", "--port", path, "--id", "0", "--motor", "XC330", "--rig", rig, "-o", str(out),
            "--profile", "steps", "--profile", "drop", "--kp", "900", "--duration", "1.0", "--rate", "100",
            "--amplitude", "0.3", "--settle", "0.3"], catch_exceptions=False)
        assert result.exit_code == 0, result.output
        assert not emu.motor(0).torque_on  # left with torque off
    manifest = load_manifest(out / "manifest.json")
    assert manifest.motor.name == "XC330-T288" and [r.file.name for r in manifest.runs] == [
        "steps_kp900.csv", "drop_kp900.csv"]
    header = (out / "drop_kp900.csv").read_text().splitlines()[0]
    assert header == "time,goal_position,position,velocity,torque,torque_enable,voltage"
    steps, drop = manifest.runs
    # 101 samples, the last one read no earlier than its 1 s slot (times are those of the reads, from the start of
    # the recording; on a loaded machine a read can come late, never early), so the log stays a faithful record
    assert len(steps.time) == 101 and steps.time[-1] >= 1.0 - 1e-6
    assert np.all(steps.time >= np.arange(101) * 0.01 - 1e-6)
    assert np.all(steps.voltage == 12.0) and steps.kp == 900
    assert drop.torque_enable[:50].all() and not drop.torque_enable[51:].any()  # off from half-time
    # the emulated motor followed the steps (0.3 rad from 0.6 s on) while powered
    late = steps.time > steps.time[60] + 0.3
    assert np.abs(steps.position[late] - steps.goal_position[late]).max() < np.radians(3)
    # the emulator's plant is the actuator model on an inertia: the catalogue replays the recording closely
    assert evaluate(manifest, default_catalogue()["XC330"].actuator).mae_deg < 1.5


def test_record_refuses_a_wrong_motor_model(tmp_path: Path) -> None:
    from toddlerbot.hardware.driver import BusError

    with emulated() as (_emu, path), pytest.raises(BusError, match=r"reports model number 1220 \(XC330-T288\)"):
        CliRunner().invoke(app, ["sysid", "record", "--port", path, "--id", "0", "--motor", "XL330-M288",
                                 "-o", str(tmp_path), "--duration", "0.2"], catch_exceptions=False)
    unknown = CliRunner().invoke(app, ["sysid", "record", "--port", "/dev/null", "--id", "0", "--motor", "XC330",
                                       "-o", str(tmp_path), "--profile", "wobble"])  # a typed choice: a usage error
    assert unknown.exit_code == 2
    assert "Invalid value for '--profile': Value error, 'wobble' is not one of 'chirp'," in unknown.output
