"""Simulated manipulation tasks (scenes, success checks, head camera, scripted demonstrators, demonstration
recording), found by name in `TASKS`: ``pick`` (lift a cube, `tasks.pick`) and ``wagon`` (grasp the wagon handle,
the wagon chain's grasp phase, `skills.wagon`). Factories are imported on first use, so listing names imports
no task."""

from __future__ import annotations

from typing import TYPE_CHECKING

from toddlerbot.registry import Registry

if TYPE_CHECKING:
    from toddlerbot.robot.description import RobotDescription

TASKS = Registry("task", entry_point_group="toddlerbot.tasks")
"""Task name -> a `tasks.base.Task` subclass (or factory) taking an optional description; installed packages add
names through the entry-point group ``toddlerbot.tasks``."""
TASKS.register("pick", "toddlerbot.tasks.pick:PickTask")
TASKS.register("wagon", "toddlerbot.skills.wagon:WagonTask")


def make_task(name: str, description: RobotDescription | None = None):
    """The task registered as `name`, on `description` (default: the gripper variant)."""
    return TASKS.get(name)(description)
