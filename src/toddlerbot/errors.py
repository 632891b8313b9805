"""Errors shown to users: each names the file, entry or value at fault and what was expected."""


class ToddlerbotError(Exception):
    """Base class for every error the CLI reports as a one-line message instead of a traceback."""


class SpecError(ToddlerbotError):
    """A robot spec, motor catalogue or variant is malformed or inconsistent."""


class ParamsError(ToddlerbotError):
    """A fitted actuator-parameter file (params.json) is malformed or names an unknown motor."""
