"""Shared plumbing of ``implementation.task``, ``scart:connect`` and ``binding.dataflow``.

* :class:`DataflowHost` — one per runtime (``host_of(runtime)``): the runtime's
  :class:`dataflow.Deployer`, the gRPC server serving it (when ``scart run`` or
  :meth:`DataflowHost.serve` asked for one) and the name-service address this runtime
  uses for data-flow components that are not local.
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
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dataflow import Deployer, OutputPort, TaskContext, registry
from dataflow.remote.defaults import DEFAULT_NS_ADDRESS, NS_ENV

if TYPE_CHECKING:
    from dataflow.remote.client import GrpcSystem
    from dataflow.remote.server import DeployerServer

log = logging.getLogger("scart.dataflow")

#: Name service used at load time for checks of remote tasks when an element names none
#: (``scart run --ns`` sets it before loading; else the ``SCART_NS`` environment variable).
AMBIENT_NS: dict[str, str] = {}


def ambient_ns() -> str | None:
    """The name service known before a runtime exists (``scart run --ns``, else ``SCART_NS``)."""
    return AMBIENT_NS.get("address") or os.environ.get(NS_ENV) or None


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


def remote_ports(ns: str, component: str, timeout: float = 1.0) -> dict[str, PortInfo] | None:
    """The ports of ``component`` registered in the name service at ``ns``; None when the
    name service does not answer or does not know the component (never raises)."""
    from dataflow import DataflowError
    from dataflow.remote import connect

    try:
        system = connect(ns, timeout=timeout)
    except DataflowError:
        return None
    try:
        ports = system.component(component).describe().ports
        return {p.name: PortInfo(p.name, p.direction, p.type_name) for p in ports}
    except DataflowError:
        return None
    finally:
        system.close()


def type_name_of(annotation: Any) -> str | None:
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
    """An owned daemon thread calling ``step()`` every ``interval`` s until :meth:`stop`.

    ``step`` exceptions are logged, never fatal. :meth:`stop` signals, then joins (≤ 5 s);
    idempotent; safe from inside ``step``.
    """

    def __init__(self, name: str, step: Callable[[], None], interval: float = 0.2) -> None:
        self._step = step
        self._interval = interval
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        """Start the thread (once)."""
        self._thread.start()

    @property
    def stopping(self) -> bool:
        """True once :meth:`stop` was called."""
        return self._stop.is_set()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._step()
            except Exception:  # noqa: BLE001 - a connector bug must not end the thread
                log.exception("%s: step failed", self._thread.name)
            if self._stop.wait(self._interval):
                return

    def stop(self) -> None:
        """Signal and join (unless called from the thread itself)."""
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=5.0)


class DataflowHost:
    """The data-flow side of one runtime: its deployer, optional server, name service."""

    def __init__(self, deployer: Deployer) -> None:
        self.deployer = deployer
        self.server: DeployerServer | None = None
        self._ns: str | None = None
        self._system: GrpcSystem | None = None
        self._lock = threading.Lock()
        self._closed = False

    @property
    def ns_address(self) -> str:
        """The name service for non-local components: the one set by :meth:`serve` /
        :meth:`use_ns`, else ``SCART_NS``, else the default address."""
        return self._ns or ambient_ns() or DEFAULT_NS_ADDRESS

    def use_ns(self, address: str) -> None:
        """Resolve non-local components through the name service at ``address``."""
        self._ns = address

    def serve(self, address: str = "127.0.0.1:0", ns: str | None = None) -> DeployerServer:
        """Serve the deployer over gRPC (``ns=None``: embedded name service at ``address``;
        else register with the name service at ``ns``). Raises what ``Deployer.serve`` raises."""
        server = self.deployer.serve(address, ns=ns)
        with self._lock:
            self.server = server
            self._ns = server.ns_address
        return server

    def refresh(self) -> None:
        """Publish tasks added after serving started (embedded name service)."""
        server = self.server
        if server is not None:
            server.refresh_names()

    def system(self, timeout: float = 2.0) -> GrpcSystem:
        """A client of the name service (created on first use, shared; raises
        ``UnavailableError`` when nothing answers)."""
        from dataflow.remote.client import GrpcSystem

        with self._lock:
            if self._system is None:
                self._system = GrpcSystem(self.ns_address, timeout=timeout)
            return self._system

    def close(self) -> None:
        """Close the client and stop the server (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            system, self._system = self._system, None
            server, self.server = self.server, None
        if system is not None:
            system.close()
        if server is not None:
            server.stop()


def host_of(runtime: Any) -> DataflowHost:
    """The :class:`DataflowHost` of ``runtime`` (created, with a stop hook, on first use)."""

    def make() -> DataflowHost:
        host = DataflowHost(runtime.shared("deployer", Deployer))
        runtime.add_stop_hook(host.close)
        return host

    return runtime.shared("dataflow.host", make)
