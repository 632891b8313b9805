"""The `toddlerbot` command line: one sub-command group per area."""

from toddlerbot import interrupts

# first, before the heavy imports below: a Ctrl-C that a third-party import swallows must still stop a hardware run
interrupts.install_for_sigint()

from toddlerbot.sim.render import keep_mujoco_importable  # noqa: E402

# before any command module imports MuJoCo: a MUJOCO_GL naming a missing library must not break every command
keep_mujoco_importable()
