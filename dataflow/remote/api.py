"""The transport-neutral proxy API (JOrocos's *core* package): what a client of a
data-flow system sees, whatever carries the calls. Two implementations:
:mod:`dataflow.remote.local` (in-process, no gRPC) and :mod:`dataflow.remote.client`
(gRPC). Nothing here imports gRPC; descriptions are the core's pydantic models, errors
the core's error tree (plus :mod:`dataflow.remote.errors`).

Story: ``system = connect(address)`` → ``proxy = system.component("driver")`` →
introspect (``ports()``, ``operations()``, ``properties()``, ``state``) → ``write`` /
``subscribe`` / ``call`` / ``set_property`` → ``sub.close()`` → ``system.close()``.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from dataflow.errors import DataflowError
from dataflow.policy import ConnPolicy, FlowStatus, WriteStatus

if TYPE_CHECKING:  # the core's description models
    from dataflow import OperationDescription, PortDescription, PropertyDescription, TaskDescription
    from dataflow.introspection import LinkDescription, SubscriptionDescription

__all__ = [
    "TRANSITIONS",
    "SampleEvent",
    "GapEvent",
    "ComponentInfo",
    "Observer",
    "Subscription",
    "PortWriter",
    "ComponentProxy",
    "System",
]


#: The lifecycle transitions :meth:`ComponentProxy.change_state` accepts.
TRANSITIONS = ("configure", "start", "stop", "cleanup", "recover")


@dataclass(frozen=True)
class SampleEvent:
    """One sample delivered to an observer.

    ``source_time`` is the wall-clock time (s since the epoch) the sample was stored for
    this subscription on the task's side; ``sequence`` counts samples stored for this
    subscription (a jump means samples were dropped by the policy).
    """

    component: str
    port: str
    value: object
    flow_status: FlowStatus
    source_time: float
    sequence: int


@dataclass(frozen=True)
class GapEvent:
    """The subscription was cut from ``started`` to ``ended`` (wall-clock s) and resumed;
    ``restarted`` when the deployer is a new process (its sequence numbers started over).
    The samples a gap lost are counted in the subscription's ``dropped``."""

    component: str
    port: str
    started: float
    ended: float
    reason: str
    restarted: bool = False

    @property
    def duration(self) -> float:
        """Length of the gap in seconds."""
        return self.ended - self.started


@dataclass(frozen=True)
class ComponentInfo:
    """One line of ``scart ls``: a component's summary and the deployer serving it."""

    name: str
    state: str
    activity: str
    period: float
    cycles: int
    overruns: int
    address: str
    #: When cycle ``cycles`` began (the deployer's monotonic clock, s; 0.0: none yet).
    last_cycle: float = 0.0


Observer = Callable[[SampleEvent], None]

