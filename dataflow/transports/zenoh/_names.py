"""Finding deployers and ports on Zenoh, without a scart name service (private to
:mod:`dataflow.transports.zenoh`, which re-exports what is public here)."""

from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING, Any
from urllib.parse import unquote

from dataflow.remote.security import is_loopback
from dataflow.transports.zenoh._keys import _WORD, DEFAULT_NS, MAX_REPLIES, ROOT, SERVED, key_of

if TYPE_CHECKING:
    from dataflow.remote._registry import NameEntry
    from dataflow.remote.client import GrpcSystem
    from dataflow.remote.security import Security

__all__ = ["ZenohNames", "connect_zenoh", "discover"]

log = logging.getLogger("dataflow.transports.zenoh")


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
    name service (:func:`connect_zenoh`). Tokens come from any Zenoh peer: an address
    that is not loopback is ignored unless ``insecure`` (the system would send its token
    there), as is anything malformed, and a component announced by more than one deployer
    is not used until only one announces it (a spoofed or a stale announcement). Each is
    logged once. The session stays the caller's.
    """

    def __init__(self, session: Any, ns: str = DEFAULT_NS, timeout: float = 1.0, insecure: bool = False) -> None:
        key_of(ns, "x")  # a namespace that is one plain key chunk (no wildcards)
        self.session = session
        self.ns = ns
        self.timeout = timeout
        self.insecure = insecure
        self._warned: set[str] = set()

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
        found = []
        for name in sorted(seen):
            entries = seen[name]
            if len(entries) > 1:  # two deployers, or someone spoofing one: never guess where to send a token
                where = ", ".join(sorted(f"{a} ({b})" for a, b in entries))
                self._warn(f"{name}@@{where}", "%s is announced on Zenoh by %d deployers (%s): not used until "
                           "one goes", name, len(entries), where)
                continue
            found.append(next(iter(entries.values())))
        return found

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
    a scart name service; calls, subscriptions and links go to the deployers as usual."""
    from dataflow.remote.client import GrpcSystem
    from dataflow.remote.security import Security

    return GrpcSystem(f"zenoh:{ns}", timeout=timeout, heartbeat_ms=heartbeat_ms,
                      security=security if security is not None else Security.from_env(),
                      names=ZenohNames(session, ns, timeout=timeout, insecure=insecure))
