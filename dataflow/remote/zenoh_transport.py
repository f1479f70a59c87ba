"""Data-flow ports on Zenoh (``eclipse-zenoh``; install ``scart[zenoh]``): publish a
deployer's output ports, subscribe to them, and find them without a scart name service.

Key scheme (documented in the README, "Transports"):

- ``scart/<ns>/<component>/<port>``: the samples of an output port. Each is the gRPC
  path's own encoding, a ``scart.dataflow.v1.Value`` message; the Zenoh encoding says so
  and carries the port's registry type name: ``application/protobuf;scart.dataflow.v1.Value;<type>``.
  The attachment is the port's write number and the time it was sent (two 8-byte little
  endian integers, the time in ns since the epoch): a subscriber tells the writes it did
  not get from the jumps in the write numbers, as on the other transports.
- Liveliness tokens announce what runs: ``scart/<ns>/<component>`` for each task and
  ``scart/<ns>/<component>/<port>`` for each of its output ports. A process that dies
  takes its tokens with it, so :func:`discover` lists only live components.

``<ns>`` is a namespace word (default ``default``), as ``__ns`` is for remapping.

gRPC stays the control plane (describe, operations, properties, state); only samples move
here. Sessions are peers, loopback by default (``tcp/127.0.0.1``), with multicast
scouting off: :func:`open_session` refuses to listen on a routable endpoint unless ``insecure`` (Zenoh
traffic carries no scart token; secure a fleet with Zenoh's own TLS and access control).
A publisher never blocks the writer: Zenoh's ``DROP`` congestion control.
"""

from __future__ import annotations

import json
import logging
import re
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

from dataflow import codec
from dataflow.policy import ConnPolicy, FlowStatus
from dataflow.ports import InputPort, OutputPort
from dataflow.remote.api import SampleEvent

__all__ = ["DEFAULT_NS", "ZenohPublisher", "ZenohSubscription", "discover", "key_of", "open_session"]

log = logging.getLogger(__name__)

DEFAULT_NS = "default"
ROOT = "scart"
ENCODING_PREFIX = "scart.dataflow.v1.Value;"
MAX_PAYLOAD = 4 * 1024 * 1024  #: bytes of one sample a subscriber decodes at most (the gRPC path's limit)
_WORD = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]{0,127}$")
_LOOPBACK = re.compile(r"^(tcp|udp|quic|tls)/(127\.\d+\.\d+\.\d+|localhost|\[::1\]):\d+$")


def key_of(ns: str, component: str, port: str | None = None) -> str:
    """The key of a component (its liveliness token) or of one of its output ports.
    Raises ``ValueError`` for a name that is no single key chunk."""
    parts = [ns, component] + ([port] if port is not None else [])
    for part in parts:
        if not _WORD.match(part):
            raise ValueError(f"{part!r} cannot be a Zenoh key chunk (letters, digits, _ . -; at most 128)")
    return "/".join([ROOT, *parts])


def open_session(connect: Iterable[str] = (), listen: Iterable[str] = (), insecure: bool = False,
                 mode: str = "peer") -> Any:
    """A Zenoh session in ``mode`` (``peer``; ``router`` for a fleet's router; ``client``
    to talk through routers only): listening on ``listen`` (default ``tcp/127.0.0.1:0``;
    a client listens on nothing) and connecting to ``connect``, with multicast scouting
    off. Raises ``ValueError`` for a routable endpoint to listen on without ``insecure``
    or an unknown mode, and Zenoh's own error when it cannot open."""
    import zenoh

    if mode not in ("peer", "router", "client"):
        raise ValueError(f"Zenoh mode {mode!r}: expected peer, router or client")
    connect, listen = list(connect), list(listen) or (["tcp/127.0.0.1:0"] if mode != "client" else [])
    for endpoint in listen:
        if not (insecure or endpoint.startswith("unixsock-stream/") or _LOOPBACK.match(endpoint)):
            raise ValueError(f"Zenoh endpoint {endpoint!r} is not loopback: Zenoh traffic carries no scart "
                             "token (use Zenoh's TLS and access control), so it needs --insecure")
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    return zenoh.open(config)


