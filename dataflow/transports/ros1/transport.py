"""ROS 1 as a scart transport: the ``scart.transports`` entry point ``ros1``
(:class:`Ros1Transport`). A **stream** joins a port to a ROS topic —
``Deployer.stream("task.port", ConnPolicy.data().with_(transport="ros1", topic="/joint_states"),
{"type": "sensor_msgs/JointState", "converter": "mod:fn"})``, ``scart stream COMP.PORT
ros1:/topic --type T``, ``<scart:stream transport="ros1" .../>`` — an output port
publishing, an input port fed from it. Not part of ``auto``: ROS carries no links.

**One node per process**, made when the first stream (or service) needs it and closed
when the last one goes; a process told it is a ROS node (:meth:`Ros1Transport.configure`:
``scart deploy``/``scart run`` ``--ros-master``, ``--ros-name``, ``--ros-namespace``,
launch-time parameters) makes it when its deployer attaches (:meth:`~Ros1Transport.attach`,
which also makes the node speak for the deployer's tasks: :mod:`.citizen`). Its settings
come from the process's defaults (those, ``--insecure``, ``--ros-read-only``, ``--remap
/from:=/to``) and the first user's options; a later stream that asks for another master
or name is refused, naming the node there is. The master is ``master``, else
``ROS_MASTER_URI``, else ROS's default; while it is down the node waits and retries
(logging that it waits) and its streams show as ``waiting`` in ``scart links``. A peer's
``shutdown`` (``rosnode kill``) ends the node and tells the process
(:meth:`~Ros1Transport.on_shutdown`: ``scart run`` stops), or, with ``respawn``, restarts it.

**Options** (:data:`OPTIONS`): ``type`` (``pkg/Type``; a plain port's default is its
``std_msgs`` type), ``converter`` (``module:function``), ``frame_id`` (a header stamped
on a model without one, on the task's clock), ``latch`` (``true``; also a buffer policy's
``init``, never DATA's), ``queue_size`` (per subscriber; default the policy's size, 1 for
DATA), ``msgs`` (``.msg``/``.srv`` files, comma-separated; else ``ROS_PACKAGE_PATH`` is
searched), and for the node: ``master``, ``node`` (or ``__name``), ``__ns``, ``host``,
``insecure``, ``respawn``. Conversion is planned and type-checked when the stream is made
(:mod:`.convert`); a message that does not convert is refused and counted (the reader
end's ``refuse``), as is a value that fails the port's type or bounds (out of range; NaN
and inf only for a port asking ``finite=True``): ``scart describe`` names the last one
under the port.

**Security.** ROS 1 authenticates no one: the node listens on loopback unless told
``insecure`` (then on every interface, or ``host``); a stream's :attr:`~Stream.authenticated`
is False, and ``scart describe`` marks its input port so.
"""

from __future__ import annotations

import ipaddress
import logging
import os
import re
import threading
import time
from dataclasses import dataclass, replace
from typing import Any

from typing import TYPE_CHECKING

from dataflow.policy import ConnType
from dataflow.transports import Stream, StreamProblem, Transport, TransportError
from dataflow.transports.ends import OutSample, ReaderEnd, WriterEnd

from .._rosplan import RefusingCarrier, flag, latched, receiver, stamper, stream_problems, usable
from scart_ros1.names import RosNameError, check_name, master_uri_from

if TYPE_CHECKING:  # imported when a stream needs them: loading the transport stays light
    from collections.abc import Callable

    from dataflow.deployer import Deployer
    from dataflow.ports import Port
    from scart_ros1.topics import Publisher, Subscriber
    from .citizen import Citizen
    from .convert import Conversion
    from scart_ros1.msgs import MessageTypes
    from scart_ros1.node import Node

__all__ = ["NODE_OPTIONS", "NodeSettings", "OPTIONS", "Ros1Transport"]

log = logging.getLogger(__name__)

#: The options that say which node a stream or service uses (the process has one node).
NODE_OPTIONS = ("master", "node", "__name", "__ns", "host", "insecure", "respawn")
#: Every option a ros1 stream takes (another is refused: a typo would otherwise be ignored).
OPTIONS = frozenset({"type", "converter", "frame_id", "latch", "queue_size", "msgs", *NODE_OPTIONS})
MAX_QUEUE = 10_000  #: messages waiting for one slow subscriber, at most
_BASE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,127}")


