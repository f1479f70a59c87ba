"""``binding.dataflow``: SCA references and services wired straight to data-flow ports.

XML (namespace ``urn:scart:1.0``)::

    <reference name="thermostat">
      <scart:binding.dataflow component="thermostat" ns="127.0.0.1:7850" policy="data">
        <scart:map operation="set_target" port="setpoint"/>
      </scart:binding.dataflow>
    </reference>
    <service name="Samples">
      <scart:binding.dataflow component="thermostat" ports="on_temperature=temperature"
                              policy="buffer:16" period="0.05"/>
    </service>

Attributes: ``component`` (required: the task's name), ``ns`` (name service
``HOST:PORT``; absent → a task of this composite if there is one, else this runtime's
name service: the settings' ``ns``, that is ``scart run --ns`` / ``SCART_NS`` / the
default), ``policy`` (``data``
default, ``buffer:N``, ``circular:N``: the connection policy of writes and of
subscriptions), ``transport`` (auto | ipc | shm | grpc: how subscriptions cross
processes, default auto), ``period`` (service only: poll every ``period`` s, JOrocos-style, instead
of the push subscription), ``ports="op=port,..."`` and/or ``<scart:map operation port/>``
children (explicit mapping; otherwise an operation maps to the port of its own name).

Reference side: an operation with one argument writes it to the input port (returns
None; a one-way operation is queued on the runtime's pool); an operation with no
argument and a return value returns the latest sample of the output port, ``None``
before any. A call while the task is unreachable raises ``InvocationError`` naming it.

Service side: every new sample of an output port invokes the operation mapped to it,
with the sample as its argument, on the subscription's own thread: while the component
is busy, DATA keeps only the newest sample, BUFFER(n) queues n and counts the overflow
(:attr:`DataflowServiceBinding.dropped`). Operations that map to no port (and are not
mapped explicitly) are not data-driven.

Checks: at load time (``file:line``), operation shapes and, by introspecting the task —
its class for a task of this contribution, else (only with ``settings.online``, as
``scart validate --online``) through the name service if it answers within 0.5 s — port
existence, direction and type (the interface annotations' registry names against the
port types). When the task cannot be introspected at load time, the same check runs
when it connects; mismatching operations are logged and left out.

Availability: the composite starts whether the task is there or not; a connector thread
connects when the task appears, and the remote proxies reconnect after it restarts. Each
change (appeared, connected, gone, restarted) is logged on ``scart.dataflow``.
``bindings_of(runtime)`` lists the live bindings (for counters and tests).
"""

from __future__ import annotations

import dataclasses
import inspect
import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import zenoh

    from dataflow.remote.naming import Lookups
    from dataflow.remote import ComponentProxy, GapEvent, PortWriter, SampleEvent, Subscription, System

from dataflow import DataflowError, FlowStatus
from dataflow.remote import local_system
from scart.errors import InvocationError
from scart.bindings.dataflow._host import TASK_KIND, PortInfo, Watcher, host_of
from scart.bindings.dataflow._plan import DF_ATTRIBUTE, Attributes, Step, attributes, check_ports, plan, static_ports
from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import (
    Binding, BindingProvider, CheckContext, Host, InterfaceInfo, Operation, Problem, ReferenceBinding, ServiceBinding,
    ServiceEndpoint, Side,
)

__all__ = ["DataflowBinding", "DataflowReferenceBinding", "DataflowServiceBinding", "bindings_of"]

log = logging.getLogger("scart.dataflow")


def bindings_of(runtime: Host) -> list[DataflowReferenceBinding | DataflowServiceBinding]:
    """The ``binding.dataflow`` instances of ``runtime`` (references and services)."""
    return runtime.shared("scart.bindings.dataflow.bindings", list)


