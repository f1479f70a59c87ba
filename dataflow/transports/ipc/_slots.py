"""shm's shared memory (private): a channel's slots at its writer (:class:`SlotPool`) and
their mappings at its reader (:class:`SlotMaps`).

A slot is an anonymous memory file (``memfd_create``): it has no name, so nothing of it is
ever in ``/dev/shm`` or on disk, and the kernel frees it once the last process holding
it (its file descriptor or a mapping) is gone, killed or not. The writer creates it,
maps it read-write and hands its descriptor to the reader once (``SCM_RIGHTS`` over the
channel's socket); the reader maps it read-only and closes the descriptor.
"""

from __future__ import annotations

import logging
import mmap
import os
import sys
import threading
import weakref
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

__all__ = ["MAX_MAPPED_BYTES", "MAX_POOL_BYTES", "MAX_SLOTS", "Slot", "SlotMaps", "SlotPool", "available"]

log = logging.getLogger(__name__)

MAX_SLOTS = 16  #: slots of one channel, at most
MAX_POOL_BYTES = 1024 * 1024 * 1024  #: bytes of one channel's slots, at most (a writer's side)
MAX_MAPPED_BYTES = 2 * MAX_POOL_BYTES  #: bytes a reader maps for one channel, at most (a writer's bound, and room)
_GRAIN = 1024 * 1024  #: a slot's size is a whole number of these (sizes that vary a little reuse slots)


def available() -> bool:
    """Whether this platform has anonymous memory files (Linux)."""
    return sys.platform.startswith("linux") and hasattr(os, "memfd_create")


class Slot:
    """One slot at the writer: its number, size, memory (a writable ``uint8`` array over
    its mapping) and, until the reader has it, its descriptor."""

    __slots__ = ("id", "size", "memory", "fd", "busy", "freed", "_map")

    def __init__(self, slot_id: int, size: int) -> None:
        import numpy as np

        self.id = slot_id
        self.size = size
        fd = os.memfd_create(f"scart-shm-{slot_id}", os.MFD_CLOEXEC)
        try:
            os.ftruncate(fd, size)
            self._map = mmap.mmap(fd, size)
        except BaseException:
            os.close(fd)
            raise
        self.fd: int | None = fd
        self.memory = np.frombuffer(self._map, dtype=np.uint8)
        self.busy = False
        self.freed = 0  # when it was last given back (a pool's count): the latest is the warmest in the caches

    def announced(self) -> None:
        """The reader has the descriptor: this side needs only the mapping."""
        fd, self.fd = self.fd, None
        if fd is not None:
            os.close(fd)

    def close(self) -> None:
        self.announced()
        self.memory = None  # type: ignore[assignment]  # the mapping's last view here, dropped first
        try:
            self._map.close()
        except BufferError:  # a view of it lives on somewhere: the mapping goes with it
            pass


