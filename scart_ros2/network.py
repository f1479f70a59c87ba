"""Which DDS domain, and over which network: loopback only unless told otherwise.

The domain id is the explicit argument, else ``ROS_DOMAIN_ID``, else 0 (as ROS 2); it must
be 0..232 (the highest whose RTPS ports fit in 16 bits). The network is a Cyclone DDS
configuration made by :class:`Network`:

* :meth:`Network.loopback` (the default): the loopback interface only (chosen by its
  address 127.0.0.1, so ``lo`` and macOS's ``lo0`` alike), no multicast at all, and
  discovery by unicast to the explicit peer 127.0.0.1 over ``max_participants``
  participant indexes (each participant on the host takes one; Cyclone's default is 9).
  Nothing is ever sent to another address.
* :meth:`Network.open` (``insecure=True``): Cyclone picks the interface (or the one
  named), multicast discovery as ROS 2 does by default, plus any unicast peers. Anyone
  on that network can then read and write the topics: DDS without DDS Security
  authenticates no one.

On loopback, whose MTU is 64 KiB, Cyclone sends large samples in 64 KB datagrams rather
than its default 14.7 KB ones of 1344-byte fragments, and asks for a socket receive buffer
of up to 8 MB: a 6 MB image then crosses in about 8 ms instead of 100 (measured by
``benchmarks/bench_big.py``). On a real network Cyclone's defaults stay, which do not
rely on IP fragmentation.

Either way a sample larger than ``max_sample_bytes`` (64 MiB, ROS 1's bound too) is
dropped by Cyclone in both directions, with a warning on its log: an outside peer cannot
make this process hold a larger one.

Cyclone DDS configures a domain once per process: every participant of this library on
one domain id shares it, and must ask for the same network (else :class:`DomainError`).
The last one closed deletes the domain (Cyclone's threads and sockets with it).
"""

from __future__ import annotations

import os
import re
import threading
from dataclasses import dataclass

from .errors import DomainError

__all__ = ["Network", "resolve_domain_id", "MAX_DOMAIN_ID", "MAX_SAMPLE_BYTES"]

MAX_DOMAIN_ID = 232
MAX_SAMPLE_BYTES = 64 << 20  #: serialised bytes of one sample, at most, either way
LOOPBACK_MESSAGE_BYTES = 65500  #: one datagram on loopback, at most (Cyclone's default: 14720)
_ADDRESS = re.compile(r"[A-Za-z0-9_.:\-\[\]%]{1,255}\Z")  # host names, IPv4/IPv6 literals, interface names


