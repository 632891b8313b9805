import fcntl
import os
import tempfile
from pathlib import Path

import mujoco
import numpy as np
import pytest

from toddlerbot.actuation.catalogue import default_catalogue
from toddlerbot.actuation.model import actuator_arrays, motor_torque
from toddlerbot.robot.builder import build_model
from toddlerbot.robot.description import RobotDescription
from toddlerbot.robot.spec import load_spec


@pytest.fixture(autouse=True)
def _realtime_runs_alone(request):
    """With pytest-xdist's workers (the default, `pyproject.toml`), a test marked `realtime` (an emulator or a
    browser that must keep wall-clock time) holds an exclusive lock and every other test a shared one, so no
    simulation on another worker competes with it for the cores."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if run is None:
        yield
        return
    exclusive = request.node.get_closest_marker("realtime") is not None
    with open(Path(tempfile.gettempdir()) / f"toddlerbot-tests-{run}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


@pytest.fixture(scope="session")
def spec():
    return load_spec()


@pytest.fixture(scope="session")
def description(spec):
    """The packaged robot's description, shared by the session (its derived objects are built once)."""
    return RobotDescription(spec)


@pytest.fixture(scope="session")
def gripper_spec():
    return load_spec(variant="gripper")


class MotorPD:
    """Holds motor targets with the actuator model, as the firmware would (test helper)."""

    def __init__(self, model: mujoco.MjModel, spec) -> None:
        motors = spec.motors_by_id
        catalogue = default_catalogue()
        self.params = actuator_arrays([catalogue[m.model].actuator for m in motors], [m.kp for m in motors],
                                      [m.kd for m in motors])
        self.qadr = np.array([model.joint(m.joint).qposadr[0] for m in motors])
        self.vadr = np.array([model.joint(m.joint).dofadr[0] for m in motors])

    def apply(self, data: mujoco.MjData, targets: np.ndarray) -> None:
        data.ctrl[:] = motor_torque(targets, data.qpos[self.qadr], data.qvel[self.vadr], self.params)


@pytest.fixture(scope="session")
def fixed_model(spec):
    return build_model(spec, "fixed")


@pytest.fixture
def restored_registries(monkeypatch):
    """Policies and variants a test registers last only for that test (installed plugins are read first, so they are
    kept and not read twice)."""
    from toddlerbot.policies import POLICY_REGISTRY
    from toddlerbot.robot.description import VARIANT_REGISTRY

    for registry in (POLICY_REGISTRY, VARIANT_REGISTRY):
        registry.names()
        monkeypatch.setattr(registry, "_targets", dict(registry._targets))
        monkeypatch.setattr(registry, "_resolved", dict(registry._resolved))
