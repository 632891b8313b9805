"""The compiled substep loop (`toddlerbot.sim.native`): numba's float forms of np.clip and np.where follow numpy,
and the compiled loop steps the robot exactly as the same code run interpreted (numba hidden) does."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from toddlerbot.sim import native

numba = pytest.importorskip("numba")

_RUN = """
import json, sys
import numpy as np
{hide}
from toddlerbot.sim import native
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

robot = MuJoCoRobot(RobotDescription.load())
home = robot.reset().motor_pos
n = len(home)
if {dc_motor}:  # PWM shape, back-EMF and a friction budget: every term of the model
    robot._params = robot._params._replace(pwm_exponent=np.full(n, 0.8), back_emf_damping=np.full(n, 0.03),
                                           stiction=np.full(n, 0.01), load_friction=np.full(n, 0.2))
for k in range({steps}):  # swinging every motor far enough that the drive limit clamps
    robot.step(home + 0.4 * np.sin(0.5 * k + np.arange(n)))
print(json.dumps({{"compiled": native.HAVE_NUMBA, "qpos": robot.data.qpos.tolist(),
                  "torque": robot.observe().motor_torque.tolist()}}))
"""


def _run(hide_numba: bool, dc_motor: bool) -> dict:
    hide = "sys.modules['numba'] = None" if hide_numba else ""
    # With pow and exp in the model, a last-bit difference grows as the swinging robot's contacts come and go: on
    # an AVX-512 machine numpy's vector pow differs from the C library's in the last bit, and after 15 control
    # steps the states were 0.24 apart. So the DC-motor model is compared over its first 3 steps.
    steps = 3 if dc_motor else 15
    out = subprocess.run([sys.executable, "-c", _RUN.format(hide=hide, dc_motor=dc_motor, steps=steps)],
                         capture_output=True,
                         text=True, check=True, timeout=300)
    return json.loads(out.stdout.strip().splitlines()[-1])


_BATCH = """
import copy, json, sys
import numpy as np
{hide}
import mujoco
from toddlerbot.sim import native
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.actuated import BatchArrays, MotorAddresses, step_batch
from toddlerbot.sim.motor_drive import MotorDrive

description = RobotDescription.load()
model = description.model("floating", scene=True)
models, datas = [copy.copy(model) for _ in range(2)], [mujoco.MjData(model) for _ in range(2)]
home = mujoco.MjData(model)
mujoco.mj_resetDataKeyframe(model, home, model.key("home").id)
arrays = BatchArrays.of(models, datas, ("model.dof_damping", "data.qpos"), ("data.qpos", "data.sensordata"))
written = np.concatenate([np.stack([model.dof_damping, 2 * model.dof_damping]), np.tile(home.qpos, (2, 1))], axis=1)
n = len(description.home_motor_pos)
targets = description.home_motor_pos + 0.3 * np.sin(np.arange(2 * n).reshape(2, n))
torques, reads, warned = step_batch(arrays, np.arange(2), MotorAddresses.of(model, description.motor_names), targets,
                                    MotorDrive(description.actuator_arrays()), 5, written, sensors_last_only=True)
print(json.dumps({{"compiled": native.HAVE_NUMBA, "torques": torques.tolist(), "reads": reads.tolist(),
                  "flags": [m.opt.disableflags for m in models], "warned": warned.tolist()}}))
