"""Deployer: the tasks of one process, their connections, and their collective lifecycle.

Connections between its tasks' ports are *links* (:meth:`Deployer.links`): each has a name
— given to :meth:`Deployer.connect` (``name=``), else ``"a.out->b.in"`` — so that it can
be listed, re-routed to another input (:meth:`Deployer.reroute`: the new connection is
made before the old one goes, so no sample of the source is missed by the new sink after
the call returns, and the source's other links never notice) and removed by name.

Tasks are kept in the order they were added: ``configure_all``/``start_all`` walk that
order, ``stop_all``/``cleanup_all`` the reverse. Used as a context manager it stops and
cleans up everything on exit. ``serve()`` exposes the tasks to other processes through
the server a ``scart.servers`` entry point names (scart's own, ``grpc``, is the control
plane's :class:`dataflow.remote.server.DeployerServer`, registered exactly as a plug-in's
would be), loaded only when called: this core imports no control plane, as it imports no
transport (:mod:`dataflow.transports`)::

    [project.entry-points."scart.servers"]
    grpc = "dataflow.remote.server:DeployerServer"
"""

from __future__ import annotations

import logging
import re
import threading
from collections.abc import Iterable
from importlib.metadata import EntryPoint, entry_points
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Protocol

from scart_wire.defaults import DEFAULT_LEASE
from scart_wire.security import Security

from .clock import WALL, Clock
from .errors import DeploymentError, NotFoundError
from .introspection import LinkDescription
from .policy import ConnPolicy
from .ports import Connection, InputPort, OutputPort, Port
from .task import TaskContext, TaskState

if TYPE_CHECKING:
    from .tf.buffer import FrameBuffer

__all__ = ["Deployer", "LINK_NAME", "SERVERS_GROUP", "Server", "ServerFactory", "server_factory"]

#: What a given link name may be: letters, digits, ``_ . / : -``, at most 128 characters.
LINK_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_./:-]{0,127}")  # no '>': default names ("a.out->b.in") are apart
MAX_NAMED_LINKS = 4096

log = logging.getLogger(__name__)

SERVERS_GROUP = "scart.servers"
#: scart's own server, used also when its entry points are not installed (a source tree).
BUILTIN_SERVERS = MappingProxyType({"grpc": "dataflow.remote.server:DeployerServer"})


class Server(Protocol):
    """A served deployer, as :meth:`Deployer.serve` returns it: where it listens
    (``listen_address``; ``address`` as bound, ``advertised`` to other hosts), the name
    service its tasks are in, its lifecycle (``stop`` is idempotent), publishing tasks
    added later, and links from its output ports to ports of other deployers."""

    address: str
    listen_address: str
    advertised: str
    ns_address: str
    boot_id: str

    def stop(self, grace: float = 0.2) -> None: ...

    def wait(self, timeout: float | None = None) -> bool: ...

    def refresh_names(self) -> list[str]: ...

    def connect_ports(self, source_task: str, source_port: str, sink_task: str, sink_port: str, policy: ConnPolicy,
                      defer: bool = False, name: str | None = None,
                      resume: bool = False) -> tuple[bool, str, str, LinkDescription | None]: ...

    def __enter__(self) -> Server: ...

    def __exit__(self, *exc: object) -> None: ...


class ServerFactory(Protocol):
    """What a ``scart.servers`` entry point names: made with the deployer and
    :meth:`Deployer.serve`'s arguments, it listens before it returns."""

    def __call__(self, deployer: Deployer, address: str = ..., ns: str | None = ..., lease_seconds: float = ...,
                 heartbeat_ms: int = ..., max_workers: int = ..., ns_timeout: float = ...,
                 security: Security | None = ..., advertise: str | None = ...) -> Server: ...


