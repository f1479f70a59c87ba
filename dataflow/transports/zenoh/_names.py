"""Finding deployers and ports on Zenoh, without a scart name service (private to
:mod:`dataflow.transports.zenoh`, which re-exports what is public here)."""

from __future__ import annotations

import hashlib
import hmac
import json
import logging
import math
import re
import secrets
from typing import TYPE_CHECKING
from urllib.parse import unquote

from scart_wire.errors import RemoteNotFoundError
from scart_wire.security import is_loopback
from dataflow.transports.zenoh._keys import _WORD, DEFAULT_NS, MAX_REPLIES, ROOT, SERVED, key_of

if TYPE_CHECKING:
    import zenoh

    from dataflow.remote._registry import NameEntry
    from dataflow.remote.client import GrpcSystem
    from scart_wire.security import Security

__all__ = ["PROOF", "Prover", "ZenohNames", "connect_zenoh", "discover", "proof_of", "token_id"]

log = logging.getLogger("dataflow.transports.zenoh")

PROOF = "scart-proof"  #: root of the queryables proving the served tokens
_NONCE = re.compile(r"^[0-9a-f]{32}$")


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


class Prover:
    """Answers a proof query for one announced task (see :mod:`dataflow.transports.zenoh`),
    on Zenoh's thread: nothing for a malformed query or a token id not in the auth file."""

    def __init__(self, ns: str, component: str, served: tuple[str, str], keys: dict[str, str]) -> None:
        self.ns, self.component, self.served, self._keys = ns, component, served, keys

    def __call__(self, query: zenoh.Query) -> None:
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


def discover(session: zenoh.Session, ns: str = DEFAULT_NS, timeout: float = 1.0) -> dict[str, list[str]]:
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

    def __init__(self, session: zenoh.Session, ns: str = DEFAULT_NS, timeout: float = 1.0, insecure: bool = False,
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
        try:
            key_of(self.ns, component)
        except ValueError:
            found: list[NameEntry] = []
        else:
            found = self._look(component, timeout)
        if not found:
            known = ", ".join(e.component for e in self.entries(timeout)[:20]) or "none"
            raise RemoteNotFoundError(f"no component named {component[:80]!r} is served on Zenoh "
                                             f"(namespace {self.ns}); known: {known}", "NOT_FOUND", "zenoh")
        return found[0]

    def close(self) -> None:
        """Nothing to release (the session is the caller's)."""


def connect_zenoh(session: zenoh.Session, ns: str = DEFAULT_NS, timeout: float = 2.0, heartbeat_ms: int = 500,
                  security: Security | None = None, insecure: bool = False) -> GrpcSystem:
    """A data-flow system whose lookups go through Zenoh (:class:`ZenohNames`) instead of
    a scart name service; calls, subscriptions and links go to the deployers as usual. With
    a token (``security``), only announcements proved for it are used."""
    from dataflow.remote.client import GrpcSystem
    from scart_wire.security import Security

    security = security if security is not None else Security.from_env()
    return GrpcSystem(f"zenoh:{ns}", timeout=timeout, heartbeat_ms=heartbeat_ms, security=security,
                      names=ZenohNames(session, ns, timeout=timeout, insecure=insecure, token=security.token))
