"""The in-process implementation of the proxy API (JOrocos's *core* package): the same
:class:`~dataflow.remote.api.System` / :class:`~dataflow.remote.api.ComponentProxy` over a
``Deployer`` in this process, without gRPC. A subscription is a writer end on the port,
as a remote one is (each sample with its write number and time), keeping samples in a
mailbox with the subscriber's policy; the observer is called on the subscription's own
thread, and one that raises is logged while the subscription goes on.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Literal, overload

from dataflow.deployer import Deployer
from dataflow.errors import DataflowError, NotFoundError, PortTypeError
from dataflow.introspection import LinkDescription, TaskDescription
from dataflow.policy import ConnPolicy, FlowStatus, WriteStatus
from dataflow.ports import InputPort, OutputPort
from dataflow.remote.api import (
    TRANSITIONS, ComponentInfo, ComponentProxy, GapEvent, Observer, PortWriter, SampleEvent, Subscription, System,
    split_port,
)
from dataflow.remote._delivery import Mailbox
from dataflow.remote.errors import ClosedError
from dataflow.threads import OwnedThread
from dataflow.transports.ends import OutSample, WriterEnd, attach, detach

if TYPE_CHECKING:
    from dataflow.ports import Port
    from dataflow.task import TaskContext

__all__ = ["LocalSystem", "LocalComponentProxy", "LocalSubscription", "LocalPortWriter"]

log = logging.getLogger(__name__)


@overload
def _port(task: TaskContext, name: str, want_input: Literal[True]) -> InputPort[object]: ...
@overload
def _port(task: TaskContext, name: str, want_input: Literal[False]) -> OutputPort[object]: ...
def _port(task: TaskContext, name: str, want_input: bool) -> Port[object]:
    port = task.port(name)
    if port.is_input != want_input:
        need = "an input" if want_input else "an output"
        raise PortTypeError(f"{task.name}.{name} is not {need} port")
    return port


class LocalPortWriter(PortWriter):
    """A free OutputPort connected to the task's input port with ``policy``."""

    def __init__(self, task: TaskContext, port: InputPort[object], policy: ConnPolicy) -> None:
        super().__init__(task.name, port.name, policy)
        self._target = port
        self._out: OutputPort = OutputPort(port.type, name=f"local_{port.name}")
        self._out.connect_to(port, policy)
        self._closed = False

    def write(self, value: object) -> WriteStatus:
        if self._closed:
            raise ClosedError(f"writer to {self.component}.{self.port} is closed")
        from scart_wire.types import registry

        try:
            value = registry.validate(self._target.type, value)
        except PortTypeError as exc:
            raise PortTypeError(f"{self.component}.{self.port} expects {self._target.type_name}: {exc}") from None
        return self._out.write(value)

    def close(self) -> None:
        self._closed = True
        self._out.disconnect(self._target)


class LocalSubscription(Subscription):
    """Samples of an output port delivered on this subscription's own thread: a writer end
    on the port (as a remote subscription's) whose carrier keeps each sample, with its
    write number and time, in a policy-shaped mailbox, in the writer's thread. An observer
    that raises is logged and the subscription keeps going (:attr:`observer_errors`
    counts them). With ``period``, the mailbox is looked at every ``period`` s.
    """

    def __init__(self, task: TaskContext, port: OutputPort[object], observer: Observer, policy: ConnPolicy, period: float | None) -> None:
        super().__init__(task.name, port.name, policy, period)
        self._port = port
        self._observer = observer
        self.polls = self.wasted_polls = 0
        self.observer_errors = 0
        self._mailbox: Mailbox[SampleEvent] = Mailbox(policy)
        self._end = WriterEnd(port, policy.with_(mandatory=False), f"local subscription to {port.qualname}",
                              reports=False)
        self._thread = OwnedThread(self._run, f"scart-local-sub-{task.name}.{port.name}", wake=self._mailbox.close)
        self._end.connected("local", self, new_peer=True)
        attach(port, self._end)
        self._thread.start()

    encode = staticmethod(lambda sample: sample.value)  # no encoding: the value itself

    def send(self, sample: OutSample, value: object) -> bool:  # the writer's thread: the carrier
        self._mailbox.put(SampleEvent(self.component, self.port, value, FlowStatus.NEW_DATA, sample.t_ns / 1e9,
                                      sample.n))
        return True  # a full mailbox drops as its policy says, counted there

    @property
    def dropped(self) -> int:
        return self._mailbox.dropped + self._end.unsent

    @property
    def connected(self) -> bool:
        return not self._thread.stopping.is_set() and self._thread.alive

    def _notify(self, event: SampleEvent) -> None:
        self.delivered += 1
        try:
            self._observer(event)
        except Exception:  # noqa: BLE001 - an observer's bug must not end the subscription
            self.observer_errors += 1
            log.exception("observer of %s.%s raised; the subscription goes on", self.component, self.port)

    def _run(self, stopping: threading.Event) -> None:
        while not stopping.is_set():
            if self.period is not None and stopping.wait(self.period):
                return
            found = False
            for _ in range(100_000):  # bounded: what waits now, at most
                event = self._mailbox.get(0.0 if self.period is not None or found else 0.5)
                if event is None or stopping.is_set():
                    break
                found = True
                self._notify(event)
            if self.period is not None:
                self.polls += 1
                self.wasted_polls += 0 if found else 1

    def close(self) -> None:
        detach(self._port, self._end)
        self._end.disconnected()
        self._thread.stop()


