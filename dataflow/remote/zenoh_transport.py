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

gRPC stays the control plane (describe, operations, properties, state); only samples move
here. Sessions are loopback by default, with multicast and gossip scouting off (a
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

import hashlib
import hmac
import json
import logging
import math
import os
import re
import secrets
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any
from urllib.parse import quote, unquote

from dataflow import codec
from dataflow.policy import ConnPolicy, FlowStatus
from dataflow.ports import InputPort, OutputPort
from dataflow.remote._loss import LossCount
from dataflow.remote.api import SampleEvent
from dataflow.remote.security import is_loopback
from dataflow.types import registry

if TYPE_CHECKING:
    from dataflow.remote._registry import NameEntry
    from dataflow.remote.client import GrpcSystem
    from dataflow.remote.security import AuthTable, Security

__all__ = ["DEFAULT_NS", "ZenohInput", "ZenohNames", "ZenohPublisher", "ZenohSubscription", "check_endpoint",
           "connect_zenoh", "discover", "key_of", "open_session", "proof_of", "served_key", "token_id",
           "zenoh_credentials"]

log = logging.getLogger(__name__)

DEFAULT_NS = "default"
ROOT = "scart"
SERVED = "scart-served"  #: root of the tokens saying where a component is served
PROOF = "scart-proof"  #: root of the queryables proving those tokens
MAX_REPLIES = 10_000  #: liveliness replies read per lookup, at most
ENCODING_PREFIX = "scart.dataflow.v1.Value;"
MAX_PAYLOAD = 4 * 1024 * 1024  #: bytes of one sample a subscriber decodes at most (the gRPC path's limit)
_WORD = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]{0,127}$")
_ENDPOINT = re.compile(r"^[a-z][a-z0-9-]*/\S+$")
_NONCE = re.compile(r"^[0-9a-f]{32}$")


def key_of(ns: str, component: str, port: str | None = None) -> str:
    """The key of a component (its liveliness token) or of one of its output ports.
    Raises ``ValueError`` for a name that is no single key chunk."""
    parts = [ns, component] + ([port] if port is not None else [])
    for part in parts:
        if not _WORD.match(part):
            raise ValueError(f"{part!r} cannot be a Zenoh key chunk (letters, digits, _ . -; at most 128)")
    return "/".join([ROOT, *parts])


def served_key(ns: str, component: str, address: str, boot_id: str) -> str:
    """The liveliness token saying that the deployer at ``address`` (gRPC), process
    ``boot_id``, serves ``component``."""
    key_of(ns, component)
    return f"{SERVED}/{ns}/{component}/{quote(address, safe='')}/{quote(boot_id, safe='')}"


def token_id(token: str) -> str:
    """A token's public name in proof queries: 16 hex digits of a hash (never the token)."""
    return hashlib.sha256(b"scart-token-id:" + token.encode()).hexdigest()[:16]


def proof_of(token: str, nonce: str, ns: str, component: str, address: str, boot_id: str) -> str:
    """The HMAC (hex) proving that the deployer at ``address`` (process ``boot_id``)
    serves ``component`` in ``ns``, for a resolver holding ``token`` that asked with
    ``nonce``: under a key derived from the token, so only the token's holder and the auth
    file's can make it."""
    key = hashlib.sha256(b"scart-zenoh-proof:" + token.encode()).digest()
    return hmac.new(key, "\n".join((nonce, ns, component, address, boot_id)).encode(), hashlib.sha256).hexdigest()


def check_endpoint(endpoint: str, insecure: bool = False) -> None:
    """Raise ``ValueError`` for an endpoint that is not ``PROTOCOL/ADDRESS`` (with a port
    for the IP protocols), or not loopback (nor a Unix socket) unless ``insecure``."""
    if not _ENDPOINT.match(endpoint) or (endpoint.startswith(("tcp/", "udp/", "tls/", "quic/"))
                                         and not re.search(r":\d+$", endpoint.split("#")[0])):
        raise ValueError(f"Zenoh endpoint {endpoint!r}: expected PROTOCOL/ADDRESS, e.g. tcp/127.0.0.1:7447 "
                         "or unixsock-stream/PATH")
    protocol, _, address = endpoint.partition("/")
    host = address.rpartition(":")[0].strip("[]")
    loopback = protocol in ("tcp", "udp", "quic", "tls") and "#" not in address and is_loopback(host)
    if not (insecure or protocol == "unixsock-stream" or loopback):
        raise ValueError(f"Zenoh endpoint {endpoint!r} is not loopback: scart does not encrypt Zenoh traffic "
                         "(use Zenoh's TLS), so it needs --zenoh-insecure (zenoh-insecure=\"true\" in a composite)")


