"""The name table behind the name service (private; see :mod:`dataflow.remote.naming`).

Leases, not addresses, own names: :meth:`NameRegistry.register` returns a secret lease id
(128 random bits) and only its holder can renew, change or drop the lease. A name held by
another lease is refused unless that holder is surely gone — nothing listens at its
address any more, or another process does (the ``probe`` checks the holder's public boot
id) — so a deployer that restarted takes its names back at once, and nobody can take a
live deployer's names by claiming its address or by keeping it busy: a probe that times
out or finds the holder overloaded counts as alive. The registry's own names (its boot
id, permanent leases) are never probed; a call probes at most ``Limits.probed`` holders,
and at most ``Limits.probing`` calls probe at once (the others are refused at once), so
claims cannot tie up the server's workers.

Everything is bounded (:class:`Limits`): lease lengths (finite, positive, at most
``max_lease``), names per lease, leases per peer and in total, names in total, a page of
entries, and the names an error message lists. Expiry is kept in a heap and purged
lazily on every access (O(log n)), so the registry owns no thread and a table of 10 000
leases costs no more per call than one of ten. Thread-safe.
"""

from __future__ import annotations

import heapq
import logging
import math
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from dataflow.errors import NotFoundError
from dataflow.remote import errors

log = logging.getLogger("dataflow.remote.naming")


@dataclass(frozen=True)
class Limits:
    """The bounds of one registry (the defaults suit a robot; tests shrink them)."""

    max_lease: float = 600.0  #: longest lease (s); a longer request is shortened to it
    names_per_lease: int = 1_000
    leases_per_peer: int = 10_000
    leases: int = 20_000
    names: int = 100_000
    name_length: int = 256
    page: int = 500  #: entries per ListEntries page, at most
    listed: int = 20  #: names an error message lists, at most
    probed: int = 2  #: holders one register call may probe (beyond: refused as held)
    probing: int = 4  #: register calls probing at once (beyond: RESOURCE_EXHAUSTED, retry)


class RegistryFullError(errors.RemoteError):
    """A registration beyond the registry's bounds (``RESOURCE_EXHAUSTED``)."""


@dataclass(frozen=True)
class NameEntry:
    """One registered component: where it is served, the serving process's public boot id,
    and the lease left (s; ``inf`` for a permanent one)."""

    component: str
    address: str
    boot_id: str
    expires_in: float


@dataclass
class _Lease:
    address: str
    components: set[str]
    seconds: float
    expires: float
    boot_id: str = ""
    peer: str = ""
    permanent: bool = False
    lease_id: str = field(default_factory=lambda: secrets.token_hex(16))
    refused: list[str] = field(default_factory=list)