class ZenohPublisher:
    """Every output port of the tasks of ``deployer`` (those there now) published on
    ``session``, and a liveliness token per task and port. The samples are sent from the
    writer's thread as they are written. :meth:`close` undeclares everything (idempotent)."""

    def __init__(self, deployer: Any, session: Any, ns: str = DEFAULT_NS) -> None:
        import zenoh

        self.ns = ns
        self._closed = False
        self._ends: list[tuple[OutputPort, InputPort, Any]] = []
        self._tokens: list[Any] = []
        try:
            for task in deployer.tasks():
                self._tokens.append(session.liveliness().declare_token(key_of(ns, task.name)))
                for port in task.ports().values():
                    if port.is_input:
                        continue
                    key = key_of(ns, task.name, port.name)
                    publisher = session.declare_publisher(
                        key, encoding=zenoh.Encoding.APPLICATION_PROTOBUF.with_schema(ENCODING_PREFIX + port.type_name),
                        congestion_control=zenoh.CongestionControl.DROP)
                    self._attach(port, publisher)
                    self._tokens.append(session.liveliness().declare_token(key))
        except BaseException:
            self.close()
            raise

    def _attach(self, port: OutputPort, publisher: Any) -> None:
        """A free input port on ``port``; its data callback puts each sample it reads."""
        tap: InputPort = InputPort(port.type, name=f"zenoh_{port.name}")
        lock = threading.Lock()

        def on_data(inp: InputPort) -> None:  # the writer's thread
            with lock:
                for _ in range(10_000):
                    status, value = inp.read()
                    if status is not FlowStatus.NEW_DATA:
                        return
                    stamp = port.last_sample()[0].to_bytes(8, "little") + time.time_ns().to_bytes(8, "little")
                    publisher.put(codec.encode(value, port.type).SerializeToString(), attachment=stamp)

        tap.add_data_callback(on_data)
        port.connect_to(tap, ConnPolicy.buffer(64))
        self._ends.append((port, tap, publisher))

    @property
    def keys(self) -> list[str]:
        """The keys published."""
        return [str(publisher.key_expr) for _, _, publisher in self._ends]

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for port, tap, publisher in self._ends:
            port.disconnect(tap)
            publisher.undeclare()
        for token in self._tokens:
            token.undeclare()


class ZenohSubscription:
    """Samples of ``scart/<ns>/<component>/<port>`` handed to ``observer`` as
    :class:`~dataflow.remote.api.SampleEvent` s (in Zenoh's delivery thread; keep it short).
    Counters as a subscription's: ``delivered``, ``dropped`` (writes not received, seen as
    jumps in the write numbers, plus samples that could not be decoded)."""

    def __init__(self, session: Any, component: str, port: str, observer: Callable[[SampleEvent], None],
                 ns: str = DEFAULT_NS) -> None:
        self.component, self.port = component, port
        self.delivered = 0
        self.dropped = 0
        self._last: int | None = None
        self._lock = threading.Lock()
        self._observer = observer
        self._subscriber = session.declare_subscriber(key_of(ns, component, port), self._on_sample)

    def _on_sample(self, sample: Any) -> None:
        with self._lock:
            try:
                payload = sample.payload.to_bytes()
                if len(payload) > MAX_PAYLOAD:
                    raise ValueError(f"{len(payload)} bytes, more than {MAX_PAYLOAD}")
                value = codec.decode(codec.Value.FromString(payload))
                attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
                sequence, sent_ns = (int.from_bytes(attachment[:8], "little"), int.from_bytes(attachment[8:], "little")) \
                    if len(attachment) == 16 else (0, time.time_ns())
            except Exception as exc:  # noqa: BLE001 - one bad sample never ends the subscription
                self.dropped += 1
                log.warning("zenoh %s.%s: a sample cannot be decoded: %s", self.component, self.port, exc)
                return
            if sequence and self._last is not None:
                if sequence <= self._last:  # the writer restarted: its numbers start over
                    self._last = None
                else:
                    self.dropped += sequence - self._last - 1
            self._last = sequence or self._last
            self.delivered += 1
        self._observer(SampleEvent(self.component, self.port, value, FlowStatus.NEW_DATA, sent_ns / 1e9, sequence))

    def close(self) -> None:
        self._subscriber.undeclare()


def discover(session: Any, ns: str = DEFAULT_NS, timeout: float = 1.0) -> dict[str, list[str]]:
    """``{component: [output ports]}`` of everything live on Zenoh in ``ns`` (from the
    liveliness tokens; no name service), sorted."""
    found: dict[str, set[str]] = {}
    prefix = f"{ROOT}/{ns}/"
    for reply in session.liveliness().get(f"{ROOT}/{ns}/**", timeout=timeout):
        if reply.ok is None:
            continue
        parts = str(reply.ok.key_expr)[len(prefix):].split("/")
        if len(parts) == 1:
            found.setdefault(parts[0], set())
        elif len(parts) == 2:
            found.setdefault(parts[0], set()).add(parts[1])
    return {name: sorted(ports) for name, ports in sorted(found.items())}
