"""What every actuator-model parameter set provides (`MotorParams`)."""

from __future__ import annotations

from typing import Protocol


class MotorParams(Protocol):
    """A motor model's parameters, in joint units of the motor's output shaft (`ActuatorParams`: the appendix's
    model; `DCMotorParams`: the DC-motor model). The model builder, the hardware emulator and the summaries use
    the passive terms and the three envelope figures; the actuator model uses `array_fields`."""

    model: str
    # the passive terms every model has (units and meaning: `toddlerbot.actuation.parameters.PASSIVE`)
    damping: float
    armature: float
    frictionloss: float

    @property
    def tau_max(self) -> float:
        """Largest torque from rest, N*m."""

    @property
    def tau_brake(self) -> float:
        """Largest torque the motor applies at all (braking), N*m: the simulator's actuator range."""

    @property
    def q_dot_max(self) -> float:
        """Speed at which the motor runs out of torque to accelerate, rad/s (the hardware slew limit)."""

    def array_fields(self, kp_dynamixel: float, kd_dynamixel: float) -> dict[str, float]:
        """One motor's entries of every `toddlerbot.actuation.model.ActuatorArrays` field at these firmware gains."""

    def replace(self, **changes: float) -> MotorParams:
        """A copy with some fields changed (validated again)."""

