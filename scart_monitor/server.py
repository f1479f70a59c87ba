"""`MonitorServer`: the HTTP side of the youBot Monitor (stdlib only, plus plotly's JS file).

Routes (all on the address given, 127.0.0.1 by default):

| method | path | answer |
|---|---|---|
| GET | `/` | the page (`static/index.html`); ``/?token=...`` in token mode |
| GET | `/static/app.js`, `/static/style.css` | our page code |
| GET | `/static/plotly.min.js` | Plotly.js from the installed ``plotly`` package |
| GET | `/api/state` | one JSON snapshot (same shape as an SSE message) plus ``poses`` |
| GET | `/api/poses` | ``{"poses": [...]}`` from the backend |
| GET | `/api/history` | ``{"statuses": [...], "joint_limits": [[lo, hi], ...]}``: the last minute, at most 25 a second, and the joint position limits (a page draws both at once) |
| GET | `/events` | Server-Sent Events: ``event: update`` messages, at most `MAX_RATE_HZ`/s; 503 + ``Retry-After`` beyond `MAX_SSE_CLIENTS` streams |
| POST | `/api/period` | ``{"seconds": 0.02}`` → ``{"ok": bool, "message": str}`` from the backend |
| POST | `/api/pose` | ``{"pose": "home"}`` or ``{"pose": [5 floats]}`` → same answer shape |

POST bodies must be ``application/json``; a malformed body is a 400 whose JSON
``message`` says what was expected.

Security
--------
Trusted: whoever can open a TCP connection to the port *and* names it by one of its own
names (the local user; anyone on the network when bound to a routable address). Not
trusted: web pages from other origins running in that user's browser. The checks:

- **Host** (every request): only ``127.0.0.1:PORT``, ``localhost:PORT``, ``[::1]:PORT``
  (when bound to ``::1``/``::``) and the configured host (and the address it bound) with
  the bound port; anything else, or no Host, is a 421 and nothing else happens. Stops
  DNS rebinding: a page of ``evil.example`` whose name was re-pointed at 127.0.0.1 is
  same-origin with itself, not with us, and its requests carry ``Host: evil.example``.
- **Origin** (every POST): must be ``http://`` + an allowed Host, else 403. Stops
  cross-site requests (forms, ``fetch`` with ``no-cors``) before the backend is called;
  ``application/json`` additionally forces a CORS preflight this server never grants.
- **Token** (optional, ``token=``): POSTs must also carry it in ``X-Monitor-Token`` (the
  page reads it from its own ``?token=`` and sends it), else 401; compared in constant
  time, never logged (request lines are logged with ``token=***``). Stops other local
  users and programs that only know the port from moving the arm. GETs stay open: they
  only read.
- **Refusals are worded as at every other door**: ``COMMAND: WHAT refused: WHY``, the
  command named as the operation it reaches (``set_period``, ``move``); a value as the
  one check of operation arguments says it (``set_period(seconds): 'fast' refused: Input
  should be a valid number``); a token as the gRPC doors do (``set_period: no valid
  token ...``).
- **Headers** (every answer): ``X-Frame-Options: DENY`` and CSP ``frame-ancestors 'none'``
  (no clickjacking through a frame), a ``default-src 'self'`` CSP for the page,
  ``X-Content-Type-Options: nosniff``, ``Referrer-Policy: no-referrer`` (the token never
  leaves in a Referer).
- **Resources**: at most `MAX_SSE_CLIENTS` streams (more: 503 + ``Retry-After``), at most
  `MAX_CONNECTIONS` open connections, i.e. handler threads, a listen backlog of
  `LISTEN_BACKLOG`, `MAX_BODY` bytes per POST. A request (its head and body) must arrive
  within `REQUEST_DEADLINE_S` in all, whatever its pace (a slowloris sending a byte now
  and then is cut at that deadline, not kept by a per-read timeout), and one peer address
  may have at most `MAX_PENDING_PER_PEER` connections still sending their request. A
  connection beyond either bound takes the place of the oldest one still sending its
  request (of that peer, or of anyone when the server is full), so a legitimate request
  is answered at once while slow ones wait to be dropped; when every connection is being
  answered (streams), one more is closed at once, unanswered.

Threads: `start` creates one accept thread; each connection gets its own daemon handler
thread (at most `MAX_CONNECTIONS`). `stop` signals (closes the hub, which ends SSE
loops), shuts the listener down, shuts every open connection's socket (unblocking
reads), then joins them all with a timeout. Nothing is started in ``__init__``.
"""

