"""A ROS 1 node without rospy: :class:`Node` (see the package docstring for the story)."""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any, TypeVar

from .control import Control, Registrar
from .io import Conn, Counters, InboundConn, IoLoop, Listener
from .master import Master, MasterError, MasterUnreachable, XmlRpcValue
from .msgs import MessageTypes
from .names import NodeNames, node_names
from .services import ServiceServer, Worker, call_service
from .rpcserver import RpcServer
from .slave import SlaveApi
from .tcpros import Limits, encode_header
from .topics import Publisher, Subscriber

_P = TypeVar("_P", Publisher, Subscriber, ServiceServer)  #: a part of the node, kept in its table

__all__ = ["Node"]

log = logging.getLogger(__name__)

NODE_COUNTERS = (
    "malformed_headers", "stalled_peers", "oversized_messages", "md5_mismatches", "peer_disconnects",
    "refused_connections", "connect_failures", "callback_errors", "service_errors", "xmlrpc_bad_requests",
    "master_retries", "master_reregistrations", "idle_closed", "restarts",
)


def _advertised_host(host: str, env: Mapping[str, str]) -> str:
    """The name peers are told: ``host``, or for a wildcard ROS_HOSTNAME/ROS_IP/the hostname."""
    if host not in ("", "0.0.0.0", "::"):
        return host
    return env.get("ROS_HOSTNAME") or env.get("ROS_IP") or socket.gethostname()


