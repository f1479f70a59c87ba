"""Counting the writes a subscriber did not receive (private; no gRPC here: used by the
gRPC and ipc subscriptions, :mod:`dataflow.remote._subscription`, and by Zenoh's)."""

from __future__ import annotations

__all__ = ["LossCount"]


class LossCount:
    """The writes a subscriber did not receive, each counted once (see the module
    docstring): the jumps in the write numbers, plus the drops the server reported that no
    jump has revealed yet. Feed it, in order, :meth:`new_stream`, each message's
    :meth:`sample` s then :meth:`report`, and :meth:`restarted` when the boot id changes.
    Not thread-safe (the receiver thread owns it); :attr:`lost` may be read from anywhere."""

    def __init__(self) -> None:
        self.last: int | None = None  # the write number of the last sample received
        self._jumps = 0  # writes not received, seen as jumps (all streams)
        self._stream_jumps = 0  # ... of those, within the current (or last) stream
        self._reported = 0  # the server's drop count for the current (or last) stream
        self._before_restarts = 0  # unrevealed drops of a process that then restarted
        self._awaiting = True  # no sample of the current stream yet: the last one's tail stands

    @property
    def lost(self) -> int:
        """Writes not received so far."""
        return self._jumps + self._tail + self._before_restarts

    @property
    def _tail(self) -> int:
        return max(0, self._reported - self._stream_jumps)

    def new_stream(self) -> None:
        """A (re)connected stream begins."""
        self._awaiting = True

    def restarted(self) -> None:
        """The deployer process changed: its write numbers start over, and no jump will
        reveal what the old one dropped last."""
        self._before_restarts += self._tail
        self.last = None
        self._reported = self._stream_jumps = 0

    def sample(self, sequence: int, reported: int = 0) -> bool:
        """Note a received sample (``reported``: its message's drop count); False for one
        received already (handed over again after a reconnection)."""
        last = self.last
        if last is not None and sequence <= last:
            return False
        jump = sequence - last - 1 if last is not None else 0
        self._jumps += jump
        self._stream_jumps += jump
        self.last = sequence
        if self._awaiting:  # the jump revealed the last stream's tail, and this stream's
            self._awaiting = False  # drops so far (as many as it reported)
            self._stream_jumps = min(jump, reported)
        return True

    def report(self, dropped: int) -> None:
        """A message's drop count (the server's, for the current stream)."""
        if not self._awaiting:
            self._reported = dropped
