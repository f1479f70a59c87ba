"""The youBot case study: a dummy driver task, SCA proxy, Locomotor and Monitor."""

from .driver import YouBotDriver
from .model import ERROR_BITS, JointStatus, YouBotStatus

__all__ = ["YouBotDriver", "YouBotStatus", "JointStatus", "ERROR_BITS"]
