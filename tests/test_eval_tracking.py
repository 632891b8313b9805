"""Velocity-tracking evaluation: the error definitions on synthetic runs, and `toddlerbot eval tracking` end to end."""

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from toddlerbot.cli.main import app
from toddlerbot.policies.rl_inference import ObsConfig
from toddlerbot.runtime.tracking import evaluate_policy, tracking_errors

DT = 0.02


def _yaw_quat(yaw):
    return np.stack([np.cos(yaw / 2), np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2)], axis=1)


def test_perfect_tracking_scores_zero():
    t = np.arange(0, 10, DT)
    command = np.where(t[:, None] < 5, [0.1, 0.0, 0.0], [0.0, 0.0, 0.3])
    yaw = np.concatenate([[0.0], np.cumsum(command[:-1, 2]) * DT])
    vel = np.stack([np.cos(yaw) * command[:, 0], np.sin(yaw) * command[:, 0]], axis=1)
    pos = np.concatenate([[np.zeros(2)], np.cumsum(vel[:-1] * DT, axis=0)])
    base = np.column_stack([pos, np.full(len(t), 0.3)])
    r = tracking_errors(t, command, base, _yaw_quat(yaw), fell=False)
    assert r.position_m < 1e-9 and r.lin_vel_mps < 1e-9 and r.ang_vel_radps < 1e-9 and r.falls == 0


def test_standing_robot_under_a_walk_command():
    t = np.arange(0, 10, DT)
    command = np.tile([0.1, 0.0, 0.2], (len(t), 1))
    base = np.tile([0.0, 0.0, 0.3], (len(t), 1))
    r = tracking_errors(t, command, base, _yaw_quat(np.zeros(len(t))), fell=True)
    assert r.lin_vel_mps == pytest.approx(0.1, rel=1e-6)
    assert r.ang_vel_radps == pytest.approx(0.2, rel=1e-6)
    assert r.falls == 1
    assert 0.2 < r.position_m < 0.5  # mean distance to a 1 m curved path, well below its 1 m end


def _zero_policy(path):
    """An exported policy whose network outputs exactly zero: it holds the home pose."""
    from toddlerbot.rl.config import EnvConfig
    from toddlerbot.rl.export import write_policy
    from toddlerbot.robot.description import RobotDescription

    obs = ObsConfig(history=2, gait_period=0.72)
    description = RobotDescription.load()
    legs = len(description.groups["leg"])
    n = obs.history * obs.frame_size(description.n_motors, legs)
    arrays = {"layer0_kernel": np.zeros((n, 16), np.float32), "layer0_bias": np.zeros(16, np.float32),
              "layer1_kernel": np.zeros((16, legs), np.float32), "layer1_bias": np.zeros(legs, np.float32),
              "distribution": np.array("normal"), "action_std": np.full(legs, 0.5, np.float32),
              "obs_mean": np.zeros(n, np.float32), "obs_std": np.ones(n, np.float32)}
    return write_policy(path, arrays, EnvConfig(obs=obs), {"ctrl_dt": 0.02}, description)


def test_walk_rl_holding_home_stands_and_tracks_a_zero_command(tmp_path, description):
    r = evaluate_policy(description, "walk-rl", "0:0,0,0", seconds=3.0, weights=_zero_policy(tmp_path / "zero.npz"))
    assert r.falls == 0
    assert r.duration_s == pytest.approx(3.0)
    assert r.position_m < 0.01 and r.lin_vel_mps < 0.01 and r.ang_vel_radps < 0.02


def test_cli_prints_json_and_saves_plot(tmp_path):
    weights = _zero_policy(tmp_path / "zero.npz")
    result = CliRunner().invoke(app, ["eval", "tracking", "--policy", "walk-rl", "--weights", str(weights),
                                      "--commands", "0:0,0,0; 1:0.05,0,0", "--seconds", "2", "--json",
                                      "--plot", str(tmp_path / "track.png")])
    assert result.exit_code == 0, result.output
    metrics = json.loads(result.output)
    assert set(metrics) >= {"position_m", "lin_vel_mps", "ang_vel_radps", "falls"}
    assert metrics["falls"] == 0
    assert (tmp_path / "track.png").stat().st_size > 10_000