class NameRegistry:
    """The name table (see the module docstring). Every method is short and non-blocking,
    except that a conflicting :meth:`register` may probe the current holder.

    ``clock`` is injectable for tests; ``probe(address, boot_id)`` says whether the
    deployer process ``boot_id`` still answers at ``address``: True (alive), False (surely
    gone) or None (cannot tell: counted as alive); default: its gRPC health service, 0.5 s
    deadline. ``own_boot_id`` is the boot id of the process serving this registry.
    """

    def __init__(self, default_lease: float = 10.0, limits: Limits | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 probe: Callable[[str, str], bool | None] | None = None, own_boot_id: str = "") -> None:
        self.limits = limits or Limits()
        self._default = min(default_lease, self.limits.max_lease)
        self._clock = clock
        self._probe = probe if probe is not None else _health_probe
        self._own = own_boot_id
        self._probing = threading.BoundedSemaphore(self.limits.probing)
        self._leases: dict[str, _Lease] = {}
        self._owner: dict[str, str] = {}  # component -> lease id
        self._per_peer: dict[str, int] = {}
        self._expiry: list[tuple[float, str]] = []  # (expires, lease id), stale entries skipped
        self._lock = threading.Lock()

    # ---- bookkeeping (under the lock) ------------------------------------------------
    def _purge(self) -> None:
        now = self._clock()
        while self._expiry and self._expiry[0][0] <= now:
            expires, lease_id = heapq.heappop(self._expiry)
            lease = self._leases.get(lease_id)
            if lease is not None and not lease.permanent and lease.expires == expires:
                self._drop(lease)
                log.info("lease of %s (%d name(s)) expired", lease.address, len(lease.components))

    def _drop(self, lease: _Lease) -> None:
        self._leases.pop(lease.lease_id, None)
        for name in lease.components:
            if self._owner.get(name) == lease.lease_id:
                del self._owner[name]
        if lease.peer:
            left = self._per_peer.get(lease.peer, 1) - 1
            if left > 0:
                self._per_peer[lease.peer] = left
            else:
                self._per_peer.pop(lease.peer, None)

    def _holder(self, component: str) -> _Lease | None:
        lease_id = self._owner.get(component)
        return self._leases.get(lease_id) if lease_id is not None else None

    def _renew(self, lease: _Lease) -> None:
        lease.expires = self._clock() + lease.seconds
        if not lease.permanent:
            heapq.heappush(self._expiry, (lease.expires, lease.lease_id))

    def _set_names(self, lease: _Lease, names: set[str]) -> None:
        for gone in lease.components - names:
            if self._owner.get(gone) == lease.lease_id:
                del self._owner[gone]
        for name in names:
            self._owner[name] = lease.lease_id
        lease.components = names

    # ---- checks ----------------------------------------------------------------------
    def _seconds(self, requested: float) -> float:
        if not math.isfinite(requested) or requested < 0:
            raise ValueError(f"lease_seconds {requested!r}: expected a finite number of seconds > 0 "
                             f"(0: the default, {self._default:g} s)")
        return min(requested or self._default, self.limits.max_lease)

    def _names(self, components: list[str]) -> set[str]:
        names = set(components)
        if len(names) > self.limits.names_per_lease:
            raise RegistryFullError(f"{len(names)} names in one registration; at most {self.limits.names_per_lease}",
                                    "RESOURCE_EXHAUSTED")
        for name in names:
            if not name or len(name) > self.limits.name_length or not name.isprintable():
                raise ValueError(f"component name {name[:40]!r}: 1..{self.limits.name_length} printable characters")
        return names

    def _room(self, names: set[str], peer: str, replacing: _Lease | None) -> None:
        lim = self.limits
        new_lease = replacing is None
        if new_lease and len(self._leases) >= lim.leases:
            raise RegistryFullError(f"the name service holds {lim.leases} leases already", "RESOURCE_EXHAUSTED")
        if new_lease and peer and self._per_peer.get(peer, 0) >= lim.leases_per_peer:
            raise RegistryFullError(f"{peer} holds {lim.leases_per_peer} leases already", "RESOURCE_EXHAUSTED")
        growth = len(names) - (len(replacing.components) if replacing else 0)
        if len(self._owner) + growth > lim.names:
            raise RegistryFullError(f"the name service holds {lim.names} names already", "RESOURCE_EXHAUSTED")

    def _known(self) -> str:
        names = heapq.nsmallest(self.limits.listed, self._owner)  # O(n), not a sort of every name
        shown = ", ".join(names) or "(none)"
        more = len(self._owner) - len(names)
        return shown + (f" and {more} more" if more > 0 else "")

    # ---- the table -------------------------------------------------------------------
    def register(self, address: str, components: list[str], lease_seconds: float = 0.0, *,
                 boot_id: str = "", lease_id: str = "", peer: str = "", permanent: bool = False) -> tuple[str, float]:
        """Register ``components`` served at ``address``; returns ``(lease_id, lease_seconds)``.

        With ``lease_id``, changes that lease (only its holder knows it; an unknown one is
        ``NotFoundError``). Raises ``ValueError`` for a lease that is not finite and
        positive or bad names, :class:`errors.AlreadyRegisteredError` naming a component
        and its live holder, :class:`RegistryFullError` beyond the bounds."""
        seconds = self._seconds(lease_seconds)
        names = self._names(components)
        with self._lock:
            self._purge()
            mine = self._leases.get(lease_id) if lease_id else None
            if lease_id and mine is None:
                raise NotFoundError("lease unknown or expired; register again without it")
            self._room(names, peer, mine)
            holders = {h.lease_id: h for n in names if (h := self._holder(n)) is not None and h is not mine}
        gone = self._gone(holders)
        with self._lock:
            for lid, holder in holders.items():
                if lid not in gone and lid in self._leases:
                    taken = sorted(holder.components & names)[: self.limits.listed]
                    raise errors.AlreadyRegisteredError(
                        f"component name(s) {', '.join(taken)} already registered by the deployer at "
                        f"{holder.address}; choose another name (scart run --remap __ns=NAME puts a whole system "
                        "under NAME/), run a second system with its own name service (--ns HOST:PORT), or stop "
                        "that deployer", "ALREADY_EXISTS", address)
            for lid in gone:
                held = self._leases.get(lid)
                if held is not None:
                    log.info("the deployer at %s is gone: its names go to %s", held.address, address)
                    self._drop(held)
            if mine is None:
                mine = _Lease(address, set(), seconds, 0.0, boot_id, peer, permanent)
                self._leases[mine.lease_id] = mine
                if peer:
                    self._per_peer[peer] = self._per_peer.get(peer, 0) + 1
            mine.address, mine.seconds, mine.boot_id = address, seconds, boot_id or mine.boot_id
            self._set_names(mine, names)
            self._renew(mine)
        log.info("registered %d name(s) at %s", len(names), address)
        return mine.lease_id, seconds

    def _gone(self, holders: dict[str, _Lease]) -> set[str]:
        """The lease ids of ``holders`` whose process is surely gone (see the class docstring)."""
        probed = {lid: h for lid, h in holders.items() if not h.permanent and not (self._own and h.boot_id == self._own)}
        if not probed or len(probed) > self.limits.probed:
            return set()  # nothing to probe, or too many holders to probe in one call: all held
        if not self._probing.acquire(blocking=False):
            raise RegistryFullError("the name service is busy checking other claims; retry in a moment",
                                    "RESOURCE_EXHAUSTED")
        try:
            return {lid for lid, h in probed.items() if self._probe(h.address, h.boot_id) is False}
        finally:
            self._probing.release()

    def heartbeat(self, lease_id: str, components: list[str] | None = None) -> float:
        """Renew a lease (and update its names: those held by another lease are refused,
        logged once); returns its length. Raises ``NotFoundError`` if expired or unknown."""
        names = self._names(components) if components is not None else None
        with self._lock:
            self._purge()
            lease = self._leases.get(lease_id)
            if lease is None:
                raise NotFoundError("lease unknown or expired; register again")
            if names is not None:
                free = {n for n in names if (h := self._holder(n)) is None or h is lease}
                refused = sorted(names - free)
                if refused and refused != lease.refused:
                    log.warning("deployer at %s: name(s) %s refused, held by another deployer",
                                lease.address, ", ".join(refused[: self.limits.listed]))
                lease.refused = refused
                self._room(free, lease.peer, lease)
                self._set_names(lease, free)
            self._renew(lease)
            return lease.seconds

    def unregister(self, lease_id: str) -> None:
        """Drop a lease and its names (idempotent; an unknown id does nothing)."""
        with self._lock:
            lease = self._leases.get(lease_id)
            if lease is not None:
                self._drop(lease)

    def resolve(self, component: str) -> NameEntry:
        """Where ``component`` is served; raises ``NotFoundError`` listing some known names."""
        with self._lock:
            self._purge()
            lease = self._holder(component)
            if lease is None:
                raise NotFoundError(f"no component named {component[:80]!r} is registered; known: {self._known()}")
            return self._entry(component, lease)

    def entries(self, after: str = "", limit: int | None = None) -> list[NameEntry]:
        """Live registrations sorted by component name, those after ``after``, at most
        ``limit`` (default and cap: ``limits.page``)."""
        size = min(limit or self.limits.page, self.limits.page)
        with self._lock:
            self._purge()
            names = heapq.nsmallest(size, (n for n in self._owner if n > after))
            return [self._entry(n, self._leases[self._owner[n]]) for n in names]

    def _entry(self, component: str, lease: _Lease) -> NameEntry:
        left = math.inf if lease.permanent else max(0.0, lease.expires - self._clock())
        return NameEntry(component, lease.address, lease.boot_id, left)


def _health_probe(address: str, boot_id: str) -> bool | None:
    from scart_wire.rpc import health_state

    return health_state(address, service=boot_service(boot_id) if boot_id else "")


def boot_service(boot_id: str) -> str:
    """The gRPC health service name a deployer process answers SERVING for while it lives."""
    return f"scart.boot.{boot_id}"
