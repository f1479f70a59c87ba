"""The ``ros2`` transport: a scart port joined to a ROS 2 topic (a **stream**,
``ConnPolicy(transport="ros2", topic="/joint_states")``; ``scart stream COMP.PORT
ros2:/topic``; ``<scart:stream transport="ros2">``).

An output port's writer end publishes each sample on ``rt/<topic>`` as the ROS 2 message
its :class:`~._convert.Conversion` makes (CDR, type ``pkg::msg::dds_::Type_``); an input
port's reader end is fed from that topic, each message converted and then checked as any
value from outside (type, finiteness, the port's bounds). A message that cannot be
converted either way is refused and counted, and the stream's status says why
(``scart links --json``, ``scart describe``).

Options (``--option K=V``, or attributes of ``<scart:stream>``):

=================  ==============================================================
``type``           the ROS 2 message type, ``pkg/msg/Type`` (plain ports have a default)
``converter``      ``module:function`` converting the port's values to messages (an
                   output port) or messages to the port's values (an input port)
``best_effort``    ``true``: best-effort reliability (default reliable)
``latching``       ``true``: transient-local durability (a late joiner gets the last
                   ``depth`` samples)
``domain``         the DDS domain id (default ``ROS_DOMAIN_ID``, else 0)
``insecure``       ``true``: open to the network (multicast discovery on the interface
                   Cyclone picks); default loopback only
``interface``      with ``insecure``: the network interface (name or address)
``peers``          with ``insecure``: unicast peers, comma-separated
=================  ==============================================================

QoS comes from the stream's policy as rmw maps ROS 2 QoS: DATA → keep-last 1, BUFFER(n)
and CIRCULAR_BUFFER(n) → keep-last n (at most 10,000), reliable unless ``best_effort``.
The policy-shaped buffer stays the input port's: DDS's history is only the transit's.

One participant per process and domain (a ROS 2 node named ``scart_<pid>``), made with the
first stream and closed with the last; loopback only unless ``insecure`` or
:func:`use_network` (``scart deploy --ros2-network``). Messages carry no scart write
number, so a reader counts what it refused and what its buffer dropped, not what DDS
lost on the way (a reliable keep-last reader overwrites what it has not taken).
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from dataflow.errors import STREAM
from dataflow.policy import ConnPolicy, ConnType
from dataflow.transports import Stream, StreamProblem, Transport, TransportError
from dataflow.transports.ends import OutSample, ReaderEnd, WriterEnd

from ._convert import Conversion, plan
from ._errors import DomainError, Ros2Error
from ._names import topic_name
from ._network import Network, resolve_domain_id
from ._participant import Participant
from ._qos import QoS
from ._types import MessageTypes

__all__ = ["OPTIONS", "Ros2Transport", "participant", "qos_of", "release", "use_network"]

log = logging.getLogger("dataflow.transports.ros2")

OPTIONS = ("type", "converter", "best_effort", "latching", "domain", "insecure", "interface", "peers")
_MAX_DEPTH = 10_000
_REASON = 160  # characters of a refusal's reason kept for the listing


# ---- the process's participants ---------------------------------------------------------
class _Participants:
    """One participant per domain, shared by the streams of this process, made with the
    first and closed with the last (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._default: Network | None = None
        self._types: MessageTypes | None = None
        self._open: dict[int, list[Any]] = {}  # domain -> [Participant, Network, users]

    def types(self) -> MessageTypes:
        with self._lock:
            if self._types is None:
                self._types = MessageTypes()
            return self._types

    def use_network(self, network: Network | None) -> None:
        with self._lock:
            self._default = network

    def network(self) -> Network:
        with self._lock:
            return self._default or Network.loopback()

    def acquire(self, domain: int, network: Network) -> Participant:
        types = self.types()
        with self._lock:
            entry = self._open.get(domain)
            if entry is not None:
                if entry[1] != network:
                    raise TransportError(f"ros2: domain {domain} is open in this process on another network "
                                         f"({_shown(entry[1])}); a stream asked for {_shown(network)}")
                entry[2] += 1
                return entry[0]
            try:
                made = Participant(domain, network=network, types=types, node=f"scart_{os.getpid()}")
            except Ros2Error as exc:
                raise TransportError(f"ros2: {exc}") from None
            self._open[domain] = [made, network, 1]
            return made

    def release(self, domain: int) -> None:
        with self._lock:
            entry = self._open.get(domain)
            if entry is None:
                return
            entry[2] -= 1
            if entry[2] > 0:
                return
            del self._open[domain]
        entry[0].close()


def _participants() -> _Participants:
    """The participants of the process's ``ros2`` transport (the registry's one instance)."""
    from dataflow.transports import load

    transport = load("ros2")
    if not isinstance(transport, Ros2Transport):
        raise TransportError(f"transport 'ros2' is a {type(transport).__qualname__}, not scart's")
    return transport.participants


def use_network(network: Network | None) -> None:
    """Make ``network`` the one this process's ROS 2 streams without network options use
    from now on (``scart deploy --ros2-network``); None: loopback only again. A domain
    already open keeps its network until its last stream closes."""
    _participants().use_network(network)


def participant(domain: int | None = None, network: Network | None = None) -> Participant:
    """The process's participant on ``domain`` (default ``ROS_DOMAIN_ID``), the one its
    streams use, made if needed; give it back with :func:`release`. For services and
    calls beside the streams. Raises :class:`TransportError` as a stream would."""
    found = _participants()
    return found.acquire(resolve_domain_id(domain), network or found.network())


def release(p: Participant) -> None:
    """Give back a participant from :func:`participant` (closed with its last user)."""
    _participants().release(p.domain_id)


def _shown(network: Network) -> str:
    return "loopback only" if network.loopback_only else "open (insecure)"


# ---- what a stream asks for -------------------------------------------------------------
@dataclass(frozen=True)
class _Setup:
    topic: str
    conversion: Conversion
    best_effort: bool
    latching: bool
    domain: int
    network: Network


def qos_of(policy: ConnPolicy | None, best_effort: bool = False, latching: bool = False) -> QoS:
    """The ROS 2 QoS of a stream with ``policy``: DATA → keep-last 1, BUFFER(n) and
    CIRCULAR_BUFFER(n) → keep-last n (at most 10,000); reliable unless ``best_effort``;
    transient-local if ``latching``."""
    depth = 1 if policy is None or policy.type is ConnType.DATA else min(policy.size, _MAX_DEPTH)
    return QoS.buffer(depth, best_effort=best_effort, latching=latching)


def _flag(options: Mapping[str, str], key: str, problems: list[StreamProblem]) -> bool:
    text = options.get(key, "false").strip().lower()
    if text not in ("true", "false", "1", "0", "yes", "no"):
        problems.append(StreamProblem(STREAM, f"option {key}={options[key]!r}: expected true or false"))
    return text in ("true", "1", "yes")


def _network(participants: _Participants, options: Mapping[str, str], problems: list[StreamProblem]) -> Network:
    insecure = _flag(options, "insecure", problems)
    interface, peers = options.get("interface") or None, tuple(p for p in options.get("peers", "").split(",") if p)
    if not insecure:
        if interface or peers:
            problems.append(StreamProblem(STREAM, "options interface and peers open ROS 2 to a network: "
                                                  "give insecure=true too (anyone there may then write)"))
        return participants.network()
    try:
        return Network.open(interface, peers)
    except DomainError as exc:
        problems.append(StreamProblem(STREAM, str(exc)))
        return Network.loopback()


def setup(participants: _Participants, port: Any, topic: str, options: Mapping[str, str],
          importer: Callable[[str], object] | None = None) -> tuple[_Setup | None, list[StreamProblem]]:
    """What a stream of ``port`` on ``topic`` with ``options`` asks for, and the problems."""
    problems = [StreamProblem(STREAM, f"ros2 has no option {key!r}; options: {', '.join(OPTIONS)}")
                for key in options if key not in OPTIONS]
    try:
        full = topic_name(topic)
    except ValueError as exc:
        problems.append(StreamProblem(STREAM, str(exc)))
        full = ""
    best_effort, latching = _flag(options, "best_effort", problems), _flag(options, "latching", problems)
    domain = 0
    try:
        domain = resolve_domain_id(_domain(options.get("domain")))
    except (DomainError, ValueError) as exc:
        problems.append(StreamProblem(STREAM, str(exc)))
    network = _network(participants, options, problems)
    conversion, found = plan(port.type, port.is_input, participants.types(), options.get("type") or None,
                             options.get("converter") or None, importer)
    problems += found
    if conversion is None or any(not p.warning for p in problems):
        return None, problems
    return _Setup(full, conversion, best_effort, latching, domain, network), problems


def _domain(text: str | None) -> int | None:
    if text is None or not text.strip():
        return None
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"option domain={text!r}: expected an integer 0..232") from None