class DataflowBinding(BindingProvider):
    """The ``binding.dataflow`` provider (see the module docstring)."""

    name = "binding.dataflow"

    def check(self, model: Binding, interface: InterfaceInfo | None, side: Side,
              context: CheckContext) -> list[Problem]:
        """Static problems (see the module docstring)."""
        return _check(model, interface, context, side)

    def names_endpoint(self, model: Binding) -> bool:
        """The task it names is its endpoint."""
        return bool(attributes(model).component)

    def service(self, model: Binding, endpoint: ServiceEndpoint, host: Host) -> ServiceBinding:
        """A :class:`DataflowServiceBinding`: samples drive the service's operations."""
        return DataflowServiceBinding(model, endpoint, host)

    def reference(self, model: Binding, interface: InterfaceInfo, host: Host) -> ReferenceBinding:
        """A :class:`DataflowReferenceBinding`: calls become port writes and reads."""
        return DataflowReferenceBinding(model, interface, host)


def _check(model: Binding, iface: InterfaceInfo | None, context: CheckContext, side: str) -> list[Problem]:
    s = attributes(model)
    where = (model.loc.path, model.loc.line)
    out = [Problem(DF_ATTRIBUTE, m, *where) for m in s.problems]
    if side == "reference" and model.attributes.get("period") is not None:
        out.append(Problem(DF_ATTRIBUTE, "period is for services (polling), not references", *where))
    if iface is None or not s.component:
        return out
    steps, shape = plan(iface, side, s)
    out += [Problem(DF_ATTRIBUTE, m, *where) for m in shape]
    ports, source = static_ports(s, context)
    if ports is None:
        log.info("%s:%s: task %r not reachable at load time: ports checked when it connects", *where, s.component)
        return out
    _, problems = check_ports(steps, ports, s.component)
    out += [Problem(code, f"{m} (from {source})", *where) for code, m in problems]
    return out


def _owner_prefix(runtime: Host, model: Binding) -> str:
    """The path prefix ("Cell/" or "") of the component whose reference or service carries ``model``."""
    for path, node in runtime.assembly.nodes.items():
        found = any(getattr(ep, "binding", None) is model for eps in node.references.values() for ep in eps)
        found = found or any(b is model for bs in node.service_bindings.values() for b in bs)
        if found:
            head, _, _ = path.rpartition("/")
            return f"{head}/" if head else ""
    return ""


def resolve_component(runtime: Host, model: Binding, s: Attributes) -> Attributes:
    """``s`` with ``component`` resolved: a task next to the owning component (its nested
    composite's prefix) first, then a top-level one; otherwise as written (name service)."""
    if s.ns is not None or not s.component:
        return s
    prefix = _owner_prefix(runtime, model)
    for name in (prefix + s.component, s.component):
        node = runtime.assembly.nodes.get(name)
        if node is not None and node.kind == TASK_KIND:
            return dataclasses.replace(s, component=name) if name != s.component else s
    return s


def remapped(steps: list[Step], runtime: Host, s: Attributes) -> list[Step]:
    """``steps`` with their ports named as they run (the settings' remap)."""
    remap = DataflowSettings.of(runtime.settings).remap
    return [dataclasses.replace(st, port=remap.port(s.component, st.port)) for st in steps] if remap else steps


