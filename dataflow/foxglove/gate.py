"""A gate in front of a WebSocket server that cannot check its own handshake (the Foxglove
SDK's): it listens where the user asked, reads each connection's HTTP upgrade request,
checks its ``Host``, ``Origin`` and token, and only then relays the connection, byte for
byte, to the real server, which only the gate can reach (:mod:`dataflow.foxglove.inner_guard`).

The checks (the monitor's, for a WebSocket):

- **Host**: exactly one, naming a loopback address (``localhost``, ``127.0.0.0/8``,
  ``[::1]``); when the gate listens on a routable address (``--insecure``), an IP address
  literal too. A DNS name is refused: that is what a DNS-rebinding page sends.
- **Origin**: none (a program, not a browser: browsers always send one on a WebSocket),
  or one of ``origins`` (for Foxglove: its web app, :data:`FOXGLOVE_ORIGINS`). Any other
  web page the user's browser opens is refused before the server sees a byte.
- **Token**: ``?token=TOKEN`` in the URL (what the Foxglove app can send) or
  ``Authorization: Bearer TOKEN`` (a program), checked by ``tokens`` (constant time). A
  token that is not accepted is refused (``401``); so is no token when ``tokens_required``
  (the runtime checks tokens: reading needs one, as at every door). The token and the
  query never reach the server behind.

A refused handshake gets its status (``401``, ``403``; ``421`` for a bad Host; ``503``
when its pool is full) with the reason, and is closed.

**Bounds, so that a token holder always gets in.** Connections are counted in three
pools: *pending* (no complete request head yet: not authenticated), *tokenless* (admitted
without a token) and *token holders*. A request head must arrive within
:data:`AUTH_TIMEOUT` s and :data:`MAX_HEAD` bytes; when ``max_pending`` connections are
pending (or ``max_pending_per_peer`` from one address), the oldest gives way to the new
one, so idle sockets cannot keep anyone from sending a request. Tokenless connections are
at most ``max_tokenless`` (``max_tokenless_per_peer`` per address); token holders have
``max_connections`` of their own (``max_per_token`` per token), which no tokenless
connection can take.

Threads: :meth:`WebSocketGate.start` starts one thread running an asyncio loop (every
connection is a task on it); :meth:`WebSocketGate.stop` closes the listener and every
relayed connection and joins the thread.
"""

from __future__ import annotations

import asyncio
import hashlib
import ipaddress
import logging
from collections import OrderedDict
from collections.abc import Callable, Iterable
from types import MappingProxyType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from dataflow.foxglove.inner_guard import InnerGuard
from urllib.parse import parse_qs, urlsplit

from scart_wire.security import is_loopback
from dataflow.threads import OwnedThread

__all__ = ["AUTH_TIMEOUT", "FOXGLOVE_ORIGINS", "WebSocketGate", "handshake_refusal", "token_of"]

log = logging.getLogger("scart.foxglove")

#: The Foxglove app's origins: the web app, its former address, and the desktop app's
#: pages (Electron serves them from ``file://``).
FOXGLOVE_ORIGINS = frozenset({"https://app.foxglove.dev", "https://studio.foxglove.dev", "file://"})
MAX_HEAD = 8192  #: bytes of an upgrade request's head, at most
AUTH_TIMEOUT = 2.0  #: seconds for the whole request head (and its token) to arrive
HEAD_TIMEOUT = AUTH_TIMEOUT  # the former name
_BUFFER = 64 * 1024
_REASONS = MappingProxyType({401: "Unauthorized", 403: "Forbidden", 421: "Misdirected Request",
                             503: "Service Unavailable"})


def _host_part(value: str) -> str:
    """The host of a ``Host`` header value (``[::1]:8765`` -> ``::1``)."""
    value = value.strip().lower()
    if value.startswith("["):
        return value[1:value.find("]")] if "]" in value else value
    return value.rpartition(":")[0] if value.count(":") == 1 else value