from __future__ import annotations

import hmac
import importlib.resources
import json
import logging
import math
import re
import secrets
import socket
import threading
import time
import urllib.parse
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from types import MappingProxyType
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol, TypeVar, runtime_checkable

from scart_wire.bounds import check_argument
from scart_wire.errors import DataflowError
from scart_wire.security import is_loopback

from .connections import Connections
from .hub import Snapshot, StatusHub

if TYPE_CHECKING:
    from pydantic import JsonValue

A = TypeVar("A")

log = logging.getLogger(__name__)

MAX_RATE_HZ = 25.0
"""SSE updates per second per client at most; statuses in between are coalesced."""

HEARTBEAT_S = 0.5
"""An SSE update is sent at least this often, so the sample age keeps counting up."""

MAX_BODY = 64 * 1024
"""Largest POST body accepted (bytes)."""

MAX_SSE_CLIENTS = 256
"""Default cap on concurrent ``/events`` streams; one more is answered 503 + ``Retry-After``."""

MAX_CONNECTIONS = 512
"""Default cap on concurrent connections (one handler thread each); one more is closed
at once without an answer. Above `MAX_SSE_CLIENTS`, so a full set of streams still
leaves room for the page's commands and snapshots."""

MAX_PENDING_PER_PEER = 32
"""Connections of one peer address still sending their request, at most (see Security)."""

REQUEST_DEADLINE_S = 5.0
"""A request's head and body must have arrived this long after its connection opened."""

LISTEN_BACKLOG = 128
"""``listen()`` backlog: connections the kernel queues while the accept thread is busy."""

RETRY_AFTER_S = 5
"""``Retry-After`` (s) of the 503 sent to a stream beyond the cap."""

TOKEN_HEADER = "X-Monitor-Token"
"""The request header carrying the control token on POSTs (token mode)."""

PAGE_CSP = (
    "default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; "
    "object-src 'none'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
)
"""Content-Security-Policy of every answer: our own scripts only, no plugins, no framing.
``data:`` images are the inline favicon; inline styles are Plotly's."""

SECURITY_HEADERS: tuple[tuple[str, str], ...] = (
    ("X-Frame-Options", "DENY"),
    ("Content-Security-Policy", PAGE_CSP),
    ("X-Content-Type-Options", "nosniff"),
    ("Referrer-Policy", "no-referrer"),
)
"""Sent on every answer (pages, JSON, errors, refusals)."""

_WILDCARDS = ("", "0.0.0.0", "::")
_TOKEN_IN_TEXT = re.compile(r"(token=)[^&\s\"']*", re.IGNORECASE)

_STATIC = {
    "/": ("index.html", "text/html; charset=utf-8"),
    "/index.html": ("index.html", "text/html; charset=utf-8"),
    "/static/app.js": ("app.js", "text/javascript; charset=utf-8"),
    "/static/style.css": ("style.css", "text/css; charset=utf-8"),
}


@runtime_checkable
class MonitorBackend(Protocol):
    """What the monitor calls back; implemented by its host. Called from handler threads
    (possibly several at once); each call may block for as long as the host needs."""

    def set_period(self, seconds: float) -> tuple[bool, str]:
        """Ask the driver for a new period; (accepted?, what it accepted or why not)."""
        ...

    def send_pose(self, pose: str | list[float]) -> tuple[bool, str]:
        """Send the arm to a named pose or to joint positions; (accepted?, message)."""
        ...

    def poses(self) -> list[str]:
        """The named poses `send_pose` knows."""
        ...


class _BadRequest(Exception):
    """A client error: answered with ``status`` and a JSON ``message``."""

    def __init__(self, message: str, status: HTTPStatus = HTTPStatus.BAD_REQUEST) -> None:
        super().__init__(message)
        self.status = status


def _plotly_js() -> bytes:
    """Plotly.js as shipped inside the installed ``plotly`` Python package."""
    return (importlib.resources.files("plotly") / "package_data" / "plotly.min.js").read_bytes()


def _static_file(name: str) -> bytes:
    return (importlib.resources.files(__package__) / "static" / name).read_bytes()