class _Link:
    """The connection of one binding to its task: which system, the proxy, state logging.

    ``proxy()`` returns the component proxy or raises ``DataflowError`` (one attempt, no
    wait). ``watch()`` (connector thread) logs appear / gone / restarted transitions.
    """

    def __init__(self, runtime: Host, s: Attributes, what: str) -> None:
        self.runtime = runtime
        self.s = s
        self.what = what
        self.host = host_of(runtime)
        node = runtime.assembly.nodes.get(s.component)
        bridges = {prefix + el.attributes.get("name", "") for prefix, el in runtime.assembly.elements_of("bridge")}
        self.local = s.ns is None and s.zenoh is None and (
            (node is not None and node.kind == TASK_KIND) or s.component in bridges)
        self.task = DataflowSettings.of(runtime.settings).remap.component(s.component)  # the name it runs under
        self._system: System | None = None
        self._proxy: ComponentProxy | None = None
        self._lock = threading.Lock()
        self._boot_id: str | None = None
        self._names: Lookups | None = None
        self._zenoh: zenoh.Session | None = None  # the Zenoh session of the lookups (zenoh="ENDPOINT")
        self._zenoh_lock = threading.Lock()
        self._closed = False
        self._looked = 0.0
        self.state = "waiting"

    @property
    def ns(self) -> str:
        """The name service used (remote tasks)."""
        return self.s.ns or self.host.ns_address

    @property
    def where(self) -> str:
        """Where the task is looked up, for messages."""
        zenoh = self.s.zenoh
        return f"Zenoh {zenoh.endpoint} (namespace {zenoh.ns})" if zenoh else self.ns

    def _lookups(self) -> Lookups:
        """A new source of lookups: the name service, or Zenoh liveliness (one session, opened once)."""
        timeout, zenoh = self.runtime.settings.timeout, self.s.zenoh
        if zenoh is None:
            from dataflow.remote.naming import NameClient

            return NameClient(self.ns, timeout=timeout, security=self.runtime.settings.security)
        from dataflow.transports.zenoh import ZenohNames

        with self._zenoh_lock:
            if self._closed:
                raise DataflowError(f"binding.dataflow {self.what}: closed")
            if self._zenoh is None:
                self._zenoh = zenoh.open(self.runtime.settings.security)
            return ZenohNames(self._zenoh, zenoh.ns, timeout=timeout, insecure=zenoh.insecure,
                              token=self.runtime.settings.security.token)

    def proxy(self) -> ComponentProxy:
        """The component proxy (created on first success); raises ``DataflowError``."""
        proxy = self._proxy
        if proxy is not None:
            return proxy
        with self._lock:
            if self._proxy is None:
                if self._system is None:
                    if self.local:
                        self._system = local_system(self.host.deployer)
                    else:
                        from dataflow.remote.client import GrpcSystem

                        self._system = GrpcSystem(self.where, timeout=self.runtime.settings.timeout,
                                                  security=self.runtime.settings.security, names=self._lookups())
                self._proxy = self._system.component(self.task)
                self._set_state("connected", "")
            return self._proxy

    def _set_state(self, state: str, detail: str) -> None:
        if state != self.state:
            where = "in this process" if self.local else f"through {self.where}"
            log.info("binding.dataflow %s: task %s %s (%s)%s", self.what, self.task, state, where, detail)
            self.state = state

    def watch(self) -> bool:
        """One look at the name service (or Zenoh): logs transitions; True while the task is registered."""
        if self.local:
            return self.task in self.host.deployer.names()
        now = time.monotonic()
        if self.state == "connected" and self._boot_id is not None and now - self._looked < 1.0:
            return True  # connected: the proxies reconnect by themselves; look once a second
        self._looked = now
        try:
            if self._names is None:
                self._names = self._lookups()
            entry = self._names.resolve(self.task)
        except DataflowError as exc:
            if self.state != "waiting":
                self._set_state("gone", f": {type(exc).__name__}")
            return False
        if self._boot_id is not None and entry.boot_id != self._boot_id:
            self._set_state("restarted", f" at {entry.address}")
            self.state = "connected"
        elif self.state == "gone":
            self._set_state("connected", f" again at {entry.address}")
        self._boot_id = entry.boot_id
        return True

    def close(self) -> None:
        """Close the system (subscriptions and writers with it) and the name client."""
        with self._lock:
            system, self._system, self._proxy = self._system, None, None
        if system is not None:
            system.close()
        names, self._names = self._names, None
        if names is not None:
            names.close()
        with self._zenoh_lock:
            self._closed = True
            session, self._zenoh = self._zenoh, None
        if session is not None:
            session.close()


