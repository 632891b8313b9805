"""The wagon grasp as a task: `manip demo --task wagon` (the chain's scripted grasp as demonstrator) and
`dp eval --task wagon` with the shipped checkpoint (success: the wagon chain's `grasped` check)."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("av")
pytest.importorskip("pyarrow")

from typer.testing import CliRunner  # noqa: E402

from toddlerbot.cli.main import app  # noqa: E402
from toddlerbot.dp import evaluate as dp_evaluate  # noqa: E402
from toddlerbot.dp import shipped  # noqa: E402
from toddlerbot.errors import ToddlerbotError  # noqa: E402

runner = CliRunner()
HANDLE = "wagon_handle"


@pytest.mark.slow
def test_a_wagon_demonstration_closes_both_hands_on_the_handle_and_is_written(tmp_path):
    from toddlerbot.datasets.episode import RawEpisode
    from toddlerbot.robot.description import RobotDescription

    out = tmp_path / "ds"
    result = runner.invoke(app, ["manip", "demo", "--task", "wagon", "--episodes", "1", "--seed", "4242",
                                 "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "1 episodes (seeds 4242..4242, 0 failed" in result.output
    info = json.loads((out / "meta/info.json").read_text())
    # approach 1.5 + reach 1.5 + close 0.8 + hold 0.6 s = 4.4 s at 10 Hz
    assert info["total_episodes"] == 1 and info["total_frames"] == 44 and info["fps"] == 10
    assert info["features"]["observation.images.head"]["shape"][:2] == [96, 96]
    raw = RawEpisode.load(next((out / "raw").glob("episode_*.npz")))
    assert raw.success and raw.seed == 4242 and raw.task == "grasp the wagon handle with both hands"
    description = RobotDescription.load(variant="gripper")
    for side in ("left", "right"):
        motor = description.motor_names.index(f"{side}_gripper_drive")
        lo, hi = description.motor_range[motor]
        closed = (raw.action[:, raw.names.index(f"{side}_gripper_drive")] - lo) / (hi - lo)
        assert closed[0] < 0.05 and closed[-1] == pytest.approx(0.78, abs=1e-6)  # open -> the chain's 0.78


@pytest.mark.slow
def test_dp_eval_wagon_grasps_the_handle_with_the_shipped_checkpoint_on_most_seeds(monkeypatch):
    grips = []
    run_episode = dp_evaluate.run_episode

    def spy(task, *args, **kwargs):
        episode = run_episode(task, *args, **kwargs)
        for _ in range(20):  # then, as the chain's settle skill, 0.4 s on the last targets: the pads finish squeezing
            task.step(task.robot.last_targets)
        grips.append({side: (task.probe.pad_forces(side, HANDLE), task.probe.bar_in_hand(side, HANDLE))
                      for side in ("left", "right")})
        return episode

    monkeypatch.setattr(dp_evaluate, "run_episode", spy)
    # a rate, not one trajectory: the grasp depends on the sampler's noise (19/20 on seeds 1000-1019, 18/20 on
    # 2000-2019; seeds 1000-1002 all succeed here)
    result = runner.invoke(app, ["dp", "eval", "--task", "wagon", "--episodes", "3", "--seed", "1000", "--json"])
    summary = json.loads(result.output[result.output.index("{"):])
    assert summary["task"] == "wagon" and summary["checkpoint"].endswith("wagon.pt")
    assert summary["success_rate"] >= 2 / 3, summary["failed_seeds"]
    assert 0 < summary["inference_ms"] < 500  # 20-35 ms measured on one core; generous for a loaded CI machine
    succeeded = [g for seed, g in zip(range(1000, 1003), grips, strict=True) if seed not in summary["failed_seeds"]]
    # a firm grip on at least one of them: both pads press the handle (14.6-15.4 N measured on seeds 1000 and
    # 1001), the handle within 10 mm of the grasp point and each hand 30 mm or more from the end of its straight
    # part; the check can also pass on a weak grip (seed 1002 here: 1.3 and 2.2 N), as the docs say
    firm = [all(forces.min() > 8.0 and in_hand.to_end > 0.03 and np.linalg.norm(in_hand.offset) < 0.01
                for forces, in_hand in grip.values()) for grip in succeeded]
    assert any(firm), grips


def test_the_shipped_wagon_checkpoint_fits_the_wagon_task_and_is_small():
    from toddlerbot.dp.checkpoint import load_policy
    from toddlerbot.tasks import make_task

    path = shipped.shipped_checkpoint("wagon")
    assert path.stat().st_size < 8e6
    config = load_policy(path).config
    task = make_task("wagon")
    dp_evaluate.check_fits(config, task)
    spec = (config.image_size, config.policy_hz, config.horizon, config.latency_drop, config.n_action_steps,
            config.train_timesteps, config.inference_steps)
    assert spec == (96, 10, 16, 3, 5, 100, 3)  # pick's recipe
    task.camera.close()


def test_the_shipped_wagon_policy_commands_its_grippers_open_or_at_the_chains_closed_check():
    """The grippers are binary actions: a sampled command is the demonstrations' open or closed value, and closed
    passes the chain's check (0.78 of the range), never 0.77 (a third of the failures before they were)."""
    from toddlerbot.dp.checkpoint import load_policy
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.skills.spec import load_chain

    policy = load_policy(shipped.shipped_checkpoint("wagon"))
    names = ("left_gripper_drive", "right_gripper_drive")
    assert policy.config.binary_actions == names
    description = RobotDescription.load(variant="gripper")
    grasp = load_chain("wagon", tuple(description.groups)).skills[0]
    closed = grasp.until.params.closed_fraction  # the chain's check (0.78), which its demonstrations close to
    assert grasp.params.grip_fraction == closed
    generator = torch.Generator().manual_seed(0)
    state = policy.state_norm.unnormalize(torch.rand(32, 2, policy.config.state_dim, generator=generator) * 2 - 1)
    images = torch.randint(0, 256, (32, 2, 3, 96, 96), dtype=torch.uint8, generator=generator)
    chunk = policy.sample({"observation.state": state, "observation.images.head": images}, generator)
    seen = set()
    for name in names:
        lo, hi = description.motor_range[description.motor_names.index(name)]
        fraction = (chunk[..., policy.config.action_names.index(name)].double() - lo) / (hi - lo)
        ends = torch.where(fraction > 0.5, fraction - closed, fraction)
        assert float(ends.abs().max()) < 1e-6  # open (0) or the chain's closed_fraction, nothing between
        seen |= {round(float(f), 2) for f in fraction.flatten()}
    assert seen == {0.0, round(closed, 2)}  # random inputs give both


