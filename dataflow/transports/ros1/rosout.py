"""A node's log on ``/rosout`` and its logger services, as every rospy node has them.

:class:`Rosout` publishes each Python log record reaching the root logger on ``/rosout``
(``rosgraph_msgs/Log``, latched, as rospy does) with the node's name, level, message,
file, function, line and the topics the node publishes, so ``rostopic echo /rosout`` and
``rqt_console`` show it (:class:`~dataflow.transports._roslog.RosLog` installs it: the
root logger at INFO, the standard error kept). It also serves ``~get_loggers``
(``roscpp/GetLoggers``: every Python logger and its level) and ``~set_logger_level``
(``roscpp/SetLoggerLevel``: ``debug``, ``info``, ``warn``, ``error``, ``fatal``), which
change what a logger publishes (only loggers that exist: a caller cannot make new ones).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from .._roslog import MAX_TEXT, RosLog, loggers, set_level
from scart_ros1.node import Node

__all__ = ["Rosout"]

_BYTES = ((logging.CRITICAL, 16), (logging.ERROR, 8), (logging.WARNING, 4), (logging.INFO, 2))


class Rosout:
    """``node``'s log on ``/rosout`` and, with ``services``, its logger services (see the
    module docstring). ``now_ns()`` gives the stamps (the node's clock). Installed when made; thread-safe;
    :meth:`close` is idempotent. Raises ``ValueError`` when the node publishes ``/rosout``
    or serves a logger service already."""

    def __init__(self, node: Node, now_ns: Callable[[], int] = time.time_ns, services: bool = True) -> None:
        self.node, self._now_ns = node, now_ns
        self._pub = node.advertise("/rosout", "rosgraph_msgs/Log", latch=True, queue_size=100)
        self._services = []
        try:
            if services:
                self._services.append(node.advertise_service("~get_loggers", "roscpp/GetLoggers", self._get_loggers))
                self._services.append(node.advertise_service("~set_logger_level", "roscpp/SetLoggerLevel",
                                                             self._set_logger_level))
        except BaseException:
            self.close()
            raise
        self._log = RosLog(self._publish)

    def _publish(self, record: logging.LogRecord) -> None:
        t_ns = self._now_ns()
        self._pub.publish(self._pub.type.new(
            header={"stamp": {"sec": t_ns // 1_000_000_000, "nanosec": t_ns % 1_000_000_000}},
            level=next((b for lvl, b in _BYTES if record.levelno >= lvl), 1), name=self.node.caller_id,
            msg=record.getMessage()[:MAX_TEXT], file=record.pathname[:1024], function=record.funcName[:256],
            line=max(0, record.lineno), topics=[topic for topic, _ in self.node.publications()]))

    # -- the services (the node's service thread) -----------------------------------------
    def _get_loggers(self, _request: object) -> object:
        logger = self.node.types.msg("roscpp/Logger")
        return self.node.types.srv("roscpp/GetLoggers").response.new(
            loggers=[logger.new(name=name, level=level) for name, level in loggers()])

    def _set_logger_level(self, request: Any) -> Any:
        set_level(str(request.logger), str(request.level))
        return self.node.types.srv("roscpp/SetLoggerLevel").response.new()

    def close(self) -> None:
        """Leave the root logger as it was found, withdraw /rosout and the services
        (idempotent)."""
        log = getattr(self, "_log", None)
        if log is not None:
            log.close()
        for service in self._services:
            service.close()
        self._pub.close()
