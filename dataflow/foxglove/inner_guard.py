"""Only this process's gate may reach the server behind it (the Foxglove SDK's, which
cannot check who connects): a classic BPF socket filter on that server's listening socket.

Why a filter: the SDK listens on a TCP port (it takes no socket, no Unix path, no peer
check), and any local user reads every listening address from ``/proc/net/tcp``, so a
random loopback address hides nothing. The kernel runs a socket's filter on every packet
that socket receives — for a listening socket, on each connection request (SYN), before
the TCP handshake — and a connection accepted from it inherits the filter. The filter
here lets through only packets from ``127.0.0.1`` and a source port the gate is using
right now: the gate binds each of its outbound sockets first, names that port to the
guard (:meth:`InnerGuard.allow`), then connects, and forgets the port before it closes
the socket. No other user can send from that address and port while the gate holds it
(binding it fails, ``EADDRINUSE``: the gate's socket has no ``SO_REUSEADDR``), and after
it is closed the port is no longer let through. Anything else is dropped unanswered: a
direct connection never gets past its SYN. Root (raw packets) is out of scope, as in the
threat model.

The filter is attached once the server listens, so a connection could slip in before:
:meth:`InnerGuard.start` then finds it in ``/proc/net/tcp`` and raises
:class:`GuardError`, and the caller starts its server again on another address.

Linux only (socket filters, ``/proc``): elsewhere :meth:`InnerGuard.start` raises
:class:`GuardError`. Thread-safe; :meth:`close` is idempotent.
"""

from __future__ import annotations

import ctypes
import os
import socket
import stat
import struct
import sys
import threading

__all__ = ["GuardError", "InnerGuard"]

SO_ATTACH_FILTER = getattr(socket, "SO_ATTACH_FILTER", 26)
SKF_NET_OFF = -0x100000  # classic BPF: offsets from the network (IP) header
MAX_ALLOWED = 200  #: source ports let through at once (a conditional jump reaches at most 255 ahead)
_GATE_HOST = "127.0.0.1"  # where the gate's outbound sockets are bound
_LISTEN = "0A"  # TCP_LISTEN in /proc/net/tcp


class GuardError(OSError):
    """The guard cannot keep the server private (not Linux, no listening socket found, a
    connection that came before the filter)."""


def _insn(code: int, jt: int, jf: int, k: int) -> bytes:
    return struct.pack("HBBI", code, jt, jf, k & 0xFFFFFFFF)


def _program(host: str, ports: list[int]) -> bytes:
    """The filter: accept packets from ``host`` and one of ``ports``; drop all others."""
    ld_w_abs, ld_h_abs, jeq_k, ret_k = 0x20, 0x28, 0x15, 0x06
    n = len(ports)
    ip = struct.unpack(">I", socket.inet_aton(host))[0]
    code = [_insn(ld_w_abs, 0, 0, SKF_NET_OFF + 12),  # the IPv4 source address
            _insn(jeq_k, 0, n + 1, ip),
            _insn(ld_h_abs, 0, 0, 0)]  # the TCP source port (the packet's data starts at the TCP header)
    code += [_insn(jeq_k, n - i, 0, port) for i, port in enumerate(ports)]
    code += [_insn(ret_k, 0, 0, 0), _insn(ret_k, 0, 0, 0xFFFFFFFF)]  # drop, accept
    return b"".join(code)


def _proc_net_address(host: str, port: int) -> str:
    """``host:port`` as ``/proc/net/tcp`` prints a local address (``0100007F:1F90``)."""
    return f"{struct.unpack('=I', socket.inet_aton(host))[0]:08X}:{port:04X}"


