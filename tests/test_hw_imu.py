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


def test_static_imu_reads_what_a_mounted_bno08x_reads_on_an_upright_robot_at_rest():
    mount = Rotation.from_euler("xz", [180, 90], degrees=True)  # sensor upside down and turned in the torso
    x, y, z, w = mount.as_quat()
    # upright torso at rest: the sensor's orientation is the mount itself, no rotation rate, and the accelerometer
    # measures gravity's reaction (+g up in the world) in the sensor's axes
    at_rest = _FakeBno(mount, (0.0, 0.0, 0.0), mount.inv().apply([0.0, 0.0, GRAVITY]))
    real = Bno08xImu(mount_quat=(w, x, y, z), device=at_rest).read()
    stand_in = StaticImu().read()
    np.testing.assert_allclose(stand_in.quat, real.quat, atol=1e-12)
    np.testing.assert_allclose(stand_in.ang_vel, real.ang_vel, atol=1e-12)
    np.testing.assert_allclose(stand_in.lin_acc, real.lin_acc, atol=1e-12)
    assert stand_in.lin_acc[2] == pytest.approx(GRAVITY)  # +9.81 up at rest, like the simulated accelerometer