# ---- the ends on ROS 2 ------------------------------------------------------------------
class _Writer:
    """The carrier of a writer end on a ROS 2 topic: each sample converted (once,
    :attr:`encode`) and written, from the writer's thread. A sample that cannot be
    converted is refused (the end counts it) and remembered for the listing."""

    def __init__(self, publisher: Any, conversion: Conversion) -> None:
        self._publisher = publisher
        self.unconvertible = 0
        self.last_refusal = ""
        to_idl = conversion.to_idl

        def encode(sample: OutSample) -> Any:
            try:
                return to_idl(sample.value)
            except Exception as exc:
                self.unconvertible += 1
                self.last_refusal = str(exc)[:_REASON]
                raise
        self.encode = encode

    def send(self, sample: OutSample, data: Any) -> bool:
        self._publisher.publish(data)  # DDS keeps the newest of its history: never "no room"
        return True

    def status(self) -> str:
        refused = self.unconvertible + self._publisher.stats().refused
        if not refused:
            return ""
        return f"refused={refused} (cannot be converted: {self.last_refusal or self._publisher.stats().last_refusal})"


class _Feed:
    """A reader end fed from a ROS 2 topic (the participant's thread, one message at a
    time): each message converted, then handed to the end, which checks and keeps it."""

    def __init__(self, ros: Participant, setup: _Setup, qos: QoS, end: ReaderEnd) -> None:
        self.end = end
        self._from_idl = setup.conversion.from_idl
        self._n = 0
        self.unconvertible = 0
        self.malformed = 0
        self.last_refusal = ""
        self._sub = ros.subscribe(setup.topic, setup.conversion.ros_type, self._on_message, qos, raw=True)
        self._sub.refused_hook = self._on_malformed

    def _on_message(self, obj: Any) -> None:
        self._n += 1
        try:
            value = self._from_idl(obj)
        except Exception as exc:  # noqa: BLE001 - one bad message never ends the stream
            self._refuse(exc)
            return
        self.end.receive(self._n, time.time_ns(), value)

    def _refuse(self, exc: BaseException) -> None:
        end = self.end
        end.loss.sample(self._n)
        end.received += 1
        end.refused += 1
        self.unconvertible += 1
        self.last_refusal = str(exc)[:_REASON]
        if self.unconvertible == 1:
            log.warning("%s: a message that cannot be converted refused: %s", end.label, exc)

    def _on_malformed(self, why: str) -> None:
        self._n += 1
        self.end.loss.sample(self._n)
        self.end.received += 1
        self.end.refused += 1
        self.malformed += 1
        self.last_refusal = why[:_REASON]

    def status(self) -> str:
        checked = self.end.refused - self.unconvertible - self.malformed
        parts = [f"{n} {what}" for n, what in ((self.unconvertible, "cannot be converted"),
                                              (self.malformed, "malformed"),
                                              (checked, "refused by the port's check")) if n > 0]
        if not parts:
            return ""
        last = f": {self.last_refusal}" if self.last_refusal and (self.unconvertible or self.malformed) else ""
        return f"refused={self.end.refused} ({', '.join(parts)}{last})"

    def close(self) -> None:
        self._sub.close()


