"""Data-flow ports on Zenoh (``eclipse-zenoh``; install ``scart[zenoh]``): publish a
deployer's output ports, subscribe to them, and find them without a scart name service.

Key scheme (documented in the README, "Transports"):

- ``scart/<ns>/<component>/<port>``: the samples of an output port. Each is the gRPC
  path's own encoding, a ``scart.dataflow.v1.Value`` message; the Zenoh encoding says so
  and carries the port's registry type name: ``application/protobuf;scart.dataflow.v1.Value;<type>``.
  The attachment is the publisher's random id, the port's write number and the time it
  was sent (three 8-byte little-endian integers, the time in ns since the epoch): a
  subscriber tells the writes it did not get from the jumps in the write numbers, as on
  the other transports, and starts counting afresh when the id changes (a restart).
- Liveliness tokens announce what runs: ``scart/<ns>/<component>`` for each task and
  ``scart/<ns>/<component>/<port>`` for each of its output ports. A process that dies
  takes its tokens with it, so :func:`discover` lists only live components.
- ``scart-served/<ns>/<component>/<address>/<boot id>`` (a liveliness token per task, the
  address percent-encoded) says which deployer serves it over gRPC, the control plane:
  :class:`ZenohNames` answers lookups from these in place of a scart name service.
- ``scart-proof/<ns>/<component>`` (a queryable per task of a deployer that checks tokens)
  proves an announcement: asked with ``id=<token id>;nonce=<hex>``, it answers the
  address and boot id it serves at and an HMAC of the nonce, namespace, component,
  address and boot id under a key derived from that token (:func:`proof_of`). Only a
  holder of the auth file knows the tokens, so only a real deployer of the fleet can
  answer for a resolver's token; :class:`ZenohNames` holding a token uses only the
  announcements proved this way (it would send that token there).

``<ns>`` is a namespace word (default ``default``), as ``__ns`` is for remapping.

As a transport (``ConnPolicy(transport="zenoh", topic=KEY)``; :class:`ZenohTransport`, the
``scart.transports`` entry point ``zenoh``) it joins a port to any key: a **stream**
(``scart stream COMP.PORT zenoh:KEY``, ``<scart:stream>``), under the stream's policy, in
the process's Zenoh session (:func:`use_session`: ``scart deploy --zenoh``; or one opened
for the stream from its ``connect`` / ``listen`` options). gRPC stays the control plane
(describe, operations, properties, state); only samples move here. Sessions are loopback by default, with multicast and gossip scouting off (a
session reaches only the endpoints it is given): :func:`open_session` refuses a routable
endpoint, to listen on or to connect to, unless ``insecure`` (Zenoh traffic is not
encrypted by scart; secure a fleet with Zenoh's own TLS and access control). With scart's
tokens (an auth file), a listening session admits only peers presenting an ``operate`` or
``admin`` token, through Zenoh's own user/password authentication (``usrpwd``).
The writer's thread never waits: when another thread is publishing the port, it leaves
the newest sample to that thread (the ones in between are counted as lost by the
subscribers); Zenoh's ``DROP`` congestion control drops at once rather than wait for room;
and nothing is encoded while no subscriber matches the key.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

from scart_wire import codec
from dataflow.introspection import LinkDescription
from dataflow.policy import ConnPolicy, FlowStatus
from dataflow.ports import InputPort, OutputPort
from dataflow.remote.api import SampleEvent
from dataflow.transports import Stream, Transport, TransportError
from dataflow.transports.ends import OutSample, ReaderEnd, WriterEnd, attach, detach
from dataflow.threads import OwnedThread, Wake
from dataflow.transports.limits import check_size
from dataflow.transports.sinks import port_check
from dataflow.transports.zenoh._keys import (
    DEFAULT_NS, ENCODING_PREFIX, MAX_PAYLOAD, ROOT, SERVED, check_topic, key_of, served_key,
)
from dataflow.transports.zenoh._names import PROOF, Prover, ZenohNames, connect_zenoh, discover, proof_of, token_id
from dataflow.transports.zenoh._session import check_endpoint, open_session, zenoh_credentials

if TYPE_CHECKING:
    import zenoh

    from dataflow.deployer import Deployer
    from scart_wire.security import AuthTable

__all__ = ["DEFAULT_NS", "ROOT", "SERVED", "ZenohInput", "ZenohNames", "ZenohPublisher", "ZenohSubscription",
           "ZenohTransport", "check_endpoint", "connect_zenoh", "discover", "key_of", "open_session", "proof_of",
           "served_key", "token_id", "use_session", "zenoh_credentials"]

log = logging.getLogger(__name__)

ATTACHMENT = 24  #: bytes of scart's attachment: publisher id, write number, time (ns), little-endian
#: A payload larger than this (Zenoh's batch: it would go in fragments) is put by the
#: publisher's sender thread, which may wait for room: the writer's thread never does.
INLINE_BYTES = 64 * 1024


class _Declared(Protocol):
    """What a session declared (a liveliness token, a queryable): undeclared on close."""

    def undeclare(self) -> object: ...


def _quietly(undeclare: Callable[[], object], what: str) -> None:
    try:
        undeclare()
    except Exception as exc:  # noqa: BLE001 - a session already closed: nothing left to undeclare
        log.info("zenoh: undeclaring a %s: %s", what, exc)


# ---- the process's session ------------------------------------------------------------
_session_lock = threading.Lock()
_default: zenoh.Session | None = None


def use_session(session: zenoh.Session | None) -> None:
    """Make ``session`` the one streams and Zenoh links of this process use (``scart
    deploy --zenoh`` sets its own); None forgets it. The session stays its opener's."""
    global _default
    with _session_lock:
        _default = session


