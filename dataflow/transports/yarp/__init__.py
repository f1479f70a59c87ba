"""YARP as a scart transport: the ``scart.transports`` entry point ``yarp``
(:class:`YarpTransport`), a thin adapter over :mod:`scart_yarp` (YARP's name server, port
protocol and Bottles, natively). A **stream** joins a port to a YARP port —
``Deployer.stream("arm.state", ConnPolicy.data().with_(transport="yarp", topic="/arm/state"))``,
``scart stream arm.state yarp:/arm/state``, ``<scart:stream transport="yarp" .../>``: an
output port is a YARP port that writes (``yarp read /r`` then ``yarp connect /arm/state
/r``), an input port one that reads (``yarp write /w /arm/cmd``). Not part of ``auto``.

**Values** cross as bottles (:mod:`.convert`: the table of what each type becomes); a
bottle that does not fit the port's type is refused whole and counted, as is a value that
fails the port's own check (NaN, out of range): ``scart describe`` names the last one.

**Options** (:data:`OPTIONS`): ``connect`` (YARP ports, comma-separated: an output stream
keeps writing to each, an input stream keeps asking each to write to it; retried until
they are there), ``carrier`` (``tcp``, ``fast_tcp``, ``text`` or ``udp``, for those connections),
``server`` (the name server, ``HOST:PORT``; default ``--yarp-server``, else YARP's own
configuration: ``yarp conf``), ``insecure``.

**One network per process** and name server (:class:`scart_yarp.Network`: one io thread,
one control thread), made with the first stream and closed with the last. YARP
authenticates no one: ports listen on loopback unless ``insecure`` (``scart
--insecure``); a stream's :attr:`~Stream.authenticated` is False.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from dataflow.buffers import WaitingStorage
from dataflow.policy import ConnPolicy, ConnType, WaitMode
from dataflow.transports import Stream, StreamProblem, Transport, TransportError
from dataflow.transports.ends import OutSample, ReaderEnd, WriterEnd

if TYPE_CHECKING:
    from scart_yarp import Incoming, Network, Port

    from dataflow.buffers import Storage
    from dataflow.ports import Port as DataflowPort

    from .convert import Conversion

__all__ = ["OPTIONS", "YarpTransport"]

log = logging.getLogger(__name__)

#: Every option a yarp stream takes (another is refused: a typo would otherwise be ignored).
OPTIONS = frozenset({"connect", "carrier", "server", "insecure"})
CARRIERS = ("tcp", "fast_tcp", "text", "udp")
MAX_QUEUE = 1000  #: messages that may wait for one slow YARP reader, at most


@dataclass(frozen=True)
class _Settings:
    server: tuple[str, int] | None = None
    insecure: bool = False


class YarpTransport(Transport):
    """Streams on YARP ports through this process's YARP network (see the module
    docstring). Thread-safe; a network is made on first use and closed with its last user."""

    name = "yarp"
    rank = None
    topics = True
    converts = True

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._defaults = _Settings()
        self._networks: dict[_Settings, tuple[Network, int]] = {}
        self._plans: dict[object, tuple[Conversion | None, list[str]]] = {}

    def configure(self, *, server: str | None = None, insecure: bool | None = None) -> None:
        """This process's defaults (``--yarp-server HOST:PORT``, ``--insecure``); raises
        ``ValueError`` for a bad address."""
        from scart_yarp import parse_address

        with self._lock:
            if server is not None:
                self._defaults = _Settings(parse_address(server), self._defaults.insecure)
            if insecure is not None:
                self._defaults = _Settings(self._defaults.server, insecure)

    def settings(self, options: dict[str, str]) -> _Settings:
        """The process's defaults with what ``options`` say; raises ``ValueError``."""
        from scart_yarp import parse_address

        from .._rosplan import flag

        with self._lock:
            have = self._defaults
        server = parse_address(options["server"]) if options.get("server") else have.server
        insecure = flag(options, "insecure") if "insecure" in options else have.insecure
        return _Settings(server, insecure)

    def acquire(self, options: dict[str, str]) -> Network:
        """The network for ``options`` (made now if there is none), for one more user;
        each :meth:`acquire` is paired with a :meth:`release`."""
        from scart_yarp import Network

        try:
            wanted = self.settings(options)
        except ValueError as exc:
            raise TransportError(f"yarp: {exc}") from None
        with self._lock:
            network, users = self._networks.get(wanted, (None, 0))
            if network is None:
                network = Network(wanted.server, host="0.0.0.0" if wanted.insecure else "127.0.0.1",
                                  insecure=wanted.insecure)
            self._networks[wanted] = (network, users + 1)
            return network

    def release(self, network: Network) -> None:
        """One user less of ``network``; the last one closes it (blocks ≤ a few seconds)."""
        with self._lock:
            for key, (net, users) in list(self._networks.items()):
                if net is network:
                    if users > 1:
                        self._networks[key] = (net, users - 1)
                        return
                    del self._networks[key]
                    break
            else:
                return
        network.close()

    # ---- streams -----------------------------------------------------------------------
    def conversion(self, port: DataflowPort[Any]) -> tuple[Conversion | None, list[str]]:
        """How ``port``'s type crosses as a bottle (planned once per type)."""
        from .convert import plan

        with self._lock:
            found = self._plans.get(port.type)
        if found is None:
            found = plan(port.type)
            with self._lock:
                self._plans[port.type] = found
        return found

    def check_stream(self, port: DataflowPort[Any], topic: str, options: dict[str, str]) -> list[StreamProblem]:
        problems = [StreamProblem(p) for p in self._check_options(topic, options)]
        _, unfit = self.conversion(port)
        where = f"{'into' if port.is_input else 'from'} port {getattr(port, 'qualname', port.name)} ({port.type_name})"
        return problems + [StreamProblem(f"yarp {where}: {p}", types=True) for p in unfit]

    def _check_options(self, topic: str, options: dict[str, str]) -> list[str]:
        from scart_yarp.names import check_name

        unknown = sorted(set(options) - OPTIONS)
        out = [f"yarp: unknown option(s) {', '.join(unknown)}; options: {', '.join(sorted(OPTIONS))}"
               ] if unknown else []
        try:
            check_name(topic)
            for peer in _peers(options):
                check_name(peer)
            self.settings(options)
        except ValueError as exc:
            out.append(f"yarp: {exc}")
        carrier = options.get("carrier", "tcp")
        if carrier not in CARRIERS:
            out.append(f"yarp: carrier={carrier!r}: scart speaks YARP over {', '.join(CARRIERS)} (mcast would leave "
                       "this host: scart sends no multicast)")
        return out

    def stream(self, end: WriterEnd | ReaderEnd, topic: str, options: dict[str, str]) -> Stream:
        port = end.port
        if port is None:
            raise TransportError("yarp converts a port's values: a reader end without its port cannot be streamed")
        errors = self._check_options(topic, options)
        conv, unfit = self.conversion(port)
        if errors or conv is None:
            raise TransportError("; ".join(errors + [f"yarp: port {port.qualname} ({port.type_name}): {p}"
                                                     for p in unfit]))
        network = self.acquire(options)
        try:
            return _PortStream(self, network, end, topic, conv, options)
        except BaseException:
            self.release(network)
            raise


