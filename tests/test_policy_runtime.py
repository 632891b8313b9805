"""Policies, runner, logs, command parsing and bad-input errors."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from toddlerbot.cli.main import app
from toddlerbot.errors import ToddlerbotError
from toddlerbot.policies import make_policy
from toddlerbot.policies.motions import MotionError, builtin_motions, load_motion
from toddlerbot.runtime.commands import CommandError, CommandSchedule
from toddlerbot.runtime.log import RunLog
from toddlerbot.runtime.runner import PolicyError, RunObserver, SimulatedClock, WallClock, run_policy
from toddlerbot.sim.mujoco_robot import MuJoCoRobot


@pytest.fixture(scope="module")
def robot():
    return MuJoCoRobot()


def test_command_schedule_parses_and_holds_values():
    s = CommandSchedule.parse("0:0.1,0,0; 5:0,0,0.3")
    np.testing.assert_array_equal(s(4.99), [0.1, 0, 0])
    np.testing.assert_array_equal(s(7.0), [0, 0, 0.3])


@pytest.mark.parametrize("text", ["0:0.1,0", "abc", "0;0.1,0,0", "1:0,0,0; 0:0,0,0", ""])
def test_malformed_command_is_a_clear_error(text):
    with pytest.raises(CommandError):
        CommandSchedule.parse(text)


def test_stand_holds_30_s_and_log_round_trips(robot, tmp_path):
    res = run_policy(robot, make_policy("stand", robot), CommandSchedule.parse("0:0,0,0"), 30.0)
    assert not res.fell
    assert len(res.log.time) == 1500
    assert res.log.base_pos[-1, 2] > 0.9 * res.log.base_pos[0, 2]
    path = res.log.save(tmp_path / "run.npz")
    back = RunLog.load(path)
    np.testing.assert_array_equal(back.joint_pos, res.log.joint_pos)
    assert back.joint_names == res.log.joint_names


@pytest.mark.parametrize("motion", ["squat", "wave", "look_around"])
def test_each_shipped_motion_completes_without_falling(robot, motion):
    policy = make_policy("replay", robot, motion)
    res = run_policy(robot, policy, lambda t: np.zeros(3), 30.0)
    assert not res.fell
    assert policy.done
    assert res.log.time[-1] == pytest.approx(policy.motion.duration, abs=0.05)
    # the motion was actually performed: the joints reached the keyframes' extremes
    idx = [res.log.joint_names.index(j) for j in policy.motion.joints]
    reached = np.abs(res.log.joint_pos[:, idx] - res.log.joint_pos[0, idx]).max(axis=0)
    wanted = np.abs(policy.motion.poses - policy.motion.poses[0]).max(axis=0)
    assert np.all(reached > 0.5 * wanted)


@pytest.mark.parametrize("name", ["look_around", "squat", "wave"])
def test_each_shipped_motion_starts_and_ends_at_the_home_pose(name, description):
    assert name in builtin_motions()
    motion = load_motion(name, description)
    joint_home = dict(zip(description.joint_names, description.home_joint_pos, strict=True))
    home = np.array([joint_home[j] for j in motion.joints])
    # a replay starts from standing without a jump and hands back a standing robot (keyframes are whole degrees)
    np.testing.assert_allclose(motion.at(0.0), home, atol=np.radians(0.1))
    np.testing.assert_allclose(motion.at(motion.duration), home, atol=np.radians(0.1))
    assert np.abs(motion.poses - home).max() > 0.3  # and moves in between (rad)


def _write(tmp_path, text):
    p = tmp_path / "m.yaml"
    p.write_text(text)
    return str(p)


def test_motion_with_missing_joint_is_rejected(tmp_path, description):
    path = _write(tmp_path, "joints: [neck_yaw, neck_pitch]\nkeyframes:\n - {t: 0, neck_yaw: 0, neck_pitch: 0}\n"
                            " - {t: 1, neck_yaw: 10}\n")
    with pytest.raises(MotionError, match=r"keyframe 1: missing joint.*neck_pitch"):
        load_motion(path, description)


def test_motion_with_out_of_range_angle_is_rejected(tmp_path, description):
    path = _write(tmp_path, "joints: [left_knee]\nkeyframes:\n - {t: 0, left_knee: 0}\n - {t: 1, left_knee: 45}\n")
    with pytest.raises(MotionError, match="left_knee = 45 deg is out of range"):
        load_motion(path, description)


def test_unknown_policy_is_a_clear_error(robot):
    with pytest.raises(ToddlerbotError, match="unknown policy 'fly'"):
        make_policy("fly", robot)


@pytest.mark.parametrize("args,message", [
    (["sim", "run", "--policy", "fly"], "error: unknown policy 'fly'; expected one of "),
    (["sim", "run", "--command", "0:oops"], "error: --command: malformed command '0:oops'; expected "),
])
def test_cli_bad_input_is_one_line_without_traceback(args, message, capsys, monkeypatch):
    import sys

    from toddlerbot.cli import main as cli_main

    monkeypatch.setattr(sys, "argv", ["toddlerbot", *args])
    with pytest.raises(SystemExit) as exc:
        cli_main.main()
    assert exc.value.code == 2
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(message), err
    assert "Traceback" not in out + err


def test_cli_stand_writes_summary_json(tmp_path):
    out = tmp_path / "s.json"
    result = CliRunner().invoke(app, ["sim", "run", "--policy", "stand", "--seconds", "2", "--summary-json", str(out)])
    assert result.exit_code == 0, result.output
    summary = json.loads(out.read_text())
    assert summary["fell"] is False
    assert set(summary["tracking"]) == {"position_m", "lin_vel_mps", "ang_vel_radps"}
    assert np.hypot(*summary["displacement_m"]) < 0.02


def test_sim_run_takes_the_shared_robot_options(tmp_path):
    """`sim run` builds its robot from --spec/--variant/--motor-params like every command: the gripper variant
    stands with its 32 motors; a fixed-base variant is refused in one line (the simulator's robot is floating)."""
    log = tmp_path / "run.npz"
    result = CliRunner().invoke(app, ["sim", "run", "--policy", "stand", "--seconds", "0.5", "--variant", "gripper",
                                      "--log", str(log)])
    assert result.exit_code == 0, result.output
    assert RunLog.load(log).motor_pos.shape == (25, 32)
    refused = CliRunner().invoke(app, ["sim", "run", "--policy", "stand", "--variant", "fixed"])
    assert isinstance(refused.exception, ToddlerbotError)
    assert str(refused.exception) == ("sim run simulates the floating robot; --variant selects a fixed base (use a "
                                      "floating variant: floating, gripper)")


class _CountingStop(RunObserver):
    """Stops the run once it has seen `after` steps; remembers the steps' indices and times."""

    def __init__(self, after: int) -> None:
        self.after, self.indices, self.times, self.started = after, [], [], 0

    def on_start(self, robot, policy, obs) -> None:
        self.started += 1

    def on_step(self, step) -> None:
        self.indices.append(step.index)
        self.times.append(step.next_obs.time)

    @property
    def stop_requested(self) -> bool:
        return len(self.indices) >= self.after


def test_observers_see_every_step_and_can_end_the_run(robot):
    stop = _CountingStop(after=7)
    result = run_policy(robot, make_policy("stand", robot), seconds=1.0, observers=[stop])
    assert stop.started == 1 and stop.indices == list(range(7))
    np.testing.assert_allclose(np.diff(stop.times), robot.control_dt, atol=1e-9)
    assert result.stopped_by == "_CountingStop" and result.completed and not result.fell
    assert result.log.time.size == 7  # the run log is an observer too: one row per step


def test_the_policy_is_closed_on_every_exit_path(robot):
    class Failing(type(make_policy("stand", robot))):
        closed = 0

        def act(self, obs, command):
            if obs.time > 0.05:
                raise RuntimeError("boom")
            return super().act(obs, command)

        def close(self) -> None:
            type(self).closed += 1

    policy = Failing(robot)
    with pytest.raises(PolicyError, match=r"failed at t=0\.060 s: RuntimeError: boom"):
        run_policy(robot, policy, seconds=1.0)
    run_policy(robot, policy, seconds=0.04)
    assert Failing.closed == 2


def test_wall_clock_locks_steps_to_real_time(robot):
    import time

    simulated = run_policy(robot, make_policy("stand", robot), seconds=0.5, clock=SimulatedClock()).log
    started = time.perf_counter()
    wall = run_policy(robot, make_policy("stand", robot), seconds=0.5, clock=WallClock()).log
    assert simulated.time.size == wall.time.size == 25
    assert time.perf_counter() - started >= 0.5  # the 25th step ended no sooner than 0.5 s after the first began


def test_an_option_the_policy_does_not_take_is_refused(robot):
    result = CliRunner().invoke(app, ["sim", "run", "--policy", "stand", "--weights", "walk_rl"])
    assert isinstance(result.exception, ToddlerbotError)
    assert str(result.exception) == "--weights is not an option of policy 'stand'"


def test_any_policy_runs_in_a_task_scene(tmp_path):
    """`--task` puts the run in a task's scene (no policy named in the CLI): here stand on the pick task, whose
    progress observer reports the cube's distance from the ready pose; a policy without a status adds nothing."""
    out = tmp_path / "s.json"
    result = CliRunner().invoke(app, ["sim", "run", "--policy", "stand", "--task", "pick", "--seed", "1000",
                                      "--seconds", "0.5", "--summary-json", str(out)])
    assert result.exit_code == 0, result.output
    summary = json.loads(out.read_text())
    assert summary["task"]["name"] == "pick" and summary["task"]["succeeded"] is False
    assert 0.08 < summary["task"]["start_distance_m"] < 0.12  # the ready pose: about 10 cm from the cube
    assert "stand" not in summary
    refused = CliRunner().invoke(app, ["sim", "run", "--task", "pick", "--control-hz", "25"])
    assert str(refused.exception) == "--task runs at the task's 50 Hz control rate; drop --control-hz"
