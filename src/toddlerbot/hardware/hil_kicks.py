"""Kicks to the hardware-in-the-loop robot (`hw emulate --hil --kick TIME:SPEED[@DEGREES]`): the simulated torso
gets a horizontal velocity change at given times, as a push in the world would, so that what a run does after a
push or a fall (`hw run --on-fall get-up`) is tested through the real driver. Times count simulated seconds from
the moment torque first comes on; a direction is in degrees from the torso's heading (0 forward, 90 to the left,
180 backwards), drawn from the kick seed when not given."""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from toddlerbot.errors import ToddlerbotError

MAX_KICK_SPEED = 5.0
"""m/s; fastest kick (a 1-2 m/s kick knocks the robot over)."""


@dataclass(frozen=True)
class Kick:
    time: float
    """s of powered simulation."""
    speed: float
    """m/s added to the torso's horizontal velocity."""
    direction: float
    """rad from the torso's heading."""


def parse_kicks(items: list[str], seed: int = 0) -> tuple[Kick, ...]:
    """Kicks from ``TIME:SPEED`` or ``TIME:SPEED@DEGREES`` texts, in time order; a missing direction is drawn
    uniformly from `seed`. One line naming the text otherwise."""
    rng = random.Random(seed)
    kicks = []
    for item in items:
        timing, _, rest = item.partition(":")
        speed_text, at, degrees = rest.partition("@")
        try:
            time_s, speed = float(timing), float(speed_text)
            direction = math.radians(float(degrees)) if at else rng.uniform(0.0, 2 * math.pi)
        except ValueError:
            raise ToddlerbotError(f"--kick {item!r}: expected TIME:SPEED or TIME:SPEED@DEGREES (s, m/s, degrees)") \
                from None
        if not (0.0 <= time_s < math.inf and 0.0 < speed <= MAX_KICK_SPEED and math.isfinite(direction)):
            raise ToddlerbotError(f"--kick {item!r}: expected a time >= 0 s and a speed in (0, {MAX_KICK_SPEED:g}] m/s")
        kicks.append(Kick(time_s, speed, direction))
    return tuple(sorted(kicks, key=lambda kick: kick.time))