def _bracket(host: str) -> str:
    """``host`` as it appears in a URL authority (IPv6 literals in brackets)."""
    return f"[{host}]" if ":" in host else host


def _allowed_hosts(configured: str, bound: str, port: int) -> frozenset[str]:
    """The ``Host`` header values (lower case) a server configured for ``configured``,
    bound to address ``bound`` and port ``port`` answers: ``127.0.0.1``, ``localhost``,
    ``[::1]`` when bound to ``::1``/``::``, and the configured host and bound address
    unless they are wildcards; each with ``:port`` (and bare as well on port 80)."""
    names = {"127.0.0.1", "localhost"}
    if bound in ("::1", "::") or configured in ("::1", "::"):
        names.add("[::1]")
    names.update(_bracket(h) for h in (configured, bound) if h not in _WILDCARDS)
    hosts = {f"{n.lower()}:{port}" for n in names}
    if port == 80:
        hosts.update(n.lower() for n in names)
    return frozenset(hosts)


class _HTTPServer(ThreadingHTTPServer):
    """ThreadingHTTPServer whose connections are kept in a :class:`Connections` (bounded,
    each request under a deadline, ended by `close_connections`), holding the ``/events``
    slots."""

    daemon_threads = True
    block_on_close = False
    request_queue_size = LISTEN_BACKLOG

    def __init__(self, address: tuple[str, int], monitor: MonitorServer, max_connections: int,
                 max_sse_clients: int) -> None:
        self.monitor = monitor
        self.address_family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        self.max_connections = max_connections
        self.sse_slots = threading.BoundedSemaphore(max_sse_clients)
        self.connections = Connections(max_connections, MAX_PENDING_PER_PEER, REQUEST_DEADLINE_S)
        super().__init__(address, _Handler)
        self.port = int(self.server_address[1])
        self.allowed_hosts = _allowed_hosts(address[0], str(self.server_address[0]), self.port)
        self.allowed_origins = frozenset(f"http://{h}" for h in self.allowed_hosts)

    def process_request(self, request: Any, client_address: Any) -> None:
        # Registered here, in the accept thread, so that after shutdown() returns the
        # set of connection threads is complete.
        thread = threading.Thread(
            target=self._serve_connection,
            args=(request, client_address),
            name=f"scart-monitor-conn-{client_address[1]}",
            daemon=True,
        )
        if not self.connections.admit(thread, request, str(client_address[0])):
            log.debug("monitor: %d connections open and answering, closing one more from %s",
                      self.max_connections, client_address[0])
            self.shutdown_request(request)  # a flood must not grow threads without bound: refused, unanswered
            return
        thread.start()

    def service_actions(self) -> None:
        """Every loop of ``serve_forever``: end the requests past their deadline."""
        self.connections.sweep()

    def _serve_connection(self, request: socket.socket, client_address: tuple[str, int]) -> None:
        try:
            self.finish_request(request, client_address)
        except (ConnectionError, TimeoutError, OSError):
            pass  # the browser went away or stop() shut the socket: nothing to report
        except Exception:  # noqa: BLE001 - a handler bug must not kill the server
            log.exception("monitor: request from %s failed", client_address)
        finally:
            self.shutdown_request(request)
            self.connections.forget(threading.current_thread())

    def open_connections(self) -> int:
        """How many connections (handler threads) are open now. Thread-safe."""
        return self.connections.count()

    def close_connections(self, timeout: float) -> list[str]:
        """Shut every open connection and join its thread; returns names still alive."""
        return self.connections.close_all(timeout)


