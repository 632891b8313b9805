"""Excitation profiles for identification: goal-position trajectories (motor rad) and the firmware kp values each
is run with (one run per kp value).

* ``chirp``: exponential sweep ``f_start`` -> ``f_end`` Hz; amplitude decays as (f_start / f)^0.5, so the peak
  speed grows only with sqrt(f) and the fast end still stays within the motor's speed range.
* ``steps``: a staircase of steps of growing size, alternating in sign, 0.6 s each.
* ``sinusoids``: constant-frequency segments at 0.5, 1, 2 and 4 Hz.
* ``lift_and_drop``: a slow ramp up (lifting a load against gravity on a pendulum), a hold, then the goal jumps
  back (drop) and holds; repeated twice.
* ``fast_steps``: full-swing steps between -2 and +2 x amplitude, 0.4 s each: the torque saturates and the shaft
  runs well past ``q_dot_tau_max`` (on the XC330 pendulum of the docs to 9-13 rad/s, beyond ``q_dot_max``), which
  is what pins the speed curve (``q_dot_tau_max``, ``q_dot_max``, ``tau_q_dot_max``) and passive damping.
* ``drop``: a ramp to 2 x amplitude over the first 30 %, a hold, then torque OFF from half-time to the end: the
  pendulum falls and swings out passively, which isolates the passive friction loss, damping, static friction and
  armature from the controller (the only profile with a ``torque_enable`` schedule).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from toddlerbot.sysid.errors import SysIDError

DEFAULT_KP = (400, 900, 1500, 2100)
SAMPLE_HZ = 200.0
"""Sample rate of the excitation profiles and of a recording, Hz (the real servo logs' 200 Hz)."""
"""Firmware P gains to cycle through (the robot's motors run at 350-2700)."""


def chirp(t: np.ndarray, duration: float, amplitude: float, f_start: float = 0.1, f_end: float = 10.0) -> np.ndarray:
    rate = np.log(f_end / f_start) / duration
    freq = f_start * np.exp(rate * t)
    phase = 2.0 * np.pi * f_start * (np.exp(rate * t) - 1.0) / rate
    return amplitude * np.sqrt(f_start / freq) * np.sin(phase)


def steps(t: np.ndarray, duration: float, amplitude: float, hold: float = 0.6) -> np.ndarray:
    index = np.floor(t / hold).astype(int)
    n = int(np.ceil(duration / hold))
    sizes = np.linspace(0.25, 1.0, max(n, 1)) * amplitude * np.where(np.arange(max(n, 1)) % 2 == 0, 1.0, -1.0)
    out = sizes[np.clip(index, 0, len(sizes) - 1)]
    return np.where(index == 0, 0.0, out)


def sinusoids(t: np.ndarray, duration: float, amplitude: float,
              freqs: tuple[float, ...] = (0.5, 1, 2, 4)) -> np.ndarray:
    segment = np.clip((t / duration * len(freqs)).astype(int), 0, len(freqs) - 1)
    f = np.asarray(freqs, float)[segment]
    start = segment * duration / len(freqs)
    return amplitude * np.sin(2.0 * np.pi * f * (t - start))


def lift_and_drop(t: np.ndarray, duration: float, amplitude: float) -> np.ndarray:
    cycle = duration / 2.0
    phase = (t % cycle) / cycle
    lift = np.clip(phase / 0.5, 0.0, 1.0)  # ramp over the first half, hold until 0.7, drop, hold
    return amplitude * np.where(phase < 0.7, lift, 0.0)


def fast_steps(t: np.ndarray, duration: float, amplitude: float, hold: float = 0.4) -> np.ndarray:
    index = np.floor(t / hold).astype(int)
    return np.where(index == 0, 0.0, np.where(index % 2 == 1, 2.0 * amplitude, -2.0 * amplitude))


def drop(t: np.ndarray, duration: float, amplitude: float) -> np.ndarray:
    return 2.0 * amplitude * np.clip(t / (0.3 * duration), 0.0, 1.0)


def drop_torque_enable(t: np.ndarray, duration: float) -> np.ndarray:
    """1 (powered) for the first half of the run, 0 (torque off) after."""
    return (t < 0.5 * duration).astype(float)


PROFILES: dict[str, Callable[[np.ndarray, float, float], np.ndarray]] = {
    "chirp": chirp, "steps": steps, "sinusoids": sinusoids, "lift_and_drop": lift_and_drop,
    "fast_steps": fast_steps, "drop": drop,
}
TORQUE_SCHEDULES: dict[str, Callable[[np.ndarray, float], np.ndarray]] = {"drop": drop_torque_enable}
"""Profiles that switch torque off: name -> torque_enable (0/1) over time."""
DEFAULT_PROFILES = ("chirp", "steps", "sinusoids", "lift_and_drop", "fast_steps")
"""What ``sysid excite`` writes by default (``drop`` only on request: it needs a rig where falling is safe)."""


@dataclass(frozen=True)
class Excitation:
    profile: str
    kp: int
    time: np.ndarray
    """s, from 0."""
    goal_position: np.ndarray
    """rad."""
    torque_enable: np.ndarray | None = None
    """0/1 per sample (None: powered throughout)."""

    @property
    def name(self) -> str:
        return f"{self.profile}_kp{self.kp}"


def excitation(profile: str, duration: float = 6.0, rate: float = SAMPLE_HZ, amplitude: float = 0.5,
               center: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(time s, goal position rad) of one profile sampled at ``rate`` Hz around ``center`` rad."""
    if profile not in PROFILES:
        raise SysIDError(f"unknown excitation profile {profile!r}; expected one of {', '.join(PROFILES)}")
    if duration <= 0 or rate <= 0:
        raise SysIDError(f"duration and rate must be > 0, got {duration} s at {rate} Hz")
    t = np.arange(round(duration * rate) + 1) / rate
    return t, center + PROFILES[profile](t, duration, amplitude)


def excitation_set(profiles: tuple[str, ...] = DEFAULT_PROFILES, kp_values: tuple[int, ...] = DEFAULT_KP,
                   duration: float = 6.0, rate: float = SAMPLE_HZ, amplitude: float = 0.5,
                   center: float = 0.0) -> list[Excitation]:
    """Every profile at every kp value."""
    out = []
    for profile in profiles:
        t, goal = excitation(profile, duration, rate, amplitude, center)
        enable = TORQUE_SCHEDULES[profile](t, duration) if profile in TORQUE_SCHEDULES else None
        out += [Excitation(profile, int(kp), t, goal, enable) for kp in kp_values]
    return out
