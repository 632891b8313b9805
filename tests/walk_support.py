"""Trials of a shipped walking policy under the robustness benchmark's kicks, for the tests of shipped policies."""

from toddlerbot.policies import make_policy
from toddlerbot.robot.description import RobotDescription
from toddlerbot.runtime.robustness import conditions, reach_commands, run_trial
from toddlerbot.sim.mujoco_robot import MuJoCoRobot


def kick_trials(weights, condition: str, commands: slice, seeds=(0, 1), seconds: float = 8.0):
    """`run_trial` of walk-rl with ``weights`` under the named condition, for the ``commands`` slice of the
    policy's reach (`reach_commands`) x ``seeds``."""
    description = RobotDescription.load()
    kicks = {c.name: c for c in conditions()}[condition]
    reach = make_policy("walk-rl", MuJoCoRobot(description), weights=weights).command_reach
    return [run_trial(description, lambda robot: make_policy("walk-rl", robot, weights=weights), command, kicks,
                      seed, seconds) for command in reach_commands(reach)[commands] for seed in seeds]