class InnerGuard:
    """Keeps the TCP server listening at ``address`` (a loopback IPv4 ``(host, port)`` of
    this process) reachable only from the ports :meth:`allow` names (see the module
    docstring). ``start()`` once the server listens; :meth:`connect_from` gives the gate a
    socket to connect with."""

    def __init__(self, address: tuple[str, int]) -> None:
        self.address = address
        self._ports: list[int] = []
        self._listener: socket.socket | None = None
        self._lock = threading.Lock()

    def start(self) -> None:
        """Attach the filter (nothing let through yet) to the server's listening socket.
        Raises :class:`GuardError` when it cannot, or when a connection came first."""
        if not sys.platform.startswith("linux"):
            raise GuardError("keeping the server behind the gate private needs Linux (socket filters)")
        listener = self._find_listener()
        self._listener = listener
        self._attach()
        early = self._connections()
        if early:
            raise GuardError(f"{early} connection(s) reached {self.address[0]}:{self.address[1]} before its guard")

    def bound_socket(self) -> socket.socket:
        """A socket bound to a port of its own, let through the filter (non-blocking, to
        connect to the server). :meth:`forget` its port before closing it."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            sock.bind((_GATE_HOST, 0))  # no SO_REUSEADDR: nobody else may bind this port while we hold it
            sock.setblocking(False)
            self.allow(sock.getsockname()[1])
        except BaseException:
            sock.close()
            raise
        return sock

    def allow(self, port: int) -> None:
        """Let packets from ``port`` (of 127.0.0.1) through. Raises :class:`GuardError` past
        :data:`MAX_ALLOWED` ports."""
        with self._lock:
            if len(self._ports) >= MAX_ALLOWED:
                raise GuardError(f"more than {MAX_ALLOWED} connections to the server behind the gate")
            self._ports.append(port)
            self._attach()

    def forget(self, port: int) -> None:
        """Stop letting packets from ``port`` through (idempotent)."""
        with self._lock:
            if port in self._ports:
                self._ports.remove(port)
                self._attach()

    def close(self) -> None:
        """Let nothing through any more and drop the listener's handle (idempotent)."""
        with self._lock:
            self._ports.clear()
            listener, self._listener = self._listener, None
        if listener is not None:
            listener.close()  # a duplicate: the server's own socket stays open until it stops

    def _attach(self) -> None:
        listener = self._listener
        if listener is None:
            return
        program = ctypes.create_string_buffer(_program(_GATE_HOST, list(self._ports)))
        fprog = struct.pack("HP", len(program.raw) // 8, ctypes.addressof(program))
        try:
            listener.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER, fprog)  # the kernel copies the program
        except OSError as exc:
            raise GuardError(f"cannot filter {self.address[0]}:{self.address[1]}: {exc.strerror or exc}") from None

    def _find_listener(self) -> socket.socket:
        """A duplicate of this process's socket listening at ``address``."""
        try:
            fds = [int(name) for name in os.listdir("/proc/self/fd")]
        except OSError as exc:
            raise GuardError(f"cannot list this process's sockets: {exc.strerror or exc}") from None
        for fd in fds:
            try:
                if not stat.S_ISSOCK(os.fstat(fd).st_mode):
                    continue
                sock = socket.socket(fileno=os.dup(fd))
            except OSError:  # closed meanwhile, or not ours to use
                continue
            try:
                if sock.family == socket.AF_INET and sock.getsockname() == self.address and \
                        sock.getsockopt(socket.SOL_SOCKET, socket.SO_ACCEPTCONN):
                    return sock
            except OSError:
                pass
            sock.close()
        raise GuardError(f"no socket of this process listens at {self.address[0]}:{self.address[1]}")

    def _connections(self) -> int:
        """How many TCP connections (not the listener) have the server's address as theirs."""
        local = _proc_net_address(*self.address)
        try:
            with open("/proc/net/tcp", encoding="ascii") as fh:
                rows = [line.split() for line in fh.readlines()[1:100_001]]
        except OSError as exc:
            raise GuardError(f"cannot read /proc/net/tcp: {exc.strerror or exc}") from None
        return sum(1 for row in rows if len(row) > 3 and row[1] == local and row[3] != _LISTEN)
