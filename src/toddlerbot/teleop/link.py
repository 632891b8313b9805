"""Leader -> follower messages: msgpack over ZeroMQ PUB/SUB, latest message only (no pickle anywhere).

A message is a msgpack map ``{"seq": int, "t": float, "names": [str], "q": [float], "kind": str}``: a sequence
number that increases by one per message, the sender's wall-clock time (s), and joint values (rad). The
subscriber keeps only the newest message (ZMQ_CONFLATE), drops anything older than what it has already seen,
and reports how long ago (its own monotonic clock) the last new message arrived, so a stalled leader is detected
whatever the two machines' clocks say. By default the sockets bind and connect on localhost only.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from toddlerbot.errors import ToddlerbotError

try:  # the [manip] extra: the CLI loads this module on a core install too
    import msgpack
    import zmq
except ImportError:
    msgpack = zmq = None

DEFAULT_ENDPOINT = "tcp://127.0.0.1:5591"


class LinkError(ToddlerbotError):
    """A malformed message arrived on the teleoperation link."""


def _require_link_packages() -> None:
    if msgpack is None or zmq is None:
        raise ToddlerbotError("the leader-follower link needs pyzmq and msgpack: pip install 'toddlerbot[manip]'")


@dataclass(frozen=True)
class LinkMessage:
    seq: int
    sent_at: float
    """Sender's time.time(), s."""
    names: tuple[str, ...]
    values: np.ndarray
    kind: str = "leader"

    def encode(self) -> bytes:
        _require_link_packages()
        return msgpack.packb({"seq": self.seq, "t": self.sent_at, "names": list(self.names),
                              "q": [float(v) for v in self.values], "kind": self.kind})

    @classmethod
    def decode(cls, payload: bytes) -> LinkMessage:
        _require_link_packages()
        try:
            raw = msgpack.unpackb(payload, raw=False, strict_map_key=True)
            message = cls(int(raw["seq"]), float(raw["t"]), tuple(str(n) for n in raw["names"]),
                          np.asarray(raw["q"], dtype=float), str(raw.get("kind", "leader")))
        except (ValueError, TypeError, KeyError, msgpack.UnpackException) as exc:
            raise LinkError(f"teleop link: malformed message ({type(exc).__name__}: {exc})") from None
        if len(message.names) != len(message.values) or not np.all(np.isfinite(message.values)):
            raise LinkError(f"teleop link: message {message.seq} has {len(message.names)} names, "
                            f"{len(message.values)} values or non-finite values")
        return message


class LinkPublisher:
    """Sends leader readings; every `send` gets the next sequence number."""

    def __init__(self, endpoint: str = DEFAULT_ENDPOINT, context: zmq.Context | None = None) -> None:
        _require_link_packages()
        self._context = context or zmq.Context.instance()
        self.socket = self._context.socket(zmq.PUB)
        self.socket.setsockopt(zmq.CONFLATE, 1)  # a slow link drops old readings, never the newest
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.bind(endpoint)
        self.seq = 0

    def send(self, names: tuple[str, ...], values: np.ndarray, kind: str = "leader") -> LinkMessage:
        message = LinkMessage(self.seq, time.time(), tuple(names), np.asarray(values, dtype=float), kind)
        self.socket.send(message.encode(), zmq.NOBLOCK)
        self.seq += 1
        return message

    def close(self) -> None:
        self.socket.close()


class LinkSubscriber:
    """Receives the newest leader message without blocking."""

    def __init__(self, endpoint: str = DEFAULT_ENDPOINT, context: zmq.Context | None = None) -> None:
        _require_link_packages()
        self._context = context or zmq.Context.instance()
        self.socket = self._context.socket(zmq.SUB)
        self.socket.setsockopt(zmq.CONFLATE, 1)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.setsockopt(zmq.SUBSCRIBE, b"")
        self.socket.connect(endpoint)
        self.latest: LinkMessage | None = None
        self.received_at = -np.inf
        """time.monotonic() when `latest` arrived."""
        self.dropped_out_of_order = 0

    def poll(self) -> LinkMessage | None:
        """Take whatever arrived since the last call; returns the newest message (None before the first)."""
        while True:
            try:
                payload = self.socket.recv(zmq.NOBLOCK)
            except zmq.Again:
                return self.latest
            message = LinkMessage.decode(payload)
            if self.latest is not None and message.seq <= self.latest.seq:
                self.dropped_out_of_order += 1
                continue
            self.latest, self.received_at = message, time.monotonic()

    def age(self, now: float | None = None) -> float:
        """Seconds since the newest message arrived (inf before the first)."""
        return (time.monotonic() if now is None else now) - self.received_at

    def close(self) -> None:
        self.socket.close()
