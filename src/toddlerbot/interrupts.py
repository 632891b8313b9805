"""Stop signals remembered as well as raised.

The KeyboardInterrupt a signal raises can be swallowed by code that catches too much: measured, a SIGINT sent
while ``toddlerbot.cli.main`` was being imported was lost in 1 of 30 tries, inside a third-party import (cma's
``except ImportError`` around a matplotlib import that the interrupt had broken). The CLI therefore installs
`raise_and_remember` for SIGINT before importing anything heavy, and the hardware driver asks `take` whether a
stop arrived that nobody acted on before it powers any motor.
"""

from __future__ import annotations

import signal

_unhandled: list[int] = []


def raise_and_remember(signum: int, frame: object) -> None:
    """Signal handler: remember the signal, then raise KeyboardInterrupt as Python's default handler does."""
    _unhandled.append(signum)
    raise KeyboardInterrupt(signal.Signals(signum).name)


def take() -> int | None:
    """The first remembered stop signal (None if none), forgetting all of them."""
    first = _unhandled[0] if _unhandled else None
    _unhandled.clear()
    return first


def install_for_sigint() -> None:
    """Make SIGINT remember itself, where Python's default handler is in place (an ignored SIGINT stays ignored)."""
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, raise_and_remember)