def _session_for(options: dict[str, str]) -> tuple[zenoh.Session, bool]:
    """The session a stream uses and whether it owns it: one opened from the stream's own
    ``connect`` / ``listen`` options (comma-separated endpoints; ``insecure=true`` for a
    routable one), else the process's (:func:`use_session`). :class:`TransportError` when
    there is neither, or Zenoh is not installed."""
    connect = [e for e in options.get("connect", "").split(",") if e]
    listen = [e for e in options.get("listen", "").split(",") if e]
    if connect or listen:
        try:
            return open_session(connect, listen, insecure=options.get("insecure", "") == "true"), True
        except ImportError:
            raise TransportError("transport zenoh needs eclipse-zenoh: pip install 'scart[zenoh]'") from None
        except Exception as exc:  # noqa: BLE001 - Zenoh's own errors name a Rust source file: say it plainly
            raise TransportError(f"zenoh: cannot open a session ({str(exc).splitlines()[0][:200]})") from None
    with _session_lock:
        session = _default
    if session is None:
        raise TransportError("transport zenoh has no session in this process: give the stream connect=ENDPOINT "
                             "(e.g. tcp/127.0.0.1:7447), or run the deployer with --zenoh")
    return session, False


# ---- writer ends on Zenoh -------------------------------------------------------------
class _Publisher:
    """The carrier of a writer end on a Zenoh key: each sample put with scart's attachment
    (this publisher's id, the write number, the time), from the writer's thread. Nothing is
    encoded while no subscriber matches the key (Zenoh tells, at once when one does);
    Zenoh's ``DROP`` congestion control drops at once rather than wait for room."""

    def __init__(self, session: zenoh.Session, key: str, type_name: str, publisher_id: bytes,
                 flush: Callable[[], None] = lambda: None) -> None:
        import zenoh

        self.key = key
        self._id = publisher_id
        self._publisher = session.declare_publisher(
            key, encoding=zenoh.Encoding.APPLICATION_PROTOBUF.with_schema(ENCODING_PREFIX + type_name),
            congestion_control=zenoh.CongestionControl.DROP)
        self._matching = False
        self._listener = self._publisher.declare_matching_listener(self._on_matching)
        self._flush = flush  # the writer end's: what waited for the sender goes next
        # large payloads: put by the sender thread on a publisher that waits for room (Zenoh
        # sends them in fragments, which DROP would lose when its queue is full); bounded
        # by the session's block/wait_before_close, after which Zenoh closes the link
        self._large_publisher = session.declare_publisher(
            key, encoding=zenoh.Encoding.APPLICATION_PROTOBUF.with_schema(ENCODING_PREFIX + type_name),
            congestion_control=zenoh.CongestionControl.BLOCK)
        self._large: tuple[bytes, bytes] | None = None  # a large payload for the sender thread, and its stamp
        self._wake = Wake()
        self._sender: OwnedThread | None = None
        self._sender_lock = threading.Lock()

    def _on_matching(self, status: zenoh.MatchingStatus) -> None:  # Zenoh's thread
        self._matching = bool(status.matching)

    def encode(self, sample: OutSample) -> bytes | OutSample:
        """The sample's payload, only while someone listens (else the sample itself: not
        encoded); raises :class:`~dataflow.transports.limits.SampleTooLarge` over
        :data:`MAX_PAYLOAD`, so the writer end refuses it at ``write()`` and counts it."""
        if not self._matching:
            return sample
        return check_size(codec.encode(sample.value, sample.type).SerializeToString(), MAX_PAYLOAD, "zenoh")

    def send(self, sample: OutSample, data: bytes | OutSample) -> bool:  # the writer's thread
        if type(data) is not bytes:
            return True
        stamp = self._id + sample.n.to_bytes(8, "little") + sample.t_ns.to_bytes(8, "little")
        if len(data) <= INLINE_BYTES:
            self._publisher.put(data, attachment=stamp)
            return True
        if self._large is not None:  # the sender is busy: the writer end keeps it, as its policy says
            return False
        self._large = (data, stamp)
        self._start_sender().set()
        return True

    def _start_sender(self) -> Wake:
        with self._sender_lock:
            if self._sender is None:
                self._sender = OwnedThread(self._send_large, f"scart-zenoh-{self.key}"[:60], wake=self._wake.set)
                self._sender.start()
        return self._wake

    def _send_large(self, stopping: threading.Event) -> None:
        """The sender thread: each large payload put (Zenoh sends it in fragments, waiting
        for room), then the writer end's next."""
        while not stopping.is_set():
            self._wake.wait(1.0)
            self._wake.clear()
            large = self._large
            if large is None:
                continue
            try:
                self._large_publisher.put(large[0], attachment=large[1])
            except Exception as exc:  # noqa: BLE001 - a closed session: the subscribers count the jump
                log.info("zenoh %s: a large sample not sent: %s", self.key, exc)
            self._large = None
            self._flush()

    def close(self) -> None:
        with self._sender_lock:
            sender, self._sender = self._sender, None
        if sender is not None:
            sender.stop()
        _quietly(self._listener.undeclare, "matching listener")
        _quietly(self._publisher.undeclare, "publisher")
        _quietly(self._large_publisher.undeclare, "publisher")


