"""The `toddlerbot` command line: one sub-command group per area."""

from toddlerbot.sim.render import keep_mujoco_importable

# before any command module imports MuJoCo: a MUJOCO_GL naming a missing library must not break every command
keep_mujoco_importable()
