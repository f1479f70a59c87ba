"""Data model of the dummy youBot arm: joint records, the status sample, error bit names."""

from __future__ import annotations

from pydantic import BaseModel, Field

from dataflow import register_type

__all__ = [
    "MIN_PERIOD",
    "MAX_PERIOD",
    "N_JOINTS",
    "ERROR_BITS",
    "ERROR_MASK",
    "JOINT_LIMITS",
    "JointStatus",
    "YouBotStatus",
    "error_names",
]

N_JOINTS = 5

# Bit number → name of the 10-bit per-joint error word (after the youBot motor controller flags).
ERROR_BITS: dict[int, str] = {
    0: "OVER_CURRENT",
    1: "UNDER_VOLTAGE",
    2: "OVER_VOLTAGE",
    3: "OVER_TEMPERATURE",
    4: "MOTOR_HALTED",
    5: "HALL_SENSOR_ERROR",
    6: "ENCODER_ERROR",
    7: "POSITION_LIMIT",
    8: "TIMEOUT",
    9: "I2T_EXCEEDED",
}
ERROR_MASK = (1 << len(ERROR_BITS)) - 1

# Joint position limits in rad (youBot arm, joint 1..5, relative to the candle pose).
JOINT_LIMITS: tuple[tuple[float, float], ...] = (
    (-2.95, 2.95),
    (-1.13, 1.57),
    (-2.63, 2.55),
    (-1.78, 1.78),
    (-2.92, 2.92),
)


def error_names(flags: int) -> list[str]:
    """Names of the bits set in a joint's error word, lowest bit first."""
    return [name for bit, name in ERROR_BITS.items() if flags >> bit & 1]


@register_type("YouBotJointStatus")
class JointStatus(BaseModel):
    """One joint: position [rad], velocity [rad/s], current [A], temperature [°C], error word,
    and the position set-point [rad] it moves toward."""

    position: float = 0.0
    velocity: float = 0.0
    current: float = 0.0
    temperature: float = 25.0
    error_flags: int = Field(default=0, ge=0, le=ERROR_MASK)
    setpoint: float = 0.0


@register_type("YouBotStatus")
class YouBotStatus(BaseModel):
    """One sample of the arm: every joint, when it was taken and its sequence number."""

    joints: list[JointStatus] = Field(default_factory=list)
    timestamp: float = 0.0
    sequence: int = 0

MIN_PERIOD = 0.001
"""Shortest driver period [s] accepted (1 ms: below it the simulation only burns CPU)."""
MAX_PERIOD = 1.0
"""Longest driver period [s] accepted."""
