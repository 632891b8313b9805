"""Simulated manipulation tasks, found by name in `TASKS`: each a `tasks.base.Task` subclass that carries its whole
bundle (scene, reset, success check, head camera, demonstrator, teleop robot, chain start). ``pick`` (lift a cube,
`tasks.pick`) is registered here; ``wagon`` (grasp the wagon handle, the wagon chain's grasp phase, built on the
chain's skills in `skills.wagon`) through the package's own entry point (pyproject.toml), so that nothing here
names a higher layer. Factories are imported on first use, so listing names imports no task."""

from __future__ import annotations

from toddlerbot.errors import ToddlerbotError
from toddlerbot.registry import Registry
from toddlerbot.robot.description import GRIPPER, RobotDescription

TASKS = Registry("task", entry_point_group="toddlerbot.tasks")
"""Task name -> a `tasks.base.Task` subclass (or factory) taking an optional description; installed packages add
names through the entry-point group ``toddlerbot.tasks``."""
TASKS.register("pick", "toddlerbot.tasks.pick:PickTask")


def task_description(description: RobotDescription | None = None) -> RobotDescription:
    """`description` as the gripper variant every task is built for (default: the packaged robot's)."""
    if description is None:
        return RobotDescription.load(variant=GRIPPER)
    return description if description.spec.variant == GRIPPER else description.with_variant(GRIPPER)


def task_name(spec: str) -> str:
    """The task's name in ``NAME`` or ``NAME:VARIATION``."""
    return spec.partition(":")[0]


def make_task(spec: str, description: RobotDescription | None = None, variation: str = "default"):
    """The task registered as ``NAME`` (or ``NAME:VARIATION``), on `description` as its gripper variant (default:
    the packaged robot's), in one of its declared scene variations (`Task.variations`)."""
    name, _, named = spec.partition(":")
    variation = named or variation
    factory = TASKS.get(name)
    known = getattr(factory, "variations", ("default",))
    if variation not in known:
        raise ToddlerbotError(f"task {name!r} has no scene variation {variation!r}; expected one of {', '.join(known)}")
    if variation == "default":
        return factory(task_description(description))
    return factory(task_description(description), variation=variation)
