"""A process's YARP network: its ports, one io thread for all their sockets, one control
thread, and its name server.

**Threads.** ``Network(...)`` starts, and :meth:`Network.close` ends (idempotent, from
any thread): the *io* thread, which accepts connections, reads every one of them through
a selector (a port's ``reader`` runs there: keep it short) and sends what the kernel did
not take at once; the *control* thread, which registers names (and again after the name
server forgot them: a restarted ``yarpserver`` keeps nothing), keeps the connections a
port asked for (its ``connect`` list, retried until the peer is there), and answers
administrative commands (``yarp connect`` asks a port to connect, which needs the name
server); and one thread per RPC port, answering its requests in order. The io thread
starts the control thread's round every second.

**Bounds.** A port holds at most ``limits.inputs`` connections that said who they are and
``limits.strangers`` that have not, each for ``limits.handshake`` seconds (the oldest
stranger is closed to let a new one in, so idle connections cannot lock writers out); a
message over ``limits.message`` bytes or a broken header closes its connection. Each is
counted in the port's ``counters`` and said in one log line.

**Security.** Ports listen on ``host`` (loopback by default) and connect only to ports on
loopback unless ``insecure``: YARP authenticates no one.
"""

from __future__ import annotations

import ipaddress
import logging
import socket
import threading
import time
from collections import deque
from collections.abc import Callable

from .connection import Connection
from .names import NameClient, check_name
from .poll import READ, WRITE, Poll
from .port import Incoming, Port, PortLimits, Responder
from .dgram import DatagramReader
from .wire import Frame, ProtocolError, yarp_number

__all__ = ["Network"]

log = logging.getLogger("scart_yarp")

MAINTAIN_EVERY = 1.0  #: seconds between the control thread's rounds (registrations, wanted connections)
CHECK_REGISTERED_EVERY = 5.0  #: seconds between asking the name server whether it still knows a port
MAX_JOBS = 256  #: administrative or RPC requests waiting, at most, per worker


class _Worker:
    """A thread running jobs in order; bounded (a job over :data:`MAX_JOBS` is refused)."""

    def __init__(self, name: str) -> None:
        self._jobs: deque[Callable[[], None]] = deque()
        self._cv = threading.Condition()
        self._stop = False
        self.thread = threading.Thread(target=self._run, name=name, daemon=True)
        self.thread.start()

    def submit(self, job: Callable[[], None]) -> bool:
        with self._cv:
            if self._stop or len(self._jobs) >= MAX_JOBS:
                return False
            self._jobs.append(job)
            self._cv.notify()
        return True

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._jobs and not self._stop:
                    self._cv.wait()
                if self._stop:
                    return
                job = self._jobs.popleft()
            try:
                job()
            except Exception:  # noqa: BLE001 - one failing job never ends the worker
                log.exception("YARP %s: a job failed", self.thread.name)

    def stop(self, timeout: float = 5.0) -> None:
        with self._cv:
            self._stop = True
            self._jobs.clear()
            self._cv.notify_all()
        if self.thread is not threading.current_thread():
            self.thread.join(timeout)