def zenoh_credentials(token: str) -> tuple[str, str]:
    """The Zenoh user name and password a scart token authenticates with (Zenoh's
    ``usrpwd``): ``scart-`` and 16 hex digits of the token's SHA-256, and the hex SHA-256
    of ``scart-zenoh:`` and the token. Derived, so they hold no character Zenoh's
    ``user:password`` lines cannot, and the token itself never goes into Zenoh's file."""
    user = "scart-" + hashlib.sha256(token.encode()).hexdigest()[:16]
    return user, hashlib.sha256(b"scart-zenoh:" + token.encode()).hexdigest()


def open_session(connect: Iterable[str] = (), listen: Iterable[str] = (), insecure: bool = False,
                 mode: str = "peer", security: Security | None = None) -> Any:
    """A Zenoh session in ``mode`` (``peer``; ``router`` for a fleet's router; ``client``
    to talk through routers only): listening on ``listen`` (default ``tcp/127.0.0.1:0``;
    a client listens on nothing) and connecting to ``connect``, with multicast scouting
    off. Raises ``ValueError`` for a routable endpoint to listen on without ``insecure``
    or an unknown mode, and Zenoh's own error when it cannot open.

    ``security`` (scart's tokens, as for gRPC): a session that listens, given an auth file,
    admits only the peers that present one of its ``operate`` or ``admin`` tokens (a Zenoh
    link both reads and writes, so ``read`` tokens are not admitted); a session given a
    token presents it (:func:`zenoh_credentials`). Zenoh refuses a link whose two ends
    disagree (one presents a token the other does not check, or one checks and the other
    presents none)."""
    import zenoh

    if mode not in ("peer", "router", "client"):
        raise ValueError(f"Zenoh mode {mode!r}: expected peer, router or client")
    connect, listen = list(connect), list(listen) or (["tcp/127.0.0.1:0"] if mode != "client" else [])
    for endpoint in connect + listen:
        check_endpoint(endpoint, insecure)
    admitted = _admitted(security) if listen else []
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    if not insecure:  # reach only the endpoints given (gossip would pass on others' too)
        config.insert_json5("scouting/gossip/enabled", "false")
    drop = "transport/link/tx/queue/congestion_control/drop/"
    config.insert_json5(drop + "wait_before_drop", "0")  # never wait for room: the writer's thread
    config.insert_json5(drop + "max_wait_before_drop_fragments", "0")
    config.insert_json5("transport/link/rx/max_message_size", str(MAX_PAYLOAD + 64 * 1024))
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    if security is not None and security.token:
        user, password = zenoh_credentials(security.token)
        config.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
        config.insert_json5("transport/auth/usrpwd/password", json.dumps(password))
    if not admitted:
        return zenoh.open(config)
    with tempfile.TemporaryDirectory(prefix="scart-zenoh-") as folder:  # only this user may enter
        users = os.path.join(folder, "users")
        with os.fdopen(os.open(users, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600), "w") as out:
            out.write("".join(f"{user}:{password}\n" for user, password in admitted))
        config.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(users))
        return zenoh.open(config)  # Zenoh reads the file as it opens: it goes right after


def _admitted(security: Security | None) -> list[tuple[str, str]]:
    """The credentials of the auth file's ``operate`` and ``admin`` tokens (none without
    one). Raises ``ValueError`` for an auth file with neither: no peer could connect."""
    from dataflow.remote.security import Role

    table = security.auth_table() if security is not None else None
    if table is None:
        return []
    admitted = sorted({zenoh_credentials(token.decode()) for token, role in table.entries if role >= Role.OPERATE})
    if not admitted:
        raise ValueError(f"{security.auth_file}: no operate or admin token, so no Zenoh peer could connect "  # type: ignore[union-attr]
                         "(a Zenoh link both reads and writes)")
    return admitted


