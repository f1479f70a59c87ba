"""The process's tasks as its ROS 2 node's own (the ``ros2`` transport's adapter; the
participant knows nothing of tasks), as an rclpy node is seen by ROS 2's tools.

**Parameters.** Each task property is a parameter of the node, ``TASK.PROPERTY`` (a
``/`` in a task's name is a ``.``), served as rclpy serves them, with ``rcl_interfaces``
types, so that ``ros2 param`` works: ``~/get_parameters``, ``~/set_parameters`` (each
value through the property's own check: a refused one answers ``successful: false``
with the reason, and the property keeps its value), ``~/list_parameters``,
``~/describe_parameters`` (type, the property's doc, its range when it has both ends)
and ``~/get_parameter_types``. A value ``ParameterValue`` cannot hold (a model, an
integer beyond 64 bits) is not a parameter. ``use_sim_time`` is one too: true, the
deployers' tasks follow ``/clock`` (:mod:`dataflow.clock`), as on ROS 1; it may be true
from the start (``sim_time``: a launch-time ``_use_sim_time:=true``, or the process's
node options, :meth:`Ros2Transport.configure`).

**Logging.** Python's log records go to ``/rosout`` (``rcl_interfaces/msg/Log``,
transient-local as rcl's) under the node's logger name. The node serves
``~/get_logger_levels`` and ``~/set_logger_levels`` as rclpy does since Iron
(``rcl_interfaces/msg/LoggerLevel``: rcutils' numbers, which are Python's: 0 unset, 10
debug ... 50 fatal) over Python's loggers (existing ones only; the node's own logger
name, or ``""``, is the root logger, which every record passes), which change what a
logger publishes.

**Read-only** (``--ros-read-only``): the parameters are served to be read, every set is
refused (``successful: false``, the property keeps its value), and, as on ROS 1, the
logger services are not offered and ``/clock`` is never followed.

Handlers run on the participant's thread; :meth:`Ros2Citizen.close` ends it all
(idempotent).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from dataflow.clock import WALL, Clock, SimClock
from dataflow.errors import DataflowError

from scart_ros2.params import (LOGGER_SERVICES, MAX_NAMES, ROSOUT, ROSOUT_QOS, ROSOUT_TYPE, SERVICES, SIM_TIME,
                               from_value, log_level, service_type, to_value)
from scart_ros2.qos import QoS, Reliability

if TYPE_CHECKING:
    from dataflow.deployer import Deployer
    from dataflow.task import TaskContext
    from scart_ros2.participant import Participant
    from scart_ros2.endpoints import Publisher, Subscription
    from scart_ros2.services import ServiceServer

from .._roslog import MAX_TEXT, RosLog, level_of, set_level_number

__all__ = ["Ros2Citizen"]

log = logging.getLogger("dataflow.transports.ros2")

class Ros2Citizen:
    """The deployers' tasks (``deployers()``), as ``participant``'s node's own (see the
    module docstring; ``read_only``: every set refused; ``sim_time``: follow ``/clock``
    from the start). Raises what the participant raises when its services cannot be made,
    ``ValueError`` for ``sim_time`` with ``read_only``."""

    def __init__(self, participant: Participant, deployers: Callable[[], list[Deployer]], read_only: bool = False,
                 sim_time: bool = False) -> None:
        if sim_time and read_only:
            raise ValueError("use_sim_time is refused: this process serves ROS read-only (--ros-read-only: /clock "
                             "comes from ROS)")
        graph = participant.node
        assert graph is not None  # a citizen is made only of a participant with its node
        self._participant, self._deployers, self.read_only = participant, deployers, read_only
        base = f"{graph.namespace.rstrip('/')}/{graph.name}"
        self.logger_name = base.strip("/").replace("/", ".")
        self.clock: Clock = WALL
        self._clock_sub: Subscription | None = None
        self._closed = False
        self._parts: list[ServiceServer | Publisher] = []
        services = SERVICES if read_only else {**SERVICES, **LOGGER_SERVICES}
        try:
            for service in services:
                self._parts.append(participant.service(f"{base}/{service}", service_type(service),
                                                       getattr(self, f"_{service}")))
            self._rosout = participant.publisher(ROSOUT, ROSOUT_TYPE, ROSOUT_QOS)
            self._parts.append(self._rosout)
            if sim_time:
                self._follow(True)
        except BaseException:
            self.close()
            raise
        self._log = RosLog(self._publish_log)

    # -- parameters -----------------------------------------------------------------------
    def _params(self) -> dict[str, tuple[TaskContext, str]]:
        return {f"{task.name.replace('/', '.')}.{prop}": (task, prop)
                for deployer in self._deployers() for task in deployer.tasks() for prop in task.properties()}

    def _current(self, name: str) -> dict[str, object] | None:
        if name == SIM_TIME:
            return {"type": 1, "bool_value": self.clock.simulated}
        found = self._params().get(name)
        return None if found is None else to_value(found[0].get_property(found[1]))

    def _names(self) -> list[str]:
        return [SIM_TIME, *(n for n in self._params() if self._current(n) is not None)]

    def _get_parameters(self, request: Any) -> dict[str, Any]:
        return {"values": [self._current(str(n)) or {"type": 0} for n in list(request.names)[:MAX_NAMES]]}

    def _get_parameter_types(self, request: Any) -> dict[str, Any]:
        return {"types": [(self._current(str(n)) or {"type": 0})["type"] for n in list(request.names)[:MAX_NAMES]]}

    def _set_parameters(self, request: Any) -> dict[str, Any]:
        return {"results": [self._set_one(str(p.name), p.value) for p in list(request.parameters)[:MAX_NAMES]]}

    def _set_one(self, name: str, value: object) -> dict[str, object]:
        try:
            if self.read_only:
                raise ValueError("this process serves ROS read-only (--ros-read-only)")
            wanted = from_value(value)
            if name == SIM_TIME:
                if not isinstance(wanted, bool):
                    raise ValueError("use_sim_time is a bool")
                self._follow(wanted)
                return {"successful": True, "reason": ""}
            found = self._params().get(name)
            if found is None:
                return {"successful": False, "reason": f"parameter {name[:200]!r} is not declared"}
            found[0].set_property(found[1], wanted)
        except (ValueError, DataflowError) as exc:
            log.warning("ROS 2 parameter %s: refused: %s", name[:200], exc)
            return {"successful": False, "reason": str(exc)[:1000]}
        return {"successful": True, "reason": ""}

    def _list_parameters(self, request: Any) -> dict[str, Any]:
        prefixes = [str(p) for p in request.prefixes][:MAX_NAMES]
        depth = int(request.depth)
        names = []
        for name in self._names():
            under = [p for p in prefixes if name == p or name.startswith(p + ".")] if prefixes else [""]
            if not under:
                continue
            rest = name[len(under[0]):].lstrip(".")
            if depth and rest.count(".") >= depth:
                continue
            names.append(name)
        found = sorted({n.rpartition(".")[0] for n in names if "." in n})
        return {"result": {"names": names, "prefixes": found}}

    def _describe_parameters(self, request: Any) -> dict[str, Any]:
        return {"descriptors": [self._descriptor(str(n)) for n in list(request.names)[:MAX_NAMES]]}

    def _descriptor(self, name: str) -> dict[str, object]:
        value = self._current(name)
        out: dict[str, object] = {"name": name, "type": value["type"] if value else 0}
        found = self._params().get(name)
        if name == SIM_TIME:
            out["description"] = "follow /clock (a simulation's time)"
        elif found is not None and value is not None:
            bound = found[0].properties()[found[1]]
            out["description"] = bound.doc
            limits = getattr(bound.prop, "bounds", None)
            low, high = (limits.ge, limits.le) if limits is not None else (None, None)
            if low is not None and high is not None and value["type"] in (2, 3):
                key = "integer_range" if value["type"] == 2 else "floating_point_range"
                cast = int if value["type"] == 2 else float
                out[key] = [{"from_value": cast(low), "to_value": cast(high), "step": cast(0)}]
        return out

    # -- loggers ----------------------------------------------------------------------------
    def _python_logger(self, name: str) -> str:
        return "" if name == self.logger_name else name  # every record is published under the node's name

    def _get_logger_levels(self, request: Any) -> dict[str, Any]:
        names = [str(n) for n in list(request.names)[:MAX_NAMES]]
        return {"levels": [{"name": n, "level": level_of(self._python_logger(n))} for n in names]}

    def _set_logger_levels(self, request: Any) -> dict[str, Any]:
        return {"results": [self._set_level(str(asked.name), int(asked.level))
                            for asked in list(request.levels)[:MAX_NAMES]]}

    def _set_level(self, name: str, level: int) -> dict[str, object]:
        try:
            set_level_number(self._python_logger(name), level)
        except ValueError as exc:
            return {"successful": False, "reason": str(exc)[:1000]}
        return {"successful": True, "reason": ""}

    # -- time -----------------------------------------------------------------------------
    def _follow(self, simulated: bool) -> None:
        """Follow ``/clock`` (or stop): the deployers' tasks on a simulated clock (the one
        they have already when the ROS 1 node follows its ``/clock`` too), or back on the
        system's when it was this one."""
        deployers = self._deployers()
        if simulated and self._clock_sub is None:
            clock = SimClock.among(d.clock for d in deployers)

            def tick(message: Any) -> None:
                clock.set(message.clock.sec * 1_000_000_000 + message.clock.nanosec)

            self._clock_sub = self._participant.subscribe("/clock", "rosgraph_msgs/msg/Clock", tick,
                                                          QoS(1, Reliability.BEST_EFFORT), raw=True)
            self.clock = clock
        elif not simulated and self._clock_sub is not None:
            self._clock_sub.close()
            old, self._clock_sub, self.clock = self.clock, None, WALL
            for deployer in deployers:
                if deployer.clock is old:
                    deployer.use_clock(WALL)
        for deployer in deployers:
            if self.clock.simulated and not deployer.clock.simulated:
                deployer.use_clock(self.clock)

    # -- logging ----------------------------------------------------------------------------
    def _publish_log(self, record: logging.LogRecord) -> None:
        t_ns = self.clock.now_ns() if self.clock.simulated else time.time_ns()
        self._rosout.publish({
            "stamp": {"sec": t_ns // 1_000_000_000, "nanosec": t_ns % 1_000_000_000},
            "level": log_level(record.levelno), "name": self.logger_name,
            "msg": record.getMessage()[:MAX_TEXT], "file": record.pathname[:1024],
            "function": record.funcName[:256], "line": max(0, record.lineno)})

    def close(self) -> None:
        """Stop logging to /rosout, withdraw the services, leave /clock (idempotent)."""
        if self._closed:
            return
        self._closed = True
        log_handler = getattr(self, "_log", None)
        if log_handler is not None:
            log_handler.close()
        if self._clock_sub is not None:
            self._follow(False)
        for part in reversed(self._parts):
            part.close()
