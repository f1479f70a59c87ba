"""The errors of the ROS 2 library: one base class, a subclass per kind of problem."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping

__all__ = ["NEEDS_DDS", "Ros2Error", "UnknownTypeError", "ConversionError", "DomainError", "lazy_names"]

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


def lazy_names(package: str, where: Mapping[str, str]) -> Callable[[str], object]:
    """A module ``__getattr__`` for ``package``: each public name imported from its module
    (``where[name]``, relative to ``package``) when first asked for, so that importing the
    package imports neither Cyclone DDS nor rosbags; a name that needs a missing Cyclone DDS
    raises ``ImportError(NEEDS_DDS)``. Used by this package and by scart's ``ros2`` adapter."""

    def __getattr__(name: str) -> object:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        try:
            return getattr(importlib.import_module(f"{package}.{module}"), name)
        except ImportError as exc:
            if (exc.name or "").partition(".")[0] == "cyclonedds":
                raise ImportError(NEEDS_DDS) from exc
            raise

    return __getattr__
