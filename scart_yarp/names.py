"""YARP's name server, from the client's side: where it is (YARP's own configuration, as
``yarp conf`` writes it) and what it is asked (``register``, ``unregister``, ``query``,
``list``), in the name server's own line protocol (``NAME_SERVER query /r``), as YARP's
``NameClient`` speaks it (the server answers it also when many ask at once).

Where the server is, as YARP 3.5 finds it (``NameConfig``): the namespace is
``YARP_NAMESPACE``, else the first word of ``yarp_namespace.conf``, else ``/root``; its
file is ``yarp.conf`` for ``/root``, else the namespace made safe (``/my ns`` →
``_my_ns.conf``), in ``YARP_CONFIG_HOME``, else ``$XDG_CONFIG_HOME/yarp``, else
``~/.config/yarp``; the file's first line is ``HOST PORT yarp``.

Every call opens one connection, sends one command and reads the reply with a deadline
(blocking; thread-safe: a client's calls go one at a time).
"""

from __future__ import annotations

import os
import re
import socket
import threading
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Contact", "NameClient", "NameServerError", "config_dir", "name_server_address", "namespace",
           "parse_address"]

MAX_REPLY = 1 << 20  #: bytes of a name server's reply, at most
ATTEMPTS = 6  #: tries of one command when the server drops the connection (it is busy)
_NAME = re.compile(r"/[^\s\"]{0,255}")
_REGISTRATION = re.compile(r"registration name (\S+) ip (\S+) port (\d+) type (\S+)")


class NameServerError(OSError):
    """The name server cannot be found, reached, or did what was asked."""


class _Dropped(OSError):
    """The server closed a connection before answering (it was busy): tried again."""


@dataclass(frozen=True)
class Contact:
    """A registered port: its name, host, TCP port and carrier (as ``yarp name query`` says)."""

    name: str
    host: str
    port: int
    carrier: str = "tcp"


def check_name(name: str) -> str:
    """``name`` if it is a YARP port name (``/`` then up to 255 characters, no space or
    quote); raises ``ValueError`` otherwise."""
    if not _NAME.fullmatch(name):
        raise ValueError(f"YARP port name {name[:60]!r}: '/' then at most 255 characters, no space or quote")
    return name


def config_dir() -> Path:
    """Where YARP keeps its configuration (``YARP_CONFIG_HOME``, else XDG's, else ``~/.config/yarp``)."""
    if os.environ.get("YARP_CONFIG_HOME"):
        return Path(os.environ["YARP_CONFIG_HOME"])
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "yarp"


def namespace() -> str:
    """The YARP namespace of this process (``/root`` unless told otherwise)."""
    text = os.environ.get("YARP_NAMESPACE", "")
    if not text:
        try:
            text = (config_dir() / "yarp_namespace.conf").read_text(encoding="utf-8", errors="replace")[:4096]
        except OSError:
            text = ""
    words = text.split()
    return words[0] if words else "/root"


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (or ``HOST PORT``) as a pair; raises ``ValueError`` saying the form."""
    host, sep, port = text.strip().rpartition(":")
    if not sep:
        host, _, port = text.strip().partition(" ")
    if not host or not port.strip().isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"a YARP name server address is HOST:PORT, got {text[:80]!r}")
    return host.strip(), int(port)


def name_server_address() -> tuple[str, int]:
    """The name server's address from YARP's configuration; :class:`NameServerError`
    saying which file was read when there is none (run ``yarp conf HOST PORT``)."""
    ns = namespace()
    stem = "yarp" if ns == "/root" else re.sub(r"[^0-9A-Za-z]", "_", ns)
    path = config_dir() / f"{stem}.conf"
    try:
        words = path.read_text(encoding="utf-8", errors="replace")[:4096].split()
        return parse_address(f"{words[0]}:{words[1]}")
    except (OSError, IndexError, ValueError):
        raise NameServerError(f"no YARP name server is configured in {path} (run `yarp conf HOST PORT`, or give "
                              "the server as HOST:PORT)") from None


class NameClient:
    """Asks one name server (``address``; None: YARP's configuration, read at each call so
    that a ``yarp conf`` meanwhile is seen). ``timeout``: seconds per call."""

    def __init__(self, address: tuple[str, int] | None = None, timeout: float = 5.0) -> None:
        self._address = address
        self.timeout = timeout
        self._lock = threading.Lock()

    @property
    def address(self) -> tuple[str, int]:
        return self._address if self._address is not None else name_server_address()

    def register(self, name: str, host: str, port: int, carrier: str = "tcp") -> Contact:
        """Register ``name`` at ``host:port`` for ``carrier``; returns what the server stored."""
        found = self._registrations(self.command(f"register {check_name(name)} {carrier} {host} {port}"))
        if not found or found[0].name != name:
            raise NameServerError(f"the YARP name server at {self._where()} did not register {name}")
        return found[0]

    def unregister(self, name: str) -> None:
        """Forget ``name`` (nothing when it is not registered)."""
        self.command(f"unregister {check_name(name)}")

    def query(self, name: str) -> Contact | None:
        """Where ``name`` is, or None when it is not registered."""
        found = self._registrations(self.command(f"query {check_name(name)}"))
        return found[0] if found else None

    def registrations(self) -> list[Contact]:
        """Every registration the server has (``yarp name list``)."""
        return self._registrations(self.command("list"))

    def command(self, text: str) -> str:
        """Send one command line; the reply's lines up to ``*** end of message`` (blocks ≤
        timeout). ``yarpserver`` drops connections when several come at once: a dropped
        one is tried again (≤ :data:`ATTEMPTS` times, backing off), as YARP's own client does."""
        host, port = self.address
        deadline = time.monotonic() + self.timeout
        with self._lock:  # one at a time from this client: the server serves one at a time
            for attempt in range(ATTEMPTS):
                try:
                    with socket.create_connection((host, port), timeout=max(0.01, deadline - time.monotonic())) as sock:
                        sock.sendall(b"NAME_SERVER " + text.encode("utf-8") + b"\n")
                        return self._reply(sock, deadline)
                except (ConnectionResetError, _Dropped) as exc:
                    if attempt == ATTEMPTS - 1 or time.monotonic() + 0.05 * 2 ** attempt >= deadline:
                        raise NameServerError(f"the YARP name server at {host}:{port} does not answer: {exc}") \
                            from None
                    time.sleep(0.05 * 2 ** attempt)  # then again, as the server frees up
                except OSError as exc:
                    raise NameServerError(f"the YARP name server at {host}:{port} does not answer: {exc}") from None
        raise AssertionError("unreachable")

    @staticmethod
    def _reply(sock: socket.socket, deadline: float) -> str:
        data = b""
        while b"*** end of message" not in data:
            left = deadline - time.monotonic()
            if left <= 0 or len(data) > MAX_REPLY:
                raise OSError("no whole reply in time" if left <= 0 else f"a reply over {MAX_REPLY} bytes")
            sock.settimeout(left)
            chunk = sock.recv(65536)
            if not chunk:
                raise _Dropped("the connection closed before the reply ended")
            data += chunk
        return data.decode("utf-8", errors="replace")

    @staticmethod
    def _registrations(reply: str) -> list[Contact]:
        return [Contact(m[1], m[2], int(m[3]), m[4]) for m in _REGISTRATION.finditer(reply)]

    def _where(self) -> str:
        try:
            host, port = self.address
        except NameServerError:
            return "(not configured)"
        return f"{host}:{port}"
