"""A node's log on ``/rosout`` and its logger services, as every rospy node has them.

:class:`Rosout` is a ``logging.Handler`` on the root logger: each record that reaches it
is published on ``/rosout`` (``rosgraph_msgs/Log``, latched, as rospy does) with the
node's name, level, message, file, function, line and the topics the node publishes, so
``rostopic echo /rosout`` and ``rqt_console`` show it. It also serves ``~get_loggers``
(``roscpp/GetLoggers``: every Python logger and its level) and ``~set_logger_level``
(``roscpp/SetLoggerLevel``: ``debug``, ``info``, ``warn``, ``error``, ``fatal``), which
change what a logger publishes (only loggers that exist: a caller cannot make new ones).

Installing it makes the root logger's level INFO when it was Python's default (WARNING),
as rospy publishes INFO and above, and keeps the standard error where it was: Python's
last-resort handler (WARNING and above) is added to a root logger that had no handler.
:meth:`Rosout.close` undoes both. A record logged while publishing one is dropped (no
loop); the handler never blocks (the publisher queues).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from .node import Node

__all__ = ["LEVELS", "Rosout"]

#: ROS's names of Python's levels (rosgraph_msgs/Log and roscpp's logger services).
LEVELS = {"debug": logging.DEBUG, "info": logging.INFO, "warn": logging.WARNING, "error": logging.ERROR,
          "fatal": logging.CRITICAL}
_BYTES = {logging.DEBUG: 1, logging.INFO: 2, logging.WARNING: 4, logging.ERROR: 8, logging.CRITICAL: 16}
MAX_TEXT = 64 * 1024  #: characters of a message published, at most
MAX_LOGGERS = 1000  #: loggers get_loggers lists, at most


def _byte(level: int) -> int:
    return next((b for lvl, b in sorted(_BYTES.items(), reverse=True) if level >= lvl), 1)


def _name(level: int) -> str:
    return next((n for n, lvl in sorted(LEVELS.items(), key=lambda kv: -kv[1]) if level >= lvl), "debug")


class Rosout(logging.Handler):
    """``node``'s log on ``/rosout`` and its logger services (see the module docstring).
    ``now_ns()`` gives the stamps (the node's clock). Made installed; thread-safe."""

    def __init__(self, node: Node, now_ns: Callable[[], int] = time.time_ns) -> None:
        super().__init__(logging.DEBUG)
        self.node, self._now_ns = node, now_ns
        self._busy = threading.local()
        self._pub = node.advertise("/rosout", "rosgraph_msgs/Log", latch=True, queue_size=100)
        self._services = [
            node.advertise_service("~get_loggers", "roscpp/GetLoggers", self._get_loggers),
            node.advertise_service("~set_logger_level", "roscpp/SetLoggerLevel", self._set_logger_level),
        ]
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
            t_ns = self._now_ns()
            msg = self._pub.type.new(
                header={"stamp": {"sec": t_ns // 1_000_000_000, "nanosec": t_ns % 1_000_000_000}},
                level=_byte(record.levelno), name=self.node.caller_id, msg=record.getMessage()[:MAX_TEXT],
                file=record.pathname[:1024], function=record.funcName[:256], line=max(0, record.lineno),
                topics=[topic for topic, _ in self.node.publications()])
            self._pub.publish(msg)
        except Exception:  # noqa: BLE001 - a log record never raises into the code that logs
            self.handleError(record)
        finally:
            self._busy.on = False

    # -- the services (the node's service thread) -----------------------------------------
    def _get_loggers(self, _request: Any) -> Any:
        srv = self.node.types.srv("roscpp/GetLoggers")
        logger_type = self.node.types.msg("roscpp/Logger")
        named = sorted((n, lg) for n, lg in logging.Logger.manager.loggerDict.items() if isinstance(lg, logging.Logger))
        loggers = [("root", logging.getLogger()), *named][:MAX_LOGGERS]
        return srv.response.new(loggers=[logger_type.new(name=name, level=_name(lg.getEffectiveLevel()))
                                         for name, lg in loggers])

    def _set_logger_level(self, request: Any) -> Any:
        level = LEVELS.get(str(request.level).lower())
        if level is None:
            raise ValueError(f"no level {request.level!r}: one of {', '.join(LEVELS)}")
        name = str(request.logger)
        if name in ("", "root"):
            logger = logging.getLogger()
        elif isinstance(logging.Logger.manager.loggerDict.get(name), logging.Logger):
            logger = logging.getLogger(name)
        else:
            raise ValueError(f"no logger {name[:200]!r} (get_loggers lists them)")
        logger.setLevel(level)
        return self.node.types.srv("roscpp/SetLoggerLevel").response.new()

    def close(self) -> None:
        """Leave the root logger as it was found, withdraw /rosout and the services
        (idempotent)."""
        root = logging.getLogger()
        if self not in root.handlers:
            return
        root.removeHandler(self)
        if self._last_resort is not None:
            root.removeHandler(self._last_resort)
        if self._raised and root.level == logging.INFO:
            root.setLevel(logging.WARNING)
        for service in self._services:
            service.close()
        self._pub.close()
        super().close()
