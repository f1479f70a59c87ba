"""The errors of the ROS 2 library: one base class, a subclass per kind of problem."""

from __future__ import annotations

__all__ = ["NEEDS_DDS", "Ros2Error", "UnknownTypeError", "ConversionError", "DomainError"]

#: What a user is told when Cyclone DDS (the ``scart[ros2]`` extra) is missing.
NEEDS_DDS = "ROS 2 needs Cyclone DDS: pip install 'scart[ros2]'"


class Ros2Error(Exception):
    """Base of every error this package raises on purpose."""


class UnknownTypeError(Ros2Error, KeyError):
    """A ROS 2 type name that no message definition gives (neither the distro's store nor
    a definition added by the user)."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class ConversionError(Ros2Error, ValueError):
    """A value that cannot become (or come from) the named ROS 2 message type."""


class DomainError(Ros2Error):
    """A domain id or network configuration that cannot be used."""