@dataclass(frozen=True)
class NodeSettings:
    """How this process's ROS node is made: ``master`` (None: ``ROS_MASTER_URI``, else
    ROS's default), ``name`` ("": ``scart_<pid>``), ``namespace`` (None: ``ROS_NAMESPACE``),
    ``host`` it listens on (loopback unless ``insecure``), what a ``rosnode kill`` does."""

    master: str | None = None
    name: str = ""
    namespace: str | None = None
    host: str = "127.0.0.1"
    insecure: bool = False
    respawn: bool = False  #: a ``rosnode kill`` restarts the node instead of ending it
    remaps: tuple[str, ...] = ()  #: ``from:=to`` names (``scart run --remap /from:=/to``)
    read_only: bool = False  #: publish only: no input port fed, no service, no parameter set (``--ros-read-only``)

    @property
    def node_name(self) -> str:
        return self.name or f"scart_{os.getpid()}"


def _loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class Ros1Transport(Transport):
    """Streams on ROS 1 topics through this process's one ROS node (see the module
    docstring). Thread-safe; the node is made on first use and closed with its last user."""

    name = "ros1"
    rank = None
    topics = True
    converts = True

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._defaults = NodeSettings()
        self._types: MessageTypes | None = None
        self._node: Node | None = None
        self._settings: NodeSettings | None = None
        self._users = 0
        self._shutdown_hooks: list[Callable[[str, str, str], None]] = []
        self._told = False  # configure() was given something: the process is a ROS node from its start
        self._launch_params: dict[str, object] = {}
        self._sim_time = False  # a launch-time _use_sim_time:=true: the node follows /clock from its start
        self._deployers: list[Deployer] = []
        self._held: list[Node] = []
        self._citizen: Citizen | None = None

    # ---- the process's node ------------------------------------------------------------
    def configure(self, *, master: str | None = None, name: str | None = None, namespace: str | None = None,
                  insecure: bool | None = None, respawn: bool | None = None,
                  params: dict[str, Any] | None = None, remaps: dict[str, str] | None = None,
                  read_only: bool | None = None, use_sim_time: bool | None = None) -> None:
        """Set this process's defaults for its ROS node (``--ros-master``, ``--ros-name``,
        ``--ros-namespace``, ``--insecure``, ``respawn``, launch-time ``_TASK/PROP:=value``
        ``params``, graph name ``remaps`` ``{"/from": "/to"}``); a node already made keeps
        its own. A process told any of these but remaps and ``use_sim_time`` is a ROS node
        from its start (:meth:`attach`). ``use_sim_time`` (``_use_sim_time:=true``): the
        node follows ``/clock`` from its start, whatever ``/use_sim_time`` says. Raises
        ``ValueError`` for a bad master URI, name or remap, or ``use_sim_time`` when
        read-only."""
        for old, new in (remaps or {}).items():
            check_name(old, "remapped name")
            check_name(new, "remapped name")
        if master is not None:
            master_uri_from(master)
        if name and not _BASE_NAME.fullmatch(name):
            raise ValueError(f"node name {name!r}: a base name (letters, digits and '_', starting with a letter)")
        with self._lock:
            if (use_sim_time if use_sim_time is not None else self._sim_time) and \
                    (read_only if read_only is not None else self._defaults.read_only):
                raise ValueError("use_sim_time is refused: this process serves ROS read-only (--ros-read-only "
                                 "takes nothing from ROS, /clock included)")
            self._sim_time = self._sim_time if use_sim_time is None else use_sim_time
            if any(v is not None for v in (master, name, namespace, insecure, respawn)) or params:
                self._told = True
            self._launch_params.update(params or {})
            changes: dict[str, Any] = {k: v for k, v in (("master", master), ("name", name), ("namespace", namespace))
                                       if v is not None}
            if insecure is not None:
                changes.update(insecure=insecure, host="0.0.0.0" if insecure else "127.0.0.1")
            if respawn is not None:
                changes["respawn"] = respawn
            if remaps:
                changes["remaps"] = (*self._defaults.remaps, *(f"{old}:={new}" for old, new in remaps.items()))
            if read_only is not None:
                changes["read_only"] = read_only
            self._defaults = replace(self._defaults, **changes)

    @property
    def read_only(self) -> bool:
        """Whether this process serves ROS read-only (``--ros-read-only``): it publishes its
        output ports and nothing from ROS reaches it (no stream into an input port, no
        service, no parameter set, no ``shutdown``)."""
        with self._lock:
            return self._defaults.read_only

    def refuse_input(self, what: str) -> None:
        """Raise :class:`TransportError` saying ``what`` is refused, when read-only."""
        if self.read_only:
            raise TransportError(f"ros1: {what} is refused: this process serves ROS read-only (--ros-read-only: "
                                 "it publishes only)")

    def on_shutdown(self, hook: Callable[[str, str, str], None]) -> None:
        """Call ``hook(node, caller_id, reason)`` when a peer (``rosnode kill``) has shut this
        process's node down, as rospy ends its process then: ``scart run`` and ``scart
        deploy`` stop. Not called when the node respawns."""
        with self._lock:
            self._shutdown_hooks.append(hook)

    def attach(self, deployer: Deployer) -> None:
        """Let this process's node speak for ``deployer``'s tasks (:mod:`.citizen`: their
        properties are its parameters), now or when it is made. The launch-time parameters
        are set on its tasks now (``ValueError`` naming one refused)."""
        from .citizen import apply_launch_params

        with self._lock:
            params = dict(self._launch_params)
        apply_launch_params(deployer.tasks(), params)
        with self._lock:
            self._deployers.append(deployer)
            node = self._node
        if node is not None:
            self._become_citizen(node)

    def detach(self, deployer: Deployer) -> None:
        """Undo :meth:`attach` (idempotent)."""
        with self._lock:
            if deployer in self._deployers:
                self._deployers.remove(deployer)

    def hold(self) -> None:
        """When the process was told it is a ROS node (:meth:`configure`), make its node
        now if no stream or service has (:class:`TransportError` when it cannot), and hold
        it until :meth:`unhold`: a ``scart run`` or ``scart deploy`` once everything of
        its own has started (a composite's streams may name the node)."""
        with self._lock:
            if not self._told or self._held:
                return
        node = self.acquire({})
        with self._lock:
            self._held.append(node)

    def unhold(self) -> None:
        """Undo :meth:`hold` (idempotent): the node goes with its last user."""
        with self._lock:
            held = self._held.pop() if self._held else None
        if held is not None:
            self.release(held)

    def _attached(self) -> list[Deployer]:
        with self._lock:
            return list(self._deployers)

    def _become_citizen(self, node: Node) -> None:
        from .citizen import Citizen

        with self._lock:
            if self._citizen is not None or not self._deployers or node is not self._node:
                return
            citizen = self._citizen = Citizen(node, self._attached, sim_time=self._sim_time)
        citizen.start()

    def _end_citizen(self) -> None:
        with self._lock:
            citizen, self._citizen = self._citizen, None
        if citizen is not None:
            citizen.close()

    def _node_shut_down(self, node: Node, caller_id: str, reason: str) -> None:
        self._end_citizen()
        with self._lock:
            hooks = list(self._shutdown_hooks)
            if node is self._node:
                self._node, self._settings = None, None  # a later stream makes a new one
        if not hooks:
            log.warning("ROS 1 node %s was shut down by %s (%s): its streams and services are down", node.caller_id,
                        caller_id, reason or "no reason")
        for hook in hooks:
            hook(node.caller_id, caller_id, reason)

    @property
    def types(self) -> MessageTypes:
        """The message types of this process (rosbags' Noetic store and the ``msgs`` given)."""
        from scart_ros1.msgs import MessageTypes

        with self._lock:
            if self._types is None:
                self._types = MessageTypes()
            return self._types

    def node_settings(self, options: dict[str, str]) -> NodeSettings:
        """The process's defaults with what ``options`` say; raises ``ValueError``."""
        with self._lock:
            settings = self._defaults
        insecure = flag(options, "insecure") if "insecure" in options else settings.insecure
        host = options.get("host") or ("0.0.0.0" if insecure else "127.0.0.1")
        if not insecure and not _loopback(host):
            raise ValueError(f"host={host}: ROS 1 authenticates no one; a node listens on loopback unless told "
                             "insecure=true (or scart's --insecure)")
        name = options.get("node") or options.get("__name") or settings.name
        if name and not _BASE_NAME.fullmatch(name):
            raise ValueError(f"node name {name!r}: a base name (letters, digits and '_', starting with a letter)")
        master = options.get("master") or settings.master
        if master is not None:
            master_uri_from(master)
        respawn = flag(options, "respawn") if "respawn" in options else settings.respawn
        return NodeSettings(master=master, name=name, namespace=options.get("__ns", settings.namespace), host=host,
                            insecure=insecure, respawn=respawn, remaps=settings.remaps, read_only=settings.read_only)

    def acquire(self, options: dict[str, str]) -> Node:
        """This process's node (made now if there is none), for one more user; each
        :meth:`acquire` is paired with a :meth:`release`. Raises :class:`TransportError`
        when ``options`` ask for another node than the one there is, or it cannot be made."""
        try:
            wanted = self.node_settings(options)
        except ValueError as exc:
            raise TransportError(f"ros1: {exc}") from None
        from scart_ros1.node import Node

        types = self.types
        with self._lock:
            node = self._node
            if node is not None and not node.closed:
                self._same_node(node, wanted, options)
                self._users += 1
                return node
            try:
                node = Node(wanted.node_name, master_uri=wanted.master, host=wanted.host, namespace=wanted.namespace,
                            types=types, respawn=wanted.respawn, remaps=list(wanted.remaps),
                            read_only=wanted.read_only)
            except (OSError, ValueError) as exc:
                raise TransportError(f"ros1: cannot make the ROS node {wanted.node_name}: {exc}") from None
            made = node
            node.add_shutdown_hook(lambda caller, reason: self._node_shut_down(made, caller, reason))
            self._node, self._settings, self._users = node, wanted, 1
        log.info("ROS 1 node %s: master %s, listening on %s", node.caller_id, node.master_uri, wanted.host)
        self._become_citizen(node)
        return node

    def _same_node(self, node: Node, wanted: NodeSettings, options: dict[str, str]) -> None:
        have = self._settings
        assert have is not None
        asked = [k for k in NODE_OPTIONS if k in options]
        if not asked:
            return
        if (wanted.node_name, wanted.master, wanted.namespace, wanted.host, wanted.respawn) != \
                (have.node_name, have.master, have.namespace, have.host, have.respawn):
            raise TransportError(f"ros1: this process's ROS node is {node.caller_id} (master {node.master_uri}, "
                                 f"listening on {have.host}); {', '.join(f'{k}={options[k]}' for k in asked)} asks "
                                 "for another: one node per process")

    def release(self, node: Node) -> None:
        """One user less of ``node``; the last one closes it (blocks ≤ ~1 s to unregister)."""
        with self._lock:
            if node is not self._node:
                return
            self._users -= 1
            if self._users > 0:
                return
            self._node, self._settings = None, None
        self._end_citizen()
        node.close()

    # ---- streams -----------------------------------------------------------------------
    def check_stream(self, port: Port[object], topic: str, options: dict[str, str]) -> list[StreamProblem]:
        problems = [StreamProblem(p) for p in self._check_options(topic, options)]
        if port.is_input and self.read_only:
            problems.append(StreamProblem(f"ros1: a stream into port {getattr(port, 'qualname', port.name)} is "
                                          "refused: this process serves ROS read-only (--ros-read-only)"))
        if problems:
            return problems
        _, found = self.conversion(port, options)
        return found

    def _check_options(self, topic: str, options: dict[str, str]) -> list[str]:
        unknown = sorted(set(options) - OPTIONS)
        out = [f"ros1: unknown option(s) {', '.join(unknown)}; options: {', '.join(sorted(OPTIONS))}"] if unknown else []
        try:
            check_name(topic, "topic name")
            self.node_settings(options)
            for key in ("latch", "respawn"):
                if key in options:
                    flag(options, key)
            if "queue_size" in options and not (options["queue_size"].isdigit()
                                                and 1 <= int(options["queue_size"]) <= MAX_QUEUE):
                out.append(f"ros1: queue_size={options['queue_size']!r}: a whole number 1..{MAX_QUEUE}")
            self._add_msgs(options)
        except (ValueError, RosNameError) as exc:
            out.append(f"ros1: {exc}")
        return out

    def _add_msgs(self, options: dict[str, str]) -> None:
        from scart_ros1.msgs import TypeDefinitionError

        for path in filter(None, (p.strip() for p in options.get("msgs", "").split(","))):
            try:
                self.types.add_file(path)
            except TypeDefinitionError as exc:
                raise ValueError(str(exc)) from None

    def conversion(self, port: Port[object], options: dict[str, str]) -> tuple[Conversion | None, list[StreamProblem]]:
        """How ``port``'s values cross to the topic's type, and the problems found."""
        from .convert import plan

        conv, problems = plan(self.types, port.type, options.get("type") or None, outgoing=not port.is_input,
                              converter=options.get("converter", ""), frame_id=options.get("frame_id", ""))
        return conv, stream_problems("ros1", port, problems)

    def stream(self, end: WriterEnd | ReaderEnd, topic: str, options: dict[str, str]) -> Stream:
        port = end.port
        if port is None:
            raise TransportError("ros1 converts a port's values: a reader end without its port cannot be streamed")
        errors = self._check_options(topic, options)
        if errors:
            raise TransportError("; ".join(errors))
        if isinstance(end, ReaderEnd):
            self.refuse_input(f"a stream from {topic} into port {port.qualname}")
        conv = usable(*self.conversion(port, options), log)
        node = self.acquire(options)
        try:
            return _TopicStream(self, node, end, topic, conv, options)
        except BaseException:
            self.release(node)
            raise