def _origin_key(origin: str) -> str:
    """An origin compared without case or a trailing ``/`` (``file://`` stays itself)."""
    origin = origin.lower()
    scheme, sep, rest = origin.partition("://")
    return f"{scheme}{sep}{rest.rstrip('/')}" if sep else origin.rstrip("/")


def _headers(head: bytes) -> list[tuple[str, str]]:
    """``(lower-case name, value)`` of each header line of a request head."""
    out = []
    for line in head.decode("latin-1").split("\r\n")[1:]:
        name, colon, value = line.partition(":")
        if colon:
            out.append((name.strip().lower(), value.strip()))
    return out


def handshake_refusal(head: bytes, origins: Iterable[str], routable: bool) -> tuple[int, str] | None:
    """Why the upgrade request ``head`` is refused for its Host or Origin, as ``(HTTP
    status, reason)``; None when both are allowed (see the module docstring)."""
    headers = _headers(head)
    hosts = [v for k, v in headers if k == "host"]
    origin = next((v for k, v in reversed(headers) if k == "origin"), None)
    if len(hosts) != 1:
        return 421, "exactly one Host header is needed"
    host = _host_part(hosts[0])
    if not is_loopback(host):
        try:
            literal = bool(ipaddress.ip_address(host))
        except ValueError:
            literal = False
        if not (routable and literal):
            return 421, f"Host {hosts[0][:80]!r} is not this server's (use ws://127.0.0.1:PORT)"
    if origin is not None and _origin_key(origin) not in {_origin_key(o) for o in origins}:
        return 403, (f"Origin {origin[:80]!r} may not connect (allowed: none, i.e. a program, or "
                     f"{', '.join(sorted(origins))})")
    return None


def token_of(head: bytes) -> str | None:
    """The token a request carries: ``?token=`` in its URL, else ``Authorization: Bearer``."""
    request_line = head.split(b"\r\n", 1)[0].decode("latin-1")
    parts = request_line.split(" ")
    if len(parts) == 3:
        found = parse_qs(urlsplit(parts[1]).query).get("token")
        if found:
            return found[0]
    for name, value in _headers(head):
        if name == "authorization" and value[:7].lower() == "bearer ":
            return value[7:].strip()
    return None


def _forwarded(head: bytes) -> bytes:
    """The request head as the server behind receives it: no query (the token), no
    ``Authorization`` header."""
    lines = head.decode("latin-1").split("\r\n")
    method, _, rest = lines[0].partition(" ")
    target, _, version = rest.partition(" ")
    kept = [f"{method} {urlsplit(target).path or '/'} {version}"]
    kept += [line for line in lines[1:] if not line.lower().startswith("authorization:")]
    return "\r\n".join(kept).encode("latin-1")


class _Pool:
    """Connections counted in total and by key (a peer address, a token's digest)."""

    def __init__(self, total: int, per_key: int) -> None:
        self.total, self.per_key = total, per_key
        self.count = 0
        self.by_key: dict[str, int] = {}

    def full_for(self, key: str) -> bool:
        return self.count >= self.total or self.by_key.get(key, 0) >= self.per_key

    def add(self, key: str) -> None:
        self.count += 1
        self.by_key[key] = self.by_key.get(key, 0) + 1

    def remove(self, key: str) -> None:
        self.count -= 1
        self.by_key[key] -= 1
        if not self.by_key[key]:
            del self.by_key[key]


class _Refused(Exception):
    def __init__(self, status: int, reason: str) -> None:
        super().__init__(reason)
        self.status, self.reason = status, reason


