"""Teleoperation: controller mapping and SDL input, the leader-follower link, the arm follower and the teleop
session (a policy recording episodes)."""