class Subscription(ABC):
    """A live subscription to an output port; the observer runs on the subscription's own
    thread, so a slow observer never slows the task or other subscribers.

    :meth:`close` is idempotent, blocks until the subscription's threads ended (≤ ~5 s),
    and may be called from inside the observer.
    """

    def __init__(self, component: str, port: str, policy: ConnPolicy, period: float | None) -> None:
        self.component = component
        self.port = port
        self.policy = policy
        self.period = period
        self._gaps: list[GapEvent] = []
        self._lock = threading.Lock()
        self.delivered = 0

    @property
    @abstractmethod
    def dropped(self) -> int:
        """Samples lost to the policy so far (task side and client side together)."""

    @property
    @abstractmethod
    def connected(self) -> bool:
        """True while samples can flow (False during a gap)."""

    @property
    def gaps(self) -> list[GapEvent]:
        """The gaps (disconnections that ended by resuming) so far, oldest first."""
        with self._lock:
            return list(self._gaps)

    @abstractmethod
    def close(self) -> None:
        """Stop delivering and release every resource; idempotent."""

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class PortWriter(ABC):
    """A connection from the client to one input port, with the policy it was opened with.

    :meth:`write` returns a :class:`WriteStatus` (hot path: no raise for a full buffer) but
    raises :class:`dataflow.errors.PortTypeError` for a value of the wrong type.
    :meth:`close` is idempotent.
    """

    def __init__(self, component: str, port: str, policy: ConnPolicy) -> None:
        self.component = component
        self.port = port
        self.policy = policy

    @abstractmethod
    def write(self, value: object) -> WriteStatus:
        """Send one sample."""

    @abstractmethod
    def close(self) -> None:
        """Disconnect from the port."""

    def __enter__(self) -> PortWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class ComponentProxy(ABC):
    """A data-flow component seen from a client (the JOrocos ``TaskProxy``).

    Every method may raise :class:`dataflow.errors.NotFoundError` (unknown port, property,
    operation — the message lists what exists) and, for remote proxies,
    :class:`dataflow.remote.errors.UnavailableError` / ``RemoteTimeoutError`` (each call has
    a deadline). Methods are thread-safe.
    """

    name: str

    @property
    @abstractmethod
    def state(self) -> str:
        """The task's lifecycle state name (e.g. ``"RUNNING"``)."""

    @abstractmethod
    def describe(self) -> TaskDescription:
        """Full introspection: state, activity, ports, properties, operations."""

    @abstractmethod
    def last_values(self) -> dict[str, object]:
        """The last value written on each output port that has one."""

    def describe_with_values(self) -> tuple[TaskDescription, dict[str, object]]:
        """The description and the output ports' last values (one call where the transport allows)."""
        return self.describe(), self.last_values()

    def ports(self) -> dict[str, PortDescription]:
        """The ports by name."""
        return {p.name: p for p in self.describe().ports}

    def properties(self) -> dict[str, PropertyDescription]:
        """The properties (with current values) by name."""
        return {p.name: p for p in self.describe().properties}

    def operations(self) -> dict[str, OperationDescription]:
        """The operations by name."""
        return {o.name: o for o in self.describe().operations}

    @abstractmethod
    def change_state(self, transition: str) -> bool:
        """Run ``configure|start|stop|cleanup|recover``; True if the task accepted it."""

    def configure(self) -> bool:
        """Configure the task; True if accepted."""
        return self.change_state("configure")

    def start(self) -> bool:
        """Start the task; True if accepted."""
        return self.change_state("start")

    def stop(self) -> bool:
        """Stop the task; True if accepted."""
        return self.change_state("stop")

    def cleanup(self) -> bool:
        """Clean the task up; True if accepted."""
        return self.change_state("cleanup")

    @abstractmethod
    def connect_input(self, port: str, policy: ConnPolicy = ConnPolicy.data()) -> PortWriter:
        """A writer connected to input ``port`` with ``policy``."""

    @abstractmethod
    def write(self, port: str, value: object) -> WriteStatus:
        """Write one sample to input ``port`` through its default (DATA) writer."""

    @abstractmethod
    def write_json(self, port: str, json_value: object) -> WriteStatus:
        """Write a JSON-shaped value; converted to the port's type by the task's side."""

    @abstractmethod
    def read(self, port: str) -> tuple[FlowStatus, object | None]:
        """The newest sample of output ``port``: NEW_DATA if written since this proxy's last read."""

    @abstractmethod
    def subscribe(
        self,
        port: str,
        observer: Observer,
        policy: ConnPolicy = ConnPolicy.data(),
        period: float | None = None,
        on_gap: Callable[[GapEvent], None] | None = None,
    ) -> Subscription:
        """Deliver samples of output ``port`` to ``observer`` (push; ``period`` = polling)."""

    @abstractmethod
    def call(self, operation: str, *args: object, timeout: float | None = None) -> object:
        """Call an operation and return its result (blocks ≤ ``timeout``)."""

    @abstractmethod
    def call_json(self, operation: str, json_args: list[object], timeout: float | None = None) -> object:
        """Call with JSON-shaped arguments, converted to the parameter types by the task's side."""

    @abstractmethod
    def get_property(self, name: str) -> object:
        """A property's current value."""

    @abstractmethod
    def set_property(self, name: str, value: object) -> None:
        """Set a property (validated; raises ``PortTypeError`` / ``PropertyValueError``)."""

    @abstractmethod
    def set_property_json(self, name: str, json_value: object) -> object:
        """Set a property from a JSON-shaped value; returns the stored value as JSON."""