class _TopicStream(Stream):
    """A writer or reader end joined to a ROS 2 topic (what :meth:`Ros2Transport.stream` makes)."""

    def __init__(self, participants: _Participants, end: WriterEnd | ReaderEnd, setup: _Setup) -> None:
        self.topic = setup.topic
        self._domain = setup.domain
        self._participants = participants
        self._ros = participants.acquire(setup.domain, setup.network)
        self._writer: _Writer | None = None
        self._feed: _Feed | None = None
        self._closed = False
        try:
            qos = qos_of(end.policy, setup.best_effort, setup.latching)
            if isinstance(end, WriterEnd):
                publisher = self._ros.publisher(setup.topic, setup.conversion.ros_type, qos)
                self._writer = _Writer(publisher, setup.conversion)
                end.connected("ros2", self._writer, new_peer=True)
            else:
                end.transport = "ros2"
                self._feed = _Feed(self._ros, setup, qos, end)
        except BaseException:
            self.close()
            raise

    def status(self) -> str:
        part = self._writer or self._feed
        return part.status() if part is not None else ""

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._feed is not None:
            self._feed.close()
        if self._writer is not None:
            self._writer._publisher.close()
        self._participants.release(self._domain)


class Ros2Transport(Transport):
    """Streams on ROS 2 topics over Cyclone DDS (see the module docstring); not part of ``auto``."""

    name = "ros2"
    rank = None
    topics = True
    converts = True
    authenticated = False  # DDS without DDS Security authenticates no one

    def __init__(self) -> None:
        #: The participants its streams use, one per domain (the registry loads one
        #: transport per process: so one participant per process and domain).
        self.participants = _Participants()

    def check_stream(self, port: Any, topic: str, options: Mapping[str, str],
                     importer: Callable[[str], object] | None = None) -> list[StreamProblem]:
        return setup(self.participants, port, topic, options, importer)[1]

    def stream(self, end: WriterEnd | ReaderEnd, topic: str, options: dict[str, str]) -> Stream:
        port = end.port
        if port is None:
            raise TransportError("ros2: a stream needs the end's port (its type is mapped onto a ROS 2 message)")
        found, problems = setup(self.participants, port, topic, options)
        errors = [p for p in problems if not p.warning]
        if found is None or errors:
            raise TransportError("; ".join(str(p) for p in errors) or "ros2: the stream cannot be made")
        for problem in problems:
            log.warning("stream %s ros2:%s: %s", port.qualname, topic, problem)
        try:
            return _TopicStream(self.participants, end, found)
        except (Ros2Error, ValueError) as exc:
            raise TransportError(f"ros2: {exc}") from None
