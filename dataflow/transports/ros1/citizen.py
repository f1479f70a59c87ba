"""The process's tasks as its ROS 1 node's own: what makes the node a citizen of a ROS
system rather than a guest (the ``ros1`` transport's adapter; the node library knows
nothing of tasks).

**Parameters.** Each task's properties are the node's private parameters, one namespace
per task: property ``max_velocity`` of task ``youBotDriver`` of node ``/youbot`` is
``/youbot/youBotDriver/max_velocity``. When the node is made, every property is set
there (the tasks' values win over what an earlier run left: a launch-time value is
``_TASK/PROP:=VALUE``, or ``_PROP:=VALUE`` when one task has ``PROP``,
:func:`apply_launch_params`). ``rosparam set`` reaches the
task through the property's check (type, bounds, read-only): a refused value is logged
with the reason (so ``/rosout`` says it) and the parameter set back to the property's
value, which it keeps. A property changed otherwise (``scart prop set``, the task
itself) is set on the server within a second. A value XML-RPC cannot carry (bytes, an
integer beyond 32 bits) is not a parameter. After a master restart, all are set again.

**Time.** With the parameter ``/use_sim_time`` true (read at start, and followed), or
the node's own launch-time ``_use_sim_time:=true`` (``sim_time``), the node subscribes
to ``/clock`` and every task of the deployers lives in that time (one
:class:`~dataflow.clock.SimClock`, which the ROS 2 node's ``/clock`` feeds too when it
follows one, :meth:`Deployer.use_clock`): periodic tasks tick on
it (``rosbag play --clock -r 2`` runs them twice as fast, a paused bag pauses them) and
the stamps scart puts on messages come from it. Without it, nothing changes.

**Logging.** Python's log records go to ``/rosout`` with the node's name, and the node
serves ``~get_loggers`` and ``~set_logger_level`` (:mod:`.rosout`).

Everything runs on the node's control thread (the clock's ticks on its io thread);
:meth:`Citizen.close` ends it (idempotent).
"""

from __future__ import annotations

import logging
import math
import struct
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import pydantic

from dataflow.clock import WALL, Clock, SimClock
from dataflow.errors import DataflowError

from scart_ros1.master import MasterError, XmlRpcValue
from scart_ros1.names import RosNameError, check_name
from scart_ros1.node import Node

if TYPE_CHECKING:
    from dataflow.deployer import Deployer
    from dataflow.task import TaskContext
    from scart_ros1.topics import Subscriber

    from .rosout import Rosout

__all__ = ["Citizen", "SYNC_SECONDS", "apply_launch_params", "to_param"]

log = logging.getLogger(__name__)

SYNC_SECONDS = 1.0  #: how often properties changed by others are set on the parameter server
_INT32 = range(-(2**31), 2**31)


def to_param(value: object) -> XmlRpcValue:
    """``value`` as a ROS parameter (what XML-RPC carries), or None when it cannot be one."""
    if isinstance(value, bool) or isinstance(value, str):
        return value
    if isinstance(value, int):
        return value if value in _INT32 else None
    if isinstance(value, float):
        return value
    if isinstance(value, pydantic.BaseModel):
        return to_param(value.model_dump(mode="json"))
    if isinstance(value, (list, tuple)):
        items = [to_param(v) for v in value]
        return None if any(i is None for i in items) else items
    if isinstance(value, Mapping):
        pairs = {str(k): to_param(v) for k, v in value.items() if v is not None}
        return None if any(v is None for v in pairs.values()) else pairs
    return None


def _ns(secs: int, nsecs: int) -> int:
    return secs * 1_000_000_000 + nsecs


def _same(a: object, b: object) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))


def _find(tasks: list[Any], path: str) -> tuple[Any, str] | None:
    """``(task, property)`` of ``TASK/PROP`` (a task's name may hold ``/``), or None."""
    name, _, prop = path.rpartition("/")
    for task in tasks:
        if task.name == name and prop in task.properties():
            return task, prop
    return None