class _Handler(BaseHTTPRequestHandler):
    """One request (HTTP/1.0: one request per connection, SSE streams until closed)."""

    server: _HTTPServer
    server_version = "scart-monitor/0.1"
    timeout = 10.0  # a connection that never sends its request line does not pin a thread

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - stdlib name
        if log.isEnabledFor(logging.DEBUG):  # request lines may carry ?token=: never logged
            log.debug("monitor: %s", _TOKEN_IN_TEXT.sub(r"\1***", format % args))

    def send_response(self, code: int, message: str | None = None) -> None:
        """Answering: the request has arrived (its deadline no longer applies)."""
        self.server.connections.answering(threading.current_thread())
        super().send_response(code, message)

    def end_headers(self) -> None:
        """Every answer (errors and refusals included) carries `SECURITY_HEADERS`."""
        for name, value in SECURITY_HEADERS:
            self.send_header(name, value)
        super().end_headers()

    def parse_request(self) -> bool:
        """The stdlib parse plus the Host check: a request for another host (DNS
        rebinding) or without exactly one Host header is answered 421 and not served."""
        if not super().parse_request():
            return False
        hosts = self.headers.get_all("Host") or []
        if len(hosts) == 1 and hosts[0].strip().lower() in self.server.allowed_hosts:
            return True
        message = f"misdirected request: use http://127.0.0.1:{self.server.port}/"
        self._send_json(HTTPStatus.MISDIRECTED_REQUEST, {"ok": False, "message": message})
        return False

    # -- routing --------------------------------------------------------------------

    def do_GET(self) -> None:  # noqa: N802 - stdlib name
        path = self.path.split("?", 1)[0].split("#", 1)[0]
        monitor = self.server.monitor
        if path in _STATIC:
            name, ctype = _STATIC[path]
            self._send(HTTPStatus.OK, _static_file(name), ctype, cache=False)
        elif path == "/static/plotly.min.js":
            try:
                script = monitor._plotly()
            except (ImportError, OSError) as exc:
                message = f"Plotly.js not found ({exc}); install the 'plotly' package: pip install 'plotly>=5'"
                self._send_json(HTTPStatus.INTERNAL_SERVER_ERROR, {"ok": False, "message": message})
                return
            self._send(HTTPStatus.OK, script, "text/javascript; charset=utf-8", cache=True)
        elif path == "/api/state":
            state, _ = monitor._hub.snapshot()
            doc = {**state, "status": json.loads(state["status"]), "poses": monitor._safe_poses()}
            self._send_json(HTTPStatus.OK, doc)
        elif path == "/api/poses":
            self._send_json(HTTPStatus.OK, {"poses": monitor._safe_poses()})
        elif path == "/api/history":
            self._send_json(HTTPStatus.OK, {"statuses": monitor._hub.history(),
                                            "joint_limits": [list(lim) for lim in monitor.joint_limits]})
        elif path == "/events":
            self._events_if_room()
        else:
            self._send_json(HTTPStatus.NOT_FOUND, {"ok": False, "message": f"no such page: {path}"})

    def do_POST(self) -> None:  # noqa: N802 - stdlib name
        path = self.path.split("?", 1)[0]
        backend = self.server.monitor._backend
        command = _COMMANDS.get(path, path)
        try:
            self._check_origin()
            self._check_token()
            if path == "/api/period":
                seconds = _number(self._json_body(), "seconds")
                ok, message = self._call(backend.set_period, seconds)
            elif path == "/api/pose":
                ok, message = self._call(backend.send_pose, _pose(self._json_body()))
            else:
                raise _BadRequest(f"no such command: {path}", HTTPStatus.NOT_FOUND)
        except _BadRequest as exc:
            said = str(exc) if str(exc).startswith(f"{command}") else f"{command}: {exc}"
            self._send_json(exc.status, {"ok": False, "message": said})
            return
        self._send_json(HTTPStatus.OK, {"ok": bool(ok), "message": str(message)})

    # -- checks -----------------------------------------------------------------------

    def _check_origin(self) -> None:
        """A command must come from our own page: ``Origin`` is ``http://`` + an allowed Host."""
        origin = self.headers.get("Origin")
        if origin is None:
            raise _BadRequest("a command without an Origin header refused (send it from the monitor page)",
                              HTTPStatus.FORBIDDEN)
        if origin.strip().lower() not in self.server.allowed_origins:
            raise _BadRequest(f"Origin {origin[:100]!r} refused: cross-origin command", HTTPStatus.FORBIDDEN)

    def _check_token(self) -> None:
        """In token mode, ``X-Monitor-Token`` must equal the token (constant-time compare)."""
        expected = self.server.monitor._token
        if expected is None:
            return
        given = self.headers.get(TOKEN_HEADER, "")
        if not hmac.compare_digest(given.encode("utf-8", "replace"), expected.encode()):
            raise _BadRequest("no valid token (missing or wrong control token: open the URL the monitor printed, "
                              "which carries it)", HTTPStatus.UNAUTHORIZED)

    # -- helpers ----------------------------------------------------------------------

    def _resume_from(self, instance: str) -> int:
        """Event cursor from a reconnecting EventSource's ``Last-Event-ID`` (``instance:id``);
        0 (send the whole log) for a new page or after this server was replaced."""
        token, _, number = self.headers.get("Last-Event-ID", "").partition(":")
        return int(number) if token == instance and number.isdigit() else 0

    def _json_body(self) -> JsonValue:
        ctype = self.headers.get("Content-Type", "").split(";", 1)[0].strip().lower()
        if ctype != "application/json":
            raise _BadRequest(
                f"expected Content-Type application/json, got {ctype or 'none'!r}",
                HTTPStatus.UNSUPPORTED_MEDIA_TYPE,
            )
        try:
            length = int(self.headers.get("Content-Length", "0"))
        except ValueError:
            raise _BadRequest("bad Content-Length") from None
        if length > MAX_BODY:
            raise _BadRequest(f"body too large: {length} > {MAX_BODY} bytes", HTTPStatus.REQUEST_ENTITY_TOO_LARGE)
        raw = self.rfile.read(length) if length > 0 else b""
        try:
            return json.loads(raw)
        except (ValueError, UnicodeDecodeError) as exc:
            raise _BadRequest(f"body is not valid JSON: {exc}") from None

    def _call(self, func: Callable[[A], tuple[object, object]], arg: A) -> tuple[bool, str]:
        try:
            ok, message = func(arg)
        except Exception as exc:  # noqa: BLE001 - the host's failure is reported, not raised
            log.warning("monitor: backend %s failed: %s", getattr(func, "__name__", func), exc)
            return False, f"backend error: {type(exc).__name__}: {exc}"
        return bool(ok), str(message)

    def _send(self, status: HTTPStatus, body: bytes, ctype: str, cache: bool = False,
              extra: tuple[tuple[str, str], ...] = ()) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "max-age=3600" if cache else "no-cache")
        for name, value in extra:
            self.send_header(name, value)
        self.end_headers()
        self.wfile.write(body)

    def _send_json(self, status: HTTPStatus, obj: object, extra: tuple[tuple[str, str], ...] = ()) -> None:
        self._send(status, json.dumps(obj, default=str).encode(), "application/json", extra=extra)

    def _events_if_room(self) -> None:
        """Stream events while holding one of the server's SSE slots; none free: 503."""
        slots = self.server.sse_slots
        if not slots.acquire(blocking=False):
            message = f"too many event streams open; retry in {RETRY_AFTER_S} s"
            self._send_json(HTTPStatus.SERVICE_UNAVAILABLE, {"ok": False, "message": message},
                            extra=(("Retry-After", str(RETRY_AFTER_S)),))
            return
        try:
            self._stream_events()
        finally:
            slots.release()

    def _stream_events(self) -> None:
        """Send `update` events until the client leaves or the server stops.

        At most MAX_RATE_HZ messages/s (newest status only) and at least one every
        HEARTBEAT_S. Bounded: ends when the hub is closed or a write fails.
        """
        hub = self.server.monitor._hub
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", "text/event-stream")
        self.send_header("Cache-Control", "no-cache")
        self.send_header("X-Accel-Buffering", "no")
        self.end_headers()
        self.wfile.write(b"retry: 1000\n\n")
        self.wfile.flush()
        seen, last_event = -1, self._resume_from(self.server.monitor._instance)
        min_gap = 1.0 / MAX_RATE_HZ
        stop = self.server.monitor._stopping
        while not hub.closed:
            sent_at = time.monotonic()
            message, last_event = hub.snapshot(last_event)
            seen = message["version"]
            self.wfile.write(_sse_frame(message, f"{self.server.monitor._instance}:{last_event}"))
            self.wfile.flush()
            # Throttle (a rate limit, not synchronisation): wake early only on stop.
            if stop.wait(max(0.0, min_gap - (time.monotonic() - sent_at))):
                break
            hub.wait(seen, HEARTBEAT_S)


