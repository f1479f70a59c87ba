"""QoS as a frozen value with named constructors, mapped as rmw_cyclonedds maps ROS 2 QoS.

=====================================  ==========  ===========  ===============
constructor                            history     reliability  durability
=====================================  ==========  ===========  ===============
``QoS.data()``                         keep-last 1  reliable     volatile
``QoS.buffer(n)``                      keep-last n  reliable     volatile
``QoS.data(best_effort=True)``         keep-last 1  best-effort  volatile
``QoS.buffer(n, latching=True)``       keep-last n  reliable     transient-local
=====================================  ==========  ===========  ===============

``latching`` is ROS 1's word for what ROS 2 calls transient-local durability: a late
joining reader gets the writer's last ``depth`` samples. ``deadline`` (s: a writer
promises, a reader asks for, a sample at least that often), ``lifespan`` (s: a sample
older than that is not delivered) and ``liveliness_lease`` (s: a writer not heard of for
that long is taken as gone; liveliness is automatic) are ROS 2's own, infinite unless
given (rclpy's defaults). As rmw_cyclonedds does, every entity also gets: no
auto-dispose, the durability service history equal to the history, and XCDR1 (plain
CDR) as its only data representation.

DDS's request/offer rules apply between peers: a reliable reader does not match a
best-effort writer, a transient-local reader does not match a volatile writer.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, replace

from cyclonedds.qos import Policy, Qos
from cyclonedds.util import duration

__all__ = ["QoS", "Reliability", "Durability"]

_MAX_DEPTH = 10_000  # the same bound scart puts on any buffer
_MAX_SECONDS = 1e6  # deadlines, lifespans and leases beyond this are infinite: give none


class Reliability(enum.Enum):
    """Whether lost samples are sent again (RELIABLE) or not (BEST_EFFORT)."""

    RELIABLE = "reliable"
    BEST_EFFORT = "best_effort"


class Durability(enum.Enum):
    """Whether a late joiner gets the last ``depth`` samples (TRANSIENT_LOCAL) or not."""

    VOLATILE = "volatile"
    TRANSIENT_LOCAL = "transient_local"


@dataclass(frozen=True)
class QoS:
    """A ROS 2 QoS profile (immutable, hashable); ``ValueError`` for a depth outside
    1..10000."""

    depth: int = 1
    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    deadline: float | None = None
    lifespan: float | None = None
    liveliness_lease: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.depth, int) or isinstance(self.depth, bool) or not 1 <= self.depth <= _MAX_DEPTH:
            raise ValueError(f"QoS depth must be an integer in 1..{_MAX_DEPTH}, got {self.depth!r}")
        if not isinstance(self.reliability, Reliability) or not isinstance(self.durability, Durability):
            raise ValueError("QoS reliability and durability are Reliability and Durability values")
        for name in ("deadline", "lifespan", "liveliness_lease"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                      or not 0 < value < _MAX_SECONDS):
                raise ValueError(f"QoS {name} must be seconds in (0, {_MAX_SECONDS:g}), got {value!r}")

    @classmethod
    def data(cls, *, best_effort: bool = False, latching: bool = False) -> QoS:
        """The last value only: keep-last 1 (a stream of scart's DATA policy is keep-last 10,
        rclpy's default depth: :func:`~._transport.qos_of`)."""
        return cls(1, _reliability(best_effort), _durability(latching))

    @classmethod
    def buffer(cls, size: int, *, best_effort: bool = False, latching: bool = False) -> QoS:
        """A FIFO of ``size``: keep-last ``size``, reliable unless ``best_effort`` (scart's
        BUFFER(n) policy)."""
        return cls(size, _reliability(best_effort), _durability(latching))

    def with_best_effort(self) -> QoS:
        """This profile, best-effort."""
        return replace(self, reliability=Reliability.BEST_EFFORT)

    def with_latching(self) -> QoS:
        """This profile, transient-local."""
        return replace(self, durability=Durability.TRANSIENT_LOCAL)

    def to_cyclone(self, user_data: bytes = b"", *, reader: bool = False) -> Qos:
        """The cyclonedds ``Qos`` of a writer (or a ``reader``) with this profile and
        ``user_data`` (rmw's ``typehash=...;`` and, for services, ``clientid=...;``).

        A reader ignores member names when it checks a peer's XTypes type: rmw_cyclonedds
        announces no XTypes type at all and matches by type name, so only the type name
        and the layout may matter."""
        history = Policy.History.KeepLast(self.depth)
        policies = [
            history,
            Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100))
            if self.reliability is Reliability.RELIABLE else Policy.Reliability.BestEffort,
            Policy.WriterDataLifecycle(autodispose=False),
            Policy.DataRepresentation(use_cdrv0_representation=True),
        ]
        if self.durability is Durability.TRANSIENT_LOCAL:
            policies += [Policy.Durability.TransientLocal,
                         Policy.DurabilityService(cleanup_delay=0, history=history, max_samples=-1,
                                                  max_instances=-1, max_samples_per_instance=-1)]
        else:
            policies.append(Policy.Durability.Volatile)
        if self.deadline is not None:
            policies.append(Policy.Deadline(duration(seconds=self.deadline)))
        if self.lifespan is not None:
            policies.append(Policy.Lifespan(duration(seconds=self.lifespan)))
        if self.liveliness_lease is not None:
            policies.append(Policy.Liveliness.Automatic(lease_duration=duration(seconds=self.liveliness_lease)))
        if user_data:
            policies.append(Policy.Userdata(data=user_data))
        if reader:
            policies.append(Policy.TypeConsistency.AllowTypeCoercion(ignore_member_names=True,
                                                                     prevent_type_widening=True))
        return Qos(*policies)

    def __str__(self) -> str:
        words = [f"keep-last {self.depth}", self.reliability.value.replace("_", "-"),
                 self.durability.value.replace("_", "-")]
        durations = (("deadline", self.deadline), ("lifespan", self.lifespan),
                     ("liveliness_lease", self.liveliness_lease))
        words += [f"{name.replace('_', ' ')} {value:g} s" for name, value in durations if value is not None]
        return ", ".join(words)


def _reliability(best_effort: bool) -> Reliability:
    return Reliability.BEST_EFFORT if best_effort else Reliability.RELIABLE


def _durability(latching: bool) -> Durability:
    return Durability.TRANSIENT_LOCAL if latching else Durability.VOLATILE