class Node:
    """A ROS 1 node: its XML-RPC API, TCPROS listener, io and control threads.

    ``name`` is a base name; ``namespace``, ``remaps`` (``["from:=to", "__ns:=/x"]`` or a
    mapping) and ``master_uri`` resolve as :mod:`.names` says. ``host``: where the XML-RPC
    API and TCPROS listen (loopback by default; another host opens them there, a wildcard
    is advertised as ``ROS_HOSTNAME``/``ROS_IP``/the hostname). ``types``: a shared
    :class:`MessageTypes` (else one of its own). ``limits``: the bounds on peers.
    ``master_timeout``: s per master call; ``master_poll``: s between checks that the
    master still knows the node. ``respawn``: a peer's ``shutdown`` (``rosnode kill``)
    restarts the node (everything unregistered, then registered again at once) instead
    of closing it. ``read_only``: the node only publishes: :meth:`subscribe` and
    :meth:`advertise_service` raise ``PermissionError`` and a peer's ``shutdown`` is
    refused. ``env`` stands for ``os.environ`` (tests).

    The constructor starts the servers and threads and raises ``OSError`` if a port
    cannot be bound, :class:`~.names.RosNameError` for a bad name, remap or master URI,
    ``ValueError`` for a bad timeout. Registration with the master is asynchronous: a
    master that is down is waited for (logged, retried). Thread-safe; :meth:`close`
    (idempotent) unregisters and ends every thread.
    """

    def __init__(
        self,
        name: str,
        *,
        master_uri: str | None = None,
        host: str = "127.0.0.1",
        namespace: str | None = None,
        remaps: Iterable[str] | Mapping[str, str] | None = None,
        types: MessageTypes | None = None,
        limits: Limits | None = None,
        master_timeout: float = 3.0,
        master_poll: float = 1.0,
        respawn: bool = False,
        read_only: bool = False,
        env: Mapping[str, str] | None = None,
    ) -> None:
        env = os.environ if env is None else env
        for what, value in (("master_timeout", master_timeout), ("master_poll", master_poll)):
            if not (isinstance(value, (int, float)) and 0 < value < float("inf")):
                raise ValueError(f"{what} must be a finite number of seconds > 0, not {value!r}")
        self.names: NodeNames = node_names(name, namespace=namespace, master_uri=master_uri, remaps=remaps, env=env)
        self.caller_id: str = self.names.node
        self.master_uri: str = self.names.master_uri
        self.types = types if types is not None else MessageTypes()
        self.limits = limits if limits is not None else Limits()
        self.counters = Counters(*NODE_COUNTERS)
        self.host, self.advertised_host = host, _advertised_host(host, env)
        self.master = Master(self.master_uri, self.caller_id, master_timeout)
        self._lock = threading.Lock()
        self._pubs: dict[str, Publisher] = {}
        self._subs: dict[str, Subscriber] = {}
        self._srvs: dict[str, ServiceServer] = {}
        self._worker: Worker | None = None
        self._closed = threading.Event()
        self.respawn, self.read_only = respawn, read_only
        self.shutdown_reason: str | None = None  #: who asked it to shut down, and why (``CALLER: reason``)
        self._shutdown_hooks: list[Callable[[str, str], None]] = []
        self._params: dict[str, Callable[[str, XmlRpcValue], None]] = {}  # namespace/ -> callback
        self._start(master_poll)

    def _start(self, master_poll: float) -> None:
        self.loop = IoLoop(self.caller_id)
        self._listener: Listener | None = None
        self._slave: RpcServer | None = None
        try:
            self._listener = Listener(self.loop, self.host, 0, self._accept)
            self._slave = RpcServer(SlaveApi(self), self.host, 0, self.counters, self.caller_id,
                                      self.limits.xmlrpc_bytes, self.limits.xmlrpc_seconds)
        except OSError:
            if self._listener is not None:
                self._listener.close()
            raise
        self.tcpros_port: int = self._listener.port
        self.uri: str = f"http://{_url_host(self.advertised_host)}:{self._slave.port}/"
        self._registrar = Registrar(self.master, self.uri, master_poll, self.counters, self._on_publishers,
                                    self._on_param)
        self.control = Control(self.caller_id, self._registrar.tick)
        self.loop.start()
        self.loop.call_later(max(0.05, self.limits.idle_seconds / 4), self._sweep_idle)
        self._listener.start()
        self._slave.start()
        self.control.start()

    def __repr__(self) -> str:
        return f"Node({self.caller_id!r}, uri={self.uri!r}, master={self.master_uri!r})"

    def __enter__(self) -> Node:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- the public API -------------------------------------------------------------------
    def resolve(self, name: str) -> str:
        """``name`` resolved for this node (namespace, ``~``, remaps); raises ``RosNameError``."""
        return self.names.resolve(name)

    def advertise(self, topic: str, type_name: str, *, latch: bool = False, queue_size: int | None = None,
                  queue_bytes: int | None = None) -> Publisher:
        """Publish ``topic`` as ``type_name`` (``pkg/Type``); registers with the master.

        ``queue_size``/``queue_bytes`` bound what waits for each slow subscriber (the
        node's :class:`~.tcpros.Limits` by default). Raises ``UnknownTypeError``,
        ``RosNameError``, or ``ValueError`` if this node already publishes ``topic``.
        """
        resolved, msgtype = self.resolve(topic), self.types.msg(type_name)
        queue = (queue_size or self.limits.queue_size, queue_bytes or self.limits.queue_bytes)
        if min(queue) < 1:
            raise ValueError(f"queue bounds of {resolved} must be >= 1, not {queue}")
        pub = Publisher(self, resolved, msgtype, latch, *queue)
        self._add(self._pubs, resolved, pub, "publishes")
        self._want(("pub", resolved), (msgtype.name,))
        return pub

    def subscribe(self, topic: str, type_name: str, callback: Callable[[Any], None], *, raw: bool = False,
                  tcp_nodelay: bool = True) -> Subscriber:
        """Subscribe to ``topic``; ``callback(msg)`` runs on the node's io thread — keep it short.

        With ``raw=True`` the callback gets the message's ROS 1 bytes, and ``type_name``
        may be ``"*"`` (any type, as ``rostopic hz`` subscribes). Raises as :meth:`advertise`.
        """
        self._writable("subscribe to", topic)
        resolved = self.resolve(topic)
        if type_name == "*" and not raw:
            raise ValueError("type '*' (any type) needs raw=True: there is no type to decode with")
        msgtype = None if type_name == "*" else self.types.msg(type_name)
        sub = Subscriber(self, resolved, msgtype, callback, raw, tcp_nodelay)
        self._add(self._subs, resolved, sub, "subscribes to")
        self._want(("sub", resolved), (type_name if msgtype is None else msgtype.name,))
        return sub

    def advertise_service(self, service: str, type_name: str, handler: Callable[[Any], object]) -> ServiceServer:
        """Serve ``service`` as ``type_name`` (``pkg/Srv``): ``handler(request) -> response``.

        Handlers run one at a time on the node's service thread. Raises as :meth:`advertise`.
        """
        self._writable("serve", service)
        resolved, srvtype = self.resolve(service), self.types.srv(type_name)
        srv = ServiceServer(self, resolved, srvtype, handler)
        self._add(self._srvs, resolved, srv, "serves")
        self._want(("srv", resolved), (f"rosrpc://{_url_host(self.advertised_host)}:{self.tcpros_port}",))
        return srv

    def _writable(self, verb: str, name: str) -> None:
        if self.read_only:
            raise PermissionError(f"node {self.caller_id} is read-only (it publishes only): it does not {verb} {name}")

    def call_service(self, service: str, type_name: str, request: object, timeout: float = 5.0) -> object:
        """Call ``service`` with ``request`` and return the response (blocks ≤ ``timeout`` s).

        Raises :class:`~.services.ServiceError` (no such service, refused, its error,
        no answer in time), ``ValueError``/``TypeError`` for a bad request, and
        ``RuntimeError`` when called on the io thread (from a subscriber callback).
        """
        if not (0 < timeout < float("inf")):
            raise ValueError(f"timeout must be a finite number of seconds > 0, not {timeout!r}")
        if self.loop.in_loop() and not self.closed:
            raise RuntimeError("call_service from a subscriber callback would block the node's io thread")
        return call_service(self, self.resolve(service), self.types.srv(type_name), request, timeout)

    # -- parameters (the master's parameter server) -----------------------------------------
    def get_param(self, key: str, default: XmlRpcValue = None) -> XmlRpcValue:
        """The parameter ``key`` (resolved: ``~x`` is private), ``default`` when unset.
        Blocks ≤ the master timeout; raises :class:`~.master.MasterUnreachable`."""
        try:
            return self.master.get_param(self.resolve(key))
        except MasterUnreachable:
            raise
        except MasterError:
            return default

    def set_param(self, key: str, value: XmlRpcValue) -> None:
        """Set the parameter ``key`` (resolved) to ``value`` (an XML-RPC value; a dict sets
        a namespace). Blocks ≤ the master timeout; raises :class:`~.master.MasterError`."""
        self.master.set_param(self.resolve(key), value)

    def subscribe_param(self, key: str, callback: Callable[[str, XmlRpcValue], None]) -> str:
        """Call ``callback(key, value)`` with ``key``'s value (``{}`` when unset; a dict for a
        namespace) once subscribed, and with each change of ``key`` or a name under it
        (a peer's ``setParam``: ``rosparam set``), on the control thread, as rospy's
        parameter cache is kept. Kept subscribed across master restarts. Returns the
        resolved key; raises ``RosNameError``, ``ValueError`` if subscribed already."""
        resolved = self.resolve(key)
        with self._lock:
            if resolved in self._params:
                raise ValueError(f"node {self.caller_id} subscribes to parameter {resolved} already")
            self._params[resolved] = callback
        self._want(("param", resolved), ())
        return resolved

    def unsubscribe_param(self, key: str) -> None:
        """Stop :meth:`subscribe_param`'s callbacks for ``key`` (idempotent)."""
        resolved = self.resolve(key)
        with self._lock:
            if self._params.pop(resolved, None) is None:
                return
        if not self._closed.is_set():
            self._registrar.drop(("param", resolved))
            self.control.tick_now()

    def param_update(self, key: str, value: XmlRpcValue) -> None:
        """A ``paramUpdate`` from the master (the XML-RPC thread): each subscription under
        which ``key`` lies is told, on the control thread."""
        key = key.rstrip("/") or "/"
        for sub, callback in list(self._params.items()):
            if key == sub or key.startswith(sub.rstrip("/") + "/"):
                self.control.submit(callback, key, value)

    def _on_param(self, key: str, value: XmlRpcValue) -> None:
        callback = self._params.get(key)
        if callback is not None:
            callback(key, value)

    def master_for(self, timeout: float) -> Master:
        """A client of this node's master whose calls time out after ``timeout`` s."""
        return Master(self.master_uri, self.caller_id, timeout)

    def wait_registered(self, timeout: float = 5.0) -> bool:
        """Block until the master knows everything this node offers and wants (True), or timeout."""
        return self._registrar.wait_registered(timeout)

    def is_registered(self, kind: str, name: str) -> bool:
        """Whether the master knows this node's ``kind`` (``pub``, ``sub``, ``srv``) ``name`` now."""
        return self._registrar.is_registered((kind, self.resolve(name)))

    @property
    def master_reachable(self) -> bool:
        """False while the node waits for a master that does not answer."""
        return self._registrar.master_reachable

    @property
    def closed(self) -> bool:
        return self._closed.is_set()

    def add_shutdown_hook(self, hook: Callable[[str, str], None]) -> None:
        """Call ``hook(caller_id, reason)`` when a peer's ``shutdown`` (``rosnode kill``) has
        closed the node, as ``rospy.on_shutdown`` (on the node's control thread; not with
        ``respawn``, which restarts instead, nor on :meth:`close`)."""
        self._shutdown_hooks.append(hook)

    def wait_closed(self, timeout: float | None = None) -> bool:
        """Block until the node is closed (by :meth:`close` or a peer's ``shutdown``)."""
        return self._closed.wait(timeout)

    def close(self, timeout: float = 5.0) -> None:
        """Unregister from the master (one quick try), close every connection, end every thread.

        Idempotent; safe from any thread, its own included (it then only signals them).
        """
        with self._lock:
            if self._closed.is_set():
                return
            self._closed.set()
            parts: list[Publisher | Subscriber | ServiceServer] = [*self._pubs.values(), *self._subs.values(),
                                                                   *self._srvs.values()]
        self.control.close(timeout)
        self._registrar.unregister_all(min(1.0, self.master.timeout))
        for part in parts:
            part.closed = True
        if self._slave is not None:
            self._slave.close(timeout)
        self.loop.close(timeout)
        if self._worker is not None:
            self._worker.close(timeout)

    # -- helpers for the parts ------------------------------------------------------------
    def _add(self, table: dict[str, _P], name: str, part: _P, verb: str) -> None:
        with self._lock:
            if self._closed.is_set():
                raise RuntimeError(f"node {self.caller_id} is closed")
            if name in table:
                raise ValueError(f"node {self.caller_id} already {verb} {name}: share that object, or close it first")
            table[name] = part

    def _want(self, key: tuple[str, str], args: tuple[str, ...]) -> None:
        self._registrar.want(key, args)
        self.control.tick_now()

    def _drop(self, table: dict[str, _P], name: str, part: _P, key: tuple[str, str]) -> None:
        with self._lock:
            if table.get(name) is not part:
                return
            del table[name]
        if not self._closed.is_set():
            self._registrar.drop(key)
            self.control.tick_now()

    def _drop_publisher(self, pub: Publisher) -> None:
        self._drop(self._pubs, pub.topic, pub, ("pub", pub.topic))

    def _drop_subscriber(self, sub: Subscriber) -> None:
        self._drop(self._subs, sub.topic, sub, ("sub", sub.topic))

    def _drop_service(self, srv: ServiceServer) -> None:
        self._drop(self._srvs, srv.name, srv, ("srv", srv.name))

    def worker(self) -> Worker:
        """The node's service thread, started on first use."""
        with self._lock:
            if self._worker is None:
                self._worker = Worker(self.caller_id)
            return self._worker

    def _on_publishers(self, topic: str, uris: list[str]) -> None:
        sub = self._subs.get(topic)
        if sub is not None:
            sub.update_publishers(uris)

    # -- the io thread: accepted connections ----------------------------------------------
    def _accept(self, sock: socket.socket, addr: Any) -> None:
        peer, limits = f"{addr[0]}:{addr[1]}", self.limits
        open_now = self.loop.owned()
        full = open_now >= limits.max_connections
        if not full:
            from_peer = sum(1 for c in self.loop.connections() if isinstance(c, InboundConn) and c.address == addr[0])
            full = from_peer >= limits.max_per_peer
        if full:
            self.counters["refused_connections"] += 1
            n = self.counters["refused_connections"]
            if n & (n - 1) == 0:  # the 1st, 2nd, 4th... refusal: a flood is said, not echoed
                why = (f"{open_now} connections open" if open_now >= limits.max_connections
                       else f"{limits.max_per_peer} connections open from {addr[0]}")
                log.warning("ROS 1 node %s: %s: refusing %s (%d refused so far)", self.caller_id, why, peer, n)
            sock.close()
            return
        conn = InboundConn(self.loop, sock, peer, limits.max_header, self._route, self.counters)
        conn.address = addr[0]
        self.loop.register(sock, conn)
        conn.expect_header_within(limits.header_timeout)

    def _sweep_idle(self) -> None:
        """Close the connections idle past ``Limits.idle_seconds`` (io thread, re-armed)."""
        if self.closed:
            return
        now, bound = time.monotonic(), self.limits.idle_seconds
        for conn in self.loop.connections():
            if conn.idle_kind and not conn.closed and conn.idle_for(now) >= bound:
                self.counters["idle_closed"] += 1
                log.info("ROS 1 node %s: %s connection %s idle for %.0f s: closed", self.caller_id, conn.idle_kind,
                         conn.peer, bound)
                conn.close("idle")
        self.loop.call_later(max(0.05, bound / 4), self._sweep_idle)

    def _route(self, conn: InboundConn, header: dict[str, str]) -> None:
        if "service" in header:
            part: ServiceServer | Publisher | None = self._srvs.get(header["service"])
            missing = f"{self.caller_id} does not serve {header['service']}"
        elif "topic" in header:
            part = self._pubs.get(header["topic"])
            missing = f"{self.caller_id} does not publish {header['topic']}"
        else:
            self.counters["malformed_headers"] += 1
            log.warning("ROS 1 node %s: header from %s names neither topic nor service: dropped", self.caller_id, conn.peer)
            part, missing = None, "header names neither a topic nor a service"
        if part is None or part.closed:
            conn.send(encode_header({"error": missing}), droppable=False)
            conn.close_when_flushed()
            return
        part.accept(conn, header)

    # -- the slave API's questions (its thread) -------------------------------------------
    def publications(self) -> list[list[str]]:
        return [[p.topic, p.type.name] for p in list(self._pubs.values())]

    def subscriptions(self) -> list[list[str]]:
        return [[s.topic, s.type.name if s.type else "*"] for s in list(self._subs.values())]

    def tcpros_endpoint(self, topic: str) -> tuple[str, int] | None:
        return (self.advertised_host, self.tcpros_port) if topic in self._pubs else None

    def publisher_update(self, topic: str, uris: list[str]) -> None:
        sub = self._subs.get(topic)
        if sub is not None:
            self.control.submit(sub.update_publishers, uris)

    def request_shutdown(self, caller_id: str, reason: str) -> bool:
        """A peer's ``shutdown`` (the XML-RPC thread); False when refused (read-only)."""
        if self.read_only:
            log.warning("ROS 1 node %s: %s asked it to shut down: refused (read-only)", self.caller_id, caller_id)
            return False
        self.shutdown_reason = f"{caller_id}: {reason or '(no reason)'}"
        if self.respawn:
            log.warning("ROS 1 node %s: %s asked it to shut down (%s): it restarts (respawn)", self.caller_id,
                        caller_id, reason or "no reason")
            self.control.submit(self._restart)
            return True
        log.warning("ROS 1 node %s: %s asked it to shut down: %s", self.caller_id, caller_id, reason or "(no reason)")
        self.control.submit(self._shut_down, caller_id, reason)
        return True

    def _shut_down(self, caller_id: str, reason: str) -> None:
        """As rospy's ``signal_shutdown``: unregister everything, close, then tell the hooks."""
        self.close()
        for hook in list(self._shutdown_hooks):
            try:
                hook(caller_id, reason)
            except Exception:
                log.exception("ROS 1 node %s: a shutdown hook failed", self.caller_id)

    def _restart(self) -> None:
        """Unregister everything, then register it all again at once (the control thread)."""
        self._registrar.reset(min(1.0, self.master.timeout))
        self.counters["restarts"] += 1
        self._registrar.tick()
        log.warning("ROS 1 node %s: restarted, registered again with %s", self.caller_id, self.master_uri)

    def _connections(self) -> list[Conn]:
        parts: list[Publisher | Subscriber] = [*list(self._pubs.values()), *list(self._subs.values())]
        return [c for part in parts for c in part.connections()]

    def bus_info(self) -> list[list[XmlRpcValue]]:
        """``[[id, peer, direction, 'TCPROS', topic, True, transport info], ...]`` as rospy."""
        out: list[list[XmlRpcValue]] = []
        for conn in self._connections():
            try:
                local, remote = conn.sock.getsockname(), conn.sock.getpeername()
            except OSError:
                continue
            info = f"TCPROS connection on port {local[1]} to [{remote[0]}:{remote[1]} on socket {conn.sock.fileno()}]"
            out.append([conn.conn_id, conn.peer_id, conn.direction, "TCPROS", conn.topic, True, info])
        return out

    def bus_stats(self) -> list[XmlRpcValue]:
        """``[publishStats, subscribeStats, serviceStats]`` as the Slave API describes."""
        pubs: list[XmlRpcValue] = [[p.topic, p.counters["bytes_sent"],
                 [[c.conn_id, c.stats["bytes_sent"], c.stats["messages_sent"], True] for c in p.connections()]]
                for p in list(self._pubs.values())]
        subs: list[XmlRpcValue] = [[s.topic, [[c.conn_id, c.stats["bytes_received"], -1, True] for c in s.connections()]]
                for s in list(self._subs.values())]
        requests = sum(s.counters["requests"] for s in list(self._srvs.values()))
        return [pubs, subs, [requests, 0, 0]]


def _url_host(host: str) -> str:
    return f"[{host}]" if ":" in host else host