class SlotPool:
    """The slots of one channel at its writer: at most ``max_slots`` of them and
    :data:`MAX_POOL_BYTES` in all (so a slow reader pins no more than that: the policy's
    buffer and the few its task holds). :meth:`take` a free one for a sample (made, or
    made larger, as needed), :meth:`release` those the reader gave back. Thread-safe."""

    def __init__(self, max_slots: int) -> None:
        self.max_slots = max(1, min(MAX_SLOTS, max_slots))
        self._lock = threading.Lock()
        self._slots: list[Slot] = []
        self._by_id: dict[int, Slot] = {}
        self._next_id = 1
        self._freed = 0
        self._closed = False
        self.retired: list[int] = []  #: slots replaced by larger ones, to tell the reader (then cleared)

    def take(self, size: int) -> Slot | None:
        """A free slot of at least ``size`` bytes, now busy; None when every slot is taken
        (the reader holds them) or a new one would pass the bounds."""
        with self._lock:
            if self._closed:
                return None
            free = [s for s in self._slots if not s.busy]
            fit = max((s for s in free if s.size >= size), key=lambda s: s.freed, default=None)  # the warmest
            if fit is None:
                want = max(_GRAIN, -(-size // _GRAIN) * _GRAIN)
                total = sum(s.size for s in self._slots)
                if free and total - free[0].size + want <= MAX_POOL_BYTES:  # one too small: made larger
                    self._retire(free[0])
                    total -= free[0].size
                elif len(self._slots) >= self.max_slots or total + want > MAX_POOL_BYTES:
                    return None
                fit = Slot(self._next_id, want)
                self._next_id += 1
                self._slots.append(fit)
                self._by_id[fit.id] = fit
            fit.busy = True
            return fit

    def _retire(self, slot: Slot) -> None:
        self._slots.remove(slot)
        del self._by_id[slot.id]
        if slot.fd is None:  # the reader has it: tell it to let go
            self.retired.append(slot.id)
        slot.close()

    def give_back(self, slot: Slot) -> None:
        """A slot taken and not sent after all: free again."""
        slot.busy = False

    def release(self, ids: Iterable[int]) -> None:
        """The reader is done with these slots (ids it may not have had are ignored)."""
        with self._lock:
            for slot_id in ids:
                slot = self._by_id.get(slot_id)
                if slot is not None:
                    slot.busy = False
                    self._freed += 1
                    slot.freed = self._freed

    @property
    def busy(self) -> int:
        """Slots the reader holds now."""
        return sum(1 for s in self._slots if s.busy)

    def close(self) -> None:
        """Let go of every slot (idempotent): the reader's mappings, if any, stay valid."""
        with self._lock:
            self._closed = True
            slots, self._slots = self._slots, []
            self._by_id.clear()
        for slot in slots:
            slot.close()


class SlotMaps:
    """The slots of one channel at its reader, mapped read-only: :meth:`add` each one
    announced (with its descriptor), :meth:`view` a sample's bytes — a read-only array
    that calls ``release(slot id)`` once nothing refers to it any more (the task let go of
    the sample). Bounded by :data:`MAX_SLOTS` mappings and :data:`MAX_MAPPED_BYTES`.
    One thread adds and views (the io thread); ``release`` may run in any."""

    def __init__(self, release: Callable[[int], None]) -> None:
        self._release = release
        self._maps: dict[int, NDArray[np.uint8]] = {}  # id -> uint8 array over the mapping

    def add(self, slot_id: int, size: int, fd: int) -> None:
        """Map the slot ``slot_id`` of ``size`` bytes (``fd`` is closed either way);
        ``ValueError`` when that would pass the bounds, or the file is not that large."""
        import numpy as np

        try:
            if len(self._maps) >= 2 * MAX_SLOTS or self.mapped + size > MAX_MAPPED_BYTES:
                raise ValueError(f"a slot of {size} bytes is past this reader's bounds "
                                 f"({2 * MAX_SLOTS} slots, {MAX_MAPPED_BYTES} bytes)")
            if os.fstat(fd).st_size < size:
                raise ValueError(f"slot {slot_id} is smaller than the {size} bytes announced")
            memory = mmap.mmap(fd, size, prot=mmap.PROT_READ)
        finally:
            os.close(fd)
        self._maps[slot_id] = np.frombuffer(memory, dtype=np.uint8)

    def retire(self, slot_id: int) -> None:
        """The writer let go of this slot: its mapping goes once no view holds it."""
        self._maps.pop(slot_id, None)

    @property
    def mapped(self) -> int:
        return sum(m.size for m in self._maps.values())

    def view(self, slot_id: int, size: int) -> NDArray[np.uint8]:
        """The first ``size`` bytes of slot ``slot_id``, read-only; the slot is released
        when the last array made of them is gone. ``ValueError`` for an unknown slot or a
        size past its end."""
        memory = self._maps.get(slot_id)
        if memory is None or size > memory.size:
            raise ValueError(f"no slot {slot_id} of {size} bytes")
        owner = memory[:size]  # an array of its own: what every view of this sample refers to
        weakref.finalize(owner, self._release, slot_id)
        return owner

    def close(self) -> None:
        """Forget every mapping (each goes once no view holds it)."""
        self._maps.clear()