@dataclass(frozen=True)
class Network:
    """A Cyclone DDS network configuration (immutable); see the module docstring."""

    loopback_only: bool = True
    interface: str | None = None
    peers: tuple[str, ...] = ()
    multicast: bool = False
    max_participants: int = 32
    max_sample_bytes: int = MAX_SAMPLE_BYTES

    def __post_init__(self) -> None:
        for word in (self.interface, *self.peers):
            if word is not None and not _ADDRESS.match(word):
                raise DomainError(f"{word!r} is not an interface name, host or address")
        if not 1 <= self.max_participants <= 120:
            raise DomainError(f"max_participants must be 1..120, got {self.max_participants}")
        if not 1024 <= self.max_sample_bytes <= MAX_SAMPLE_BYTES:
            raise DomainError(f"max_sample_bytes must be 1024..{MAX_SAMPLE_BYTES}, got {self.max_sample_bytes}")
        if self.loopback_only and (self.multicast or self.interface or self.peers):
            raise DomainError("a loopback network has no interface, peers or multicast: use Network.open()")

    @classmethod
    def loopback(cls, max_participants: int = 32, max_sample_bytes: int = MAX_SAMPLE_BYTES) -> Network:
        """Loopback only, no multicast, the explicit peer 127.0.0.1 (the default)."""
        return cls(max_participants=max_participants, max_sample_bytes=max_sample_bytes)

    @classmethod
    def open(cls, interface: str | None = None, peers: tuple[str, ...] = (), *,
             multicast: bool = True, max_participants: int = 32) -> Network:
        """A real network (what ``insecure=True`` means): ``interface`` (name or address;
        None lets Cyclone choose), multicast discovery unless ``multicast=False``, and
        unicast ``peers``."""
        return cls(False, interface, tuple(peers), multicast, max_participants)

    def config_xml(self) -> str:
        """This configuration as Cyclone DDS XML (what ``CYCLONEDDS_URI`` may hold too)."""
        sizes = receive = ""
        if self.loopback_only:
            interface, multicast = '<NetworkInterface address="127.0.0.1"/>', False
            peers: tuple[str, ...] = ("127.0.0.1",)
            sizes = f"<MaxMessageSize>{LOOPBACK_MESSAGE_BYTES}B</MaxMessageSize><FragmentSize>64000B</FragmentSize>"
            receive = '<SocketReceiveBufferSize max="8MB"/>'
        else:
            attr = "address" if self.interface and self.interface[0].isdigit() else "name"
            interface = f'<NetworkInterface {attr}="{self.interface}"/>' if self.interface else \
                '<NetworkInterface autodetermine="true"/>'
            peers, multicast = self.peers, self.multicast
        peer_xml = "".join(f'<Peer address="{p}"/>' for p in peers)
        return (
            '<CycloneDDS xmlns="https://cdds.io/config"><Domain Id="any"><General>'
            f"<Interfaces>{interface}</Interfaces>"
            f"<AllowMulticast>{'true' if multicast else 'false'}</AllowMulticast>{sizes}</General>"
            f"<Internal>{receive}<MaxSampleSize>{self.max_sample_bytes}B</MaxSampleSize></Internal>"
            "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
            f"<MaxAutoParticipantIndex>{self.max_participants - 1}</MaxAutoParticipantIndex>"
            + (f"<Peers>{peer_xml}</Peers>" if peer_xml else "")
            + "</Discovery></Domain></CycloneDDS>")


def resolve_domain_id(explicit: int | None = None) -> int:
    """``explicit``, else ``ROS_DOMAIN_ID``, else 0; raises :class:`DomainError` for a
    value that is not an integer in 0..232 (naming where it came from)."""
    if explicit is not None:
        source, value = "domain_id", explicit
    else:
        text = os.environ.get("ROS_DOMAIN_ID", "").strip()
        if not text:
            return 0
        source = "ROS_DOMAIN_ID"
        try:
            value = int(text)
        except ValueError:
            raise DomainError(f"ROS_DOMAIN_ID={text!r} is not an integer 0..{MAX_DOMAIN_ID}") from None
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= MAX_DOMAIN_ID:
        raise DomainError(f"{source}={value!r} is not an integer 0..{MAX_DOMAIN_ID}")
    return value


class _Domains:
    """The Cyclone domains this process opened, shared by id, counted (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._open: dict[int, list] = {}  # id -> [Domain, config xml, users]

    def acquire(self, domain_id: int, xml: str) -> None:
        with self._lock:
            entry = self._open.get(domain_id)
            if entry is not None:
                if entry[1] != xml:
                    raise DomainError(
                        f"DDS domain {domain_id} is already open in this process with another network "
                        "configuration: Cyclone DDS configures a domain once per process")
                entry[2] += 1
                return
            from cyclonedds.core import DDSException
            from cyclonedds.domain import Domain

            try:
                domain = Domain(domain_id, xml)
            except DDSException as exc:
                raise DomainError(
                    f"cannot open DDS domain {domain_id} with the configuration asked for ({exc}); "
                    "a cyclonedds participant made earlier in this process may hold it") from None
            self._open[domain_id] = [domain, xml, 1]

    def release(self, domain_id: int) -> None:
        with self._lock:
            entry = self._open.get(domain_id)
            if entry is None:
                return
            entry[2] -= 1
            if entry[2] == 0:
                del self._open[domain_id]
                delete_entity(entry[0])


DOMAINS = _Domains()


def delete_entity(entity: object) -> None:
    """Delete a cyclonedds entity now (and its children), not when it is collected.

    cyclonedds-python deletes an entity in its finaliser only; calling that finaliser is
    idempotent (it forgets the entity first), so a later collection does nothing.
    """
    finalise = getattr(entity, "__del__", None)
    if finalise is not None:
        finalise()