def _identity(sample: OutSample) -> OutSample:
    return sample


class _Carrier(RefusingCarrier):
    """A writer end's carrier onto a ROS publisher: each sample converted and serialised
    once (only while someone subscribes, or the topic latches) and handed to every
    subscriber's connection, never blocking (a slow subscriber's queue drops its oldest).
    A value that does not convert is refused and counted here."""

    encode = staticmethod(_identity)  # converted in send(), only when someone listens

    def __init__(self, pub: Publisher, conv: Conversion, label: str, stamp: Callable[[int], int]) -> None:
        super().__init__(label, log)
        to_ros, to_frame, frame = conv.to_ros, conv.to_frame, pub.type.frame
        assert to_ros is not None
        self._pub = pub
        if to_frame is not None:  # one fixed field: straight to bytes
            self._frame: Callable[[OutSample], bytes | bytearray] = lambda sample: to_frame(sample.value, sample.n, stamp(sample.t_ns))
        else:
            self._frame = lambda sample: frame(to_ros(sample.value, sample.n, stamp(sample.t_ns)))

    def send(self, sample: OutSample, _data: object) -> bool:  # the writer's thread
        pub = self._pub
        if not pub.wanted:
            return True
        try:
            frame = sample.encoded(self._frame)
        except Exception as exc:  # noqa: BLE001 - a value that does not convert never reaches the writer
            self._refuse(f"sample {sample.n}: {type(exc).__name__}: {exc}")
            return True
        pub.publish_frame(frame)
        return True