class ZenohPublisher:
    """Every output port of the tasks of ``deployer`` (those there now) published on
    ``session``, and a liveliness token per task and port. The samples are sent from the
    writer's thread as they are written (see the module docstring). :meth:`close`
    undeclares everything (idempotent, also after a failure half-way)."""

    def __init__(self, deployer: Any, session: Any, ns: str = DEFAULT_NS, served: tuple[str, str] | None = None,
                 auth: AuthTable | None = None) -> None:
        """``served``: ``(address, boot id)`` of the deployer's gRPC server, announced with
        each task (:func:`served_key`) so that :class:`ZenohNames` finds it; ``auth``: the
        deployer's auth file, with which it proves those announcements (``scart-proof``)."""
        import zenoh

        self.ns = ns
        self._closed = False
        self._id = secrets.randbits(64).to_bytes(8, "little")  # this publisher: a subscriber tells restarts by it
        self._ends: list[_PortEnd] = []
        self._tokens: list[Any] = []
        keys = {token_id(t.decode()): t.decode() for t, _ in auth.entries} if auth is not None else {}
        try:
            for task in deployer.tasks():
                self._tokens.append(session.liveliness().declare_token(key_of(ns, task.name)))
                if served is not None:
                    self._tokens.append(session.liveliness().declare_token(served_key(ns, task.name, *served)))
                    if keys:
                        self._tokens.append(session.declare_queryable(
                            f"{PROOF}/{ns}/{task.name}", _Prover(ns, task.name, served, keys)))
                for port in task.ports().values():
                    if port.is_input:
                        continue
                    key = key_of(ns, task.name, port.name)
                    publisher = session.declare_publisher(
                        key, encoding=zenoh.Encoding.APPLICATION_PROTOBUF.with_schema(ENCODING_PREFIX + port.type_name),
                        congestion_control=zenoh.CongestionControl.DROP)
                    end = _PortEnd(port, publisher, self._id)
                    self._ends.append(end)
                    end.attach()
                    self._tokens.append(session.liveliness().declare_token(key))
        except BaseException:
            self.close()
            raise

    @property
    def keys(self) -> list[str]:
        """The keys published."""
        return [str(end.publisher.key_expr) for end in self._ends]

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for end in self._ends:
            end.close()
        for token in self._tokens:
            _quietly(token.undeclare, "liveliness token")


class _Prover:
    """Answers a proof query for one announced task (see the module docstring), on
    Zenoh's thread: nothing for a malformed query or a token id not in the auth file."""

    def __init__(self, ns: str, component: str, served: tuple[str, str], keys: dict[str, str]) -> None:
        self.ns, self.component, self.served, self._keys = ns, component, served, keys

    def __call__(self, query: Any) -> None:
        try:
            params = query.parameters
            ident, nonce = str(params.get("id") or ""), str(params.get("nonce") or "")
            token = self._keys.get(ident)
            if token is None or not _NONCE.match(nonce):
                return
            address, boot = self.served
            mac = proof_of(token, nonce, self.ns, self.component, address, boot)
            query.reply(f"{PROOF}/{self.ns}/{self.component}",
                        json.dumps({"address": address, "boot": boot, "mac": mac}).encode())
        except Exception as exc:  # noqa: BLE001 - a query we cannot answer: the resolver hears nothing
            log.info("zenoh: a proof query for %s not answered: %s", self.component, exc)


def _quietly(undeclare: Callable[[], Any], what: str) -> None:
    try:
        undeclare()
    except Exception as exc:  # noqa: BLE001 - a session already closed: nothing left to undeclare
        log.info("zenoh: undeclaring a %s: %s", what, exc)