class WebSocketGate:
    """Listens on ``host:port`` and relays each connection whose handshake passes (see the
    module docstring) to ``inner``, a loopback ``(host, port)`` reached through ``guard``
    (an :class:`~dataflow.foxglove.inner_guard.InnerGuard`, started: it gives the sockets the
    server behind lets through; None: a plain connection). ``tokens(token)`` says whether
    a token is accepted (None: none is). ``start()`` then ``stop()`` (idempotent);
    ``port`` is the bound port once started."""

    def __init__(self, host: str, port: int, inner: tuple[str, int], origins: Iterable[str] = FOXGLOVE_ORIGINS, *,
                 tokens: Callable[[str], bool] | None = None, tokens_required: bool = False,
                 guard: InnerGuard | None = None,
                 max_connections: int = 64, max_per_token: int = 16, max_tokenless: int = 16,
                 max_tokenless_per_peer: int = 4, max_pending: int = 64, max_pending_per_peer: int = 16,
                 auth_timeout: float = AUTH_TIMEOUT) -> None:
        self.host, self._port, self.inner = host, port, inner
        self.origins = frozenset(origins)
        self.routable = not is_loopback(host)
        self.tokens, self.tokens_required, self.guard = tokens, tokens_required, guard
        self.auth_timeout = auth_timeout
        self.refused = 0  #: handshakes refused so far
        self.evicted = 0  #: pending connections closed to make room for newer ones
        self._holders = _Pool(max_connections, max_per_token)
        self._tokenless = _Pool(max_tokenless, max_tokenless_per_peer)
        self._pending: OrderedDict[asyncio.Task[None], str] = OrderedDict()  # oldest first, with its peer
        self._max_pending, self._max_pending_per_peer = max_pending, max_pending_per_peer
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: asyncio.base_events.Server | None = None
        self._tasks: set[asyncio.Task[None]] = set()
        self._thread: OwnedThread | None = None

    @property
    def port(self) -> int:
        """The port listened on (the one given until started)."""
        if self._server is not None and self._server.sockets:
            return int(self._server.sockets[0].getsockname()[1])
        return self._port

    def counts(self) -> dict[str, int]:
        """Connections now: ``pending``, ``tokenless``, ``token`` (for tests and logs)."""
        return {"pending": len(self._pending), "tokenless": self._tokenless.count, "token": self._holders.count}

    def start(self) -> None:
        """Bind and serve on a thread of its own. Raises ``OSError`` when it cannot bind."""
        loop = asyncio.new_event_loop()
        try:
            self._server = loop.run_until_complete(asyncio.start_server(
                self._connection, self.host, self._port, limit=MAX_HEAD, backlog=128))
        except BaseException:
            loop.close()
            raise
        self._loop = loop
        self._thread = OwnedThread(lambda _stopping: loop.run_forever(), "scart-ws-gate").start()

    def stop(self) -> None:
        """Close the listener and every connection, end the thread (idempotent)."""
        loop, self._loop = self._loop, None
        if loop is None:
            return

        async def close() -> None:
            assert self._server is not None
            self._server.close()
            for task in list(self._tasks):
                task.cancel()
            await asyncio.gather(*self._tasks, return_exceptions=True)

        try:
            asyncio.run_coroutine_threadsafe(close(), loop).result(timeout=10)
        except Exception as exc:  # noqa: BLE001 - a stuck close still ends the loop below
            log.warning("foxglove gate: closing: %s", exc)
        loop.call_soon_threadsafe(loop.stop)
        if self._thread is not None:
            self._thread.join(timeout=10)
        if not loop.is_running():
            loop.close()

    async def _connection(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        peer = str((writer.get_extra_info("peername") or ("?",))[0])
        self._tasks.add(task)
        try:
            await self._serve(task, peer, reader, writer)
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError, asyncio.TimeoutError):
            pass  # gone, too slow or too large: nothing to answer
        except asyncio.CancelledError:
            pass  # stop(), or a newer connection took its place while it sent nothing
        finally:
            self._pending.pop(task, None)
            self._tasks.discard(task)
            writer.close()

    def _make_room(self, peer: str) -> None:
        """Close the oldest pending connection of ``peer`` when it has its share, else the
        oldest of all when they are ``max_pending``: a new connection always gets to ask."""
        mine = [t for t, p in self._pending.items() if p == peer]
        victim = mine[0] if len(mine) >= self._max_pending_per_peer else (
            next(iter(self._pending)) if len(self._pending) >= self._max_pending else None)
        if victim is not None:
            self._pending.pop(victim, None)
            self.evicted += 1
            victim.cancel()

    async def _serve(self, task: asyncio.Task[None], peer: str, reader: asyncio.StreamReader,
                     writer: asyncio.StreamWriter) -> None:
        self._make_room(peer)
        self._pending[task] = peer
        head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), self.auth_timeout)
        self._pending.pop(task, None)
        try:
            pool, key = self._admit(head, peer)
        except _Refused as refusal:
            self.refused += 1
            await self._answer(writer, refusal.status, refusal.reason)
            return
        pool.add(key)
        try:
            await self._relay(head, reader, writer)
        finally:
            pool.remove(key)

    def _admit(self, head: bytes, peer: str) -> tuple[_Pool, str]:
        """The pool a request joins and its key there; :class:`_Refused` saying why not."""
        refusal = handshake_refusal(head, self.origins, self.routable)
        if refusal is not None:
            raise _Refused(*refusal)
        token = token_of(head)
        if token is not None:
            if self.tokens is None or not self.tokens(token):
                raise _Refused(401, "that token is not accepted here")
            key = hashlib.sha256(token.encode()).hexdigest()
            if self._holders.full_for(key):
                raise _Refused(503, f"too many connections with this token (at most {self._holders.per_key}, "
                                    f"{self._holders.total} in all)")
            return self._holders, key
        if self.tokens_required:
            raise _Refused(401, "a token is needed (this server checks tokens): connect to ws://HOST:PORT/?token=TOKEN")
        if self._tokenless.full_for(peer):
            raise _Refused(503, f"too many connections without a token (at most {self._tokenless.per_key} from one "
                                f"address, {self._tokenless.total} in all): connect with the URL scart printed, "
                                "which carries a token")
        return self._tokenless, peer

    async def _answer(self, writer: asyncio.StreamWriter, status: int, reason: str) -> None:
        body = reason.encode()
        writer.write(f"HTTP/1.1 {status} {_REASONS.get(status, 'Refused')}\r\nContent-Type: text/plain\r\n"
                     f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n".encode() + body)
        await asyncio.wait_for(writer.drain(), self.auth_timeout)
        log.info("foxglove: handshake refused: %s", reason)

    async def _relay(self, head: bytes, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        guard = self.guard
        sock = guard.bound_socket() if guard is not None else None
        port = sock.getsockname()[1] if sock is not None else None
        try:
            if sock is not None:
                await asyncio.wait_for(asyncio.get_running_loop().sock_connect(sock, self.inner), self.auth_timeout)
                inner_reader, inner_writer = await asyncio.open_connection(sock=sock)
            else:
                inner_reader, inner_writer = await asyncio.wait_for(asyncio.open_connection(*self.inner),
                                                                    self.auth_timeout)
            try:
                inner_writer.write(_forwarded(head))
                await asyncio.gather(_pump(reader, inner_writer), _pump(inner_reader, writer))
            finally:
                if port is not None and guard is not None:
                    guard.forget(port)  # before the socket closes: its port is never let through again
                inner_writer.close()
        finally:
            if sock is not None:
                if port is not None and guard is not None:
                    guard.forget(port)
                sock.close()


async def _pump(source: asyncio.StreamReader, sink: asyncio.StreamWriter) -> None:
    """Copy ``source`` to ``sink`` until the end of ``source`` (then half-close ``sink``)."""
    try:
        while chunk := await source.read(_BUFFER):
            sink.write(chunk)
            await sink.drain()
        if sink.can_write_eof():
            sink.write_eof()
    except OSError:
        sink.close()
