"""ROS 2 as a scart transport: the ``scart.transports`` entry point ``ros2``
(:class:`Ros2Transport`). A **stream** joins a port to a ROS 2 topic —
``Deployer.stream("task.port", ConnPolicy.data().with_(transport="ros2", topic="/joint_states"),
{"type": "sensor_msgs/msg/JointState", "converter": "mod:fn"})``, ``scart stream COMP.PORT
ros2:/topic --type T``, ``<scart:stream transport="ros2" .../>`` — an output port
publishing on ``rt/<topic>`` (CDR, DDS type ``pkg::msg::dds_::Type_``), an input port fed
from it. Not part of ``auto``: DDS carries no links.

**One participant per process and domain** (a ROS 2 node named ``--ros-name``, else
``scart_<pid>``, in ``--ros-namespace``, else ``ROS_NAMESPACE``; with the process's tasks'
properties as its parameters and its log on ``/rosout``, see :mod:`._citizen`), made
when the first stream (or service) needs it and closed when the last one goes. The
domain is the ``domain`` option, else ``ROS_DOMAIN_ID``, else 0. The network is loopback
only (the ``lo`` interface, no multicast, the explicit peer 127.0.0.1) unless the stream
says ``insecure=true`` (with ``interface``, ``peers``) or the process does
(:meth:`Ros2Transport.configure`: ``scart deploy --insecure``); a later stream that asks
for another network on an open domain is refused.

**Options** (:data:`OPTIONS`): ``type`` (``pkg/msg/Type``; a plain port's default is its
``std_msgs`` type), ``converter`` (``module:function``), ``frame_id`` (a header stamped on
a model without one), ``latch`` (``true``: transient-local; for a writer, also a buffer
policy's ``init``), ``best_effort`` (``true``), ``deadline``, ``lifespan``,
``liveliness_lease`` (seconds), ``msgs`` (``.msg`` files named ``.../pkg/msg/Type.msg``,
comma-separated), and ``domain``, ``insecure``, ``interface``, ``peers``. Conversion is
planned and type-checked when the stream is made (:mod:`._convert`); a message that does
not convert is refused and counted (the reader end's ``refuse``, or
:attr:`~dataflow.transports.Stream.refused` for a value scart publishes), as is a value
that fails the port's type or bounds (out of range; NaN and inf only for a port asking
``finite=True``): ``scart describe`` names the last one under the port.

**QoS** from the stream's policy, rclpy's defaults unless asked otherwise: DATA →
keep-last 10 (rclpy's depth); BUFFER(n) and CIRCULAR_BUFFER(n) → keep-last n (at most
10,000); reliable unless ``best_effort``; volatile, transient-local only with ``latch``
(or a buffer policy given ``init``); ``deadline``, ``lifespan``, ``liveliness_lease``
(seconds) when given, else infinite; liveliness automatic. The policy-shaped buffer stays the input port's: DDS's
history is the transit's only. A message carries no scart write number, so a reader
counts what it refused and what its buffer dropped, not what DDS lost on the way (a
reliable keep-last reader overwrites what it has not taken).

**Security.** DDS without DDS Security authenticates no one: a stream's
:attr:`~dataflow.transports.Stream.authenticated` is False, and ``scart describe`` marks
its input port so.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dataflow.policy import ConnPolicy, ConnType
from dataflow.transports import Stream, StreamProblem, Transport, TransportError
from dataflow.transports.ends import OutSample, ReaderEnd, WriterEnd

from scart_ros2.errors import NEEDS_DDS, DomainError, Ros2Error
from scart_ros2.names import check_node_name, topic_name
from scart_ros2.network import MAX_DOMAIN_ID, Network, resolve_domain_id

from .._rosplan import RefusingCarrier, flag, latched, receiver, stamper, stream_problems, usable

if TYPE_CHECKING:  # these import Cyclone DDS and rosbags: a stream imports them (see _dds)
    from collections.abc import Callable

    from dataflow.deployer import Deployer
    from dataflow.ports import Port
    from scart_ros2.endpoints import Publisher, Subscription

    from ._citizen import Ros2Citizen
    from ._convert import Conversion
    from scart_ros2.participant import Participant
    from scart_ros2.qos import QoS
    from scart_ros2.msgs import MessageTypes

__all__ = ["OPTIONS", "Ros2Transport", "add_type_file", "qos_of"]

log = logging.getLogger(__name__)

NETWORK_OPTIONS = frozenset({"domain", "insecure", "interface", "peers"})
DURATIONS = ("deadline", "lifespan", "liveliness_lease")  #: QoS options in seconds
#: Every option a ros2 stream takes (another is refused: a typo would otherwise be ignored).
OPTIONS = frozenset({"type", "converter", "frame_id", "latch", "best_effort", "msgs", *DURATIONS}) | NETWORK_OPTIONS
DATA_DEPTH = 10  #: keep-last depth of a DATA stream: rclpy's default
MAX_DEPTH = 10_000  #: keep-last depth, at most (the library's bound)
MAX_DEFINITION_BYTES = 1 << 20  #: a .msg file larger than this is refused (as ros1's)


def _dds() -> None:
    """Raise :class:`TransportError` naming the extra when Cyclone DDS is missing: the
    transport loads without it (``auto`` reads its rank), its streams need it."""
    try:
        import cyclonedds  # noqa: F401
    except ImportError:
        raise TransportError(NEEDS_DDS) from None


def qos_of(policy: ConnPolicy | None, *, best_effort: bool = False, latch: bool = False,
           seconds: Mapping[str, float] | None = None) -> QoS:
    """The ROS 2 QoS of a stream with ``policy`` (see the module docstring); ``seconds``:
    ``deadline``, ``lifespan``, ``liveliness_lease`` when given."""
    from scart_ros2.qos import QoS, Durability, Reliability

    depth = DATA_DEPTH if policy is None or policy.type is ConnType.DATA else max(1, min(policy.size, MAX_DEPTH))
    given = seconds or {}
    return QoS(depth, Reliability.BEST_EFFORT if best_effort else Reliability.RELIABLE,
               Durability.TRANSIENT_LOCAL if latch else Durability.VOLATILE,
               deadline=given.get("deadline"), lifespan=given.get("lifespan"),
               liveliness_lease=given.get("liveliness_lease"))


def _seconds(options: Mapping[str, str]) -> dict[str, float]:
    """The QoS durations ``options`` give (s); raises ``ValueError`` naming a bad one."""
    out = {}
    for key in DURATIONS:
        if key in options:
            try:
                value = float(options[key])
            except ValueError:
                value = float("nan")
            if not 0 < value < 1e6:
                raise ValueError(f"option {key}={options[key]!r}: seconds > 0 (omit it for ROS's infinite)")
            out[key] = value
    return out


@dataclass(frozen=True)
class _Where:
    """The domain and network a stream asks for."""

    domain: int
    network: Network


class Ros2Transport(Transport):
    """Streams on ROS 2 topics through this process's participants (see the module
    docstring). Thread-safe; a participant is made on first use and closed with its last
    user."""

    name = "ros2"
    rank = None
    topics = True
    converts = True

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._network = Network.loopback()
        self._types: MessageTypes | None = None
        self._open: dict[int, list[Any]] = {}  # domain -> [Participant, Network, users]
        self._node_name = ""
        self._namespace: str | None = None
        self._remaps: dict[str, str] = {}  # full topic or service name -> the one used
        self.read_only = False  #: publish only (``--ros-read-only``): no input stream, service or parameter set
        self.use_sim_time = False  #: the node's ``use_sim_time`` at its start (``_use_sim_time:=true``)
        self._deployers: list[Deployer] = []
        self._citizens: dict[int, Ros2Citizen | None] = {}  # domain -> its participant's Ros2Citizen

    # ---- the process's participants ----------------------------------------------------
    def configure(self, *, insecure: bool | None = None, interface: str | None = None,
                  peers: tuple[str, ...] = (), name: str | None = None, namespace: str | None = None,
                  remaps: Mapping[str, str] | None = None, read_only: bool | None = None,
                  use_sim_time: bool | None = None) -> None:
        """Set this process's defaults for ROS 2: its node's ``name`` and ``namespace``
        (``--ros-name``, ``--ros-namespace``; else ``scart_<pid>`` in ``ROS_NAMESPACE``,
        else ``/``), and its network (``scart deploy --insecure``): ``insecure`` opens it
        (multicast discovery on ``interface``, else the one Cyclone picks, and unicast
        ``peers``); False: loopback only; None: as it is. A domain already open keeps its
        node and network until its last user goes. Raises ``ValueError`` for a bad name,
        namespace, interface or peer. ``remaps``: ``{"/from": "/to"}``, topic and service
        names used in place of others (``scart run --remap /from:=/to``). ``read_only``:
        publish only (``--ros-read-only``). ``use_sim_time``: the node's parameter at its
        start (a launch-time ``_use_sim_time:=true``): its tasks follow ``/clock`` from then
        (``ValueError`` with ``read_only``, which takes nothing from ROS)."""
        if (use_sim_time if use_sim_time is not None else self.use_sim_time) and \
                (read_only if read_only is not None else self.read_only):
            raise ValueError("use_sim_time is refused: this process serves ROS read-only (--ros-read-only takes "
                             "nothing from ROS, /clock included)")
        if read_only is not None:
            self.read_only = read_only
        if use_sim_time is not None:
            self.use_sim_time = use_sim_time
        if remaps:
            checked = {topic_name(old): topic_name(new) for old, new in remaps.items()}
            with self._lock:
                self._remaps.update(checked)
        if name is not None or namespace is not None:
            check_node_name(name or "scart", namespace or "/")
            with self._lock:
                self._node_name = name or self._node_name
                self._namespace = namespace if namespace is not None else self._namespace
        if insecure is None:
            return
        try:
            network = Network.open(interface, tuple(peers)) if insecure else Network.loopback()
        except DomainError as exc:
            raise ValueError(str(exc)) from None
        with self._lock:
            self._network = network

    @property
    def types(self) -> MessageTypes:
        """The message types of this process (rosbags' Jazzy store and the ``msgs`` given)."""
        with self._lock:
            if self._types is None:
                _dds()
                from scart_ros2.msgs import MessageTypes

                self._types = MessageTypes()
            return self._types

    def where(self, options: Mapping[str, str]) -> _Where:
        """The domain and network ``options`` ask for (with the process's defaults);
        raises ``ValueError``."""
        text = options.get("domain", "").strip()
        if text and not (text.isdigit() and int(text) <= MAX_DOMAIN_ID):
            raise ValueError(f"option domain={text!r}: an integer 0..{MAX_DOMAIN_ID}")
        try:
            domain = resolve_domain_id(int(text) if text else None)
        except DomainError as exc:  # ROS_DOMAIN_ID
            raise ValueError(str(exc)) from None
        interface = options.get("interface") or None
        peers = tuple(p.strip() for p in options.get("peers", "").split(",") if p.strip())
        if "insecure" not in options:
            if interface or peers:
                raise ValueError("options interface and peers open ROS 2 to a network: give insecure=true too "
                                 "(anyone there may then read and write)")
            with self._lock:
                return _Where(domain, self._network)
        try:
            return _Where(domain, Network.open(interface, peers) if flag(options, "insecure") else Network.loopback())
        except DomainError as exc:
            raise ValueError(str(exc)) from None

    def acquire(self, where: _Where) -> Participant:
        """This process's participant on ``where.domain`` (made now if there is none), for
        one more user; pair each with :meth:`release`. Raises :class:`TransportError` when
        it is open on another network, or cannot be made."""
        types = self.types
        with self._lock:
            entry = self._open.get(where.domain)
            if entry is not None and not entry[0].closed:
                if entry[1] != where.network:
                    raise TransportError(f"ros2: DDS domain {where.domain} is open in this process "
                                         f"{_shown(entry[1])}; this asks for it {_shown(where.network)}")
                entry[2] += 1
                return entry[0]
            from scart_ros2.participant import Participant

            namespace = self._namespace or os.environ.get("ROS_NAMESPACE") or "/"
            try:
                made = Participant(where.domain, network=where.network, types=types,
                                   node=self._node_name or f"scart_{os.getpid()}", namespace=namespace)
            except (Ros2Error, ValueError) as exc:
                raise TransportError(f"ros2: {exc}") from None
            self._open[where.domain] = [made, where.network, 1]
        log.info("ROS 2 participant on domain %d, %s", where.domain, _shown(where.network))
        self._become_citizen(made)
        return made

    def refuse_input(self, what: str) -> None:
        """Raise :class:`TransportError` saying ``what`` is refused, when read-only."""
        if self.read_only:
            raise TransportError(f"ros2: {what} is refused: this process serves ROS read-only (--ros-read-only: "
                                 "it publishes only)")

    def remapped(self, name: str) -> str:
        """The full topic or service name used for ``name`` (``--remap``); ``ValueError``
        for a name ROS 2 refuses."""
        full = topic_name(name)
        with self._lock:
            return self._remaps.get(full, full)

    def attach(self, deployer: Deployer) -> None:
        """Let this process's ROS 2 nodes speak for ``deployer``'s tasks (:mod:`._citizen`:
        their properties its parameters), now or when one is made."""
        with self._lock:
            self._deployers.append(deployer)
            open_now = [entry[0] for entry in self._open.values()]
        for participant in open_now:
            self._become_citizen(participant)

    def detach(self, deployer: Deployer) -> None:
        """Undo :meth:`attach` (idempotent)."""
        with self._lock:
            if deployer in self._deployers:
                self._deployers.remove(deployer)

    def _attached(self) -> list[Deployer]:
        with self._lock:
            return list(self._deployers)

    def _become_citizen(self, participant: Participant) -> None:
        from ._citizen import Ros2Citizen

        with self._lock:
            if not self._deployers or participant.domain_id in self._citizens or participant.node is None:
                return
            self._citizens[participant.domain_id] = None  # being made
        try:
            citizen = Ros2Citizen(participant, self._attached, self.read_only, self.use_sim_time)
        except (Ros2Error, ValueError) as exc:
            log.warning("ROS 2 node %s: no parameter services or /rosout: %s", participant.node.name, exc)
            citizen = None
        with self._lock:
            self._citizens[participant.domain_id] = citizen

    def release(self, participant: Participant) -> None:
        """One user less of ``participant``; the last one closes it."""
        with self._lock:
            entry = self._open.get(participant.domain_id)
            if entry is None or entry[0] is not participant:
                return
            entry[2] -= 1
            if entry[2] > 0:
                return
            del self._open[participant.domain_id]
            citizen = self._citizens.pop(participant.domain_id, None)
        if citizen is not None:
            citizen.close()
        participant.close()

    def participants(self) -> dict[int, Participant]:
        """The participants open now, by domain (a snapshot)."""
        with self._lock:
            return {domain: entry[0] for domain, entry in self._open.items()}

    # ---- streams -----------------------------------------------------------------------
    def check_stream(self, port: Port[object], topic: str, options: dict[str, str]) -> list[StreamProblem]:
        try:
            _dds()
        except TransportError as exc:
            return [StreamProblem(str(exc))]
        problems = [StreamProblem(p) for p in self._check_options(topic, options)]
        if port.is_input and self.read_only:
            problems.append(StreamProblem(f"ros2: a stream into port {getattr(port, 'qualname', port.name)} is "
                                          "refused: this process serves ROS read-only (--ros-read-only)"))
        if problems:
            return problems
        return self.conversion(port, options)[1]

    def _check_options(self, topic: str, options: Mapping[str, str]) -> list[str]:
        unknown = sorted(set(options) - OPTIONS)
        out = [f"ros2: unknown option(s) {', '.join(unknown)}; options: {', '.join(sorted(OPTIONS))}"] if unknown else []
        try:
            topic_name(topic)
            self.where(options)
            for key in ("latch", "best_effort"):
                if key in options:
                    flag(options, key)
            _seconds(options)
            self._add_msgs(options)
        except ValueError as exc:
            out.append(f"ros2: {exc}")
        return out

    def _add_msgs(self, options: Mapping[str, str]) -> None:
        for path in filter(None, (p.strip() for p in options.get("msgs", "").split(","))):
            add_type_file(self.types, path)

    def conversion(self, port: Port[object], options: Mapping[str, str]) -> tuple[Conversion | None, list[StreamProblem]]:
        """How ``port``'s values cross to the topic's type, and the problems found."""
        from ._convert import plan

        conv, problems = plan(self.types, port.type, options.get("type") or None, outgoing=not port.is_input,
                              converter=options.get("converter", ""), frame_id=options.get("frame_id", ""))
        return conv, stream_problems("ros2", port, problems)

    def stream(self, end: WriterEnd | ReaderEnd, topic: str, options: dict[str, str]) -> Stream:
        _dds()
        port = end.port
        if port is None:
            raise TransportError("ros2 converts a port's values: a reader end without its port cannot be streamed")
        errors = self._check_options(topic, options)
        if errors:
            raise TransportError("; ".join(errors))
        if isinstance(end, ReaderEnd):
            self.refuse_input(f"a stream from {topic} into port {port.qualname}")
        conv = usable(*self.conversion(port, options), log)
        participant = self.acquire(self.where(options))
        try:
            return _TopicStream(self, participant, end, self.remapped(topic), conv, options)
        except (Ros2Error, ValueError) as exc:
            self.release(participant)
            raise TransportError(f"ros2: {exc}") from None
        except BaseException:
            self.release(participant)
            raise


def _shown(network: Network) -> str:
    return "loopback only" if network.loopback_only else "open to the network (insecure)"


def add_type_file(types: MessageTypes, path: str, kinds: tuple[str, ...] = ("msg",)) -> None:
    """Add the type defined in the file ``path``, named by its place:
    ``.../PACKAGE/msg/TYPE.msg`` (or ``.../PACKAGE/srv/TYPE.srv`` with ``"srv"`` in ``kinds``);
    nothing if that type is known already. Raises ``ValueError`` naming the file: a name
    out of place, more than :data:`MAX_DEFINITION_BYTES`, unreadable, or not a definition."""
    file = Path(path)
    kind = file.parent.name
    if kind not in kinds or file.suffix != f".{kind}":
        if kinds == ("msg",):
            raise ValueError(f"msgs: {path}: a message file is named .../PACKAGE/msg/TYPE.msg")
        raise ValueError(f"msgs: {path}: a ROS 2 type file is named "
                         + " or ".join(f".../PACKAGE/{k}/TYPE.{k}" for k in kinds))
    name = f"{file.parent.parent.name}/{kind}/{file.stem}"
    if types.has(f"{name}_Request" if kind == "srv" else name):
        return  # added by another stream or service already
    try:
        if file.stat().st_size > MAX_DEFINITION_BYTES:
            raise ValueError(f"larger than {MAX_DEFINITION_BYTES} bytes")
        (types.add_srv_file if kind == "srv" else types.add_msg_file)(file, name)
    except (OSError, ValueError) as exc:
        raise ValueError(f"msgs: {path}: {exc}") from None


class _Carrier(RefusingCarrier):
    """A writer end's carrier onto a ROS 2 publisher: each sample converted (its header
    stamped with the sample's time) and written, from the writer's thread, never blocking
    (keep-last history). A value that does not convert is refused and counted here."""

    @staticmethod
    def encode(sample: OutSample) -> OutSample:
        return sample  # converted in send(): the conversion is this stream's own

    def __init__(self, publisher: Publisher, conv: Conversion, label: str, stamp: Callable[[int], int]) -> None:
        super().__init__(label, log)
        to_message = conv.to_cdr or conv.to_idl
        assert to_message is not None
        self._to_idl = to_message
        self._publisher = publisher
        self._stamp = stamp

    def send(self, sample: OutSample, _data: object) -> bool:  # the writer's thread
        try:
            message = self._to_idl(sample.value, self._stamp(sample.t_ns))
        except Exception as exc:  # noqa: BLE001 - a value that does not convert never reaches the writer
            self._refuse(f"sample {sample.n}: {type(exc).__name__}: {exc}")
            return True
        if not self._publisher.publish(message):
            if self._publisher.closed:  # the stream is closing: not sent, counted by the writer end
                return False
            self._refuse(f"sample {sample.n}: {self._publisher.stats().last_refusal}")
        return True  # DDS keeps the newest of its history: never "no room"


class _TopicStream(Stream):
    """A writer end publishing a ROS 2 topic, or a reader end fed from one."""

    authenticated = False

    def __init__(self, transport: Ros2Transport, participant: Participant, end: WriterEnd | ReaderEnd, topic: str,
                 conv: Conversion, options: Mapping[str, str]) -> None:
        self._transport, self._participant = transport, participant
        self.topic = topic
        self.type_name = conv.ros_type
        self._pub: Publisher | None = None
        self._sub: Subscription | None = None
        self._carrier: _Carrier | None = None
        self._closed = False
        best_effort, seconds = flag(options, "best_effort"), _seconds(options)
        try:
            if isinstance(end, WriterEnd):
                latch = latched(options, end.policy)
                self._publish(end, conv, qos_of(end.policy, best_effort=best_effort, latch=latch, seconds=seconds))
            else:
                self._subscribe(end, conv, qos_of(end.policy, best_effort=best_effort, latch=flag(options, "latch"),
                                                  seconds=seconds))
        except BaseException:
            self._close_parts()  # the participant is the caller's to release
            raise

    def _publish(self, end: WriterEnd, conv: Conversion, qos: QoS) -> None:
        self._pub = self._participant.publisher(self.topic, conv.ros_type, qos, cdr=conv.to_cdr is not None)
        self._carrier = _Carrier(self._pub, conv, end.label, stamper(end.port))
        end.connected("ros2", self._carrier, new_peer=True)

    def _subscribe(self, end: ReaderEnd, conv: Conversion, qos: QoS) -> None:
        from_message, label = conv.from_cdr or conv.from_idl, conv.ros_type
        assert from_message is not None
        end.transport = "ros2"  # the participant's thread calls the receiver, one message at a time
        self._sub = self._participant.subscribe(self.topic, conv.ros_type, receiver(end, from_message, label), qos,
                                                raw=True, cdr=conv.from_cdr is not None)
        self._sub.refused_hook = lambda why: end.refuse(f"a malformed {label}: {why}")

    # ---- what it says ------------------------------------------------------------------
    @property
    def matched(self) -> int:
        """DDS readers (of a writer end) or writers (of a reader end) matched now."""
        part = self._pub if self._pub is not None else self._sub
        return part.matched() if part is not None else 0

    @property
    def refused(self) -> int:
        return self._carrier.refused if self._carrier is not None else 0

    @property
    def refusal(self) -> str:
        return self._carrier.refusal if self._carrier is not None else ""

    def _close_parts(self) -> None:
        for part in (self._pub, self._sub):
            if part is not None:
                part.close()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._close_parts()
        self._transport.release(self._participant)