class DataflowReferenceBinding(ReferenceBinding):
    """Reference side (see the module docstring). Thread-safe."""

    def __init__(self, model: Binding | None, interface: InterfaceInfo, host: Host) -> None:
        super().__init__(model, interface, host)
        assert model is not None
        attrs = resolve_component(host, model, attributes(model))
        self._link = _Link(host, attrs, f"reference {interface.name}")
        self.steps = {st.operation: st for st in remapped(plan(interface, "reference", attrs)[0], host, attrs)}
        self.attrs = dataclasses.replace(attrs, component=self._link.task)
        self._writers: dict[str, PortWriter] = {}
        self._lock = threading.Lock()
        self._watcher: Watcher | None = None
        self._checked = False
        self.calls = 0
        bindings_of(host).append(self)

    def _writer(self, port: str) -> PortWriter:
        writer = self._writers.get(port)
        if writer is None:
            with self._lock:
                writer = self._writers.get(port)
                if writer is None:
                    writer = self._writers[port] = self._link.proxy().connect_input(port, self.attrs.policy)
        return writer

    def write(self, port: str, value: object) -> None:
        """Write ``value`` to input ``port``; raises ``InvocationError`` when unreachable."""
        try:
            self._writer(port).write(value)
        except DataflowError as exc:
            raise InvocationError(f"binding.dataflow: writing {self.attrs.component}.{port} failed: {exc}",
                                  type(exc).__name__) from exc
        self.calls += 1

    def read(self, port: str) -> object:
        """The latest sample of output ``port`` (None before any)."""
        try:
            flow, value = self._link.proxy().read(port)
        except DataflowError as exc:
            raise InvocationError(f"binding.dataflow: reading {self.attrs.component}.{port} failed: {exc}",
                                  type(exc).__name__) from exc
        self.calls += 1
        return None if flow is FlowStatus.NO_DATA else value

    def invoker(self, operation: Operation, callback: object | None) -> Callable[..., object]:
        """A callable writing (one argument) or reading (none) the mapped port."""
        step = self.steps.get(operation.name)
        if step is None:
            def unusable(*args: object, **kwargs: object) -> object:
                raise InvocationError(f"binding.dataflow: operation {operation.name!r} maps to no port")
            return unusable
        port = step.port
        bind = self._binder(operation.name, port, step.kind == "read")
        if step.kind == "read":
            def read(*args: object, **kwargs: object) -> object:
                bind(args, kwargs)
                return self.read(port)
            return read
        if operation.oneway:
            submit = self.host.submit

            def send(*args: object, **kwargs: object) -> None:
                submit(self.write, port, bind(args, kwargs))
            return send

        def write(*args: object, **kwargs: object) -> None:
            return self.write(port, bind(args, kwargs))
        return write

    def _binder(self, name: str, port: str, read: bool) -> Callable[[tuple[object, ...], dict[str, object]], object]:
        """Binds a call's arguments as the interface method's signature does (so the
        interface's own parameter names work); returns the one value written (reads: none).
        A wrong call raises ``InvocationError`` naming the operation and the port."""
        method = getattr(self.interface.python_type, name, None) if self.interface.python_type else None
        sig: inspect.Signature | None = None
        try:
            if method is not None:
                sig = inspect.signature(method)
                params = list(sig.parameters.values())
                if params and params[0].name in ("self", "cls"):
                    sig = sig.replace(parameters=params[1:])
        except (TypeError, ValueError):
            sig = None
        where = f"binding.dataflow: {self.interface.name}.{name} (port {self.attrs.component}.{port})"

        def bind(args: tuple[object, ...], kwargs: dict[str, object]) -> object:
            if sig is not None:
                try:
                    bound = sig.bind(*args, **kwargs)
                except TypeError as exc:
                    raise InvocationError(f"{where}: {exc}") from None
                values = list(bound.arguments.values())
            else:
                values = [*args, *kwargs.values()]
            if read:
                if values:
                    raise InvocationError(f"{where}: reads the port and takes no argument, got {len(values)}")
                return None
            if len(values) != 1:
                raise InvocationError(f"{where}: writes one value to the port, got {len(values)} argument(s)")
            return values[0]
        return bind

    def start(self) -> None:
        """Start the connector (remote tasks: connect when it appears, log changes)."""
        self._watcher = Watcher(f"scart-df-ref-{self.attrs.component}", self._step, interval=0.25)
        self._watcher.start()

    def _step(self) -> None:
        if not self._link.watch() or self._checked:
            return
        try:
            ports = self._link.proxy().describe().ports
        except DataflowError:
            return
        self._checked = True  # the load-time check could not reach the task: check it now, once
        infos = {p.name: PortInfo(p.name, p.direction, p.type_name) for p in ports}
        for _code, msg in check_ports(list(self.steps.values()), infos, self.attrs.component)[1]:
            log.error("binding.dataflow %s: %s", self.model.loc if self.model else "?", msg)

    def stop(self) -> None:
        """Stop the connector, close writers and the connection (idempotent)."""
        if self._watcher is not None:
            self._watcher.stop()
        with self._lock:
            writers, self._writers = list(self._writers.values()), {}
        for w in writers:
            try:
                w.close()
            except DataflowError:
                pass
        self._link.close()


