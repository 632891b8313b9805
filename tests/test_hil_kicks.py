"""`hw emulate --hil --kick TIME:SPEED[@DEGREES]`: the hardware-in-the-loop robot is pushed at the given powered
times, in directions from its heading (seeded where not given), and the emulator reports each kick."""

import math

import numpy as np
import pytest

from toddlerbot.errors import ToddlerbotError
from toddlerbot.hardware.emulator import EmulatedBus
from toddlerbot.hardware.hil_kicks import Kick, parse_kicks
from toddlerbot.hardware.plant import commands
from toddlerbot.robot.description import RobotDescription


def test_kicks_are_parsed_in_time_order_with_seeded_directions():
    kicks = parse_kicks(["3:1.5", "1:0.5@180"], seed=7)
    assert kicks[0] == Kick(1.0, 0.5, math.pi)
    assert kicks[1].time == 3.0 and kicks[1].speed == 1.5 and 0 <= kicks[1].direction < 2 * math.pi
    assert parse_kicks(["3:1.5"], seed=7)[0].direction == kicks[1].direction  # the seed fixes it
    assert parse_kicks(["3:1.5"], seed=8)[0].direction != kicks[1].direction


@pytest.mark.parametrize(("text", "message"), [
    ("1", r"--kick '1': expected TIME:SPEED or TIME:SPEED@DEGREES"),
    ("1:fast", r"--kick '1:fast': expected TIME:SPEED"),
    ("-1:1", r"--kick '-1:1': expected a time >= 0 s and a speed in \(0, 5\] m/s"),
    ("1:0", r"--kick '1:0': expected a time >= 0 s"),
    ("1:nan", r"--kick '1:nan': expected a time >= 0 s"),
    ("1:1@inf", r"--kick '1:1@inf': expected a time >= 0 s"),
])
def test_a_bad_kick_is_one_line(text, message):
    with pytest.raises(ToddlerbotError, match=message):
        parse_kicks([text])


def test_the_plant_kicks_once_torque_is_on_backwards_from_its_heading():
    description = RobotDescription.load()
    with pytest.raises(ToddlerbotError, match="--kick pushes the simulated robot: it needs --hil"):
        EmulatedBus(description, kicks=parse_kicks(["0:1"]))
    plant = EmulatedBus(description, hil=True, kicks=parse_kicks(["0.01:1.0@180"])).plant
    dt = plant.model.opt.timestep
    plant.advance(commands(plant.motors, plant.params), 20)  # unpowered: the kicks' clock has not started
    assert plant.powered_time == 0.0 and not plant.kicked
    for motor in plant.motors:
        motor.set("torque_enable", 1)
    heading = plant.torso_planar_pose()[1]
    plant.advance(commands(plant.motors, plant.params), 9)
    assert not plant.kicked
    plant.advance(commands(plant.motors, plant.params), 1)
    assert plant.powered_time == pytest.approx(10 * dt)
    (time_s, dvx, dvy), = plant.kicked
    assert time_s == pytest.approx(0.01)
    np.testing.assert_allclose([dvx, dvy], [-np.cos(heading), -np.sin(heading)], atol=0.01)  # it settled a little
    assert plant.data.qvel[0] * np.cos(heading) + plant.data.qvel[1] * np.sin(heading) < -0.9  # moving backwards
    plant.advance(commands(plant.motors, plant.params), 10)
    assert len(plant.kicked) == 1