@pytest.mark.parametrize("command", [["manip", "demo", "-o", "unused"], ["manip", "demo-rate"], ["dp", "eval"]])
def test_an_unknown_task_is_a_one_line_error_naming_the_tasks(command, tmp_path):
    result = runner.invoke(app, [*command, "--task", "wagn"])
    assert isinstance(result.exception, ToddlerbotError)
    message = str(result.exception)
    assert "\n" not in message and "'wagn'" in message and message.endswith("expected one of pick, wagon")


def test_the_wagon_chain_grasps_by_script_unless_told_to_use_the_shipped_policy_at_the_same_gains():
    from toddlerbot.robot.description import RobotDescription
    from toddlerbot.sim.mujoco_robot import MuJoCoRobot
    from toddlerbot.skills.library import grasp_gains
    from toddlerbot.skills.runner import ChainRunner
    from toddlerbot.skills.spec import load_chain
    from toddlerbot.tasks.probe import SceneProbe
    from toddlerbot.tasks.scenes import scene_model

    description = RobotDescription.load(variant="gripper")
    chain = load_chain("wagon", tuple(description.groups))
    model = scene_model(description, "wagon")
    robot = MuJoCoRobot(description, model=model)

    def grasp_skill(spec):
        return ChainRunner(spec, robot, model, SceneProbe(model, robot.data),
                           lambda: np.zeros((96, 96, 3), np.uint8)).skills[0]

    assert grasp_skill(chain.with_scripted_grasps()).by == "scripted (no checkpoint named)"  # 20/20 chains
    policy = grasp_skill(chain)  # the chain's default: 18/20 chains
    assert policy.by == "dp (wagon.pt)"
    np.testing.assert_array_equal(policy.live.kp, grasp_gains(description, chain.skills[0].params))
    arm = description.groups["arm"]
    np.testing.assert_array_equal(policy.live.kp[arm], 2 * description.default_kp[arm])  # wagon.yaml: arm_kp_scale 2
    policy.close()


@pytest.mark.slow
def test_chain_run_wagon_is_grasped_by_the_policy_and_reports_its_outcome():
    """By default the policy drives the grasp (18/20 chains succeed, so one seed's outcome is not asserted, only
    that the report is the chain's own checks; where it succeeds, walk-rl pushed the wagon about 0.8 m with 14 N
    pads)."""
    result = runner.invoke(app, ["chain", "run", "wagon", "--seed", "1000", "--json"])
    out = json.loads(result.output)
    assert result.exit_code == (0 if out["success"] else 1)
    assert out["grasp_by"] == "dp (wagon.pt)"
    assert out["driven_by"] == {"grasp": "dp (wagon.pt)", "settle": "hold", "push": "walk-rl",
                                "stand": "pose", "open": "pose", "retract": "pose"}  # the last three: back-offs
    assert out["dp"]["grasp"]["failures"] == 0 and out["dp"]["grasp"]["chunks_used"] >= 8
    retries = sum(r["kind"] == "retry" for r in out["recoveries"])
    if out["switch_time_s"] is not None:  # the grasp closed: by its check, before its 6 s timeout (per attempt)
        assert 3.8 <= out["switch_time_s"] <= 6.0 + retries * (0.4 + 1.0 + 6.0)
    if out["success"]:
        assert out["wagon_displacement_m"] >= 0.5
        for grip in out["grip"].values():
            # the pads end 11.5 mm past the grasp point; walk-rl's push slides the handle 6-8.7 mm (walk-zmp's < 4)
            assert grip["min_force_n"] >= 10.0 and grip["slide_mm"] <= 10.0 and grip["to_end_mm"] >= 20.0


@pytest.mark.slow
def test_chain_run_wagon_scripted_grasp_grasps_by_script():
    result = runner.invoke(app, ["chain", "run", "wagon", "--scripted-grasp", "--seed", "0", "--json"])
    out = json.loads(result.output)
    assert result.exit_code == 0 and out["success"] and out["wagon_displacement_m"] >= 0.5
    assert out["grasp_by"] == "scripted (no checkpoint named)" and "dp" not in out