def _launch_target(tasks: list[Any], path: str) -> tuple[Any, str]:
    """``(task, property)`` a launch-time parameter names: ``TASK/PROP``, or a plain
    ``PROP`` (a private parameter, as ROS takes it) that exactly one task has. Raises
    ``ValueError`` saying why there is none, naming the tasks that have it when several do."""
    if "/" not in path:
        having = [t.name for t in tasks if path in t.properties()]
        if len(having) == 1:
            return next(t for t in tasks if t.name == having[0]), path
        if having:
            raise ValueError(f"ROS parameter _{path}: the tasks {', '.join(having)} have that property: name one "
                             f"(_{having[0]}/{path}:=VALUE)")
        raise ValueError(f"ROS parameter _{path}: no task has that property (the tasks are "
                         f"{', '.join(t.name for t in tasks) or 'none'}; _TASK/PROPERTY:=VALUE names one)")
    found = _find(tasks, path)
    if found is None:
        name, _, prop = path.rpartition("/")
        task = next((t for t in tasks if t.name == name), None)
        known = (f"task {name} has the properties {', '.join(sorted(task.properties())) or 'none'}" if task
                 else f"the tasks are {', '.join(t.name for t in tasks) or 'none'}")
        raise ValueError(f"ROS parameter _{path}: no such task property ({known})")
    return found


def apply_launch_params(tasks: list[Any], params: Mapping[str, Any]) -> None:
    """Set launch-time parameters on the tasks' properties, each through its check:
    ``_TASK/PROP:=value``, or ``_PROP:=value`` when exactly one task has ``PROP``. Raises
    ``ValueError`` naming the parameter and why."""
    for path, value in params.items():
        found = _launch_target(tasks, path)
        try:
            found[0].set_property(found[1], value)
        except DataflowError as exc:
            raise ValueError(f"ROS parameter _{path}:={value!r}: refused: {exc}") from None


_CLOCK = struct.Struct("<II")  # rosgraph_msgs/Clock: time (secs, nsecs)