class _PortEnd:
    """One output port's publisher: a free DATA input port on it whose data callback (the
    writer's thread) publishes the port's newest sample with its own write number."""

    def __init__(self, port: OutputPort, publisher: Any, publisher_id: bytes) -> None:
        self.port = port
        self.publisher = publisher
        self._id = publisher_id
        self._lock = threading.Lock()
        self._more = False
        self._sent = 0  # the write number last published
        self._closed = False
        self._tap: InputPort = InputPort(port.type, name=f"zenoh_{port.name}")
        # Whether a subscriber matches the key, as Zenoh tells it (at once when one does
        # already): the writer's thread reads a bool instead of asking Zenoh every write.
        self._matching = False
        self._listener: Any = None

    def attach(self) -> None:
        self._listener = self.publisher.declare_matching_listener(self._on_matching)
        self._tap.add_data_callback(self._on_data)
        self.port.connect_to(self._tap, ConnPolicy.data(init=False))

    def _on_data(self, _tap: InputPort) -> None:  # the writer's thread: never waits
        self._more = True  # before trying the lock: the holder re-checks it after releasing
        for _ in range(1000):
            if not self._lock.acquire(blocking=False):
                return  # the holder publishes the newest
            try:
                self._more = False
                self._tap.read()  # (the tap only says "written")
                number, value = self.port.last_sample()  # a sample and its own write number, together
                if self._closed or number <= self._sent:
                    return
                self._sent = number
                if self._matching:  # nobody listening: nothing to encode
                    stamp = self._id + number.to_bytes(8, "little") + time.time_ns().to_bytes(8, "little")
                    self.publisher.put(codec.encode(value, self.port.type).SerializeToString(), attachment=stamp)
            except Exception as exc:  # noqa: BLE001 - Zenoh refusing (a closed session) never fails the write
                log.info("zenoh %s: not published: %s", self.port.qualname, exc)
                return
            finally:
                self._lock.release()
            if not self._more:
                return

    def _on_matching(self, status: Any) -> None:  # Zenoh's thread
        self._matching = bool(status.matching)

    def close(self) -> None:
        with self._lock:
            self._closed = True
        self._tap.remove_data_callback(self._on_data)
        self.port.disconnect(self._tap)
        if self._listener is not None:
            _quietly(self._listener.undeclare, "matching listener")
        _quietly(self.publisher.undeclare, "publisher")