@pytest.mark.parametrize("args,message", [
    (["--policy", "dance"],
     "error: --policy: unknown policy 'dance'; expected one of stand, replay, walk-zmp, walk-rl, dp, get-up, "
     "track"),
    (["--policy", "walk-zmp", "--commands", "0:0.1,0"],
     "error: --commands: malformed command '0:0.1,0'; expected 'time: vx,vy,yaw_rate' like '0:0.1,0,0' with time >= 0"),
    (["--policy", "stand"],  # registered, but it ignores velocity commands
     "error: policy 'stand' does not follow velocity commands; tracking needs a walking policy (walk-rl, walk-zmp "
     "or a registered one with a command reach)"),
    (["--policy", "walk-rl", "--weights", "walk_rl_tpu"],  # neither a file nor a shipped policy's name
     "error: walk_rl_tpu: exported policy not found (run `toddlerbot rl export`)"),
])
def test_cli_rejects_unknown_policy_and_bad_commands(args, message, capsys, monkeypatch):
    import sys

    from toddlerbot.cli import main as cli_main

    monkeypatch.setattr(sys, "argv", ["toddlerbot", "eval", "tracking", *args])
    with pytest.raises(SystemExit) as exc:
        cli_main.main()
    assert exc.value.code == 2  # a user error (1 would be a failed evaluation), before anything is simulated
    out, err = capsys.readouterr()
    assert err.strip() == message and out == ""


def test_the_shipped_gpu_policy_by_name_walks_forward_then_turns(description):
    """`--weights walk_rl_gpu` (no such file here) is the GPU run's file shipped beside walk_rl.npz; it walks and
    turns without a fall (measured 0.111 m / 0.029 m/s / 0.031 rad/s on this schedule)."""
    from toddlerbot.policies.walk_rl import DEFAULT_WEIGHTS, resolve_weights

    assert resolve_weights("walk_rl_gpu") == resolve_weights("walk_rl_gpu.npz") == DEFAULT_WEIGHTS.parent / \
        "walk_rl_gpu.npz"
    assert resolve_weights("walk_rl") == DEFAULT_WEIGHTS
    assert resolve_weights("no_such_policy") == Path("no_such_policy")  # left as given: the loader's error names it
    r = evaluate_policy(description, "walk-rl", "0:0.1,0,0; 3:0,0,0.3", seconds=6.0, weights="walk_rl_gpu")
    assert r.falls == 0
    assert r.position_m < 0.2 and r.lin_vel_mps < 0.05 and r.ang_vel_radps < 0.06



def test_eval_tracking_walks_on_a_terrain(tmp_path):
    """`eval tracking --terrain`: the same schedule on a gentle 3 degree slope is walked without a fall and scores
    otherwise than on the flat floor (the ground is under the robot); a bad terrain is one line, and a logged run
    (--log) refuses it."""
    def run(*extra):
        result = CliRunner().invoke(app, ["eval", "tracking", "--policy", "walk-rl", "--commands", "0:0.1,0,0",
                                          "--seconds", "6", "--json", *extra])
        return result

    flat, slope = run(), run("--terrain", "slope:degrees=3", "--terrain-seed", "1")
    assert flat.exit_code == 0 and slope.exit_code == 0, slope.output
    on_flat, on_slope = json.loads(flat.output), json.loads(slope.output)
    assert on_slope["falls"] == 0 and on_slope["position_m"] < 0.1
    assert on_slope["position_m"] != on_flat["position_m"]
    bad = run("--terrain", "slope:degrees=45")
    assert str(bad.exception).startswith("--terrain 'slope:degrees=45': degrees=45: expected -30 to 30 deg")
    logged = CliRunner().invoke(app, ["eval", "tracking", "--log", str(tmp_path / "run.npz"), "--terrain", "flat"])
    assert logged.exit_code != 0 and "--terrain" in str(logged.exception)