class Citizen:
    """The tasks of the deployers ``deployers()`` returns, as ``node``'s own (see the
    module docstring)."""

    def __init__(self, node: Node, deployers: Callable[[], list[Deployer]], sim_time: bool = False) -> None:
        self.node, self._deployers = node, deployers
        self._sim_at_start = sim_time
        self.namespace = node.resolve("~")
        self.clock: Clock = WALL
        self._clock_sub: Subscriber | None = None
        self._rosout: Rosout | None = None
        self._published: dict[str, XmlRpcValue] = {}
        self._skipped: set[str] = set()
        self._closed = False

    def _tasks(self) -> list[TaskContext]:
        return [task for deployer in self._deployers() for task in deployer.tasks()]

    def start(self) -> None:
        """Subscribe to the node's private namespace (then every property is set there, and
        again after a master restart) and to ``/use_sim_time``. Never blocks."""
        from .rosout import Rosout

        try:
            self._rosout = Rosout(self.node, lambda: self.clock.now_ns(), services=not self.node.read_only)
        except ValueError as exc:  # the node publishes /rosout, or serves a logger service, already
            log.warning("ROS 1 node %s: no /rosout: %s", self.node.caller_id, exc)
        self.node.subscribe_param("~", self._update)
        if not self.node.read_only:  # read-only: nothing from ROS reaches the tasks, their time included
            self.node.subscribe_param("/use_sim_time", self._sim_time)
            if self._sim_at_start:
                self.node.control.submit(lambda: self._sim_time("/use_sim_time", True))
        self.node.control.submit(self._sync, delay=SYNC_SECONDS)

    def close(self) -> None:
        """Stop syncing, listening to the parameters and following ``/clock``; the
        deployers' tasks go back to the system's clock (idempotent)."""
        if self._closed:
            return
        self._closed = True
        if self._rosout is not None:
            self._rosout.close()
        if not self.node.closed:
            self.node.unsubscribe_param("~")
            self.node.unsubscribe_param("/use_sim_time")  # (idempotent: read-only never subscribed)
        self._follow(False)

    # -- time -----------------------------------------------------------------------------
    def _sim_time(self, _key: str, value: object) -> None:
        self._follow((self._sim_at_start or value is True or value == "true") and not self._closed)

    def _follow(self, simulated: bool) -> None:
        """Follow ``/clock`` (or stop) and give the deployers' tasks that clock (the one
        they have already when the ROS 2 node follows its ``/clock`` too), or put them back
        on the system's when it was this one."""
        if simulated and self._clock_sub is None:
            clock = SimClock.among(d.clock for d in self._deployers())
            self._clock_sub = self.node.subscribe("/clock", "rosgraph_msgs/Clock", lambda data: clock.set(
                _ns(*_CLOCK.unpack_from(data))) if len(data) == 8 else None, raw=True)
            self.clock = clock
            log.info("ROS 1 node %s: use_sim_time: the tasks follow /clock", self.node.caller_id)
        elif not simulated and self._clock_sub is not None:
            self._clock_sub.close()
            old, self._clock_sub, self.clock = self.clock, None, WALL
            for deployer in self._deployers():
                if deployer.clock is old:
                    deployer.use_clock(WALL)
            log.info("ROS 1 node %s: use_sim_time off: the tasks follow the system's clock", self.node.caller_id)
        self._give_clock()

    def _give_clock(self) -> None:
        """Following ``/clock``, put the deployers not on a simulated clock on it (one
        attached since, too); otherwise leave their clocks alone (the ROS 2 node may
        follow its own ``/clock``)."""
        if not self.clock.simulated:
            return
        for deployer in self._deployers():
            if not deployer.clock.simulated:
                deployer.use_clock(self.clock)

    # -- the control thread ---------------------------------------------------------------
    def _params(self) -> dict[str, tuple[Any, str]]:
        """Every task property that can be a parameter: key → (task, property)."""
        out: dict[str, tuple[TaskContext, str]] = {}
        for task in self._tasks():
            try:
                check_name(task.name, "task name")
            except RosNameError:
                if task.name not in self._skipped:
                    self._skipped.add(task.name)
                    log.warning("ROS 1 node %s: task %r is no ROS name: its properties are no parameters",
                                self.node.caller_id, task.name)
                continue
            for prop in task.properties():
                out[f"{self.namespace}/{task.name}/{prop}"] = (task, prop)
        return out

    def _update(self, key: str, value: Any) -> None:
        """A parameter under the namespace changed (or the namespace's whole value came)."""
        if self._closed:
            return
        if isinstance(value, dict):
            if key.rstrip("/") == self.namespace:  # the node's start, or a new master: the tasks' values win
                self._publish(force=True)
                return
            for sub, item in value.items():  # a task's namespace set at once: its leaves
                self._update(f"{key.rstrip('/')}/{sub}", item)
            return
        target = self._params().get(key)
        if target is None:
            return  # a parameter of the user's own under the namespace
        task, prop = target
        if _same(to_param(task.get_property(prop)), value):
            self._published[key] = value
            return
        try:
            if self.node.read_only:
                raise PermissionError("this process serves ROS read-only (--ros-read-only)")
            task.set_property(prop, value)
        except (DataflowError, PermissionError) as exc:
            kept = task.get_property(prop)
            log.warning("ROS parameter %s: %r refused: %s; it keeps %r", key, value, exc, kept)
            self._set(key, to_param(kept))
            return
        self._published[key] = to_param(task.get_property(prop))

    def _sync(self) -> None:
        if self._closed or self.node.closed:
            return
        self._give_clock()  # (a deployer attached since)
        self._publish(force=False)
        self.node.control.submit(self._sync, delay=SYNC_SECONDS)

    def _publish(self, force: bool) -> None:
        for key, (task, prop) in self._params().items():
            value = to_param(task.get_property(prop))
            if value is None or (not force and key in self._published and _same(self._published[key], value)):
                continue
            if not self._set(key, value):
                return

    def _set(self, key: str, value: XmlRpcValue) -> bool:
        if value is None:
            return True
        try:
            self.node.master.set_param(key, value)
        except MasterError as exc:
            log.debug("ROS parameter %s not set: %s", key, exc)
            return False
        self._published[key] = value
        return True
