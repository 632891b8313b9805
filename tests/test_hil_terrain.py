"""`hw emulate --hil --terrain T --terrain-seed S`: the hardware-in-the-loop robot stands on the simulator's seeded
ground (`toddlerbot.sim.terrain`), its fall check measures the torso above the ground under it, and the emulator
reports the ground; without --hil the option is refused in one line."""

import mujoco
import numpy as np
import pytest

from cli_support import one_line_error, run_main
from toddlerbot.hardware.emulator import EmulatedBus
from toddlerbot.hardware.plant import HilPlant, commands
from toddlerbot.hardware.serve import _plant_report
from toddlerbot.sim.ground_truth import FALL_HEIGHT_FRACTION
from toddlerbot.sim.terrain import TERRAIN_GEOM, Ground, parse_terrain

X = 1.0
"""Where the robot is put, m along x: on the second 0.5 m step out from the start square (0.75 < x <= 1.25)."""


def _powered_at(plant: HilPlant, x: float, seconds: float) -> float:
    """Move the plant's robot from home to (x, 0), its soles on the ground there, and hold the home pose with
    torque on for ``seconds``; the ground's height there, m."""
    ground = float(Ground.of(plant.model).height(np.array(x), np.array(0.0)))
    plant.data.qpos[0] = x
    plant.data.qpos[2] += ground
    mujoco.mj_forward(plant.model, plant.data)
    for motor in plant.motors:  # what the driver writes first: hold where you are
        motor.set("goal_position", motor.get("present_position"))
        motor.set("torque_enable", 1)
    _advance(plant, seconds)
    return ground


def _advance(plant: HilPlant, seconds: float) -> None:
    for _ in range(round(seconds / plant.model.opt.timestep / 10)):
        plant.advance(commands(plant.motors, plant.params), 10)


def _torso_z(plant: HilPlant, description) -> float:
    return float(plant.data.xpos[plant.model.body(description.handles.torso).id, 2])


@pytest.mark.parametrize("step", [0.1, -0.1])
def test_the_hil_robot_stands_on_the_terrain_with_its_feet_at_the_ground_there(description, step):
    """Two 0.1 m steps up (or down) from the start, the HIL robot holding its home pose has both feet on the step,
    0.2 m above (below) the start, its torso as high above that step as at home, and is not fallen; 0.2 m down,
    its torso's z is below the flat-floor fall height."""
    plant = EmulatedBus(description, hil=True, terrain=parse_terrain(f"stairs:height={step},depth=0.5")).plant
    home_feet = plant.data.site_xpos[[plant.model.site(s).id for s in description.handles.feet_sites], 2].copy()
    ground = _powered_at(plant, X, 1.0)
    assert ground == pytest.approx(2 * step)
    feet = plant.data.site_xpos[[plant.model.site(s).id for s in description.handles.feet_sites], 2]
    np.testing.assert_allclose(feet - home_feet, ground, atol=0.003)  # both soles on the step, not sunk into it
    touching = {g for pair in plant.data.contact.geom[:plant.data.ncon].tolist() for g in pair}
    assert plant.model.geom(TERRAIN_GEOM).id in touching and plant.model.geom("floor").id not in touching
    assert plant.torso_height() == pytest.approx(_torso_z(plant, description) - ground, abs=1e-6)
    assert plant.torso_height() > 0.95 * plant.standing_height and not plant.fallen
    if step < 0:  # a fall by the torso's z above z = 0, which the flat floor's check would have reported
        assert _torso_z(plant, description) < FALL_HEIGHT_FRACTION * plant.standing_height
    assert _plant_report(plant)["ground"] == f"stairs:height={step:g},depth=0.5 (seed 0)"


def test_the_hil_robot_collapsed_on_a_raised_step_has_fallen(description):
    """Torque off on the step 0.2 m up, the robot collapses onto it: its torso is less than 0.6 x its standing height
    above the step, a fall, though its z is still above that height over z = 0."""
    plant = EmulatedBus(description, hil=True, terrain=parse_terrain("stairs:height=0.1,depth=0.5")).plant
    ground = _powered_at(plant, X, 0.2)
    assert not plant.fallen
    for motor in plant.motors:
        motor.set("torque_enable", 0)
    _advance(plant, 2.0)
    threshold = FALL_HEIGHT_FRACTION * plant.standing_height
    assert plant.fallen and plant.torso_height() < threshold < _torso_z(plant, description)
    assert float(Ground.of(plant.model).height(*plant.torso_planar_pose()[0])) == pytest.approx(ground)  # still on it


def test_the_flat_floor_stays_the_descriptions_own_model(description):
    plant = EmulatedBus(description, hil=True).plant
    assert plant.model is description.model("floating", scene=True) and plant.ground == "flat"


def test_terrain_without_hil_is_refused_in_one_line(monkeypatch, capsys):
    code, out, err = run_main(monkeypatch, capsys, "hw", "emulate", "--terrain", "rough:height=0.01")
    assert "--terrain rough:height=0.01,cell=0.1: the ground is the simulated robot's: it needs --hil" \
        in one_line_error(code, err)
    assert out == ""  # no device path: nothing served
    code, _, err = run_main(monkeypatch, capsys, "hw", "emulate", "--hil", "--terrain", "rough:height=0.5")
    assert "--terrain 'rough:height=0.5': height=0.5: expected 0 to 0.1 m" in one_line_error(code, err)