def is_loopback(host: str) -> bool:
    try:
        return host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class Network:
    """This process's YARP side (see the module docstring): ``server`` is the name server's
    ``(host, port)`` (None: YARP's configuration), ``host`` where ports listen."""

    def __init__(self, server: tuple[str, int] | None = None, *, host: str = "127.0.0.1", insecure: bool = False,
                 timeout: float = 5.0, limits: PortLimits | None = None) -> None:
        if not insecure and not is_loopback(host):
            raise ValueError(f"host {host}: YARP authenticates no one; ports listen on loopback unless insecure")
        self.names = NameClient(server, timeout)
        self.host = host
        self.insecure = insecure
        self.limits = limits or PortLimits()
        self._ports: dict[str, Port] = {}
        self._wanted: dict[str, dict[str, str]] = {}  # port -> {peer: carrier} it keeps connected
        self._rpc: dict[str, _Worker] = {}
        self._conns: dict[int, Connection] = {}
        self._sel: Poll[Connection | Port | None] = Poll()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._calls: deque[Callable[[], None]] = deque()
        self._lock = threading.Lock()
        self._closed = False
        self._checked = 0.0
        self._round = threading.Event()  # set while a control round is queued or running: one at a time
        self._sel.register(self._wake_r, READ, None)
        self._io = threading.Thread(target=self._run, name="scart-yarp-io", daemon=True)
        self._control = _Worker("scart-yarp-control")
        self._io.start()

    # ---- ports --------------------------------------------------------------------------
    def open_port(self, name: str, *, reader: Callable[[Incoming], object] | None = None,
                  responder: Responder | None = None, queue: int = 1,
                  connect: dict[str, str] | None = None) -> Port:
        """Open ``name``: listen, register it (now — blocking ≤ the name client's timeout —
        or, when the name server does not answer, as soon as it does), and keep connected
        to ``connect`` (``{peer: carrier}``: as a writer, connect to each reader; as a
        reader, ask each writer to connect here). Raises ``ValueError`` for a bad or taken
        name, ``OSError`` when no socket can be had."""
        check_name(name)
        listener = socket.socket(socket.AF_INET6 if ":" in self.host else socket.AF_INET)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((self.host, 0))
        listener.listen(1024)
        listener.setblocking(False)
        port = Port(self, name, listener, reader=reader, responder=responder, queue=queue, limits=self.limits)
        with self._lock:
            if self._closed or name in self._ports:
                listener.close()
                raise ValueError(f"YARP port {name} is open in this process already" if not self._closed else
                                 "the YARP network is closed")
            self._ports[name] = port
            self._wanted[name] = dict(connect or {})
            if responder is not None:
                self._rpc[name] = _Worker(f"scart-yarp-rpc{name}")
        self._call(lambda: self._listen(port))
        self._register(port)  # at once when the name server answers; else the control thread retries
        return port

    def close_port(self, port: Port) -> None:
        """Close ``port`` (see :meth:`Port.close`)."""
        with self._lock:
            if self._ports.get(port.name) is not port:
                return
            del self._ports[port.name]
            self._wanted.pop(port.name, None)
            worker = self._rpc.pop(port.name, None)
        port.closed = True
        if worker is not None:
            worker.stop()
        for target in list(port.outputs):
            port.remove_output(target)
        for conn in port.inputs:
            self.drop(conn, "")
        self._call(lambda: self._unlisten(port))
        if port.registered:
            try:
                self.names.unregister(port.name)
            except OSError as exc:
                log.info("YARP port %s: not unregistered (%s)", port.name, exc)
            port.registered = False

    def _listen(self, port: Port) -> None:
        if not port.closed:
            self._sel.register(port.listener, READ, port)

    def _unlisten(self, port: Port) -> None:
        try:
            self._sel.unregister(port.listener)
        except (KeyError, ValueError):
            pass
        port.listener.close()

    def ports(self) -> dict[str, Port]:
        with self._lock:
            return dict(self._ports)

    # ---- control thread ---------------------------------------------------------------------
    def _register(self, port: Port) -> None:
        if port.closed:
            return
        try:
            self.names.register(port.name, self._advertised(port), port.tcp_port, "tcp")
        except OSError as exc:
            if not port.last_problem:
                log.warning("YARP port %s: waiting for the name server (%s)", port.name, exc)
            port.last_problem = str(exc)
            return
        if port.closed:  # closed meanwhile: leave nothing behind
            self.names.unregister(port.name)
            return
        if port.last_problem:
            log.info("YARP port %s: registered with the name server again", port.name)
        port.registered, port.last_problem = True, ""

    def _advertised(self, port: Port) -> str:
        if port.host not in ("0.0.0.0", "::"):
            return str(port.host)
        return socket.gethostbyname(socket.gethostname())

    def _maintain(self) -> None:
        """The control thread's round: registrations, the connections ports keep."""
        try:
            self._maintain_ports()
        finally:
            self._round.clear()

    def _maintain_ports(self) -> None:
        now = time.monotonic()
        check = now - self._checked >= CHECK_REGISTERED_EVERY
        if check:
            self._checked = now
        for port in self.ports().values():
            if not port.registered:
                self._register(port)
            elif check:
                self._still_registered(port)
            self._keep(port)

    def _still_registered(self, port: Port) -> None:
        try:
            found = self.names.query(port.name)
        except OSError as exc:
            port.registered, port.last_problem = False, str(exc)
            log.warning("YARP port %s: the name server does not answer (%s); waiting", port.name, exc)
            return
        if found is None or found.port != port.tcp_port:
            port.registered = False
            self._register(port)

    def _keep(self, port: Port) -> None:
        with self._lock:
            wanted = dict(self._wanted.get(port.name, {}))
        if not wanted or not port.registered:
            return
        outputs, inputs = port.outputs, {c.peer for c in port.inputs}
        for peer, carrier in wanted.items():
            if port.reader is None and peer not in outputs:
                ok, text = port.add_output(peer, carrier)
            elif port.reader is not None and peer not in inputs:
                ok, text = self._ask_to_connect(peer, port.name, carrier)
            else:
                continue
            if not ok and text != port.last_problem:
                log.info("YARP port %s: %s; retrying", port.name, text)
            port.last_problem = "" if ok else text

    def _ask_to_connect(self, writer: str, reader: str, carrier: str) -> tuple[bool, str]:
        """Ask the port ``writer`` to connect to ``reader`` (``[add]``, as ``yarp connect``)."""
        from .admin import admin_call

        try:
            reply = admin_call(self, writer, ["add", f"{carrier}:/{reader}" if carrier else reader])
        except OSError as exc:
            return False, f"cannot ask {writer} to connect: {exc}"
        ok = bool(reply) and reply[0] == 0
        return ok, str(reply[1]) if len(reply) > 1 else "no answer"

    def wanted(self, port: Port) -> dict[str, str]:
        with self._lock:
            return dict(self._wanted.get(port.name, {}))

    def admin(self, port: Port, conn: Connection, frame: Frame) -> None:
        """An administrative or text command: answered in the control thread."""
        def job() -> None:
            reply = port.command(conn, frame)
            if frame.key == "a":
                port.answer(conn, reply, frame)
            elif conn.text:
                conn.send(("".join(str(line) + "\r\n" for line in reply).encode("utf-8"),), force=True)
                conn.ack()
            else:
                conn.ack()

        if not self._control.submit(job):
            self.drop(conn, "too many administrative requests waiting")

    def request(self, port: Port, conn: Connection, frame: Frame) -> None:
        """A request to an RPC port: answered in that port's thread, in order."""
        worker = self._rpc.get(port.name)
        conn.received += 1

        def job() -> None:
            try:
                values = Incoming(conn.peer, frame.payload, port.limits.bottle).values()
                assert port.responder is not None
                reply = port.responder(values)
            except Exception as exc:  # noqa: BLE001 - the caller gets the failure as its reply
                reply = ["fail", f"{type(exc).__name__}: {exc}"[:1000]]
            port.answer(conn, reply, frame)

        if worker is None or not worker.submit(job):
            port.answer(conn, ["fail", "too many requests waiting"], frame)

    # ---- sockets ------------------------------------------------------------------------
    def connect_to(self, host: str, port: int) -> socket.socket:
        """A TCP connection to a port at ``host:port`` (loopback only unless insecure)."""
        if not self.insecure and not is_loopback(host):
            raise OSError(f"{host} is not loopback: scart's YARP connects to other hosts only when insecure")
        sock = socket.create_connection((host, port), timeout=self.names.timeout)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return sock

    def datagram_to(self, host: str, port: int) -> socket.socket:
        """A datagram socket sending to ``host:port`` (a ``udp`` reader; loopback only unless insecure)."""
        if not self.insecure and not is_loopback(host):
            raise OSError(f"{host} is not loopback: scart's YARP sends to other hosts only when insecure")
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.connect((host, port))
        sock.setblocking(False)
        return sock

    def tell_reader_gone(self, reader: str, writer: str) -> None:
        """Ask the port ``reader`` to drop its (connectionless) input from ``writer``, in
        the control thread (a reader that does not answer keeps it until it restarts)."""
        from .admin import admin_call

        def job() -> None:
            try:
                admin_call(self, reader, ["del", writer])
            except OSError as exc:
                log.info("YARP port %s: %s not told its udp input from it is gone (%s)", writer, reader, exc)

        self._control.submit(job)

    def _to_datagrams(self, conn: Connection) -> None:
        """A writer asked for ``udp``: open a datagram socket, answer its port over TCP,
        close the TCP connection and read the datagrams from now on (io thread)."""
        port = conn.port
        udp = socket.socket(socket.AF_INET6 if ":" in self.host else socket.AF_INET, socket.SOCK_DGRAM)
        udp.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        udp.bind((self.host, 0))
        udp.setblocking(False)
        try:
            conn.sock.send(yarp_number(udp.getsockname()[1]))
        except OSError:
            udp.close()
            self._forget(conn, "")
            return
        self._forget(conn, "")
        dgram = Connection(port, udp, inbound=True, carrier="udp", peer=conn.peer)
        dgram.parser = None
        dgram.dgram = DatagramReader(conn.peer, port.limits.message)
        port.accepted(dgram)
        self._conns[udp.fileno()] = dgram
        self._sel.register(udp, READ, dgram)

    def watch(self, conn: Connection) -> None:
        """Read ``conn`` in the io thread from now on."""
        def add() -> None:
            if conn.closed:
                return
            self._conns[conn.sock.fileno()] = conn
            self._sel.register(conn.sock, READ, conn)
        self._call(add)

    def watch_write(self, conn: Connection) -> None:
        """``conn`` has bytes waiting for room: the io thread sends them when it has."""
        def want() -> None:
            if not conn.closed and not conn.paused and conn.sock.fileno() in self._conns:
                self._events(conn, READ | WRITE)
        self._call(want)

    def read_acks(self, conns: tuple[Connection, ...]) -> None:
        """Read what waits on the outbound ``conns`` now (their acknowledgements), in the io thread."""
        def read() -> None:
            for conn in conns:
                if not conn.closed and self._conns.get(conn.sock.fileno()) is conn:
                    self._read(conn)
        self._call(read)

    def drop(self, conn: Connection, why: str, flush: bool = False) -> None:
        """Close ``conn`` (``why`` logged when said; ``flush``: once what waits is sent,
        within the handshake time)."""
        def close() -> None:
            if flush and not conn.closed:
                try:
                    done = conn.writable()
                except OSError:
                    done = True
                if not done:
                    conn.closing = time.monotonic() + self.limits.handshake
                    return
            self._forget(conn, why)
        self._call(close)

    def _forget(self, conn: Connection, why: str) -> None:
        fd = conn.sock.fileno()
        if fd >= 0 and self._conns.get(fd) is conn:
            del self._conns[fd]
            try:
                self._sel.unregister(conn.sock)
            except (KeyError, ValueError):
                pass
        if conn.held:
            conn.port.counters["dropped"] += len(conn.held)  # held back, and its writer went: not delivered
            conn.held.clear()
        conn.close()
        conn.port.forget(conn)
        if why:
            log.info("YARP port %s: connection %s %s closed: %s", conn.port.name,
                     "from" if conn.inbound else "to", conn.peer or conn.address, why)

    def _call(self, fn: Callable[[], None]) -> None:
        if threading.current_thread() is self._io:
            fn()
            return
        self._calls.append(fn)
        try:
            self._wake_w.send(b"\0")
        except (BlockingIOError, OSError):
            pass  # a wake-up is pending already, or the network is closing

    def _events(self, conn: Connection, events: int) -> None:
        try:
            self._sel.modify(conn.sock, events, conn)
        except (KeyError, ValueError):
            pass

    # ---- the io thread ------------------------------------------------------------------
    def _run(self) -> None:
        next_round = next_check = 0.0
        while not self._closed:
            for data, events in self._sel.select(0.5):
                if data is None:
                    self._woken()
                elif type(data) is Connection:
                    if events == READ:  # a message came: read it at once (the hop's path)
                        if not data.closed:
                            self._read(data)
                    else:
                        self._serve(data, events)
                elif isinstance(data, Port):  # a listener (rare: the hot case is above)
                    self._accept(data)
            now = time.monotonic()
            if now >= next_check:  # not on every message's wake-up: a deadline is seconds long
                next_check = now + 0.25
                self._overdue(now)
            if now >= next_round and not self._round.is_set():  # a slow name server: no rounds pile up
                next_round = now + MAINTAIN_EVERY
                self._round.set()
                if not self._control.submit(self._maintain):
                    self._round.clear()
        for conn in list(self._conns.values()):
            conn.close()

    def _woken(self) -> None:
        try:
            while self._wake_r.recv(4096):
                pass
        except (BlockingIOError, OSError):
            pass
        while self._calls:
            self._calls.popleft()()

    def _accept(self, port: Port) -> None:
        for _ in range(64):  # bounded per wake-up: other ports get their turn
            try:
                sock, _addr = port.listener.accept()
            except (BlockingIOError, OSError):
                return
            sock.setblocking(False)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn = Connection(port, sock, inbound=True)
            if len(port.inputs) >= self.limits.inputs:
                port.counters["refused_connections"] += 1
                self._say_once(port, f"{self.limits.inputs} connections open: refusing more")
                sock.close()
                continue
            port.accepted(conn)
            self._conns[sock.fileno()] = conn
            self._sel.register(sock, READ, conn)
            self._evict_strangers(port)

    def _evict_strangers(self, port: Port) -> None:
        with port._lock:  # noqa: SLF001 - the port's own list, under its lock
            strangers = [c for c in port._inputs if not c.greeted]  # noqa: SLF001
        for conn in strangers[:max(0, len(strangers) - self.limits.strangers)]:
            port.counters["strangers_closed"] += 1
            self._say_once(port, f"over {self.limits.strangers} connections that have not said who they are: "
                                 "closing the oldest")
            self._forget(conn, "")

    def _overdue(self, now: float) -> None:
        """Close connections that did not say who they are within the handshake time, and
        those closing whose last bytes could not leave in that time."""
        limit = now - self.limits.handshake
        for conn in [c for c in self._conns.values() if (not c.greeted and c.opened < limit)
                     or (c.closing and c.closing < now)]:
            if not conn.greeted:
                conn.port.counters["strangers_closed"] += 1
                self._say_once(conn.port, f"connections that said nothing for {self.limits.handshake:g} s "
                                          "closed")
            self._forget(conn, "")

    @staticmethod
    def _say_once(port: Port, text: str) -> None:
        port.say(text)

    def _serve(self, conn: Connection, events: int) -> None:
        if events & WRITE:
            try:
                done = conn.writable()
            except OSError as exc:
                self._forget(conn, f"send failed: {exc}")
                return
            if done:
                if conn.closing:
                    self._forget(conn, "")
                    return
                self._events(conn, READ)
            conn.port.progressed()
        if events & READ and not conn.closed:
            self._read(conn)

    def _read(self, conn: Connection) -> None:
        port = conn.port
        try:
            frames = conn.readable()
        except ProtocolError as exc:
            port.counters["protocol_errors"] += 1
            who = conn.peer or (conn.parser.sender if conn.parser is not None else "") or conn.address
            self._say_once(port, f"{who} broke the protocol ({exc}): its connection closed")
            if not conn.greeted:
                try:
                    conn.sock.send(b"* Error. Protocol not found.\r\n* Hello. You appear to be trying to communicate "
                                   b"with a YARP Port.\r\n* Goodbye.\r\n")
                except OSError:
                    pass
            self._forget(conn, "")
            return
        if frames is None:
            self._forget(conn, "")
            return
        if not conn.inbound:
            port.progressed()
            return
        if conn.carrier == "udp" and conn.dgram is None:
            self._to_datagrams(conn)
            return
        for frame in frames:
            if conn.closed:
                return
            if conn.held or not port.handle(conn, frame):
                conn.held.append(frame)  # in order: once one is held, the later ones wait behind it
        if conn.held and not conn.paused:
            self._pause(conn)

    def _pause(self, conn: Connection) -> None:
        """Stop reading ``conn``: its writer waits (its socket fills, or its acknowledgement does not come)."""
        conn.paused = True
        try:
            self._sel.unregister(conn.sock)
        except (KeyError, ValueError):
            pass

    def resume(self, port: Port) -> None:
        """Hand ``port``'s held messages over again, and read their connections again once
        none is left (thread-safe: done in the io thread)."""
        def again() -> None:
            for conn in [c for c in self._conns.values() if c.port is port and c.paused and not c.closed]:
                while conn.held and port.handle(conn, conn.held[0]):
                    conn.held.popleft()
                if not conn.held:
                    conn.paused = False
                    events = READ | (WRITE if conn.sending else 0)
                    self._sel.register(conn.sock, events, conn)
        self._call(again)

    # ---- the end ------------------------------------------------------------------------
    def close(self) -> None:
        """Close every port (each says ``q`` and unregisters), then the threads (each
        joined, ≤ a few seconds). Idempotent."""
        for port in list(self.ports().values()):
            port.close()
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._call(lambda: None)
        self._io.join(5.0)
        self._control.stop()
        self._sel.close()
        self._wake_r.close()
        self._wake_w.close()
