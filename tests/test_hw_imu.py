"""IMU readings in the simulated IMU's conventions, with the sensor mounted rotated in the torso."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from toddlerbot.hardware.imu import GRAVITY, Bno08xImu, StaticImu


class _FakeBno:
    """Quacks like adafruit_bno08x: quaternion as (i, j, k, real)."""

    def __init__(self, sensor_in_world: Rotation, gyro, accel) -> None:
        x, y, z, w = sensor_in_world.as_quat()
        self.game_quaternion = (x, y, z, w)
        self.gyro, self.acceleration = gyro, accel


def test_bno08x_reading_is_rotated_into_the_imu_site_frame():
    mount = Rotation.from_euler("z", 90, degrees=True)  # sensor x axis along the site's y axis
    torso = Rotation.from_euler("y", 10, degrees=True)  # torso pitched 10 degrees
    sensor_in_world = torso * mount
    x, y, z, w = mount.as_quat()
    # the torso spins about its own x axis at 1 rad/s: the sensor sees that about its -y axis
    imu = Bno08xImu(mount_quat=(w, x, y, z), device=_FakeBno(sensor_in_world, (0.0, -1.0, 0.0), (0.0, 0.0, GRAVITY)))
    reading = imu.read()
    q = reading.quat
    assert Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_euler("xyz", degrees=True) == pytest.approx([0, 10, 0],
                                                                                                       abs=1e-9)
    assert reading.ang_vel == pytest.approx([1.0, 0.0, 0.0])
    assert reading.lin_acc == pytest.approx([0.0, 0.0, GRAVITY])


def test_static_imu_is_upright_at_rest():
    reading = StaticImu().read()
    assert np.array_equal(reading.quat, [1, 0, 0, 0]) and reading.lin_acc[2] == GRAVITY
