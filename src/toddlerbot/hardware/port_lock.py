"""One process per serial port: an exclusive advisory lock on the device node, taken before the port is opened.

The lock is ``flock(LOCK_EX | LOCK_NB)`` on the device node itself, the lock pyserial's ``exclusive=True`` takes,
so such pyserial users are kept out as well, and two names of one device (``/dev/serial/by-id/...`` and
``/dev/ttyUSB0``) share it. It is held on a descriptor of its own, opened without sending a byte: the SDK closes
and reopens its port while setting the baud rate, which would drop a POSIX record lock. The kernel releases it
when the process ends in any way (SIGKILL included), so no stale lock is ever left behind. The holder's PID is
looked up in /proc/locks (Linux) for the refusal message.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

from toddlerbot.errors import ToddlerbotError

PROC_LOCKS = Path("/proc/locks")


class PortInUseError(ToddlerbotError):
    """Another process holds the serial port."""


def lock_holder(path: str) -> int | None:
    """PID of the process holding a flock on the file at `path` (from /proc/locks), None if unknown."""
    try:
        st = os.stat(path)
        table = PROC_LOCKS.read_text()
    except OSError:
        return None
    # "1: FLOCK  ADVISORY  WRITE 4321 00:1a:3 0 EOF": the PID, then device major:minor (hex) and inode
    inode = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    for line in table.splitlines():
        fields = line.split()
        if len(fields) >= 6 and fields[1] == "FLOCK" and fields[5] == inode and fields[4].isdigit():
            return int(fields[4])
    return None


def _process_name(pid: int) -> str | None:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()[:60] or None
    except OSError:
        return None


class PortLock:
    """The exclusive lock of one serial port; `acquire` raises `PortInUseError` naming the holder's PID."""

    def __init__(self, port: str) -> None:
        self.port = port
        self._fd: int | None = None

    def acquire(self) -> PortLock:
        """Take the lock (an `OSError` if the device cannot be opened at all)."""
        if self._fd is not None:
            return self
        # O_NONBLOCK: a port without carrier detect would otherwise block in open(); O_NOCTTY: never our terminal
        fd = os.open(self.port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise PortInUseError(self._in_use_message()) from None
        except BaseException:
            os.close(fd)
            raise
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing the last descriptor of the lock releases it
            self._fd = None

    def _in_use_message(self) -> str:
        pid = lock_holder(self.port)
        if pid is None:
            return f"{self.port} is in use by another process (another toddlerbot command?); stop it first"
        who = _process_name(pid) or "another toddlerbot command?"
        return f"{self.port} is in use by process {pid} ({who}); stop it first"
