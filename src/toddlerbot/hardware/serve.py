"""`hw emulate`: serve an emulated bus on a pseudo-terminal until stopped, then its statistics (with the HIL
plant's ground truth: torso height, uprightness and planar motion while powered). A HIL plant's IMU and torso pose
are published beside the bus (`toddlerbot.hardware.imu_stream`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from toddlerbot.hardware.calibration import Calibration, save_calibration, spec_label
from toddlerbot.hardware.driver import raise_on_stop_signals
from toddlerbot.hardware.emulator import EmulatedBus, PtyServer
from toddlerbot.hardware.imu_stream import ImuPublisher, imu_socket_path
from toddlerbot.hardware.plant import HilPlant


def write_true_calibration(bus: EmulatedBus, path: Path) -> None:
    """The emulated robot's hidden mounting offsets as a calibration file (what a perfect calibration finds)."""
    offsets = {m.name: m.mounting_offset for m in bus.motors}
    save_calibration(Calibration("emulated", spec_label(bus.description), offsets, {}), path)


def serve_until_stopped(bus: EmulatedBus, on_ready: Callable[[str], None]) -> dict:
    """Serve `bus` on a pseudo-terminal (its path given to `on_ready` first; a HIL plant's IMU published beside
    it) until Ctrl-C or a stop signal; returns the statistics."""
    server = PtyServer(bus)
    plant = bus.plant
    imu = (ImuPublisher(imu_socket_path(server.path), lambda: plant.imu_sample, pose=lambda: plant.pose_sample).start()
           if isinstance(plant, HilPlant) else None)
    raise_on_stop_signals()  # every stop signal ends serving, even a SIGINT a background shell job ignores
    try:
        on_ready(server.path)
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
        if imu is not None:
            imu.stop()
    report = {"packets": bus.stats.packets_in, "bytes_in": bus.stats.bytes_in, "bytes_out": bus.stats.bytes_out,
              "crc_errors": bus.stats.crc_errors}
    if isinstance(plant, HilPlant):
        report |= _plant_report(plant) | {"imu_reports": imu.reports, "pose_reports": imu.pose_reports}
    return report


def _plant_report(plant: HilPlant) -> dict:
    motion = plant.powered_motion()
    return {"ground": plant.ground, "sim_time": round(plant.sim_time, 3),
            "realtime_factor": round(plant.realtime_factor, 3),
            "torso_height": round(plant.torso_height(), 4), "torso_upright": round(plant.torso_uprightness(), 4),
            "powered_min_torso_height": _finite(plant.powered_min_height),
            "powered_min_torso_upright": _finite(plant.powered_min_upright),
            "powered_torso_motion": None if motion is None else dict(
                zip(("dx_m", "dy_m", "yaw_rad"), (round(v, 4) for v in motion), strict=True)),
            "kicks": [dict(zip(("time_s", "dvx_mps", "dvy_mps"), kick, strict=True)) for kick in plant.kicked],
            "retried_steps": plant.retried_steps}


def _finite(value: float) -> float:
    """Rounded value (NaN, never measured, becomes JSON null)."""
    return round(value, 4) if np.isfinite(value) else value