class DataflowServiceBinding(ServiceBinding):
    """Service side (see the module docstring): samples invoke operations."""

    def __init__(self, model: Binding, endpoint: ServiceEndpoint, host: Host) -> None:
        super().__init__(model, endpoint, host)
        attrs = resolve_component(host, model, attributes(model))
        self._link = _Link(host, attrs, f"service {endpoint.component}/{endpoint.service}")
        self.steps: list[Step] = remapped(plan(endpoint.interface, "service", attrs)[0], host, attrs)
        self.attrs = dataclasses.replace(attrs, component=self._link.task)
        self._subs: list[Subscription] = []
        self._watcher: Watcher | None = None
        self.delivered = 0
        self.failures = 0
        self.last_latency = 0.0
        bindings_of(host).append(self)

    @property
    def dropped(self) -> int:
        """Samples lost to the policy while the component was busy (all subscriptions)."""
        return sum(s.dropped for s in list(self._subs))

    @property
    def connected(self) -> bool:
        """True when subscribed and every subscription can receive."""
        return bool(self._subs) and all(s.connected for s in list(self._subs))

    @property
    def address(self) -> str | None:
        """``dataflow:COMPONENT`` (``@NS`` for a remote task)."""
        where = "" if self._link.local else f"@{self._link.ns}"
        return f"dataflow:{self.attrs.component}{where}"

    def start(self) -> None:
        """Subscribe now if the task is there, else when it appears (connector thread)."""
        self._watcher = Watcher(f"scart-df-svc-{self.attrs.component}", self._step, interval=0.25)
        self._watcher.start()

    def _step(self) -> None:
        present = self._link.watch()
        if self._subs or not present:
            return
        try:
            proxy = self._link.proxy()
            ports = {p.name: p for p in proxy.describe().ports}
        except DataflowError:
            return
        infos = {n: PortInfo(n, p.direction, p.type_name) for n, p in ports.items()}
        steps, problems = check_ports(self.steps, infos, self.attrs.component)
        for _code, msg in problems:
            log.error("binding.dataflow %s: %s (operation left out)", self.model.loc, msg)
        subs = []
        try:
            for st in steps:
                subs.append(proxy.subscribe(st.port, self._observer(st.operation), policy=self.attrs.policy,
                                            period=self.attrs.period, on_gap=self._on_gap))
        except DataflowError as exc:
            for sub in subs:
                sub.close()
            log.info("binding.dataflow %s: subscribing to %s failed: %s", self.model.loc, self.attrs.component, exc)
            return
        self._subs = subs
        log.info("binding.dataflow %s: %d operation(s) of %s/%s driven by %s", self.model.loc, len(subs),
                 self.endpoint.component, self.endpoint.service, self.attrs.component)

    def _on_gap(self, gap: GapEvent) -> None:
        """The subscription was cut and resumed by itself (the task's deployer restarted or
        stalled): say so, even when the name-service watch did not see it go."""
        log.info("binding.dataflow %s: task %s restarted or stalled: samples of %s resumed after %.2f s (%s)",
                 self.model.loc, gap.component, gap.port, gap.duration, gap.reason)

    def _observer(self, operation: str) -> Callable[[SampleEvent], None]:
        call = self.endpoint.operation(operation, None)

        def observe(event: SampleEvent) -> None:
            try:
                call(event.value)
            except Exception:
                self.failures += 1
                raise
            finally:
                self.delivered += 1
                self.last_latency = time.time() - event.source_time

        return observe

    def stop(self) -> None:
        """Stop the connector and every subscription (idempotent)."""
        if self._watcher is not None:
            self._watcher.stop()
        subs, self._subs = self._subs, []
        for sub in subs:
            sub.close()
        self._link.close()