class _TopicStream(Stream):
    """A writer end publishing a ROS topic, or a reader end fed from one."""

    authenticated = False

    def __init__(self, transport: Ros1Transport, node: Node, end: WriterEnd | ReaderEnd, topic: str,
                 conv: Conversion, options: dict[str, str]) -> None:
        self._transport, self._node = transport, node
        self.topic = node.resolve(topic)
        self.type_name = conv.ros_type
        self._pub: Publisher | None = None
        self._sub: Subscriber | None = None
        self._carrier: _Carrier | None = None
        self._closed = False
        if isinstance(end, WriterEnd):
            self._publish(end, conv, options)
        else:
            self._subscribe(end, conv)

    def _publish(self, end: WriterEnd, conv: Conversion, options: dict[str, str]) -> None:
        policy = end.policy
        latch = latched(options, policy)
        size = int(options["queue_size"]) if "queue_size" in options else (
            1 if policy.type is ConnType.DATA else max(1, min(policy.size, MAX_QUEUE)))
        self._pub = self._node.advertise(self.topic, conv.ros_type, latch=latch, queue_size=size)
        self._carrier = _Carrier(self._pub, conv, end.label, stamper(end.port))
        end.connected("ros1", self._carrier, new_peer=True)
        if latch and not policy.init:  # the last value written is what a late subscriber gets first (init: the end's)
            n, value = end.port.last_sample()
            if n:
                self._carrier.send(OutSample(n, time.time_ns(), value, end.port.type), None)

    def _subscribe(self, end: ReaderEnd, conv: Conversion) -> None:
        raw = conv.from_bytes is not None  # one fixed field: straight from the bytes, no message object
        from_ros = conv.from_bytes if raw else conv.from_ros
        assert from_ros is not None
        end.transport = "ros1"  # the node's io thread calls the receiver, one message at a time
        self._sub = self._node.subscribe(self.topic, conv.ros_type, receiver(end, from_ros, conv.ros_type), raw=raw,
                                         tcp_nodelay=True)

    # ---- what it says ------------------------------------------------------------------
    @property
    def waiting(self) -> str:
        node = self._node
        if node.closed:
            return f"a ROS node: {node.caller_id} was shut down by {node.shutdown_reason or 'its owner'}"
        if not node.master_reachable:
            return f"the ROS master {node.master_uri}"
        if not node.is_registered("pub" if self._pub is not None else "sub", self.topic):
            return f"the ROS master {node.master_uri} to register {self.topic}"
        return ""

    @property
    def refused(self) -> int:
        return self._carrier.refused if self._carrier is not None else 0

    @property
    def refusal(self) -> str:
        if self._carrier is not None and self._carrier.refusal:
            return self._carrier.refusal
        part = self._pub if self._pub is not None else self._sub
        return f"a peer refused: {part.last_refusal}" if part is not None and part.last_refusal else ""

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for part in (self._pub, self._sub):
            if part is not None:
                part.close()
        self._transport.release(self._node)