def server_factory(name: str = "grpc") -> ServerFactory:
    """The server the ``scart.servers`` entry point ``name`` names (scart's own when none
    is installed). Reads the entry points on each call (serving is rare; nothing is kept
    process-wide). Raises :class:`DeploymentError` naming the entry point when it is
    unknown or cannot be loaded."""
    found = {ep.name: ep for ep in entry_points(group=SERVERS_GROUP)}
    ep = found.get(name)
    if ep is None and name in BUILTIN_SERVERS:
        ep = EntryPoint(name, BUILTIN_SERVERS[name], SERVERS_GROUP)
    if ep is None:
        raise DeploymentError(f"no deployer server {name!r}; known: {', '.join(sorted(found)) or 'none'}")
    try:
        factory: ServerFactory = ep.load()
    except Exception as exc:
        raise DeploymentError(f"deployer server {name!r} (entry point {ep.value!r}) cannot be loaded: "
                              f"{type(exc).__name__}: {exc}") from exc
    return factory


class Deployer:
    """Holds the tasks of a process (unique names). Thread-safe for add/lookup."""

    def __init__(self) -> None:
        self._tasks: dict[str, TaskContext] = {}
        self._lock = threading.Lock()
        self._link_names: dict[tuple[str, str], str] = {}  # ("a.out", "b.in") -> name given
        self._link_lock = threading.RLock()  # links are checked, made and named as one step
        self._streams: dict[str, Any] = {}  # name -> a stream (anything with describe() -> LinkDescription)
        self._clock: Clock = WALL
        self._frames: FrameBuffer | None = None

    @property
    def frames(self) -> FrameBuffer:
        """The frame tree of these tasks (:mod:`dataflow.tf`; ``task.frames`` in each):
        one per deployer, made on first use. Setting another gives it to every task."""
        with self._lock:
            if self._frames is None:
                from .tf.buffer import FrameBuffer

                self._frames = FrameBuffer()
            return self._frames

    @frames.setter
    def frames(self, buffer: FrameBuffer) -> None:
        with self._lock:
            self._frames = buffer
            for task in self._tasks.values():
                task.frames = buffer

    def add(self, task: TaskContext) -> TaskContext:
        """Add ``task`` (it takes this deployer's clock); returns it. Raises
        ``DeploymentError`` if its name is taken."""
        with self._lock:
            if task.name in self._tasks:
                raise DeploymentError(f"a task named {task.name!r} is already deployed")
            self._tasks[task.name] = task
            task._tc_frames_from = lambda: self.frames
            if self._clock is not WALL:
                task.clock = self._clock
        return task

    @property
    def clock(self) -> Clock:
        """The time every task of this deployer lives in (:mod:`dataflow.clock`)."""
        return self._clock

    def use_clock(self, clock: Clock) -> None:
        """Make ``clock`` the time of every task here, and of those added later (ROS's
        ``use_sim_time``: a :class:`~dataflow.clock.SimClock`); running periodic tasks
        follow it at their next wake-up. Thread-safe."""
        with self._lock:
            self._clock = clock
            tasks = list(self._tasks.values())
        for task in tasks:
            task.clock = clock

    def task(self, name: str) -> TaskContext:
        """The task called ``name``; raises ``NotFoundError`` listing the deployed names."""
        try:
            return self._tasks[name]
        except KeyError:
            raise NotFoundError(f"no task {name!r}; deployed: {self.names() or 'none'}") from None

    def tasks(self) -> list[TaskContext]:
        """The tasks in the order they were added."""
        return list(self._tasks.values())

    def names(self) -> list[str]:
        """Task names in the order they were added."""
        return list(self._tasks)

    def _port(self, ref: str) -> Port[Any]:
        task_name, dot, port_name = ref.rpartition(".")
        if not dot or not task_name or not port_name:
            raise DeploymentError(f"expected 'task.port', got {ref!r}")
        return self.task(task_name).port(port_name)

    def _output(self, ref: str) -> OutputPort[Any]:
        port = self._port(ref)
        if not isinstance(port, OutputPort):
            raise DeploymentError(f"{ref} is not an output port")
        return port

    def connect(self, source: str, target: str, policy: ConnPolicy | None = None, name: str | None = None) -> Connection[Any]:
        """Connect output ``"a.out"`` to input ``"b.in"``, as the link ``name`` (default
        ``"a.out->b.in"``); raises NotFound/PortType/DeploymentError (also for a name
        another link has). A refused connection keeps no name."""
        out, inp = self._port(source), self._port(target)
        if not isinstance(out, OutputPort):
            raise DeploymentError(f"{source} is not an output port")
        if not isinstance(inp, InputPort):
            raise DeploymentError(f"{target} is not an input port")
        with self._link_lock:
            if name is not None:
                self._check_name(source, target, name)
            conn = out.connect_to(inp, policy if policy is not None else ConnPolicy())
            if name is not None:
                self._link_names[(source, target)] = name
            return conn

    def connect_or_change(self, source: str, target: str, policy: ConnPolicy, name: str | None = None) -> str:
        """:meth:`connect`, or for a pair connected already: change its policy (the new
        connection is made before the old one is undone) and its name, as asked. Returns
        what holds when it is not simply "connected": ``""`` for a new link, else e.g.
        ``"policy changed from buffer:8 to circular:4"`` or ``"connected already"``."""
        with self._link_lock:
            old = self.connection(source, target)
            if old is None:
                self.connect(source, target, policy, name)
                return ""
            notes = []
            if name is not None and name != self.link_name(source, target):
                self._check_name(source, target, name)
                notes.append(f"renamed from {self.link_name(source, target)} to {name}")
                self._link_names[(source, target)] = name
            if not same_policy(old.policy, policy):
                old.close()
                self._output(source).connect_to(self._port(target), policy)
                notes.insert(0, f"policy changed from {old.policy} to {policy}")
            return "; ".join(notes) or "connected already"

    def add_stream(self, name: str, stream: Any) -> None:
        """Keep ``stream`` (a port joined to a topic of a transport: anything whose
        ``describe()`` gives a :class:`LinkDescription`) under ``name``, listed with the
        links; ``DeploymentError`` when a link or stream has that name already. Its owner
        makes and closes it (RTT's deployer ``stream()``)."""
        with self._link_lock:
            if name in self._streams or name in self._link_names.values():
                raise DeploymentError(f"a link or stream named {name!r} exists already")
            if len(self._streams) >= MAX_NAMED_LINKS:
                raise DeploymentError(f"more than {MAX_NAMED_LINKS} streams")
            self._streams[name] = stream

    def stream(self, port: str, policy: ConnPolicy, options: dict[str, str] | None = None,
               name: str | None = None) -> LinkDescription:
        """Join ``"task.port"`` to the topic ``policy.topic`` of ``policy.transport`` (RTT's
        ``stream()``: an output port publishes there, an input port is fed from there,
        under ``policy``), as the stream ``name`` (default ``"task.port~transport:topic"``);
        returns its description. Raises ``DeploymentError`` (no topic, a bad or taken
        name), ``NotFoundError`` (no such port), or the transport's ``TransportError`` (no
        topics on it, a bad topic)."""
        from dataflow.transports.streams import STREAM_NAME, PortStream, default_name

        if not policy.topic:
            raise DeploymentError(f"a stream needs a topic: {policy.transport}:TOPIC")
        target = self._port(port)
        name = name or default_name(port, policy)
        if not STREAM_NAME.fullmatch(name):  # a default name's topic is the transport's to judge, below
            raise DeploymentError(f"stream name {name[:80]!r}: letters, digits and _ . / : ~ - only, at most 300")
        with self._link_lock:
            if name in self._streams or name in self._link_names.values():
                raise DeploymentError(f"a link or stream named {name!r} exists already")
            stream = PortStream(target, policy, options or {}, name)
            try:
                self.add_stream(name, stream)
            except BaseException:
                stream.close()
                raise
        return stream.describe()

    def unstream(self, name: str) -> bool:
        """Undo the stream ``name`` (leave its topic); False when there is none."""
        stream = self.remove_stream(name)
        if stream is None:
            return False
        stream.close()
        return True

    def remove_stream(self, name: str) -> Any:
        """Forget the stream ``name`` (returned, for its owner to close); None if there is none."""
        with self._link_lock:
            return self._streams.pop(name, None)

    def streams(self) -> dict[str, Any]:
        """The streams kept, by name."""
        with self._link_lock:
            return dict(self._streams)

    def name_link(self, source: str, sink: str, name: str) -> None:
        """Call the link ``source`` → ``sink`` ``name`` (once it is made). Raises
        ``DeploymentError`` for a malformed name or one another link has."""
        with self._link_lock:
            self._check_name(source, sink, name)
            self._link_names[(source, sink)] = name

    def check_link_name(self, source: str, sink: str, name: str) -> None:
        """Raise ``DeploymentError`` unless ``name`` may be given to the link ``source`` → ``sink``."""
        with self._link_lock:
            self._check_name(source, sink, name)

    def _check_name(self, source: str, sink: str, name: str) -> None:
        if not LINK_NAME.fullmatch(name):
            raise DeploymentError(f"link name {name!r}: letters, digits and _ . / : - only, at most 128")
        holder = next((k for k, v in self._link_names.items() if v == name), None)
        if holder is not None and holder != (source, sink):
            raise DeploymentError(f"a link named {name!r} exists already: {holder[0]} -> {holder[1]}")
        if len(self._link_names) >= MAX_NAMED_LINKS and (source, sink) not in self._link_names:
            raise DeploymentError(f"more than {MAX_NAMED_LINKS} named links")

    def link_name(self, source: str, sink: str) -> str:
        """The name of the link ``source`` → ``sink``: the one given, else ``"source->sink"``."""
        return self._link_names.get((source, sink)) or f"{source}->{sink}"

    def forget_link(self, source: str, sink: str) -> None:
        """Drop the name of a link that is gone."""
        with self._link_lock:
            self._link_names.pop((source, sink), None)

    def links(self, remote: Iterable[LinkDescription] = ()) -> list[LinkDescription]:
        """Every connection from an output port of these tasks to an input port of these
        tasks, as a link (name, ends, policy, samples the source wrote, samples dropped),
        then ``remote`` (links to other deployers, described by their server), then the
        streams. Names of links that are gone (a task's ports disconnected) are forgotten
        here."""
        out: list[LinkDescription] = []
        for task in self.tasks():
            for port in task.ports().values():
                if not isinstance(port, OutputPort):
                    continue
                written = port.last_sample()[0]
                for conn in port.connections():
                    sink_task = getattr(conn.input, "task", None)
                    if not isinstance(sink_task, TaskContext) or self._tasks.get(sink_task.name) is not sink_task:
                        continue  # an observer's port (subscription, remote link), not a link
                    source, sink = f"{task.name}.{port.name}", f"{sink_task.name}.{conn.input.name}"
                    out.append(LinkDescription(name=self.link_name(source, sink), source=source, sink=sink,
                                               policy=str(conn.policy), transport="local", samples=written,
                                               dropped=conn.dropped))
        out += list(remote)
        live = {(lk.source, lk.sink) for lk in out}
        out += [stream.describe() for stream in self.streams().values()]
        with self._link_lock:
            for key in [k for k in self._link_names if k not in live]:
                del self._link_names[key]
        return out

    def find_link(self, name: str) -> LinkDescription:
        """The local link called ``name``; raises ``NotFoundError`` listing the names."""
        links = self.links()
        for link in links:
            if link.name == name:
                return link
        raise NotFoundError(f"no link {name!r}; links: {', '.join(lk.name for lk in links[:20]) or 'none'}")

    def connection(self, source: str, sink: str) -> Connection[Any] | None:
        """The connection from output ``source`` to input ``sink``, if they are connected."""
        inp = self._port(sink)
        return next((c for c in self._port(source).connections() if c.input is inp), None)

    def reroute(self, name: str, sink: str) -> LinkDescription:
        """Point the local link ``name`` at input ``sink`` instead (same source, policy and
        name): connected first, then the old input disconnected. Raises ``NotFoundError``,
        ``PortTypeError``, or ``DeploymentError`` when the source feeds ``sink`` already."""
        with self._link_lock:
            link = self.find_link(name)
            if sink == link.sink:
                return link
            if self.connection(link.source, sink) is not None:
                raise DeploymentError(f"{link.source} feeds {sink} already (link "
                                      f"{self.link_name(link.source, sink)!r}): disconnect that link first")
            old = self.connection(link.source, link.sink)
            assert old is not None  # listed a moment ago, under the lock
            given = self._link_names.pop((link.source, link.sink), None)
            try:
                self._output(link.source).connect_to(self._port(sink), old.policy)
            except BaseException:
                if given is not None:
                    self._link_names[(link.source, link.sink)] = given
                raise
            if given is not None:
                self._link_names[(link.source, sink)] = given
            old.close()
            return self.find_link(given or f"{link.source}->{sink}")

    def disconnect(self, source: str, sink: str) -> bool:
        """Disconnect output ``source`` from input ``sink`` (and forget the link's name);
        False when they were not connected."""
        with self._link_lock:
            conn = self.connection(source, sink)
            if conn is not None:
                conn.close()
            self._link_names.pop((source, sink), None)
            return conn is not None

    def configure_all(self) -> None:
        """Configure every task that is not running (PRE_OPERATIONAL or STOPPED), in order.

        Raises ``DeploymentError`` naming the first task that refused and why; tasks after
        it are left as they are.
        """
        for task in self.tasks():
            if task.is_running():
                continue
            if not task.configure():
                reason = (
                    "configure_hook vetoed"
                    if task.state is TaskState.PRE_OPERATIONAL
                    else f"it is in state {task.state.name}"
                )
                raise DeploymentError(f"task {task.name} failed to configure: {reason}")

    def start_all(self) -> None:
        """Start every STOPPED task, in order; raises ``DeploymentError`` naming a task that refused."""
        for task in self.tasks():
            if task.is_running():
                continue
            if not task.start():
                raise DeploymentError(
                    f"task {task.name} failed to start (state {task.state.name})"
                )

    def stop_all(self) -> None:
        """Stop every running task, in reverse order. Never raises for a task; idempotent."""
        for task in reversed(self.tasks()):
            if task.is_running():
                task.stop()

    def cleanup_all(self) -> None:
        """Clean up every STOPPED task, in reverse order (after ``stop_all``). Idempotent."""
        for task in reversed(self.tasks()):
            if task.state is TaskState.STOPPED:
                task.cleanup()

    def serve(self, address: str = "127.0.0.1:0", ns: str | None = None, *, lease_seconds: float | None = None,
              heartbeat_ms: int = 500, max_workers: int = 64, security: Security | None = None,
              advertise: str | None = None) -> Server:
        """Serve these tasks over gRPC at ``address``; returns the running server once it
        listens (does not block). The one public way to serve a deployer (the server is
        the ``grpc`` entry point of ``scart.servers``: see the module docstring).

        ``ns=None`` embeds a name service in the server; otherwise the tasks are registered
        with the name service at ``ns`` under a lease of ``lease_seconds`` (default
        ``scart_wire.defaults.DEFAULT_LEASE``; renewed by heartbeats every third of it). ``heartbeat_ms``: idle interval of subscription
        heartbeats; ``max_workers``: concurrent RPCs; ``security``: TLS and tokens, for this
        server and for its calls to the name service and other deployers (see
        :mod:`scart_wire.security`; default: plaintext, no tokens, loopback only);
        ``advertise``: the ``HOST[:PORT]`` registered in the name service (default: the bound
        address, or this host's name when listening on every interface). Raises
        :class:`dataflow.remote.AlreadyRegisteredError` for a name held by another live
        deployer, :class:`dataflow.remote.UnavailableError` when nothing answers at ``ns``
        or ``address`` cannot be bound. See :mod:`dataflow.remote.server`."""
        return server_factory()(self, address, ns=ns, lease_seconds=lease_seconds or DEFAULT_LEASE,
                                heartbeat_ms=heartbeat_ms, max_workers=max_workers, security=security,
                                advertise=advertise)

    def __enter__(self) -> Deployer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop_all()
        self.cleanup_all()


def same_policy(a: ConnPolicy, b: ConnPolicy) -> bool:
    """Whether two policies make the same connection (the transport aside, which a
    connection in one process ignores)."""
    return a.with_(transport="auto") == b.with_(transport="auto")