def _peers(options: dict[str, str]) -> list[str]:
    return [p.strip() for p in options.get("connect", "").split(",") if p.strip()]


class _Refused:
    """What :attr:`_Carrier.encode` gives for a value that does not convert: why."""

    __slots__ = ("why",)

    def __init__(self, why: str) -> None:
        self.why = why


class _Carrier:
    """A writer end's carrier onto a YARP port: each sample converted and encoded once
    (:attr:`encode`, in the writer's thread; only while a reader is connected), written
    to every reader from that thread (a reader that is behind drops it: counted). The
    policy's ``wait`` (YARP's flow control) makes the writer wait, ≤ ``wait_timeout``
    s, until every reader acknowledged the sample before (``WAIT_BEFORE``) or this one
    (``WAIT_AFTER``); without it, it never waits. A value that does not convert is
    refused and counted here, as is one whose wait timed out."""

    def __init__(self, port: Port, conv: Conversion, label: str, policy: ConnPolicy) -> None:
        from scart_yarp import bottle

        self._port = port
        self._label = label
        self._wait, self._timeout = policy.wait, policy.wait_timeout
        to_bottle, one, encode_bottle = conv.to_bottle, conv.one, bottle.encode
        self.refused = 0
        self.refusal = ""

        def encode(sample: OutSample) -> bytes | _Refused:
            if not port.writers:
                return b""  # no bottle is empty: nothing to convert, nothing to send
            try:
                return encode_bottle([one(sample.value)] if one is not None else to_bottle(sample.value))
            except Exception as exc:  # noqa: BLE001 - a value that does not convert never reaches the writer
                return _Refused(f"{type(exc).__name__}: {exc}")

        #: The sample's bottle, in binary form (an attribute, not a method: the writer end
        #: keeps one encoding per encoder, known by its identity).
        self.encode = encode

    def send(self, sample: OutSample[object], data: bytes | _Refused) -> bool:  # the writer's thread
        if not data:  # no reader
            return True
        if isinstance(data, _Refused):
            self._refuse(sample, data.why)
            return True
        port = self._port
        if self._wait is WaitMode.WAIT_BEFORE and not port.wait_sent(self._timeout):
            self._refuse(sample, f"no reader had room within {self._timeout:g} s (wait-before)")
            return True
        port.write(binary=data)
        if self._wait is WaitMode.WAIT_AFTER and not port.wait_sent(self._timeout):
            self._refuse(sample, f"not every reader took it within {self._timeout:g} s (wait-after)")
        return True

    def _refuse(self, sample: OutSample, why: str) -> None:
        self.refused += 1
        self.refusal = f"sample {sample.n}: {why}"[:300]
        if self.refused == 1:
            log.warning("%s: a sample refused: %s", self._label, self.refusal)


