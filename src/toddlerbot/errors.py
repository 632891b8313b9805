"""Errors shown to users: each names the file, entry or value at fault and what was expected."""

import reprlib

_QUOTE = reprlib.Repr()  # keyword arguments only from Python 3.12
_QUOTE.maxstring = _QUOTE.maxother = 60
_QUOTE.maxlevel = 2


def quoted(value: object) -> str:
    """``repr(value)`` shortened for a message about a user's file: at most about 60 characters, one line (a file
    that is not what was expected, e.g. /etc/passwd given as a chain, is named, not printed)."""
    return _QUOTE.repr(value)


class ToddlerbotError(Exception):
    """Base class for every error the CLI reports as a one-line message instead of a traceback."""


class SpecError(ToddlerbotError):
    """A robot spec, motor catalogue or variant is malformed or inconsistent."""


class ParamsError(ToddlerbotError):
    """A fitted actuator-parameter file (params.json) is malformed or names an unknown motor."""