class ZenohPublisher:
    """Every output port of the tasks of ``deployer`` (those there now) published on
    ``session`` at ``scart/<ns>/<task>/<port>`` (a writer end each, with DATA's policy),
    and a liveliness token per task and port. :meth:`close` undeclares everything
    (idempotent, also after a failure half-way)."""

    def __init__(self, deployer: Deployer, session: zenoh.Session, ns: str = DEFAULT_NS, served: tuple[str, str] | None = None,
                 auth: AuthTable | None = None) -> None:
        """``served``: ``(address, boot id)`` of the deployer's gRPC server, announced with
        each task (:func:`served_key`) so that :class:`ZenohNames` finds it; ``auth``: the
        deployer's auth file, with which it proves those announcements (``scart-proof``)."""
        import secrets

        self.ns = ns
        self._closed = False
        self._id = secrets.randbits(64).to_bytes(8, "little")  # this publisher: a subscriber tells restarts by it
        self._ends: list[tuple[WriterEnd, _Publisher]] = []
        self._tokens: list[_Declared] = []
        keys = {token_id(t.decode()): t.decode() for t, _ in auth.entries} if auth is not None else {}
        try:
            for task in deployer.tasks():
                self._tokens.append(session.liveliness().declare_token(key_of(ns, task.name)))
                if served is not None:
                    self._tokens.append(session.liveliness().declare_token(served_key(ns, task.name, *served)))
                    if keys:
                        self._tokens.append(session.declare_queryable(
                            f"{PROOF}/{ns}/{task.name}", Prover(ns, task.name, served, keys)))
                for port in task.ports().values():
                    if isinstance(port, OutputPort):
                        self._publish(session, port, key_of(ns, task.name, port.name))
        except BaseException:
            self.close()
            raise

    def _publish(self, session: zenoh.Session, port: OutputPort, key: str) -> None:
        end = WriterEnd(port, ConnPolicy.data(init=False).with_(mandatory=False), f"zenoh {key}", reports=False)
        carrier = _Publisher(session, key, port.type_name, self._id, end.flush)
        self._ends.append((end, carrier))
        end.connected("zenoh", carrier, new_peer=True)
        attach(port, end)
        self._tokens.append(session.liveliness().declare_token(key))

    @property
    def keys(self) -> list[str]:
        """The keys published."""
        return [carrier.key for _, carrier in self._ends]

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for end, carrier in self._ends:
            detach(end.port, end)
            end.disconnected()
            carrier.close()
        for token in self._tokens:
            _quietly(token.undeclare, "liveliness token")