"""


def test_the_batch_step_runs_compiled_as_interpreted():
    """`step_batch` reads and writes MuJoCo's arrays by address: compiled through numba's pointers, interpreted
    (numba hidden) through ctypes, with the same bits."""
    runs = []
    for hide in ("", "sys.modules['numba'] = None"):
        out = subprocess.run([sys.executable, "-c", _BATCH.format(hide=hide)], capture_output=True, text=True,
                             check=True, timeout=300)
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    compiled, interpreted = runs
    assert compiled["compiled"] and not interpreted["compiled"]
    assert np.abs(compiled["torques"]).max() > 0.1 and compiled["warned"] == [False, False]
    assert compiled["reads"][0] != compiled["reads"][1]  # the damping written per robot took effect
    assert compiled == {**interpreted, "compiled": True}


@pytest.mark.parametrize("dc_motor", [False, True], ids=["appendix", "dc_motor"])
def test_compiled_loop_steps_like_the_interpreted_one(dc_motor):
    compiled, interpreted = _run(False, dc_motor), _run(True, dc_motor)
    assert compiled["compiled"] and not interpreted["compiled"]
    assert np.max(np.abs(compiled["torque"])) > 0.3  # the motors really push (some at their drive limit)
    if dc_motor:  # numpy's and the C library's exp and pow may differ in the last bit
        np.testing.assert_allclose(compiled["qpos"], interpreted["qpos"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(compiled["torque"], interpreted["torque"], rtol=0, atol=1e-6)  # stiff: kp x qpos
    else:  # the appendix model has neither: the same operations, the same bits
        assert compiled == {**interpreted, "compiled": True}


def test_compiled_float_clip_and_where_follow_numpy_signed_zeros_included():
    @numba.njit
    def clip_where(a, lo, hi, condition):
        return np.clip(a, lo, hi), np.where(condition, a, lo)

    values = [-np.inf, -2.0, -1.0, -0.0, 0.0, 0.5, 1.0, 2.0, np.inf]
    for a in values:
        for lo in values:
            for hi in values:
                if lo > hi:
                    continue
                got = clip_where(a, lo, hi, a > 0)
                want = (np.clip(np.array([a]), lo, hi)[0], np.where(a > 0, a, lo))
                for g, w in zip(got, want, strict=True):
                    assert g == w and np.signbit(g) == np.signbit(w), (a, lo, hi, got, want)
    assert native.HAVE_NUMBA


def test_stale_cache_folders_are_pruned_to_the_most_recently_used(tmp_path):
    import os

    from toddlerbot.sim.native import prune_stale_caches

    for age in range(12):  # folder k was last used k hours ago
        folder = tmp_path / f"state{age:02d}"
        folder.mkdir()
        (folder / "index.nbi").write_bytes(b"x")
        os.utime(folder, (1e9 - 3600 * age, 1e9 - 3600 * age))
    deleted = prune_stale_caches(str(tmp_path / "state11"), keep=3)  # the current one is the oldest: kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state00", "state01", "state02", "state11"]
    assert len(deleted) == 8
    assert prune_stale_caches(str(tmp_path / "missing" / "x")) == []


_ARENA_TOO_SMALL = """
import sys
{hide}
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

description = RobotDescription.load()
spec = description.mjspec("floating", True)
spec.memory = 100_000  # enough to compile, too little for the contacts of the first steps on the floor
robot = MuJoCoRobot(description, model=spec.compile())
for _ in range(50):
    robot.step(description.home_motor_pos)
print("still running")
"""


@pytest.mark.parametrize("hide_numba", [False, True], ids=["compiled", "interpreted"])
def test_a_fatal_mujoco_error_in_the_substep_loop_is_one_line_and_exit_code_2(hide_numba):
    """MuJoCo cannot go on after an error and no exception passes through compiled code: the process ends as the
    command line ends on an error, one line naming MuJoCo's message, not MuJoCo's exit code 1 (a fall's)."""
    hide = "sys.modules['numba'] = None" if hide_numba else ""
    out = subprocess.run([sys.executable, "-c", _ARENA_TOO_SMALL.format(hide=hide)], capture_output=True, text=True,
                         timeout=300)
    errors = [line for line in out.stderr.splitlines() if line.startswith("error:")]
    assert out.returncode == native.FATAL_EXIT_CODE == 2 and "still running" not in out.stdout
    assert len(errors) == 1 and "Traceback" not in out.stderr, out.stderr
    assert errors[0].startswith("error: MuJoCo stopped the simulation: mj_stackAlloc: out of memory")
    assert "narena = 100000" in errors[0]  # MuJoCo's figures and hint, on the same line


_STAND = """
from toddlerbot.robot.description import RobotDescription
from toddlerbot.sim.mujoco_robot import MuJoCoRobot

robot = MuJoCoRobot(RobotDescription.load())
for _ in range(5):
    robot.step(robot.description.home_motor_pos)
print("height", round(robot.torso_height(), 4))
"""


def test_a_corrupt_compiled_code_cache_is_moved_aside_and_rebuilt(tmp_path):
    """An interrupted first compile or a full disk leaves truncated index and code files: every simulator command
    used to fail with numba's UnpicklingError until the user deleted the cache by hand."""
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    run = lambda: subprocess.run([sys.executable, "-c", _STAND], capture_output=True, text=True, env=env,  # noqa: E731
                                 timeout=300)
    first = run()
    assert first.returncode == 0, first.stderr
    cached = sorted((tmp_path / "toddlerbot" / "numba").rglob("*.nb[ic]"))
    assert len(cached) >= 2  # index and code of the substep loop (and of the drive it calls)
    for path in cached:
        path.write_bytes(path.read_bytes()[:20])
    second = run()
    assert second.returncode == 0, second.stderr
    assert second.stdout == first.stdout  # the same standing robot from the rebuilt code
    warnings = [line for line in second.stderr.splitlines() if "compiled-code cache" in line]
    assert len(warnings) == 1 and warnings[0].startswith("warning: ") and "moved it to" in warnings[0]
    folders = [p.name for p in (tmp_path / "toddlerbot" / "numba").iterdir()]
    assert len(folders) == 2 and sum(".corrupt-" in name for name in folders) == 1
    third = run()
    assert third.returncode == 0 and "compiled-code cache" not in third.stderr  # the rebuilt cache loads
