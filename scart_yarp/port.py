"""A YARP port: a name registered with the name server, a TCP socket every other port
may connect to, the connections it writes to and those it reads from — what a
``yarp::os::Port`` is, on the wire.

A port answers what a YARP port answers: data (``d``/``D``) for its owner's ``reader``,
or a request for its ``responder`` (an RPC port: the reply goes back on the same
connection); administrative bottles (``[add]``, ``[del]``, ``[list] [in|out]``, ``[ver]``,
``[help]``: what ``yarp connect``, ``yarp disconnect`` and ``yarp ping`` send); and the
text commands of a ``CONNECT`` session (``/port``, ``!/port``, ``~/port``, ``*``, ``?``,
``q``). It writes to every connection it has (:meth:`Port.write`), never blocking: a
connection whose reader is behind holds at most ``queue`` messages, then drops (counted).

Made by :meth:`scart_yarp.Network.open_port`; closed by :meth:`Port.close` (it says ``q``
to its readers, closes its sockets and unregisters its name).
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeAlias

from . import bottle
from .bottle import BottleError, Item, Vocab
from .connection import Connection
from .dgram import datagrams
from .wire import _DATA_COMMAND, _DATA_HEAD, _DATA_LENGTHS, QUIT_BINARY, Frame, carrier_header, data_parts, \
    read_number, sender_specifier

if TYPE_CHECKING:
    from .network import Network

__all__ = ["Incoming", "Port", "PortLimits"]

log = logging.getLogger("scart_yarp")

SAY_AGAIN_S = 60.0  #: seconds before a problem already logged is logged again

HELP = ("This is a YARP port.  Here are the commands it responds to:", "*       Gives a description of this port",
        "d       Signals the beginning of input for the port's owner", "q       Disconnects",
        "/port   Requests to send output to /port", "!/port  Requests to stop sending output to /port",
        "~/port  Requests to stop receiving input from /port", "?       Gives this help")


@dataclass(frozen=True)
class PortLimits:
    """What a port takes from peers, at most: ``message`` bytes per message, ``inputs``
    connections that have said who they are, ``strangers`` connections that have not
    (yet), each for ``handshake`` seconds; ``bottle``: what one bottle may hold."""

    message: int = 64 << 20
    inputs: int = 128
    strangers: int = 16
    handshake: float = 5.0
    bottle: bottle.Limits = bottle.DEFAULT_LIMITS


#: An RPC port's answer to a request: the request's values in, the reply's out (None: no reply).
Responder: TypeAlias = "Callable[[list[Item]], Sequence[object] | None]"


class Incoming:
    """A message for a port's owner: who sent it (``source``, a port name), and its
    bottle, decoded when asked (:meth:`values` raises :class:`BottleError` for a
    malformed one)."""

    __slots__ = ("source", "payload", "limits")

    def __init__(self, source: str, payload: bytes | str, limits: bottle.Limits) -> None:
        self.source = source
        self.payload = payload
        self.limits = limits

    def values(self) -> list[Item]:
        if isinstance(self.payload, str):
            return bottle.from_text(self.payload, self.limits)
        return bottle.decode(self.payload, self.limits)


class Port:
    """A YARP port of ``network`` (see the module docstring). ``reader(Incoming)`` is
    called in the io thread for each data message (keep it short; returning False holds
    the message back until :meth:`resume`); ``responder(values)
    -> values`` answers requests in the port's own thread (an RPC port). Thread-safe."""

    def __init__(self, network: Network, name: str, listener: socket.socket, *,
                 reader: Callable[[Incoming], object] | None, responder: Responder | None,
                 queue: int, limits: PortLimits) -> None:
        self.network = network
        self.name = name
        self.listener = listener
        self.host, self.tcp_port = listener.getsockname()[:2]
        self.reader = reader
        self.responder = responder
        self.queue = queue
        self.limits = limits
        self.registered = False
        self.closed = False
        self.counters = {"refused_connections": 0, "protocol_errors": 0, "dropped": 0, "strangers_closed": 0,
                         "reader_errors": 0}
        self.last_problem = ""
        self._said: dict[str, float] = {}
        self._outputs: dict[str, Connection] = {}
        #: The connections it writes to (``_outputs``' values), replaced whole: a writer reads it unlocked.
        self.writers: tuple[Connection, ...] = ()
        self._inputs: list[Connection] = []
        self._lock = threading.Lock()
        self._done = threading.Condition(self._lock)  # notified when a write is sent or acknowledged
        self._waiters = 0  # threads in wait_sent (under the lock)

    # ---- writing ------------------------------------------------------------------------
    @property
    def has_outputs(self) -> bool:
        """It writes to at least one reader now (no lock: a hint for the hot path)."""
        return bool(self.writers)

    @property
    def outputs(self) -> dict[str, Connection]:
        with self._lock:
            return dict(self._outputs)

    @property
    def inputs(self) -> list[Connection]:
        with self._lock:
            return [c for c in self._inputs if c.greeted and not c.closed]

    def write(self, values: Sequence[object] | None = None, *, binary: bytes | None = None) -> int:
        """Send one bottle (``values``, or its ``binary`` form already encoded) to every
        reader, never blocking; how many connections took it (the others were behind:
        counted in their ``dropped``). Raises :class:`BottleError` for values with no
        bottle form."""
        outputs = self.writers
        if not outputs:
            return 0
        data = binary if binary is not None else bottle.encode(values or [])
        if len(outputs) == 1 and outputs[0].kind == "binary":  # the common case: one tcp reader (data_parts, inline)
            if outputs[0].send((_DATA_HEAD + _DATA_LENGTHS.pack(8, len(data), 0) + _DATA_COMMAND, data)):
                return 1
            self.counters["dropped"] += 1
            return 0
        frames: dict[str, list[bytes] | tuple[bytes, ...]] = {}
        taken = 0
        for conn in outputs:
            kind = conn.kind
            frame = frames.get(kind)
            if frame is None:
                frame = frames[kind] = self._frame(kind, data, values)
            if conn.send_datagrams(frame) if kind == "udp" else conn.send(frame):
                taken += 1
            else:
                self.counters["dropped"] += 1
        return taken

    @staticmethod
    def _frame(kind: str, data: bytes, values: Sequence[object] | None) -> list[bytes] | tuple[bytes, ...]:
        if kind == "text":
            text = bottle.to_text(values if values is not None else bottle.decode(data))
            return [f"d\r\n{text}\r\n".encode("utf-8")]
        parts = data_parts(data)
        return datagrams(list(parts)) if kind == "udp" else parts

    def wait_sent(self, timeout: float) -> bool:
        """Block until every connection has sent (tcp: had acknowledged) what was written
        to it, ≤ ``timeout`` s; False on timeout. YARP's *wait-after* and, called before a
        write, *wait-before*."""
        deadline = time.monotonic() + timeout
        with self._done:
            self._waiters += 1
            first = self._waiters == 1
            if first:  # each acknowledgement counts now: have each wake the io thread
                for conn in self.writers:
                    conn.batch_acks(False)
        try:
            if first:
                self.network.read_acks(self.writers)  # and read those that piled up (not under the lock)
            with self._done:
                while not all(c.idle or c.closed for c in self._outputs.values()):
                    left = deadline - time.monotonic()
                    if left <= 0:
                        return False
                    self._done.wait(left)
            return True
        finally:
            with self._done:
                self._waiters -= 1
                if not self._waiters:
                    for conn in self.writers:
                        conn.batch_acks(True)

    def progressed(self) -> None:
        """A connection sent or had acknowledged a message (the io thread). A waiter
        counts itself in before it looks, so one that comes after this read sees the
        progress itself."""
        if self._waiters:
            with self._done:
                self._done.notify_all()

    # ---- connections --------------------------------------------------------------------
    def add_output(self, target: str, carrier: str = "") -> tuple[bool, str]:
        """Connect to the port ``target`` (``/name`` or ``carrier://name``) and write to it
        from now on (blocks ≤ the network's timeout: a name query, a connection and its
        greeting). ``(True, "Added connection from ...")`` or ``(False, why)``, as YARP words it."""
        if ":/" in target:
            carrier, target = target.split(":/", 1)
        if self.closed:
            return False, f"port {self.name} is closed"
        try:
            contact = self.network.names.query(target)
        except OSError as exc:
            return False, f"Do not know how to connect to {target} ({exc})"
        if contact is None:
            return False, f"Do not know how to connect to {target}"
        carrier = carrier or (contact.carrier if contact.carrier in ("tcp", "fast_tcp", "text", "udp") else "tcp")
        try:
            sock = self.network.connect_to(contact.host, contact.port)
            answer = self._greet(sock, carrier)
            if carrier == "udp":  # agreed over TCP; the messages go as datagrams to the port it answered
                sock.close()
                sock = self.network.datagram_to(contact.host, answer)
        except (OSError, ValueError) as exc:
            return False, f"Cannot connect to {target}: {exc}"
        conn = Connection(self, sock, inbound=False, carrier=carrier, peer=target, queue=self.queue)
        with self._lock:
            old = self._outputs.pop(target, None)
            self._outputs[target] = conn
            self.writers = tuple(self._outputs.values())
            if self._waiters:
                conn.batch_acks(False)
        if old is not None:
            self._quit(old)
        self.network.watch(conn)
        log.info("YARP port %s: output to %s (%s)", self.name, target, carrier)
        return True, f"Added connection from {self.name} to {target}"

    def _greet(self, sock: socket.socket, carrier: str) -> int:
        """Open a connection as ``carrier`` and read the reader's answer (blocking,
        bounded); the number a binary carrier's reader answered (udp: its datagram port)."""
        sock.settimeout(self.network.names.timeout)
        if carrier.startswith("text"):
            sock.sendall(carrier_header(carrier) + self.name.encode() + b"\r\n")
            answer = b""
            while not answer.endswith(b"\n"):
                chunk = sock.recv(1)
                if not chunk or len(answer) > 1024:
                    raise OSError("no welcome from the reader")
                answer += chunk
        else:
            sock.sendall(carrier_header(carrier) + sender_specifier(self.name))
            answer = b""
            while len(answer) < 8:
                chunk = sock.recv(8 - len(answer))
                if not chunk:
                    raise OSError("the reader closed the connection at its greeting")
                answer += chunk
            number = read_number(answer)
            if number is None:
                raise OSError(f"the reader answered {answer!r}, not a YARP greeting")
            sock.setblocking(False)
            return number
        sock.setblocking(False)
        return 0

    def remove_output(self, target: str) -> bool:
        """Stop writing to ``target`` (``q`` said, socket closed; on ``udp``, which has no
        connection to say it on, the reader is asked to drop its input, as YARP does);
        False when not connected."""
        with self._lock:
            conn = self._outputs.pop(target, None)
            self.writers = tuple(self._outputs.values())
        if conn is None:
            return False
        if conn.datagrams:
            self.network.drop(conn, "")
            self.network.tell_reader_gone(target, self.name)
        else:
            self._quit(conn)
        return True

    def remove_input(self, source: str) -> bool:
        """Close the connection from ``source``; False when there is none."""
        found = [c for c in self.inputs if c.peer == source]
        for conn in found:
            self.network.drop(conn, f"{source} disconnected by request")
        return bool(found)

    def _quit(self, conn: Connection) -> None:
        conn.send((b"q\r\n",) if conn.text else (QUIT_BINARY,), force=True)
        self.network.drop(conn, "", flush=True)

    def accepted(self, conn: Connection) -> None:
        with self._lock:
            self._inputs.append(conn)

    def forget(self, conn: Connection) -> None:
        """``conn`` is gone (io thread)."""
        with self._lock:
            if conn in self._inputs:
                self._inputs.remove(conn)
            for name, out in list(self._outputs.items()):
                if out is conn:
                    del self._outputs[name]
            self.writers = tuple(self._outputs.values())
        self.progressed()

    def say(self, text: str) -> None:
        """Log a problem once (again only after :data:`SAY_AGAIN_S` s): a flood of alike
        problems is one line."""
        now = time.monotonic()
        if now - self._said.get(text, -SAY_AGAIN_S) < SAY_AGAIN_S:
            return
        if len(self._said) > 64:
            self._said.clear()
        self._said[text] = now
        self.last_problem = text
        log.warning("YARP port %s: %s", self.name, text)

    def resume(self) -> None:
        """The owner has room again: what was held back is handed over (in order) and the
        held connections are read again (thread-safe; see :meth:`handle`)."""
        self.network.resume(self)

    # ---- what comes in (io thread) ------------------------------------------------------
    def handle(self, conn: Connection, frame: Frame) -> bool:
        """One message from ``conn``; False when the owner's ``reader`` returned False
        (no room now): the message is then held, unacknowledged, and the connection is
        not read until :meth:`resume` — so a writer waiting for its acknowledgement waits
        for the reader (YARP's flow control)."""
        key = frame.key
        if key == "D" or key == "d":
            if self.responder is not None:
                self.network.request(self, conn, frame)
                return True
            if self.reader is not None:
                try:
                    if self.reader(Incoming(conn.peer, frame.payload, self.limits.bottle)) is False:
                        return False
                except Exception as exc:  # noqa: BLE001 - the owner's failure never ends the connection
                    self.counters["reader_errors"] += 1
                    self.say(f"its reader failed: {type(exc).__name__}: {exc}"[:300])
            conn.received += 1
            conn.ack()
        elif key == "q":
            self.network.drop(conn, "")
        else:
            self.network.admin(self, conn, frame)
        return True

    def answer(self, conn: Connection, reply: Sequence[object] | None, frame: Frame) -> None:
        """Send ``reply`` (or nothing) for ``frame`` back on ``conn``, then its acknowledgement."""
        if reply is not None and frame.key != "D":
            if conn.text:
                conn.send((bottle.to_text(reply).encode("utf-8") + b"\r\n",), force=True)
            else:
                conn.send((bottle.encode(reply),), force=True)
        conn.ack()

    def command(self, conn: Connection, frame: Frame) -> Sequence[Item] | list[str]:
        """An administrative bottle (``a``) or a text command; its reply."""
        if frame.key != "a":
            return self._text_command(frame.text)
        try:
            cmd = bottle.from_text(frame.payload) if isinstance(frame.payload, str) else bottle.decode(frame.payload)
        except BottleError as exc:
            return [Vocab("fail"), f"malformed administrative bottle: {exc}"]
        words = [w.text if isinstance(w, Vocab) else w for w in cmd]
        verb = words[0] if words else ""
        if verb == "add" and len(words) >= 2:
            ok, text = self.add_output(str(words[1]), str(words[2]) if len(words) > 2 else "")
            return [0 if ok else -1, text]
        if verb == "del" and len(words) >= 2:
            out, inp = self.remove_output(str(words[1])), self.remove_input(str(words[1]))
            name = str(words[1])
            text = (f"Removed connection from {self.name} to {name}" if out else
                    f"Removing connection from {name} to {self.name}" if inp else
                    f"Could not find an outgoing connection to {name}Could not find an incoming connection from {name}")
            return [0 if out or inp else -1, text]
        if verb == "list" and len(words) >= 2:
            return self._list(str(words[1]), str(words[2]) if len(words) > 2 else "")
        if verb == "ver":
            return [Vocab("ver"), 1, 2, 3]
        if verb == "help":
            return [Vocab("many"), "[help]", "[ver]", "[add] $portname", "[del] $portname", "[list] [in]",
                    "[list] [out]"]
        return [Vocab("fail"), f"unknown administrative command {bottle.to_text(cmd)[:80]}"]

    def _list(self, direction: str, target: str) -> list[Item]:
        conns = self.inputs if direction == "in" else list(self.outputs.values())
        if not target:
            return [c.peer for c in conns]
        for c in conns:
            if c.peer == target:
                src, dst = (c.peer, self.name) if direction == "in" else (self.name, c.peer)
                return [["from", src], ["to", dst], ["carrier", c.carrier]]
        return []

    def _text_command(self, text: str) -> list[str]:
        if text.startswith("/"):
            return [self.add_output(text)[1]]
        if text.startswith("!"):
            ok = self.remove_output(text[1:])
            return [f"Removed connection from {self.name} to {text[1:]}" if ok else
                    f"Could not find an outgoing connection to {text[1:]}"]
        if text.startswith("~"):
            ok = self.remove_input(text[1:])
            return [f"Removing connection from {text[1:]} to {self.name}" if ok else
                    f"Could not find an incoming connection from {text[1:]}"]
        if text.startswith("*"):
            return self.describe()
        if text[:1] in ("?", "h"):
            return list(HELP)
        return ["Port command not understood.", "Type d to send data to the port's owner.", "Type ? for help."]

    def describe(self) -> list[str]:
        """What ``*`` answers: the port, its outputs and inputs."""
        lines = [f"This is {self.name} at tcp://{self.host}:{self.tcp_port}/"]
        outs, ins = self.outputs, self.inputs
        lines += [f"There is an output connection from {self.name} to {n} using {c.carrier}" for n, c in outs.items()]
        lines += [f"There is an input connection from {c.peer} to {self.name} using {c.carrier}" for c in ins]
        if not outs and not ins:
            lines.append("There are no connections")
        return lines

    def close(self) -> None:
        """Say ``q`` to every reader, close every connection and the socket, unregister
        the name (blocks ≤ the name server's timeout). Idempotent."""
        self.network.close_port(self)