class ZenohSubscription:
    """Samples of ``scart/<ns>/<component>/<port>`` handed to ``observer`` as
    :class:`~dataflow.remote.api.SampleEvent` s (in Zenoh's delivery thread; keep it short).
    Counters as a subscription's: ``delivered``, ``dropped`` (writes not received, seen as
    jumps in the write numbers, plus samples that could not be decoded)."""

    def __init__(self, session: Any, component: str, port: str, observer: Callable[[SampleEvent], None],
                 ns: str = DEFAULT_NS) -> None:
        self.component, self.port = component, port
        self.delivered = 0
        self.undecodable = 0
        self._loss = LossCount()
        self._writer = b""  # the publisher's id the write numbers belong to
        self._lock = threading.Lock()
        self._closed = False
        self._observer = observer
        self._subscriber = session.declare_subscriber(key_of(ns, component, port), self._on_sample)

    def _on_sample(self, sample: Any) -> None:
        with self._lock:  # one sample at a time, in order, to the observer too
            if self._closed:
                return
            try:
                if len(sample.payload) > MAX_PAYLOAD:
                    raise ValueError(f"{len(sample.payload)} bytes, more than {MAX_PAYLOAD}")
                value = codec.decode(codec.Value.FromString(sample.payload.to_bytes()))
                attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
                if len(attachment) != 24:
                    raise ValueError("no scart attachment (publisher id, write number, time)")
                writer, sequence = attachment[:8], int.from_bytes(attachment[8:16], "little")
                sent_ns = int.from_bytes(attachment[16:], "little")
            except Exception as exc:  # noqa: BLE001 - one bad sample never ends the subscription
                self.undecodable += 1
                if self.undecodable == 1:
                    log.warning("zenoh %s.%s: a sample cannot be decoded: %s", self.component, self.port, exc)
                return
            last = self._loss.last
            if writer != self._writer or (last is not None and not last < sequence <= last + 1_000_000):
                self._writer = writer  # a (re)started publisher, or numbers that make no sense: count afresh
                self._loss.restarted()
            self._loss.sample(sequence)
            self.delivered += 1
            self._observer(SampleEvent(self.component, self.port, value, FlowStatus.NEW_DATA, sent_ns / 1e9,
                                       sequence))

    @property
    def dropped(self) -> int:
        """Writes not received (jumps in the write numbers) and samples not decodable."""
        return self._loss.lost + self.undecodable

    def close(self) -> None:
        """Stop (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        _quietly(self._subscriber.undeclare, "subscriber")


class ZenohInput:
    """An input port fed from Zenoh: the samples of ``scart/<ns>/<component>/<port>``
    written into ``target`` through a connection with ``policy`` (as a remote writer's: the
    policy's storage keeps, overwrites or drops them, and counts). Each value is checked as
    one written from outside is (its type, finiteness and the port's bounds); a refused one
    is counted in ``refused`` and logged once."""

    def __init__(self, session: Any, component: str, port: str, target: InputPort,
                 policy: ConnPolicy | None = None, ns: str = DEFAULT_NS) -> None:
        self.target = target
        self.refused = 0
        self._out: OutputPort = OutputPort(target.type, name=f"zenoh_{target.name}")
        self._out.connect_to(target, policy or ConnPolicy.data())
        try:
            self.subscription = ZenohSubscription(session, component, port, self._write, ns)
        except BaseException:
            self._out.disconnect(target)
            raise

    def _write(self, event: SampleEvent) -> None:
        try:
            self._out.write(self.target.admit(registry.validate(self.target.type, event.value)))
        except Exception as exc:  # noqa: BLE001 - a sample of another type or out of bounds: refused
            self.refused += 1
            if self.refused == 1:
                log.warning("zenoh %s.%s into %s refused: %s", event.component, event.port, self.target.qualname, exc)

    def close(self) -> None:
        self.subscription.close()
        self._out.disconnect(self.target)


def discover(session: Any, ns: str = DEFAULT_NS, timeout: float = 1.0) -> dict[str, list[str]]:
    """``{component: [output ports]}`` of everything live on Zenoh in ``ns`` (from the
    liveliness tokens; no name service), sorted."""
    key_of(ns, "x")  # a namespace that is one plain key chunk (no wildcards)
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


class ZenohNames:
    """Data-flow lookups answered from Zenoh liveliness tokens, in place of a scart name
    service: which deployer serves a component (``scart deploy --zenoh`` announces its
    gRPC address and boot id with each task, :func:`served_key`). It has the name
    client's ``resolve``/``entries``/``close``, so a :class:`GrpcSystem` takes it as its
    name service (:func:`connect_zenoh`). Tokens come from any Zenoh peer, so:

    - with a ``token`` (which the system would send to the address found), only an
      announcement its deployer proves for that token is used (``scart-proof``: only a
      holder of the auth file can); any other is ignored: a peer of a lower role, or none,
      can neither lure the token to an address of its own nor, by announcing a live
      component a second time, make it unresolvable;
    - an address that is not loopback is ignored unless ``insecure``, as is anything
      malformed;
    - a component announced (and proved) by more than one deployer is not used until only
      one announces it (a stale announcement; without a token, a spoofed one too).

    Each is logged once. The session stays the caller's.
    """

    def __init__(self, session: Any, ns: str = DEFAULT_NS, timeout: float = 1.0, insecure: bool = False,
                 token: str | None = None) -> None:
        key_of(ns, "x")  # a namespace that is one plain key chunk (no wildcards)
        self.session = session
        self.ns = ns
        self.timeout = timeout
        self.insecure = insecure
        self._token = token
        self._warned: set[str] = set()

    def __repr__(self) -> str:  # never the token
        return f"ZenohNames({self.ns!r}, proved={self._token is not None})"

    def _look(self, component: str, timeout: float | None) -> list[NameEntry]:
        """The entries of ``component`` (``*``: of every one), one per component, sorted."""
        from dataflow.remote._registry import NameEntry
        prefix = f"{SERVED}/{self.ns}/"
        seen: dict[str, dict[tuple[str, str], NameEntry]] = {}
        replies = self.session.liveliness().get(f"{prefix}{component}/*/*", timeout=timeout or self.timeout)
        for _, reply in zip(range(MAX_REPLIES), replies):
            if reply.ok is None:
                continue
            parts = str(reply.ok.key_expr)[len(prefix):].split("/")
            if len(parts) != 3 or not _WORD.match(parts[0]):
                continue
            name, address, boot = parts[0], unquote(parts[1]), unquote(parts[2])
            host, colon, port = address.rpartition(":")
            if not colon or not port.isdigit() or not 0 < int(port) < 65536 or len(address) > 260 or len(boot) > 64:
                log.debug("ignoring a malformed Zenoh announcement %s", reply.ok.key_expr)
                continue
            if not (self.insecure or is_loopback(host.strip("[]"))):
                self._warn(f"{name}@{address}", "ignoring %s announced at %s on Zenoh: not loopback (needs "
                           "insecure)", name, address)
                continue
            seen.setdefault(name, {})[(address, boot)] = NameEntry(name, address, boot, math.inf)
        if self._token is not None and seen:
            self._keep_proved(component, seen, timeout)
        found = []
        for name in sorted(seen):
            entries = seen[name]
            if len(entries) > 1:  # two deployers, or someone spoofing one: never guess where to send a token
                where = ", ".join(sorted(f"{a} ({b})" for a, b in entries))
                self._warn(f"{name}@@{where}", "%s is announced on Zenoh by %d deployers (%s): not used until "
                           "one goes", name, len(entries), where)
                continue
            if entries:
                found.append(next(iter(entries.values())))
        return found

    def _keep_proved(self, component: str, seen: dict[str, dict[tuple[str, str], NameEntry]],
                     timeout: float | None) -> None:
        """Drop from ``seen`` every announcement its deployer does not prove for our token."""
        import zenoh

        assert self._token is not None
        nonce = secrets.token_hex(16)
        proved: set[tuple[str, str, str]] = set()
        selector = f"{PROOF}/{self.ns}/{component}?id={token_id(self._token)};nonce={nonce}"
        replies = self.session.get(selector, target=zenoh.QueryTarget.ALL, consolidation=zenoh.ConsolidationMode.NONE,
                                   timeout=timeout or self.timeout)
        for _, reply in zip(range(MAX_REPLIES), replies):
            try:
                if reply.ok is None or len(reply.ok.payload) > 1024:
                    continue
                name = str(reply.ok.key_expr).rpartition("/")[2]
                body = json.loads(reply.ok.payload.to_bytes())
                address, boot = str(body["address"]), str(body["boot"])
                expected = proof_of(self._token, nonce, self.ns, name, address, boot)
                if hmac.compare_digest(expected, str(body["mac"])):
                    proved.add((name, address, boot))
            except (ValueError, KeyError, TypeError):
                continue  # a malformed answer proves nothing
        for name, entries in seen.items():
            for address, boot in [k for k in entries if (name, *k) not in proved]:
                del entries[(address, boot)]
                self._warn(f"{name}@{address}/{boot}?", "ignoring %s announced at %s on Zenoh: its deployer does not "
                           "prove it for this token (an announcement by a peer without the auth file, or a "
                           "deployer that checks no tokens)", name, address)

    def _warn(self, key: str, message: str, *args: object) -> None:
        """Log ``message`` once per ``key`` (announcements come again at every lookup)."""
        if key not in self._warned and len(self._warned) < 1000:
            self._warned.add(key)
            log.warning(message, *args)

    def entries(self, timeout: float | None = None) -> list[NameEntry]:
        """Every component served in the namespace, sorted (one per component)."""
        return self._look("*", timeout)

    def resolve(self, component: str, timeout: float | None = None) -> NameEntry:
        """Where ``component`` is served; ``RemoteNotFoundError`` listing the known names."""
        from dataflow.remote import errors

        try:
            key_of(self.ns, component)
        except ValueError:
            found: list[NameEntry] = []
        else:
            found = self._look(component, timeout)
        if not found:
            known = ", ".join(e.component for e in self.entries(timeout)[:20]) or "none"
            raise errors.RemoteNotFoundError(f"no component named {component[:80]!r} is served on Zenoh "
                                             f"(namespace {self.ns}); known: {known}", "NOT_FOUND", "zenoh")
        return found[0]

    def close(self) -> None:
        """Nothing to release (the session is the caller's)."""


def connect_zenoh(session: Any, ns: str = DEFAULT_NS, timeout: float = 2.0, heartbeat_ms: int = 500,
                  security: Security | None = None, insecure: bool = False) -> GrpcSystem:
    """A data-flow system whose lookups go through Zenoh (:class:`ZenohNames`) instead of
    a scart name service; calls, subscriptions and links go to the deployers as usual. With
    a token (``security``), only announcements proved for it are used."""
    from dataflow.remote.client import GrpcSystem
    from dataflow.remote.security import Security

    security = security if security is not None else Security.from_env()
    return GrpcSystem(f"zenoh:{ns}", timeout=timeout, heartbeat_ms=heartbeat_ms, security=security,
                      names=ZenohNames(session, ns, timeout=timeout, insecure=insecure, token=security.token))
