"""How big one sample may be on scart's own transports, said where it bites.

A sample's value may be up to :data:`MAX_SAMPLE_BYTES` (64 MiB: a 4K RGB frame is 25 MB)
on ``ipc``, ``shm``, ``grpc`` (which sends a large frame in parts, each within gRPC's own
message limit) and ``zenoh``; its encoding with scart's framing, up to
:data:`MAX_FRAME_BYTES`. A carrier's encoder raises :class:`SampleTooLarge` for a larger
one, so the writer end refuses it at ``write()`` (``WRITE_FAILURE`` on a mandatory
channel), counts it in the channel's drops and logs the first one with its size and the
limit: a sample never leaves to be dropped unseen at the reader.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from dataflow.errors import DeploymentError

if TYPE_CHECKING:
    from dataflow.ports import Port

__all__ = ["FRAME_ROOM", "MAX_FRAME_BYTES", "MAX_SAMPLE_BYTES", "SampleTooLarge", "check_fits", "check_size"]

MAX_SAMPLE_BYTES = 64 * 1024 * 1024  #: bytes of one sample's value a transport carries, at least
FRAME_ROOM = 64 * 1024  #: scart's framing around a value (write number, time, type name...), at most
MAX_FRAME_BYTES = MAX_SAMPLE_BYTES + FRAME_ROOM  #: bytes of one encoded sample, at most


class SampleTooLarge(ValueError):
    """A sample over its transport's limit: refused at ``write()``, counted, said once."""

    def __init__(self, size: int, limit: int = MAX_FRAME_BYTES, transport: str = "") -> None:
        where = f"{transport}'s" if transport else "the transport's"
        super().__init__(f"{size} bytes encoded, over {where} limit of {limit} bytes "
                         f"({_mib(limit)}): refused")
        self.size = size
        self.limit = limit


def check_size(data: bytes, limit: int = MAX_FRAME_BYTES, transport: str = "") -> bytes:
    """``data`` when it is within ``limit``; raises :class:`SampleTooLarge` otherwise."""
    if len(data) > limit:
        raise SampleTooLarge(len(data), limit, transport)
    return data


def check_fits(port: Port[Any], across: str) -> None:
    """Refuse, when it is made, a channel of ``port`` (``across``: what it joins) whose
    type makes every write fail: a fixed-size type (an array of a fixed shape) over the
    limit. Raises :class:`~dataflow.errors.DeploymentError` saying the size and the limit."""
    size = getattr(port.type, "fixed_bytes", None)
    if size is not None and size + _LEAST_FRAMING > MAX_FRAME_BYTES:
        raise DeploymentError(f"{port.qualname} ({port.type_name}) cannot cross processes ({across}): one sample is "
                              f"{size} bytes, over the transports' limit of {MAX_FRAME_BYTES} bytes "
                              f"({_mib(MAX_FRAME_BYTES)}); every write would be refused")


_LEAST_FRAMING = 16  #: bytes a frame adds to a value, at least (write number, time, type name)


def _mib(n: int) -> str:
    return f"{n / (1024 * 1024):.2f} MiB"