def _sse_frame(message: Snapshot, event_id: str) -> bytes:
    status_json = message.pop("status")
    body = json.dumps(message, default=str)
    # Splice the pre-serialised status in, rather than decoding and re-encoding it.
    body = body[:-1] + ', "status": ' + status_json + "}"
    return f"id: {event_id}\nevent: update\ndata: ".encode() + body.encode() + b"\n\n"


#: The operation each command reaches: what its refusals are named after.
_COMMANDS = MappingProxyType({"/api/period": "set_period", "/api/pose": "move"})


def _number(body: JsonValue, key: str) -> float:
    """``body[key]``, a finite number (a refusal worded as the one check of operation
    arguments words it: ``set_period(seconds): VALUE refused: REASON``)."""
    if not isinstance(body, dict) or key not in body:
        raise _BadRequest(f'expected a JSON object like {{"{key}": 0.01}}')
    try:
        return float(check_argument(f"set_period({key})", float, body[key]))  # the one check every door uses
    except DataflowError as exc:
        raise _BadRequest(str(exc)) from None


def _pose(body: JsonValue) -> str | list[float]:
    if not isinstance(body, dict) or "pose" not in body:
        raise _BadRequest('expected a JSON object like {"pose": "home"} or {"pose": [0, 0, 0, 0, 0]}')
    pose = body["pose"]
    if isinstance(pose, str) and pose:
        return pose
    if isinstance(pose, list) and pose and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in pose
    ):
        return [float(v) for v in pose if isinstance(v, (int, float))]  # all of them (checked above)
    raise _BadRequest(f"move(pose): {pose!r:.80} refused: Input should be a pose name or a list of finite joint "
                      "positions")


