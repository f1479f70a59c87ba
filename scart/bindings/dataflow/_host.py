"""Shared plumbing of ``implementation.task``, ``scart:connect`` and ``binding.dataflow``.

* :class:`DataflowHost` — one per runtime (``host_of(runtime)``): the runtime's
  :class:`dataflow.Deployer`, the gRPC server serving it (when the settings say
  ``serve``, as ``scart run`` does, or :meth:`DataflowHost.serve` is called) and the
  name-service address this runtime uses for data-flow components that are not local.
  It is the extension's participant: started after every component's ``@init``, it
  serves the tasks; it closes its server at the very end of the runtime's stop.
* Port introspection for the static checks: :func:`class_ports` (a TaskContext class,
  from its declared ports) and :func:`remote_ports` (a task found through a name
  service, with a short deadline; None when unreachable).
* :class:`Watcher` — a small owned thread that calls ``step()`` every ``interval`` s
  until stopped: the connectors of bindings and cross-deployer connects run on it.

Thread-safety: every method of :class:`DataflowHost` is thread-safe; ``close`` is
idempotent.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dataflow import DataflowError, Deployer, OutputPort, TaskContext, registry
from dataflow.deployer import Server
from dataflow.threads import OwnedThread
from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import Host, Participant

if TYPE_CHECKING:
    from scart_wire.security import Security

log = logging.getLogger("scart.dataflow")

TASK_KIND = "implementation.task"


@dataclass(frozen=True)
class PortInfo:
    """A port as the checks see it."""

    name: str
    direction: str  # "in" | "out"
    type_name: str


def class_ports(cls: type[TaskContext]) -> dict[str, PortInfo]:
    """The ports a TaskContext class declares, by port name (no instance is created)."""
    out: dict[str, PortInfo] = {}
    for port in getattr(cls, "_port_templates", {}).values():
        direction = "out" if isinstance(port, OutputPort) else "in"
        out[port.name] = PortInfo(port.name, direction, port.type_name)
    return out


def remote_ports(ns: str, component: str, timeout: float = 1.0,
                 security: Security | None = None) -> dict[str, PortInfo] | None:
    """The ports of ``component`` registered in the name service at ``ns``; None when the
    name service does not answer or does not know the component (never raises)."""
    from dataflow import DataflowError
    from dataflow.remote import Security, connect

    try:
        system = connect(ns, timeout=timeout, security=security or Security())
    except DataflowError:
        return None
    try:
        ports = system.component(component).describe().ports
        return {p.name: PortInfo(p.name, p.direction, p.type_name) for p in ports}
    except DataflowError:
        return None
    finally:
        system.close()


def type_name_of(annotation: object) -> str | None:
    """The registry name of a Python annotation; None when it says nothing checkable
    (missing, ``Any``, ``object``). ``T | None`` counts as ``T``."""
    import inspect
    import types
    import typing

    if annotation in (None, inspect.Parameter.empty, Any, object) or isinstance(annotation, str):
        return None
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) != 1:
            return None
        annotation = args[0]
    return registry.type_name(annotation)


class Watcher:
    """An owned thread calling ``step()`` every ``interval`` s until :meth:`stop`.

    ``step`` exceptions are logged, never fatal. :meth:`stop` signals, then joins (≤ 5 s);
    idempotent; safe from inside ``step``.
    """

    def __init__(self, name: str, step: Callable[[], None], interval: float = 0.2) -> None:
        self._step = step
        self._interval = interval
        self._thread = OwnedThread(self._run, name)

    def start(self) -> None:
        """Start the thread (once)."""
        self._thread.start()

    @property
    def stopping(self) -> bool:
        """True once :meth:`stop` was called."""
        return self._thread.stopping.is_set()

    def _run(self, stopping: threading.Event) -> None:
        while not stopping.is_set():
            try:
                self._step()
            except Exception:  # noqa: BLE001 - a connector bug must not end the thread
                log.exception("%s: step failed", self._thread.name)
            if stopping.wait(self._interval):
                return

    def stop(self) -> None:
        """Signal and join (unless called from the thread itself)."""
        self._thread.stop()


class DataflowHost(Participant):
    """The data-flow side of one runtime: its deployer, optional server, name service."""

    def __init__(self, host: Host) -> None:
        self.host = host
        self.deployer = Deployer()
        self.server: Server | None = None
        self._ns: str | None = None
        self._lock = threading.Lock()
        self._closed = False
        self._served: dict[str, str] = {}

    @property
    def ns_address(self) -> str:
        """The name service for non-local components: the one this runtime serves or
        joined (:meth:`serve`), else the settings' (``ns``, else the default address)."""
        return self._ns or DataflowSettings.of(self.host.settings).ns_address

    def serve(self, address: str = "127.0.0.1:0", ns: str | None = None) -> Server:
        """Serve the deployer over gRPC (``ns=None``: embedded name service at ``address``;
        else register with the name service at ``ns``). Raises what ``Deployer.serve``
        raises, and ``DataflowError`` when already serving or closed (one server per runtime)."""
        with self._lock:
            if self._closed or self.server is not None:
                raise DataflowError(f"the runtime's tasks are {'closed' if self._closed else 'served already'}")
            server = self.deployer.serve(address, ns=ns, security=self.host.settings.security)
            self.server = server
            self._ns = server.ns_address
        return server

    def start(self) -> None:
        """With ``settings.serve`` and tasks in the composite: serve them (at the settings'
        ``listen``, else a free loopback port), joining the name service answering at the
        settings' address, else embedding one there (at a free port when no address was
        given and that one cannot be bound; at ``listen`` when it is given and ``ns`` is
        not). Raises ``DataflowError`` when serving fails, or when ``listen`` and ``ns``
        are both given and no name service answers at ``ns``."""
        settings = self.host.settings
        own = DataflowSettings.of(settings)
        from dataflow.launch import ros as _ros

        try:  # the process's ROS node speaks for these tasks (their properties its parameters)
            _ros.attach(self.deployer)
        except ValueError as exc:
            raise DataflowError(str(exc)) from None
        if self.server is not None or not own.serve:
            return  # served already (by a program calling serve()), or not asked to
        if not any(n.kind == TASK_KIND for n in self.host.assembly.nodes.values()) and not \
                self.host.assembly.elements_of("bridge") and not self.host.assembly.elements_of("frames"):
            return
        from dataflow.remote.errors import UnavailableError
        from dataflow.remote.naming import name_service_answers

        ns = own.ns_address
        joined = name_service_answers(ns, security=settings.security)
        if joined:
            server = self.serve(own.listen or "127.0.0.1:0", ns=ns)
        elif own.listen and own.listen != ns:
            if own.ns is not None:
                raise DataflowError(f"--listen {own.listen}: no name service answers at {ns} (--ns) to register "
                                    f"with; start one (scart nameserver --listen {ns}), or drop --listen to embed it "
                                    "there")
            server = self.serve(own.listen)  # no name service asked for: the embedded one is here
        else:
            try:
                server = self.serve(ns)
            except UnavailableError:
                if own.ns is not None:  # given explicitly: no other address will do
                    raise
                server = self.serve("127.0.0.1:0")
        self._served = {"dataflow server": f"{server.listen_address} ({len(self.deployer.names())} task(s))",
                        "name service": f"{server.ns_address} ({'joined' if joined else 'embedded'})"}

    def stop(self) -> None:
        """Nothing here: the server outlives every component and closes at the end (:meth:`close`)."""

    def addresses(self) -> dict[str, str]:
        """The data-flow server and the name service, once served."""
        return dict(self._served)

    def refresh(self) -> None:
        """Publish tasks added after serving started (embedded name service)."""
        server = self.server
        if server is not None:
            server.refresh_names()

    def close(self) -> None:
        """Stop the server (idempotent); afterwards :meth:`serve` refuses."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            server, self.server = self.server, None
        if server is not None:
            server.stop()
        from dataflow.launch import ros as _ros

        _ros.detach(self.deployer)


def host_of(host: Host) -> DataflowHost:
    """The :class:`DataflowHost` of a runtime (created, with a stop hook, on first use)."""

    def make() -> DataflowHost:
        dataflow_host = DataflowHost(host)
        host.add_stop_hook(dataflow_host.close)
        return dataflow_host

    return host.shared("scart.bindings.dataflow.host", make)