class LocalComponentProxy(ComponentProxy):
    """A task of an in-process deployer behind the proxy API."""

    def __init__(self, system: LocalSystem, task: TaskContext) -> None:
        self.system = system
        self.task = task
        self.name = task.name
        self._defaults: dict[str, LocalPortWriter] = {}
        self._taps: dict[str, InputPort] = {}
        self._lock = threading.Lock()

    @property
    def state(self) -> str:
        return self.task.state.name

    def describe(self) -> TaskDescription:
        return self.task.describe()

    def last_values(self) -> dict[str, object]:
        out = {}
        for name, port in self.task.ports().items():
            if isinstance(port, OutputPort) and (value := port.last_written_value()) is not None:
                out[name] = value
        return out

    def change_state(self, transition: str) -> bool:
        if transition not in TRANSITIONS:
            raise ValueError(f"unknown transition {transition!r}")
        return bool(getattr(self.task, transition)())

    def connect_input(self, port: str, policy: ConnPolicy = ConnPolicy.data()) -> LocalPortWriter:
        writer = LocalPortWriter(self.task, _port(self.task, port, True), policy)
        self.system._own(writer)
        return writer

    def write(self, port: str, value: object) -> WriteStatus:
        with self._lock:
            writer = self._defaults.get(port)
            if writer is None:
                writer = self._defaults[port] = self.connect_input(port, ConnPolicy.data())
        return writer.write(value)

    def write_json(self, port: str, json_value: object) -> WriteStatus:
        from scart_wire.types import registry

        target = _port(self.task, port, True)
        return self.write(port, registry.from_jsonable(target.type, json_value))

    def read(self, port: str) -> tuple[FlowStatus, object | None]:
        with self._lock:
            tap = self._taps.get(port)
            if tap is None:
                out = _port(self.task, port, False)
                tap = self._taps[port] = InputPort(out.type, name=f"tap_{port}")
                out.connect_to(tap, ConnPolicy.data())
        return tap.read()

    def subscribe(
        self,
        port: str,
        observer: Observer,
        policy: ConnPolicy = ConnPolicy.data(),
        period: float | None = None,
        on_gap: Callable[[GapEvent], None] | None = None,
    ) -> LocalSubscription:
        sub = LocalSubscription(self.task, _port(self.task, port, False), observer, policy, period)
        self.system._own(sub)
        return sub

    def call(self, operation: str, *args: object, timeout: float | None = None) -> object:
        return self.task.call(operation, *args)

    def call_json(self, operation: str, json_args: list[object], timeout: float | None = None) -> object:
        from scart_wire.types import registry

        ops = self.task.operations()
        if operation not in ops:
            raise NotFoundError(f"{self.name} has no operation {operation!r}; operations: {', '.join(sorted(ops))}")
        params = ops[operation].params
        if len(params) != len(json_args):
            raise PortTypeError(f"{self.name}.{operation} takes {len(params)} argument(s), got {len(json_args)}")
        args = [registry.from_jsonable(t, a) for (_n, t), a in zip(params, json_args, strict=True)]
        return self.task.call(operation, *args)

    def get_property(self, name: str) -> object:
        return self.task.get_property(name)

    def set_property(self, name: str, value: object) -> None:
        self.task.set_property(name, value)

    def set_property_json(self, name: str, json_value: object) -> object:
        from scart_wire.types import registry

        prop = self.task.properties()[name] if name in self.task.properties() else None
        if prop is None:
            raise NotFoundError(f"{self.name} has no property {name!r}; properties: {', '.join(self.task.properties())}")
        self.task.set_property(name, registry.from_jsonable(prop.type, json_value))
        return registry.to_jsonable(self.task.get_property(name))


class LocalSystem(System):
    """The tasks of one in-process ``Deployer`` as a :class:`System`. Thread-safe; close idempotent."""

    def __init__(self, deployer: Deployer) -> None:
        self.deployer = deployer
        self._owned: list[Subscription | PortWriter] = []
        self._lock = threading.Lock()

    def _own(self, item: Subscription | PortWriter) -> None:
        with self._lock:
            self._owned.append(item)

    def component_names(self) -> list[str]:
        return sorted(self.deployer.names())

    def component(self, name: str) -> LocalComponentProxy:
        return LocalComponentProxy(self, self.deployer.task(name))

    def components(self) -> list[ComponentInfo]:
        out = []
        for t in self.deployer.tasks():
            a = t.activity
            cycles, last_cycle = a.stamp if a.stamp[1] else (a.cycles, 0.0)
            out.append(ComponentInfo(t.name, t.state.name, a.kind, a.period, cycles, a.overruns, "in-process", last_cycle))
        return sorted(out, key=lambda c: c.name)

    def connect_ports(self, source: str, sink: str, policy: ConnPolicy = ConnPolicy.data(),
                      name: str | None = None) -> str:
        return self.deployer.connect_or_change(source, sink, policy, name=name)

    def disconnect_ports(self, source: str, sink: str) -> bool:
        split_port(source), split_port(sink)  # the same errors as the remote system
        return self.deployer.disconnect(source, sink)

    def links(self) -> list[LinkDescription]:
        return sorted(self.deployer.links(), key=lambda lk: lk.name)

    def reroute(self, name: str, sink: str) -> LinkDescription:
        split_port(sink)
        return self.deployer.reroute(name, sink)

    def disconnect_link(self, name: str) -> bool:
        link = self.deployer.find_link(name)
        return self.deployer.disconnect(link.source, link.sink)

    def close(self) -> None:
        with self._lock:
            owned, self._owned = self._owned, []
        for item in owned:
            try:
                item.close()
            except DataflowError:
                pass
