"""Transport ``shm``: ipc's own path for large samples, through shared memory
(registered as the ``scart.transports`` entry point ``shm``; rank 5, so ``auto`` tries it
first, for the ports it is for). It lives in ipc's folder because it is ipc.

It is ipc (its tickets, socket, io thread and counting), with one difference: a sample
whose value is 64 KiB or more (:data:`~._shm_conns.LARGE_BYTES`: an image, a point cloud) is
written once into a slot of the channel's shared memory, and only a small frame naming
the slot crosses the socket. The reader maps the slot read-only: an array type's value is
a read-only view of the writer's bytes, valid as long as the task holds it; the slot goes
back to the writer once the last value made of it is gone. Smaller samples cross the
socket as on ipc.

* **Memory is bounded by the policy**: a channel has at most its buffer's samples and 3
  more in slots (16 at most, 1 GiB in all): a slow reader pins no more. With every slot
  held, a sample crosses the socket instead, as on ipc.
* **Nothing leaks**: a slot is an anonymous memory file (``memfd_create``), never in
  ``/dev/shm``; its descriptor reaches the reader over the socket (``SCM_RIGHTS``, from
  a process of the same user only) and the kernel frees the memory once neither process
  holds it: kill -9 of the writer, the reader or both leaves nothing.
* ``auto`` takes it for a link whose port carries ``bytes`` or an array type (of a shape
  that can be 64 KiB or more), and for a subscription whose deployer says its port does;
  ipc takes the rest. ``transport="shm"`` uses it for any port (small samples then cross
  its socket).

Why anonymous memory files and not iceoryx2 (measured, 6.2 MB and 24.9 MB at 30 Hz
between two Python processes, writer copy included): the same latency (p50 0.44 vs
0.55 ms, and 1.73 vs 1.80 ms), no new dependency, nothing in ``/dev/shm`` (iceoryx2
leaves a management file there even after a clean exit, and stale ones after kill -9),
and the ipc socket's tickets and peer checks for free. ``multiprocessing.shared_memory``
names its segments in ``/dev/shm``: a killed process leaks them.
"""

from __future__ import annotations

from dataflow.transports import Peer, TransportError
from dataflow.transports.ends import ReaderEnd, WriterEnd
from dataflow.transports.ipc import IpcTransport
from dataflow.transports.ipc._shm_conns import LARGE_BYTES, ShmLinkOut, ShmSubIn, carries_large
from dataflow.transports.ipc._slots import available

__all__ = ["LARGE_BYTES", "ShmTransport", "available", "carries_large"]


class ShmTransport(IpcTransport):
    """Large samples through shared memory between two processes of one host (see the
    module docstring)."""

    name = "shm"
    rank = 5
    shm = True

    def link(self, end: WriterEnd, peer: Peer) -> bool:
        if not self._usable(end.policy.transport, peer):
            return False
        if end.policy.transport == "auto" and not carries_large(end.port.type):
            return False  # small samples: ipc's
        return self._link(end, peer, ShmLinkOut)

    def subscribe(self, end: ReaderEnd, peer: Peer) -> bool:
        """As ipc's; under ``auto`` the deployer declines for a port of small samples."""
        if not self._usable(peer.transport, peer):
            return False
        return self._subscribe(end, peer, ShmSubIn)

    def _usable(self, wanted: str, peer: Peer) -> bool:
        if available():
            return True
        if wanted == self.name:
            raise TransportError(f"transport shm to {peer.where}: this platform has no anonymous shared memory")
        return False