class System(ABC):
    """A data-flow system: every component known to one name service (or one deployer)."""

    @abstractmethod
    def component_names(self) -> list[str]:
        """Names of the components, sorted."""

    @abstractmethod
    def component(self, name: str) -> ComponentProxy:
        """A proxy for ``name``; raises ``NotFoundError`` listing the known names."""

    @abstractmethod
    def components(self) -> list[ComponentInfo]:
        """A summary line per component."""

    @abstractmethod
    def connect_ports(self, source: str, sink: str, policy: ConnPolicy = ConnPolicy.data(),
                      name: str | None = None) -> str:
        """Connect ``"task.out"`` to ``"task.in"`` (possibly in another deployer), as the link
        ``name`` (default ``"task.out->task.in"``). Returns what holds when the pair was
        connected already (``"policy changed from X to Y"``, ``"renamed from A to B"``,
        ``"connected already"``), ``""`` for a new link. Raises, before anything is linked,
        for ports of different types, an output used as a sink, an unknown port."""

    @abstractmethod
    def disconnect_ports(self, source: str, sink: str) -> bool:
        """Undo :meth:`connect_ports`; False if they were not connected."""

    @abstractmethod
    def links(self) -> list[LinkDescription]:
        """Every link between ports (name, ends, policy, transport, samples, drops), by name."""

    def subscriptions(self) -> list[SubscriptionDescription]:
        """Every subscription the deployers serve to other processes (port, subscriber,
        policy, transport, samples, drops). A system with no served deployers has none."""
        return []

    @abstractmethod
    def reroute(self, name: str, sink: str) -> LinkDescription:
        """Point the link ``name`` at input ``"task.in"`` (made before the old one is undone)."""

    @abstractmethod
    def disconnect_link(self, name: str) -> bool:
        """Undo the link (or stream) called ``name``; False if it was gone already."""

    def disconnect_counted(self, source: str, sink: str) -> int | None:
        """:meth:`disconnect_ports`, saying how many samples written were never delivered to
        the sink's task (after it could read what its buffer held); None when the ports were
        not connected. In one process nothing is lost on the way: 0."""
        return 0 if self.disconnect_ports(source, sink) else None

    def disconnect_link_counted(self, name: str) -> int | None:
        """:meth:`disconnect_link`, saying how many samples were never delivered (see
        :meth:`disconnect_counted`)."""
        return 0 if self.disconnect_link(name) else None

    def stream(self, port: str, policy: ConnPolicy, options: dict[str, str] | None = None,
               name: str | None = None) -> LinkDescription:
        """Join ``"task.port"`` to the topic ``policy.topic`` of the transport
        ``policy.transport`` (a stream; its deployer makes it). Raises
        :class:`~dataflow.errors.DataflowError` where streams are not served."""
        raise DataflowError("streams are made by a served deployer (scart deploy / scart run)")

    @abstractmethod
    def close(self) -> None:
        """Close every subscription, writer and channel opened through this system; idempotent."""

    def __enter__(self) -> System:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def split_port(text: str, what: str = "PORT") -> tuple[str, str]:
    """``"task.port"``, or ROS's ``"/task/port"`` and ``"task/port"``, → ``("task",
    "port")``; raises ``ValueError`` for anything else. A task name may hold ``/``
    (``left/driver.status`` and ``/left/driver/status`` are the same port).

    ``what`` names the second part in the error ("PORT", "OPERATION").
    """
    name = text[1:] if text.startswith("/") else text
    head, slash, tail = name.rpartition("/")
    if slash and "." not in tail:  # the ROS form: the last part is the port
        task, sep, port = head, slash, tail
    else:
        task, sep, port = name.rpartition(".")
    if not sep or not task or not port:
        raise ValueError(f"expected COMPONENT.{what} (or /COMPONENT/{what}), got {text!r}")
    return task, port