# ---- reader ends on Zenoh -------------------------------------------------------------
def _parse(sample: zenoh.Sample) -> tuple[bytes, int, int, codec.Value]:
    """A Zenoh sample in scart's form: ``(publisher id, write number, time ns, Value)``;
    ``ValueError`` for anything else (too large, no scart attachment)."""
    if len(sample.payload) > MAX_PAYLOAD:
        raise ValueError(f"{len(sample.payload)} bytes, more than {MAX_PAYLOAD}")
    attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
    if len(attachment) != ATTACHMENT:
        raise ValueError("no scart attachment (publisher id, write number, time)")
    value = codec.Value.FromString(sample.payload.to_bytes())
    return attachment[:8], int.from_bytes(attachment[8:16], "little"), int.from_bytes(attachment[16:], "little"), value


class _Subscriber:
    """A reader end fed from a Zenoh key (Zenoh's delivery thread, one sample at a time).
    A sample not in scart's form is refused and counted; a new publisher id (a restarted
    writer, or numbers that make no sense) starts the count afresh from 0."""

    def __init__(self, session: zenoh.Session, key: str, end: ReaderEnd) -> None:
        self.end = end
        self.malformed = 0
        self._lock = threading.Lock()
        self._closed = False
        self._subscriber = session.declare_subscriber(key, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        with self._lock:
            if self._closed:
                return
            try:
                writer, n, t_ns, value = _parse(sample)
            except Exception as exc:  # noqa: BLE001 - one bad sample never ends the stream
                self.malformed += 1
                self.end.refused += 1
                if self.malformed == 1:
                    log.warning("%s: a sample that is not scart's refused: %s", self.end.label, exc)
                return
            last = self.end.loss.last
            if last is not None and not last < n <= last + 1_000_000:
                self.end.boot_id = ""  # numbers that make no sense: as a restart
            self.end.writer(writer.hex())
            self.end.receive(n, t_ns, value)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
        _quietly(self._subscriber.undeclare, "subscriber")


class ZenohSubscription:
    """Samples of ``scart/<ns>/<component>/<port>`` handed to ``observer`` as
    :class:`~dataflow.remote.api.SampleEvent` s (in Zenoh's delivery thread; keep it short).
    Counters as a subscription's: ``delivered``, ``dropped`` (writes not received, seen as
    jumps in the write numbers, plus samples that could not be decoded)."""

    def __init__(self, session: zenoh.Session, component: str, port: str, observer: Callable[[SampleEvent], None],
                 ns: str = DEFAULT_NS) -> None:
        self.component, self.port = component, port
        self.delivered = 0
        self._observer = observer
        self._end = ReaderEnd(f"zenoh {component}.{port}", codec.decode, self._deliver, lambda: 0)
        self._subscriber = _Subscriber(session, key_of(ns, component, port), self._end)

    def _deliver(self, n: int, t_ns: int, value: object) -> bool:
        self.delivered += 1
        self._observer(SampleEvent(self.component, self.port, value, FlowStatus.NEW_DATA, t_ns / 1e9, n))
        return True

    @property
    def undecodable(self) -> int:
        """Samples refused: not scart's, or not decodable."""
        return self._end.refused

    @property
    def dropped(self) -> int:
        """Writes not received (jumps in the write numbers) and samples not decodable."""
        return self._end.lost

    def close(self) -> None:
        """Stop (idempotent)."""
        self._subscriber.close()


class ZenohInput:
    """An input port fed from Zenoh: the samples of ``scart/<ns>/<component>/<port>`` (or
    ``key``) kept in a connection with ``policy`` on ``target`` (the policy's buffer keeps,
    overwrites or drops them, and counts). Each value is checked as one written from
    outside is (its type, finiteness and the port's bounds); a refused one is counted in
    :attr:`refused` and logged once. :meth:`describe` is what ``scart links`` shows."""

    def __init__(self, session: zenoh.Session, component: str, port: str, target: InputPort,
                 policy: ConnPolicy | None = None, ns: str = DEFAULT_NS, key: str | None = None) -> None:
        self.target = target
        self.key = key or key_of(ns, component, port)
        self.policy = policy or ConnPolicy.data()
        self._close_lock, self._closed = threading.Lock(), False
        self.connection = conn = target.open_channel(self.policy, peer=f"zenoh:{self.key}")
        self.end = ReaderEnd(f"zenoh {self.key} into {target.qualname}", port_check(target),
                             conn.store, lambda: conn.dropped)
        self.end.transport = "zenoh"
        try:
            self._subscriber = _Subscriber(session, self.key, self.end)
        except BaseException:
            conn.close()
            raise

    @property
    def refused(self) -> int:
        return self.end.refused

    def describe(self, name: str = "") -> LinkDescription:
        """What ``scart links`` shows of it (a stream into the port)."""
        return LinkDescription(name=name or f"zenoh:{self.key}->{self.target.qualname}", source=f"zenoh:{self.key}",
                               sink=self.target.qualname, policy=str(self.policy), transport="zenoh",
                               samples=self.end.received, dropped=self.end.lost, kind="stream")

    def close(self) -> None:
        """Stop reading (idempotent: a stream undone is closed again at the runtime's stop)."""
        with self._close_lock:
            if self._closed:
                return
            self._closed = True
        self._subscriber.close()
        self.connection.close()


# ---- the transport --------------------------------------------------------------------
class _TopicStream(Stream):
    """A writer or reader end joined to a Zenoh key (what :meth:`ZenohTransport.stream` makes)."""

    def __init__(self, end: WriterEnd | ReaderEnd, topic: str, options: dict[str, str]) -> None:
        import secrets

        self.topic = topic
        self._session, self._owned = _session_for(options)
        self._carrier: _Publisher | None = None
        self._subscriber: _Subscriber | None = None
        try:
            if isinstance(end, WriterEnd):
                self._carrier = _Publisher(self._session, topic, end.port.type_name,
                                           secrets.randbits(64).to_bytes(8, "little"), end.flush)
                end.connected("zenoh", self._carrier, new_peer=True)
            else:
                end.transport = "zenoh"
                self._subscriber = _Subscriber(self._session, topic, end)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        if self._carrier is not None:
            self._carrier.close()
        if self._subscriber is not None:
            self._subscriber.close()
        if self._owned:
            _quietly(self._session.close, "session")
            self._owned = False


class ZenohTransport(Transport):
    """Streams on Zenoh keys (see the module docstring); not part of ``auto``."""

    name = "zenoh"
    rank = None
    topics = True
    carries = frozenset({"stream"})

    def stream(self, end: WriterEnd | ReaderEnd, topic: str, options: dict[str, str]) -> Stream:
        try:
            key = check_topic(topic)
        except ValueError as exc:
            raise TransportError(str(exc)) from None
        return _TopicStream(end, key, options)
