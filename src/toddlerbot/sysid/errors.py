"""Errors of the system-identification tools (each names the file and the problem)."""

from toddlerbot.errors import ToddlerbotError


class SysIDError(ToddlerbotError):
    """A log, manifest, rig or parameter file is malformed, missing or inconsistent."""