class MonitorServer:
    """The youBot Monitor web server, fed by its host.

    Lifecycle: ``__init__`` (nothing bound, no thread) → `start` (binds, one accept
    thread) → `stop` (idempotent; ends every stream and joins every thread it started,
    with a timeout). Publishing (`publish_status`, `publish_event`, `set_driver_info`)
    is thread-safe, never waits for a browser, and is allowed before `start` and after
    `stop` (it then only updates the state).

    ``token``: when given (e.g. ``secrets.token_urlsafe(16)``, one per launch), POSTs must
    carry it in ``X-Monitor-Token``; `page_url` hands it to the page. ``max_sse_clients``
    and ``max_connections`` bound the streams and the handler threads (see the module's
    Security section). A host other than loopback needs a token (anyone on the network
    could move the arm) unless ``insecure``. Raises `ValueError` for an empty token, a cap
    below 1, or a routable host without a token.
    """

    def __init__(self, backend: MonitorBackend, host: str = "127.0.0.1", port: int = 0, *,
                 token: str | None = None, max_sse_clients: int = MAX_SSE_CLIENTS,
                 max_connections: int = MAX_CONNECTIONS, insecure: bool = False) -> None:
        if token is not None and not token:
            raise ValueError("MonitorServer: token must be a non-empty string or None")
        if token is None and not is_loopback(host):
            if not insecure:
                raise ValueError(f"MonitorServer: refusing to serve on {host} without a control token "
                                 "(anyone who reaches it could move the arm): set control_token, or insecure")
            log.warning("MonitorServer on %s without a control token: anyone who reaches it can move the arm", host)
        if max_sse_clients < 1 or max_connections < 1:
            raise ValueError("MonitorServer: max_sse_clients and max_connections must be at least 1")
        self._backend = backend
        self._address = (host, port)
        self._token = token
        self._limits = (max_connections, max_sse_clients)
        self._hub = StatusHub()
        self._stopping = threading.Event()
        self._instance = secrets.token_hex(4)  # SSE ids: a reconnect resumes only on this server
        self._lock = threading.Lock()
        self._httpd: _HTTPServer | None = None
        self._thread: threading.Thread | None = None
        self._plotly_bytes: bytes | None = None
        #: each joint's position limits ``(lo, hi)`` in rad, drawn on its position chart (set before start)
        self.joint_limits: list[tuple[float, float]] = []

    def __repr__(self) -> str:  # never shows the token
        return f"MonitorServer({self._address[0]!r}, {self._address[1]!r}, token={'set' if self._token else None})"

    # -- lifecycle --------------------------------------------------------------------

    def start(self) -> None:
        """Bind the address and start serving. Raises `OSError` naming the address if it
        cannot bind and `RuntimeError` if already started or stopped (a server is started once)."""
        with self._lock:
            if self._httpd is not None or self._stopping.is_set():
                raise RuntimeError("MonitorServer.start: already started (or stopped)")
            try:
                self._httpd = _HTTPServer(self._address, self, *self._limits)
            except OSError as exc:
                host, port = self._address[0], self._address[1]
                raise OSError(exc.errno, f"the monitor cannot listen on {host}:{port}: "
                                         f"{exc.strerror or exc}") from None
            self._thread = threading.Thread(
                target=self._httpd.serve_forever,
                kwargs={"poll_interval": 0.05},
                name="scart-monitor-http",
                daemon=True,
            )
            self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Close every SSE stream and connection, stop serving, join the threads.

        Idempotent and thread-safe; blocks up to about ``timeout`` s. Threads still
        alive after that (a backend call that never returns) are logged, not killed.
        Called from inside a request (a backend method), that request is still answered
        and its thread ends right after.
        """
        with self._lock:
            if self._stopping.is_set():
                return
            self._stopping.set()
            httpd, thread = self._httpd, self._thread
        self._hub.close()
        if httpd is None:
            return
        deadline = time.monotonic() + timeout
        httpd.shutdown()  # returns once serve_forever has left its loop
        if thread is not None and thread is not threading.current_thread():
            thread.join(max(0.0, deadline - time.monotonic()))
        stuck = httpd.close_connections(max(0.0, deadline - time.monotonic()))
        httpd.server_close()
        if stuck:
            log.warning("monitor: connection threads still running after stop: %s", stuck)

    @property
    def url(self) -> str:
        """``http://HOST:PORT/`` with the port actually bound (a wildcard address is shown
        as the loopback one, which the Host check accepts); raises if not started. Never
        carries the token: the base to append API paths to."""
        if self._httpd is None:
            raise RuntimeError("MonitorServer.url: not started")
        host = str(self._httpd.server_address[0])
        host = {"0.0.0.0": "127.0.0.1", "::": "::1"}.get(host, host)
        return f"http://{_bracket(host)}:{self._httpd.port}/"

    @property
    def page_url(self) -> str:
        """The URL to open the page at: `url`, plus ``?token=...`` in token mode (then a
        secret: print it for the user, do not log it). Raises if not started."""
        if self._token is None:
            return self.url
        return self.url + "?" + urllib.parse.urlencode({"token": self._token})

    # -- feeding ----------------------------------------------------------------------

    def publish_status(self, sample: dict[str, object]) -> None:
        """Make ``sample`` (a YouBotStatus-like dict) the newest status. Thread-safe, never
        blocks on browsers; statuses faster than the page refresh are coalesced. The
        monitor keeps the dict: do not mutate it after publishing."""
        self._hub.publish_status(sample)

    def publish_event(self, name: str, detail: str = "") -> None:
        """Show an event (``busy``, ``idle``, ``reached``, ...); ``refresh`` is counted, not
        logged one by one. Thread-safe, never blocks on browsers."""
        self._hub.publish_event(name, detail)

    def set_summary(self, summary: dict[str, object]) -> None:
        """The newest ``ArmSummary`` of the demo's bridge (as a dict): in the next snapshot."""
        self._hub.set_summary(summary)

    def set_gripper(self, gripper: dict[str, object]) -> None:
        """Where the gripper is in ``base_link`` (``x``, ``y``, ``z`` [m]): in the next snapshot."""
        self._hub.set_gripper(gripper)

    def set_driver_info(self, state: str, period: float, connected: bool) -> None:
        """Driver state (e.g. ``RUNNING``), its accepted period in seconds, and whether
        it is reachable; a change of ``connected`` is logged. Thread-safe."""
        self._hub.set_driver_info(state, period, connected)

    @property
    def error_flag_names(self) -> dict[int, str]:
        """Bit index → name used to show error flag words (a copy; assign to change)."""
        return self._hub.error_flag_names

    @error_flag_names.setter
    def error_flag_names(self, names: dict[int, str]) -> None:
        self._hub.error_flag_names = names

    # -- for the handler --------------------------------------------------------------

    def _plotly(self) -> bytes:
        if self._plotly_bytes is None:
            self._plotly_bytes = _plotly_js()  # 4-5 MB, read once
        return self._plotly_bytes

    def _safe_poses(self) -> list[str]:
        try:
            return [str(p) for p in self._backend.poses()]
        except Exception as exc:  # noqa: BLE001 - the page still works without poses
            log.warning("monitor: backend poses() failed: %s", exc)
            return []
