"""A gate in front of a WebSocket server that cannot check its own handshake (the
Foxglove SDK's): it listens where the user asked, reads each connection's HTTP upgrade
request, checks its ``Host`` and ``Origin``, and only then relays the connection, byte
for byte, to the real server on a loopback port of its own.

The checks (the monitor's, for a WebSocket):

- **Host**: exactly one, naming a loopback address (``localhost``, ``127.0.0.0/8``,
  ``[::1]``); when the gate listens on a routable address (``--insecure``), an IP address
  literal too. A DNS name is refused: that is what a DNS-rebinding page sends.
- **Origin**: none (a program, not a browser: browsers always send one on a WebSocket),
  or one of ``origins`` (for Foxglove: its web app, :data:`FOXGLOVE_ORIGINS`). Any other
  web page the user's browser opens is refused before the server sees a byte.

A refused handshake gets ``403`` (``421`` for a bad Host) with the reason, and is closed.
Bounds: the request head at most :data:`MAX_HEAD` bytes within :data:`HEAD_TIMEOUT` s,
at most ``max_connections`` open connections, ``max_per_peer`` from one address.

Threads: :meth:`WebSocketGate.start` starts one thread running an asyncio loop (every
connection is a task on it); :meth:`WebSocketGate.stop` closes the listener and every
relayed connection and joins the thread.
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
from collections.abc import Iterable

from scart_wire.security import is_loopback
from dataflow.threads import OwnedThread

__all__ = ["FOXGLOVE_ORIGINS", "WebSocketGate", "handshake_refusal"]

log = logging.getLogger("scart.foxglove")

#: The Foxglove app's origins: the web app, its former address, and the desktop app's
#: pages (Electron serves them from ``file://``).
FOXGLOVE_ORIGINS = frozenset({"https://app.foxglove.dev", "https://studio.foxglove.dev", "file://"})
MAX_HEAD = 8192  #: bytes of an upgrade request's head, at most
HEAD_TIMEOUT = 5.0  #: seconds for the whole request head to arrive
_BUFFER = 64 * 1024


def _host_part(value: str) -> str:
    """The host of a ``Host`` header value (``[::1]:8765`` -> ``::1``)."""
    value = value.strip().lower()
    if value.startswith("["):
        return value[1:value.find("]")] if "]" in value else value
    return value.rpartition(":")[0] if value.count(":") == 1 else value


def handshake_refusal(head: bytes, origins: Iterable[str], routable: bool) -> tuple[int, str] | None:
    """Why the upgrade request ``head`` is refused, as ``(HTTP status, reason)``; None when
    its Host and Origin are allowed (see the module docstring)."""
    lines = head.decode("latin-1").split("\r\n")
    hosts, origin = [], None
    for line in lines[1:]:
        name, colon, value = line.partition(":")
        if not colon:
            continue
        name = name.strip().lower()
        if name == "host":
            hosts.append(value.strip())
        elif name == "origin":
            origin = value.strip()
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
    if origin is not None and origin.lower().rstrip("/") not in {o.lower() for o in origins}:
        return 403, (f"Origin {origin[:80]!r} may not connect (allowed: none, i.e. a program, or "
                     f"{', '.join(sorted(origins))})")
    return None


class WebSocketGate:
    """Listens on ``host:port`` and relays each connection whose handshake passes
    :func:`handshake_refusal` to ``inner`` (a loopback ``(host, port)``). ``start()`` then
    ``stop()`` (idempotent); ``port`` is the bound port once started."""

    def __init__(self, host: str, port: int, inner: tuple[str, int], origins: Iterable[str] = FOXGLOVE_ORIGINS,
                 max_connections: int = 64, max_per_peer: int = 16) -> None:
        self.host, self._port, self.inner = host, port, inner
        self.origins = frozenset(origins)
        self.routable = not is_loopback(host)
        self.max_connections, self.max_per_peer = max_connections, max_per_peer
        self.refused = 0  #: handshakes refused so far
        self._peers: dict[str, int] = {}
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
        if len(self._tasks) >= self.max_connections or self._peers.get(peer, 0) >= self.max_per_peer:
            writer.close()  # a flood: closed at once, unanswered
            return
        self._tasks.add(task)
        self._peers[peer] = self._peers.get(peer, 0) + 1
        try:
            await self._serve(reader, writer)
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError, asyncio.TimeoutError):
            pass  # gone, too slow or too large: nothing to answer
        except asyncio.CancelledError:
            pass  # stop(): the connection ends with the gate
        finally:
            self._tasks.discard(task)
            self._peers[peer] -= 1
            if not self._peers[peer]:
                del self._peers[peer]
            writer.close()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HEAD_TIMEOUT)
        refusal = handshake_refusal(head, self.origins, self.routable)
        if refusal is not None:
            self.refused += 1
            status, reason = refusal
            body = reason.encode()
            writer.write(f"HTTP/1.1 {status} {'Forbidden' if status == 403 else 'Misdirected Request'}\r\n"
                         f"Content-Type: text/plain\r\nContent-Length: {len(body)}\r\nConnection: close\r\n\r\n"
                         .encode() + body)
            await asyncio.wait_for(writer.drain(), HEAD_TIMEOUT)
            log.info("foxglove: handshake refused: %s", reason)
            return
        inner_reader, inner_writer = await asyncio.wait_for(
            asyncio.open_connection(*self.inner), HEAD_TIMEOUT)
        try:
            inner_writer.write(head)
            await asyncio.gather(_pump(reader, inner_writer), _pump(inner_reader, writer))
        finally:
            inner_writer.close()


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
