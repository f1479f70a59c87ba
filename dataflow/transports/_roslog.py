"""What the ``ros1`` and ``ros2`` transports share to put the process's log on ``/rosout``:
:class:`RosLog`, a ``logging.Handler`` on the root logger handing each record to a
``publish(record)`` of the transport's own (a ``rosgraph_msgs/Log`` or an
``rcl_interfaces/msg/Log``), and the loggers as ROS's logger services see them
(:func:`loggers`, :func:`set_level`; ROS 2's numbered levels, :func:`level_of`,
:func:`set_level_number`). ROS-agnostic: no transport, no message library.

Installing it makes the root logger's level INFO when it was Python's default (WARNING),
as ROS publishes INFO and above, and keeps the standard error as it was: Python's
last-resort handler (WARNING and above) is added to a root logger that had no handler.
:meth:`RosLog.close` undoes both (the last one, when a process has both ROS nodes). A
record logged while one is being published is dropped (no loop); ``publish`` must never
block.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from types import MappingProxyType

__all__ = ["LEVELS", "MAX_TEXT", "RosLog", "level_name", "level_of", "loggers", "set_level", "set_level_number"]

#: ROS's names of Python's levels (roscpp's and rcl's logger services).
LEVELS = MappingProxyType({"debug": logging.DEBUG, "info": logging.INFO, "warn": logging.WARNING,
                           "error": logging.ERROR, "fatal": logging.CRITICAL})
MAX_TEXT = 64 * 1024  #: characters of a message published, at most
MAX_LOGGERS = 1000  #: loggers listed, at most


def level_name(level: int) -> str:
    """ROS's name of the level at or below ``level`` (``debug`` ... ``fatal``)."""
    return next((n for n, lvl in sorted(LEVELS.items(), key=lambda kv: -kv[1]) if level >= lvl), "debug")


def loggers() -> list[tuple[str, str]]:
    """``(name, level)`` of the root logger (``root``) and every logger made, by name."""
    named = sorted((n, lg) for n, lg in logging.Logger.manager.loggerDict.items() if isinstance(lg, logging.Logger))
    return [(name, level_name(lg.getEffectiveLevel())) for name, lg in [("root", logging.getLogger()), *named]][
        :MAX_LOGGERS]


def set_level(name: str, level: str) -> None:
    """Set the level of the logger ``name`` (``root``: the root logger) to ROS's ``level``.
    Only a logger that exists (a caller cannot make new ones); raises ``ValueError``."""
    value = LEVELS.get(str(level).lower())
    if value is None:
        raise ValueError(f"no level {str(level)[:40]!r}: one of {', '.join(LEVELS)}")
    found = _existing(name)
    if found is None:
        raise ValueError(f"no logger {name[:200]!r} (get_loggers lists them)")
    found.setLevel(value)


#: rcutils' severities (ROS 2's ``rcl_interfaces/msg/LoggerLevel``), Python's numbers too;
#: 0 is unset (Python's NOTSET: the logger follows its parent)
LEVEL_NUMBERS = frozenset({logging.NOTSET, logging.DEBUG, logging.INFO, logging.WARNING, logging.ERROR,
                           logging.CRITICAL})


def _existing(name: str) -> logging.Logger | None:
    """The logger ``name`` (``""``/``root``: the root logger) if it exists, else None."""
    if name in ("", "root"):
        return logging.getLogger()
    found = logging.Logger.manager.loggerDict.get(name)
    return found if isinstance(found, logging.Logger) else None


def level_of(name: str) -> int:
    """The level set on the logger ``name`` (``root``: the root logger), as ROS 2 numbers
    them: 0 when none is set or the logger does not exist (rcutils' unset)."""
    found = _existing(name)
    return found.level if found is not None else logging.NOTSET


def set_level_number(name: str, level: int) -> None:
    """Set the level of the logger ``name`` to ROS 2's ``level`` (0 unset, 10 debug ... 50
    fatal). Only a logger that exists; raises ``ValueError`` saying why."""
    if level not in LEVEL_NUMBERS:
        raise ValueError(f"invalid logger level {level}: one of {', '.join(map(str, sorted(LEVEL_NUMBERS)))}")
    found = _existing(name)
    if found is None:
        raise ValueError(f"no logger {name[:200]!r} (only existing loggers can be set)")
    found.setLevel(level)


class RosLog(logging.Handler):
    """Hands every record reaching the root logger to ``publish(record)`` (see the module
    docstring). Installed when made; :meth:`close` (idempotent) uninstalls it."""

    def __init__(self, publish: Callable[[logging.LogRecord], None]) -> None:
        super().__init__(logging.DEBUG)
        self._publish = publish
        self._busy = threading.local()
        root = logging.getLogger()
        self._raised = root.level == logging.WARNING
        self._last_resort = logging.lastResort if not root.handlers and logging.lastResort is not None else None
        if self._raised:
            root.setLevel(logging.INFO)
        if self._last_resort is not None:
            root.addHandler(self._last_resort)
        root.addHandler(self)

    def emit(self, record: logging.LogRecord) -> None:
        if getattr(self._busy, "on", False):
            return  # logged while publishing a record: dropped, no loop
        self._busy.on = True
        try:
            self._publish(record)
        except Exception:  # noqa: BLE001 - a log record never raises into the code that logs
            self.handleError(record)
        finally:
            self._busy.on = False

    def close(self) -> None:
        """Leave the root logger as it was found (idempotent); with another :class:`RosLog`
        still on it (a process with ROS 1 and ROS 2 nodes), that one will."""
        root = logging.getLogger()
        if self in root.handlers:
            root.removeHandler(self)
            heir = next((h for h in root.handlers if isinstance(h, RosLog)), None)
            if heir is not None:
                heir._raised = heir._raised or self._raised
                heir._last_resort = heir._last_resort or self._last_resort
            else:
                if self._last_resort is not None:
                    root.removeHandler(self._last_resort)
                if self._raised and root.level == logging.INFO:
                    root.setLevel(logging.WARNING)
        super().close()