class _PortStream(Stream):
    """A writer end writing through a YARP port, or a reader end fed by one."""

    authenticated = False

    def __init__(self, transport: YarpTransport, network: Network, end: WriterEnd | ReaderEnd, topic: str,
                 conv: Conversion, options: dict[str, str]) -> None:
        self._transport, self._network = transport, network
        self.topic = topic
        self.type_name = f"bottle: {conv.shape}"[:200]
        self._carrier: _Carrier | None = None
        self._closed = False
        carrier = options.get("carrier", "tcp")
        connect = {peer: carrier for peer in _peers(options)}
        if isinstance(end, WriterEnd):
            queue = 1 if end.policy.type is ConnType.DATA else max(1, min(end.policy.size, MAX_QUEUE))
            self._port = network.open_port(topic, queue=queue, connect=connect)
            self._carrier = _Carrier(self._port, conv, end.label, end.policy)
            end.connected("yarp", self._carrier, new_peer=True)
        else:
            end.transport = "yarp"
            storage = end.storage
            self._port = network.open_port(topic, reader=_receiver(end, conv, storage), connect=connect)
            if isinstance(storage, WaitingStorage) and end.policy is not None and end.policy.wait is not WaitMode.NO_WAIT:
                storage.on_room(self._port.resume)  # a read made room: what was held back comes in

    @property
    def waiting(self) -> str:
        port = self._port
        if not port.registered:
            return f"the YARP name server ({port.last_problem or 'registering'})"
        missing = [p for p in self._network.wanted(port)
                   if p not in port.outputs and p not in {c.peer for c in port.inputs}]
        return f"YARP port {', '.join(missing)}" if missing else ""

    @property
    def refused(self) -> int:
        return (self._carrier.refused if self._carrier is not None else 0) + self._port.counters["dropped"]

    @property
    def refusal(self) -> str:
        if self._carrier is not None and self._carrier.refusal:
            return self._carrier.refusal
        if self._port.counters["dropped"]:
            return f"{self._port.counters['dropped']} sample(s) not sent: a reader was behind"
        return ""

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._port.close()
        self._transport.release(self._network)


def _receiver(end: ReaderEnd[Any], conv: Conversion, storage: Storage[Any] | None) -> Callable[[Incoming], bool]:
    """What the YARP port calls (io thread) with each bottle: decoded, converted, handed
    to ``end`` numbered; a bottle that is malformed or does not fit is refused there. With
    a policy that makes writers wait, a bottle that finds the buffer full is held back
    (False: YARP's writer then waits for its acknowledgement) until a read makes room."""
    from scart_yarp import BottleError
    from scart_yarp.bottle import decode

    from .convert import Unfit

    from_bottle = conv.from_bottle
    count = [0]
    holds = end.policy is not None and end.policy.wait is not WaitMode.NO_WAIT and storage is not None
    has_room = storage.has_room if holds and storage is not None else None

    def on_message(msg: Incoming) -> bool:
        if has_room is not None and not has_room():
            return False
        payload = msg.payload
        try:
            value = from_bottle(decode(payload, msg.limits) if type(payload) is bytes else msg.values())
        except (BottleError, Unfit) as exc:
            end.refuse(f"a bottle from {msg.source} that does not fit: {exc}")
            return True
        count[0] += 1
        end.receive(count[0], time.time_ns(), value)
        return True

    return on_message
